//! Dual-horizon ordinary state-based PD in 2D (zeng2024 (13)–(14); Ren et al.'s DH-PD as the
//! paper uses it; extraction `seed-002-dual-horizon` §2): a horizon per particle, a directed
//! bond k → j for every j in H_k = {j : |x_j − x_k| < δ_k} (strict, zeng2024 (1)), each with its
//! own bond state μ_kj and quadrature weights. The direct force of bond k → j acts on k and its
//! reaction on j, so momentum is conserved to round-off for any mix of particle sizes
//! (seed-002 §2 implementation note); the dual horizon H'_k is the list of bonds j → k.
//!
//! Quadrature weights (`BondWeights`): the paper uses V_j with Madenci's energy-based surface
//! correction (zeng2024 Sect. 2, no formulas). At its δ = 3.015 Δ the plain V_j sums miss the
//! continuum moments by 2–4 % (θ by −2 %, the distortion term's ξ̂⁴ moments by +3.7 % and −1 %,
//! measured in the module's tests), and Madenci's two scalar factors per particle fix the
//! uniaxial response only. `Moments` (the default) is our stand-in, stated as a departure:
//! per particle, the minimum-norm change of V_j that makes the even moments the energy reads
//! exact — Σ ω_θ ξ̂⊗ξ̂ = (π h δ²/2) I for θ and Σ ω_b |ξ| ξ̂⊗ξ̂⊗ξ̂⊗ξ̂ its continuum value for the
//! distortion term — so every homogeneous small strain gives the classical energy and stress,
//! in the bulk and at free edges (the surface effect), whatever the particle sizes nearby.

use rayon::prelude::*;

use crate::discretization::buckets::Buckets;
use crate::model::osb::OsbHorizon;
pub use crate::scene::BondWeights;

mod forces;
mod kernel;
mod quadrature;

/// Smallest weight factor ω/V_j a moment fit may produce; below it the particle falls back
/// to one scalar factor per term (Madenci's kind of correction), which keeps every bond's
/// weight positive.
const MIN_WEIGHT_FACTOR: f64 = 0.05;

/// The particles the bonds connect, read-only during a step.
#[derive(Clone, Copy)]
pub struct Body<'a> {
    pub reference: &'a [[f64; 2]],
    pub volumes: &'a [f64],
    /// Per particle: its horizon's constants (δ_k, a, b, d, s_c).
    pub constants: &'a [OsbHorizon],
    /// The out-of-plane thickness h.
    pub thickness: f64,
}

/// What the force pass gives per particle.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct ParticleTerms {
    /// Internal force (N): Σ_{H_k} F_kj − Σ_{H'_k} F_jk, zeng2024 (13) times V_k.
    pub force: [f64; 2],
    /// θ_k (5).
    pub dilatation: f64,
    /// W_k (4), J/m³.
    pub energy_density: f64,
    /// φ_k (14) after the pass's breaks.
    pub damage: f64,
    /// ε_xx, ε_yy of (17).
    pub strains: [f64; 2],
}

/// A bond column written from a particle-parallel pass: each task reads and writes the slots
/// of the row it visits. Sound because rows are disjoint slot ranges (`DualBonds`' invariant,
/// checked by `DualBonds::rows_are_disjoint` in the tests; dead slots lie in no row) and every
/// row is visited by one task only.
struct RowSlots<T> {
    column: *mut T,
    len: usize,
}

// SAFETY: tasks touch disjoint slots (see the type's documentation).
unsafe impl<T: Send> Sync for RowSlots<T> {}

impl<T: Copy> RowSlots<T> {
    fn new(column: &mut [T]) -> RowSlots<T> {
        RowSlots {
            column: column.as_mut_ptr(),
            len: column.len(),
        }
    }

    /// The slots `range` as a slice.
    ///
    /// # Safety
    /// `range` is (part of) the row the calling task visits.
    #[inline(always)]
    #[allow(clippy::mut_from_ref)]
    unsafe fn slice_mut(&self, range: std::ops::Range<usize>) -> &mut [T] {
        assert!(range.start <= range.end && range.end <= self.len);
        // SAFETY: in bounds (checked above); no other task touches these slots.
        unsafe { std::slice::from_raw_parts_mut(self.column.add(range.start), range.len()) }
    }

    /// # Safety
    /// Slot `b` lies in the row the calling task visits.
    #[inline(always)]
    unsafe fn write(&self, b: usize, value: T) {
        assert!(b < self.len);
        unsafe { self.column.add(b).write(value) }
    }
}

/// Marks a bond slot that belongs to no row (a row replaced by a split left it behind).
const DEAD: u32 = u32::MAX;

/// Directed bonds in CSR form with their dual lists. A split replaces only the rows it
/// changes: their new bonds are appended and their old slots left dead (owner `DEAD`, μ = 0),
/// and the dual lists of the particles they touch are appended likewise; the arrays are
/// compacted when the dead slots outnumber half the live ones, so a split costs the rows it
/// touches and the compaction is amortized over many splits (issue 17: families rebuilt
/// locally, not a global rebuild per split). Every bond-parallel pass skips dead slots.
#[derive(Debug, Clone, Default)]
pub struct DualBonds {
    /// Bonds of particle k: `starts[k]..ends[k]`.
    starts: Vec<usize>,
    ends: Vec<usize>,
    /// Slots that belong to no row.
    dead: usize,
    /// Bond slots: the neighbor j of each, its μ and its two weights.
    pub neighbors: Vec<u32>,
    /// μ: 1 intact, 0 broken (irreversible).
    pub intact: Vec<u8>,
    pub weight_theta: Vec<f64>,
    pub weight_distortion: Vec<f64>,
    weights: BondWeights,
    /// Owner k of each bond (the bond-parallel passes read it).
    owner: Vec<u32>,
    /// |ξ| of each bond (the reference never changes under a bond).
    lengths: Vec<f64>,
    /// Bonds j → k of each particle k: `dual[dual_starts[k]..dual_ends[k]]`.
    dual_starts: Vec<usize>,
    dual_ends: Vec<usize>,
    /// Every live bond's slot once; the rest (up to its length) lies in no particle's list.
    dual: Vec<u32>,
    /// Particles whose moment fit fell back to scalar factors.
    pub fallbacks: usize,
    /// Per particle, the energy density from which the force pass also gives its strains
    /// (the input of the strain criterion (16)); its damage (15) comes with every finite
    /// gate. `f64::INFINITY`: the particle cannot split (nothing computed); empty where
    /// nothing splits. Set by the simulation (`mark_splittable`).
    pub criteria: Vec<f64>,
    /// Per particle, Σ_{H_k} V_j + Σ_{H'_k} V_j: the denominator of the damage (14).
    row_volume: Vec<f64>,
    /// Per slot, where its reaction goes in `reactions`: its entry in the dual list of its
    /// neighbor.
    reaction_slot: Vec<u32>,
    /// F_kj of each bond in dual-list order, written by the force pass at `reaction_slot` so
    /// the reactions' pass reads them in sequence; zero for broken bonds.
    reactions: Vec<[f64; 2]>,
}

/// A particle's new family after a split.
#[derive(Debug, Clone)]
pub struct NewRow {
    pub particle: u32,
    pub neighbors: Vec<u32>,
    /// μ of each bond.
    pub states: Vec<u8>,
    /// 1 where the bond counts in the weight fit (not cut by a pre-crack: the pre-crack is a
    /// surface, bonds broken during the run soften the material).
    pub fitted: Vec<u8>,
}

/// |x_j − x_k|.
fn bond_length(reference: &[[f64; 2]], k: usize, j: usize) -> f64 {
    let (x, y) = (reference[k], reference[j]);
    let xi = [y[0] - x[0], y[1] - x[1]];
    (xi[0] * xi[0] + xi[1] * xi[1]).sqrt()
}

/// The family of particle k among `candidates`: j ≠ k with |x_j − x_k| < δ_k, sorted.
pub fn family_of(k: usize, body: &Body, candidates: impl Iterator<Item = u32>) -> Vec<u32> {
    let x = body.reference[k];
    let delta = body.constants[k].horizon;
    let mut row: Vec<u32> = candidates
        .filter(|&j| {
            let y = body.reference[j as usize];
            j as usize != k && (y[0] - x[0]).powi(2) + (y[1] - x[1]).powi(2) < delta * delta
        })
        .collect();
    row.sort_unstable();
    row.dedup();
    row
}

impl DualBonds {
    /// Every particle's family found through `buckets` (cells at least max δ wide), all bonds
    /// intact.
    pub fn build(body: &Body, buckets: &Buckets, weights: BondWeights) -> DualBonds {
        let rows: Vec<Vec<u32>> = (0..body.reference.len())
            .into_par_iter()
            .map(|k| {
                let mut found = Vec::new();
                let delta = body.constants[k].horizon;
                buckets.within(body.reference, &body.reference[k], delta, |j| found.push(j));
                family_of(k, body, found.into_iter())
            })
            .collect();
        let mut bonds = DualBonds {
            weights,
            ..DualBonds::default()
        };
        let states: Vec<Vec<u8>> = rows.iter().map(|r| vec![1; r.len()]).collect();
        bonds.assemble(body, &rows, &states, &states);
        bonds
    }

    pub fn particle_count(&self) -> usize {
        self.starts.len()
    }

    /// Directed bonds in the particles' rows.
    pub fn bond_count(&self) -> usize {
        self.neighbors.len() - self.dead
    }

    /// Bond slots, dead ones included: the length of `neighbors`, `intact` and the weights.
    pub fn slot_count(&self) -> usize {
        self.neighbors.len()
    }

    /// Particle k's bond slots.
    /// Verification: every row lies inside the slot arrays and no two rows share a slot (the
    /// invariant the particle-parallel force pass writes by).
    pub fn rows_are_disjoint(&self) -> bool {
        let mut rows: Vec<(usize, usize)> = (0..self.particle_count())
            .map(|k| (self.starts[k], self.ends[k]))
            .filter(|(start, end)| start < end)
            .collect();
        rows.sort_unstable();
        rows.iter()
            .all(|&(start, end)| end <= self.neighbors.len() && start < end)
            && rows.windows(2).all(|w| w[0].1 <= w[1].0)
    }

    pub fn range(&self, k: usize) -> std::ops::Range<usize> {
        self.starts[k]..self.ends[k]
    }

    pub fn dual_bonds(&self, k: usize) -> &[u32] {
        &self.dual[self.dual_starts[k]..self.dual_ends[k]]
    }

    /// The rows as a compact CSR: offsets (n + 1) and the neighbors in row order.
    pub fn compact_rows(&self) -> (Vec<usize>, Vec<u32>) {
        let n = self.particle_count();
        let mut offsets = Vec::with_capacity(n + 1);
        let mut neighbors = Vec::with_capacity(self.bond_count());
        offsets.push(0);
        for k in 0..n {
            neighbors.extend_from_slice(&self.neighbors[self.range(k)]);
            offsets.push(neighbors.len());
        }
        (offsets, neighbors)
    }

    pub fn weights(&self) -> BondWeights {
        self.weights
    }

    /// Replaces the families of the particles in `rows` (the other particles keep theirs) for
    /// a body of `body.reference.len()` particles, touching only what they change: the new
    /// rows are appended and fitted, the dual lists and damage denominators of the particles
    /// they reach (old or new bonds) are renewed, and the arrays are compacted when the dead
    /// slots outnumber half the live ones.
    pub fn replace_rows(&mut self, body: &Body, rows: &[NewRow]) {
        let n = body.reference.len();
        self.starts.resize(n, 0);
        self.ends.resize(n, 0);
        self.dual_starts.resize(n, 0);
        self.dual_ends.resize(n, 0);
        self.row_volume.resize(n, 0.0);
        let mut touched = vec![false; n];
        for row in rows {
            let k = row.particle as usize;
            touched[k] = true;
            for b in self.range(k) {
                touched[self.neighbors[b] as usize] = true;
                self.owner[b] = DEAD;
                self.intact[b] = 0;
            }
            self.dead += self.range(k).len();
        }
        // The new rows at the end, with μ = the fit's flags until the fit has read them.
        let first_new = self.neighbors.len();
        for row in rows {
            let k = row.particle as usize;
            self.starts[k] = self.neighbors.len();
            self.neighbors.extend_from_slice(&row.neighbors);
            self.owner
                .extend(std::iter::repeat_n(row.particle, row.neighbors.len()));
            self.intact.extend_from_slice(&row.fitted);
            self.lengths.extend(
                row.neighbors
                    .iter()
                    .map(|&j| bond_length(body.reference, k, j as usize)),
            );
            self.ends[k] = self.neighbors.len();
            for &j in &row.neighbors {
                touched[j as usize] = true;
            }
        }
        let total = self.neighbors.len();
        for column in [&mut self.weight_theta, &mut self.weight_distortion] {
            column.resize(total, 0.0);
        }
        self.reaction_slot.resize(total, 0);
        let replaced: Vec<usize> = rows.iter().map(|r| r.particle as usize).collect();
        self.fallbacks += self.fit_rows(body, &replaced);
        for row in rows {
            let r = self.range(row.particle as usize);
            self.intact[r].copy_from_slice(&row.states);
        }
        // The touched particles' dual lists: their old bonds still in a row, then the new
        // bonds that reach them, in slot order; in place where the list was when they fit
        // (a replaced row's bond to j usually dies and returns), else moved to the end.
        let mut arriving: Vec<(u32, u32)> = (first_new..total)
            .map(|b| (self.neighbors[b], b as u32))
            .collect();
        arriving.sort_unstable();
        let mut next = 0;
        for j in (0..n).filter(|&j| touched[j]) {
            while next < arriving.len() && (arriving[next].0 as usize) < j {
                next += 1;
            }
            let from = next;
            while next < arriving.len() && arriving[next].0 as usize == j {
                next += 1;
            }
            let new_bonds = &arriving[from..next];
            let (start, end) = (self.dual_starts[j], self.dual_ends[j]);
            let mut kept = start;
            for d in start..end {
                let b = self.dual[d];
                if self.owner[b as usize] != DEAD {
                    self.dual[kept] = b;
                    kept += 1;
                }
            }
            if kept + new_bonds.len() <= end {
                for (slot, &(_, b)) in self.dual[kept..].iter_mut().zip(new_bonds) {
                    *slot = b;
                }
                self.dual_ends[j] = kept + new_bonds.len();
            } else {
                let at = self.dual.len();
                self.dual.extend_from_within(start..kept);
                self.dual.extend(new_bonds.iter().map(|&(_, b)| b));
                (self.dual_starts[j], self.dual_ends[j]) = (at, self.dual.len());
            }
        }
        self.reactions.resize(self.dual.len(), [0.0; 2]);
        for j in (0..n).filter(|&j| touched[j]) {
            self.row_volume[j] = self.row_volume_of(j, body.volumes);
            self.place_reactions(j);
        }
        let dual_dead = self.dual.len() - self.bond_count();
        if 2 * self.dead > self.bond_count() || 2 * dual_dead > self.bond_count() {
            self.compact();
        }
    }

    /// Moves every row's bonds together in particle order (dead slots dropped) and rebuilds
    /// the dual lists; weights, states and lengths move with their bonds.
    fn compact(&mut self) {
        let n = self.particle_count();
        let order: Vec<usize> = (0..n).flat_map(|k| self.range(k)).collect();
        fn gather<T: Copy>(column: &mut Vec<T>, order: &[usize]) {
            *column = order.iter().map(|&b| column[b]).collect();
        }
        gather(&mut self.neighbors, &order);
        gather(&mut self.owner, &order);
        gather(&mut self.intact, &order);
        gather(&mut self.lengths, &order);
        gather(&mut self.weight_theta, &order);
        gather(&mut self.weight_distortion, &order);
        let mut at = 0;
        for k in 0..n {
            let len = self.ends[k] - self.starts[k];
            (self.starts[k], self.ends[k]) = (at, at + len);
            at += len;
        }
        self.dead = 0;
        self.rebuild_dual(n);
    }

    /// Writes the CSR arrays from per-particle lists and fits every row's weights over the
    /// bonds flagged in `fitted`; `states` are the bonds' μ after the fit.
    fn assemble(
        &mut self,
        body: &Body,
        lists: &[Vec<u32>],
        states: &[Vec<u8>],
        fitted: &[Vec<u8>],
    ) {
        let n = lists.len();
        self.starts.clear();
        self.ends.clear();
        let mut at = 0;
        for l in lists {
            self.starts.push(at);
            at += l.len();
            self.ends.push(at);
        }
        let total = at;
        self.dead = 0;
        self.neighbors = lists.concat();
        self.owner = (0..n)
            .flat_map(|k| std::iter::repeat_n(k as u32, lists[k].len()))
            .collect();
        // The fit reads the bonds a row is fitted over; the states are set after it.
        self.intact = (0..n)
            .flat_map(|k| {
                let row = if fitted[k].len() == lists[k].len() {
                    &fitted[k]
                } else {
                    &states[k]
                };
                row.iter().copied()
            })
            .collect();
        self.lengths = (0..total)
            .map(|b| {
                bond_length(
                    body.reference,
                    self.owner[b] as usize,
                    self.neighbors[b] as usize,
                )
            })
            .collect();
        self.weight_theta = vec![0.0; total];
        self.weight_distortion = vec![0.0; total];
        let all: Vec<usize> = (0..n).collect();
        self.fallbacks = self.fit_rows(body, &all);
        self.intact = states.concat();
        self.rebuild_dual(n);
        self.row_volume = (0..n)
            .map(|k| self.row_volume_of(k, body.volumes))
            .collect();
    }

    /// Σ_{H_k} V_j + Σ_{H'_k} V_j: the denominator of particle k's damage (14).
    fn row_volume_of(&self, k: usize, volumes: &[f64]) -> f64 {
        let own: f64 = self.neighbors[self.range(k)]
            .iter()
            .map(|&j| volumes[j as usize])
            .sum();
        let dual: f64 = self
            .dual_bonds(k)
            .iter()
            .map(|&b| volumes[self.owner[b as usize] as usize])
            .sum();
        own + dual
    }

    /// The dual lists by a counting sort of the live bonds by target.
    fn rebuild_dual(&mut self, n: usize) {
        let mut counts = vec![0usize; n + 1];
        for (&j, &k) in self.neighbors.iter().zip(&self.owner) {
            if k != DEAD {
                counts[j as usize + 1] += 1;
            }
        }
        for k in 0..n {
            counts[k + 1] += counts[k];
        }
        let mut fill = counts.clone();
        let mut dual = vec![0u32; counts[n]];
        for (b, (&j, &k)) in self.neighbors.iter().zip(&self.owner).enumerate() {
            if k != DEAD {
                dual[fill[j as usize]] = b as u32;
                fill[j as usize] += 1;
            }
        }
        self.dual_starts = counts[..n].to_vec();
        self.dual_ends = counts[1..].to_vec();
        self.dual = dual;
        self.reactions = vec![[0.0; 2]; self.dual.len()];
        self.reaction_slot = vec![0; self.neighbors.len()];
        for k in 0..n {
            self.place_reactions(k);
        }
    }

    /// Points the bonds of particle k's dual list at their entries (the force pass writes
    /// every live bond's entry, zero where the bond is broken, before anything reads them).
    fn place_reactions(&mut self, k: usize) {
        for d in self.dual_starts[k]..self.dual_ends[k] {
            self.reaction_slot[self.dual[d] as usize] = d as u32;
        }
    }

    /// The bond state μ_kj of k's bond to j (None: j is not in H_k).
    pub fn state(&self, k: usize, j: u32) -> Option<u8> {
        let r = self.range(k);
        self.neighbors[r.clone()]
            .binary_search(&j)
            .ok()
            .map(|p| self.intact[r.start + p])
    }

    /// Bytes held per directed bond (bond arrays, dual lists and scratch).
    pub fn bytes_per_bond(&self) -> f64 {
        // neighbor, owner, dual entry, reaction slot: u32; μ: u8; length, two weights: f64;
        // reaction: 2 f64.
        (4 * 4 + 1 + 3 * 8 + 16) as f64
    }
}
