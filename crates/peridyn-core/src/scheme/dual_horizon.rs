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

use nalgebra::{SMatrix, SVector};
use rayon::prelude::*;

use crate::discretization::buckets::Buckets;
use crate::model::osb::OsbHorizon;
pub use crate::scene::BondWeights;

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

    /// # Safety
    /// Slot `b` lies in the row the calling task visits.
    #[inline(always)]
    unsafe fn read(&self, b: usize) -> T {
        assert!(b < self.len);
        unsafe { self.column.add(b).read() }
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

/// Bond k → j's deformed vector η, 1/|η|, stretch, cosine and 1/|ξ| (|ξ| = `l0`), with one
/// division: the force pass evaluates every bond twice per step.
#[inline(always)]
fn bond_kinematics(
    x: &[[f64; 2]],
    y: &[[f64; 2]],
    l0: f64,
    k: usize,
    j: usize,
) -> ([f64; 2], f64, f64, f64, f64) {
    let xi = [x[j][0] - x[k][0], x[j][1] - x[k][1]];
    let eta = [y[j][0] - y[k][0], y[j][1] - y[k][1]];
    let l = (eta[0] * eta[0] + eta[1] * eta[1]).sqrt();
    let inverse = 1.0 / (l * l0);
    let (inverse_l, inverse_l0) = (l0 * inverse, l * inverse);
    let stretch = (l - l0) * inverse_l0;
    let cosine = (xi[0] * eta[0] + xi[1] * eta[1]) * inverse;
    (eta, inverse_l, stretch, cosine, inverse_l0)
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

    /// Fits the weights of `rows` (their bonds' μ flag the bonds fitted over); returns how
    /// many fell back to scalar factors.
    fn fit_rows(&mut self, body: &Body, rows: &[usize]) -> usize {
        let fitted: Vec<(Vec<f64>, Vec<f64>, bool)> =
            rows.par_iter().map(|&k| self.fit_row(k, body)).collect();
        let mut fallbacks = 0;
        for (&k, (theta, distortion, fell_back)) in rows.iter().zip(fitted) {
            let r = self.range(k);
            self.weight_theta[r.clone()].copy_from_slice(&theta);
            self.weight_distortion[r].copy_from_slice(&distortion);
            fallbacks += usize::from(fell_back);
        }
        fallbacks
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

    /// Refits every particle's weights over its bonds intact now: a pre-crack cut before the
    /// fit is a free surface whose faces keep the bulk stiffness (as Madenci's correction
    /// computed on the pre-cracked body does); bonds broken later soften the material.
    pub fn refit(&mut self, body: &Body) {
        let n = self.particle_count();
        let lists: Vec<Vec<u32>> = (0..n)
            .map(|k| self.neighbors[self.range(k)].to_vec())
            .collect();
        let states: Vec<Vec<u8>> = (0..n)
            .map(|k| self.intact[self.range(k)].to_vec())
            .collect();
        self.assemble(body, &lists, &states, &states);
    }

    /// Particle k's two weight sets over its intact bonds (0 on broken ones), and whether its
    /// moment fit fell back.
    fn fit_row(&self, k: usize, body: &Body) -> (Vec<f64>, Vec<f64>, bool) {
        let r = self.range(k);
        let x = body.reference[k];
        let all: Vec<f64> = self.neighbors[r.clone()]
            .iter()
            .map(|&j| body.volumes[j as usize])
            .collect();
        if self.weights == BondWeights::Volume || all.is_empty() {
            return (all.clone(), all, false);
        }
        let intact: Vec<usize> = r.clone().filter(|&b| self.intact[b] != 0).collect();
        let volumes: Vec<f64> = intact
            .iter()
            .map(|&b| body.volumes[self.neighbors[b] as usize])
            .collect();
        let geometry: Vec<([f64; 2], f64)> = intact
            .iter()
            .map(|&b| self.neighbors[b])
            .map(|j| {
                let y = body.reference[j as usize];
                let xi = [y[0] - x[0], y[1] - x[1]];
                let len = (xi[0] * xi[0] + xi[1] * xi[1]).sqrt();
                ([xi[0] / len, xi[1] / len], len)
            })
            .collect();
        let delta = body.constants[k].horizon;
        let h = body.thickness;
        use std::f64::consts::PI;
        // ∫_H ξ̂⊗ξ̂ dV = (π h δ²/2) I; ∫_H |ξ| ξ̂⁴ dV = (h δ³/3) ∫ ξ̂⁴ dφ.
        let area = PI * h * delta * delta / 2.0;
        let theta_target = SVector::<f64, 3>::new(area, 0.0, area);
        let quartic = h * delta.powi(3) / 3.0;
        let distortion_target = SVector::<f64, 5>::new(
            0.75 * PI * quartic,
            0.0,
            0.25 * PI * quartic,
            0.0,
            0.75 * PI * quartic,
        );
        let second = |(e, _): &([f64; 2], f64)| {
            SVector::<f64, 3>::new(e[0] * e[0], e[0] * e[1], e[1] * e[1])
        };
        let fourth = |(e, _): &([f64; 2], f64)| {
            let (a, b) = (e[0], e[1]);
            SVector::<f64, 5>::new(
                a * a * a * a,
                a * a * a * b,
                a * a * b * b,
                a * b * b * b,
                b * b * b * b,
            )
        };
        let (theta, theta_fell) = moment_fit(&geometry, &volumes, second, |_| 1.0, theta_target);
        let (distortion, distortion_fell) = moment_fit(
            &geometry,
            &volumes,
            fourth,
            |(_, len)| *len,
            distortion_target,
        );
        // Back onto the whole row: zero weight on the broken bonds.
        let spread = |fitted: Vec<f64>| {
            let mut row = vec![0.0; all.len()];
            for (&b, w) in intact.iter().zip(fitted) {
                row[b - r.start] = w;
            }
            row
        };
        (
            spread(theta),
            spread(distortion),
            theta_fell || distortion_fell,
        )
    }

    /// The force pass (zeng2024 (9)–(13)), in two particle-parallel passes. First, per
    /// particle k over its row H_k: break every intact bond whose stretch reaches k's s_c
    /// (irreversible), sum θ_k (5) over the intact ones, then (the row still in cache) each
    /// bond's force F_kj, which depends on k's state only, stored for the reactions; Σ_{H_k} F_kj
    /// and W_k (4). Second, per particle, the reactions −Σ_{H'_k} F_jk and the split criteria.
    /// Stretch and cosine are recomputed in the second loop over the row rather than stored,
    /// so a bond costs about 50 bytes of memory traffic per step instead of 170 (the pass is
    /// memory-bound). Returns the bonds broken now. Allocation-free.
    pub fn evaluate(
        &mut self,
        body: &Body,
        positions: &[[f64; 2]],
        out: &mut [ParticleTerms],
    ) -> u64 {
        let (starts, ends, neighbors, lengths) =
            (&self.starts, &self.ends, &self.neighbors, &self.lengths);
        let (weight_theta, weight_distortion) = (&self.weight_theta, &self.weight_distortion);
        let criteria = &self.criteria;
        let intact = RowSlots::new(&mut self.intact);
        let reaction_slot = &self.reaction_slot;
        // SAFETY of its writes: each live slot's entry belongs to that slot alone.
        let reactions = RowSlots::new(&mut self.reactions);
        let (x, y) = (body.reference, positions);
        let kinematics = |k: usize, j: usize, b: usize| bond_kinematics(x, y, lengths[b], k, j);
        let broken: u64 = out
            .par_iter_mut()
            .enumerate()
            .map(|(k, t)| {
                let c = &body.constants[k];
                let row = starts[k]..ends[k];
                let mut broken = 0;
                let mut theta = 0.0;
                for b in row.clone() {
                    // SAFETY (both columns): slot b lies in row k alone (rows are disjoint,
                    // `RowSlots`), and this task is the only one visiting row k.
                    if unsafe { intact.read(b) } == 0 {
                        continue;
                    }
                    let (_, _, stretch, cosine, _) = kinematics(k, neighbors[b] as usize, b);
                    if stretch >= c.critical_stretch {
                        unsafe { intact.write(b, 0) };
                        broken += 1;
                    } else {
                        theta += c.dilatation_term(cosine, stretch, weight_theta[b]);
                    }
                }
                let gated = criteria.get(k).is_some_and(|g| g.is_finite());
                let (mut force, mut distortion, mut lost) = ([0.0; 2], 0.0, 0.0);
                for b in row {
                    let j = neighbors[b] as usize;
                    if unsafe { intact.read(b) } == 0 {
                        // Every pass, not only at the break: μ is a public column that
                        // pre-cracks and restarts set directly.
                        unsafe { reactions.write(reaction_slot[b] as usize, [0.0; 2]) };
                        if gated {
                            lost += body.volumes[j];
                        }
                        continue;
                    }
                    let (eta, inverse_l, stretch, cosine, inverse_l0) = kinematics(k, j, b);
                    let scalar = c.bond_scalar(
                        theta,
                        cosine,
                        stretch,
                        inverse_l0,
                        weight_theta[b],
                        weight_distortion[b],
                    ) * body.volumes[k]
                        * inverse_l;
                    let f = [scalar * eta[0], scalar * eta[1]];
                    unsafe { reactions.write(reaction_slot[b] as usize, f) };
                    force[0] += f[0];
                    force[1] += f[1];
                    distortion += c.distortion_energy(stretch, lengths[b], weight_distortion[b]);
                }
                t.dilatation = theta;
                t.force = force;
                t.energy_density = c.a * theta * theta + distortion;
                // The row's part of the lost volume (15), finished by the reactions' pass.
                t.damage = lost;
                broken
            })
            .sum();
        let (reactions, intact, owner) = (&self.reactions, &self.intact, &self.owner);
        let (dual_starts, dual_ends, dual) = (&self.dual_starts, &self.dual_ends, &self.dual);
        out.par_iter_mut().enumerate().for_each(|(k, t)| {
            let gate = self.criteria.get(k).copied().unwrap_or(f64::INFINITY);
            let list = dual_starts[k]..dual_ends[k];
            for f in &reactions[list.clone()] {
                t.force[0] -= f[0];
                t.force[1] -= f[1];
            }
            let mut lost = t.damage;
            if gate.is_finite() {
                for &b in &dual[list] {
                    if intact[b as usize] == 0 {
                        lost += body.volumes[owner[b as usize] as usize];
                    }
                }
            }
            if !gate.is_finite() {
                t.damage = 0.0;
                return;
            }
            // The splitting criteria's inputs.
            t.damage = if self.row_volume[k] > 0.0 {
                lost / self.row_volume[k]
            } else {
                0.0
            };
            t.strains = if lost > 0.0 || t.energy_density >= gate {
                self.normal_strains(k, body, positions)
            } else {
                [0.0; 2]
            };
        });
        broken
    }

    /// Σ_{H_k} F_kj ⊗ ξ_kj / V_k, the particle's stress from its own bonds after `evaluate`
    /// (for a homogeneous deformation, ∂W_k/∂ε).
    pub fn stress(&self, k: usize, body: &Body) -> [[f64; 2]; 2] {
        let x = body.reference;
        let mut sigma = [[0.0; 2]; 2];
        for b in self.range(k) {
            let j = self.neighbors[b] as usize;
            let xi = [x[j][0] - x[k][0], x[j][1] - x[k][1]];
            for (p, row) in sigma.iter_mut().enumerate() {
                for (q, s) in row.iter_mut().enumerate() {
                    let force = self.reactions[self.reaction_slot[b] as usize];
                    *s += force[p] * xi[q] / body.volumes[k];
                }
            }
        }
        sigma
    }

    /// Damage (14) of every particle.
    pub fn damage(&self, volumes: &[f64]) -> Vec<f64> {
        (0..self.particle_count())
            .into_par_iter()
            .map(|k| self.damage_of(k, volumes))
            .collect()
    }

    /// Damage (14) of particle k:
    /// 1 − (Σ_{H_k} μ V_j + Σ_{H'_k} μ V_j) / (Σ_{H_k} V_j + Σ_{H'_k} V_j). The force pass's
    /// split check reads the same quantity as `lost_volume / row_volume` (equal to rounding);
    /// frames keep this form, whose values the crack-angle and branch estimators threshold
    /// (a damage of exactly 0.5 on the lattice must stay on the same side of 0.5).
    pub fn damage_of(&self, k: usize, volumes: &[f64]) -> f64 {
        let (mut intact, mut all) = (0.0, 0.0);
        for b in self.range(k) {
            let v = volumes[self.neighbors[b] as usize];
            all += v;
            intact += v * f64::from(self.intact[b]);
        }
        for &b in self.dual_bonds(k) {
            let v = volumes[self.owner[b as usize] as usize];
            all += v;
            intact += v * f64::from(self.intact[b as usize]);
        }
        if all > 0.0 { 1.0 - intact / all } else { 0.0 }
    }

    /// Per particle, a Gershgorin-type row sum of the linearized stiffness (N/m): each intact
    /// bond's distortional stiffness 2 δ b ω_b V_k / |ξ| counted twice in the rows of both ends,
    /// and the dilatation coupling 2 |2 a d² δ²| V_k (Σ ω_θ / |ξ|)² in its owner's row. The
    /// shape of ADR's fictitious density (Kilic & Madenci's ¼ Σ_j |K_ij|, scaled by the caller)
    /// and of the stable-step estimate.
    pub fn stiffness_rows(&self, body: &Body) -> Vec<f64> {
        let n = self.particle_count();
        let bond_stiffness = |b: usize| -> f64 {
            let k = self.owner[b] as usize;
            let c = &body.constants[k];
            f64::from(self.intact[b])
                * 2.0
                * c.horizon
                * c.b
                * self.weight_distortion[b]
                * body.volumes[k]
                / self.lengths[b]
        };
        (0..n)
            .into_par_iter()
            .map(|k| {
                let c = &body.constants[k];
                let mut row = 0.0;
                let mut theta = 0.0;
                for b in self.range(k) {
                    row += 2.0 * bond_stiffness(b);
                    theta += f64::from(self.intact[b]) * self.weight_theta[b] / self.lengths[b];
                }
                for &b in self.dual_bonds(k) {
                    row += 2.0 * bond_stiffness(b as usize);
                }
                let coupling =
                    2.0 * (2.0 * c.a * c.d * c.d * c.horizon * c.horizon).abs() * body.volumes[k];
                row + coupling * theta * theta
            })
            .collect()
    }

    /// The accumulated normal strains ε_xx, ε_yy of (17) over the intact bonds of H_k, in the
    /// regression form of seed-002 §3.1 ambiguity 1 (Σ μ (Δu·n_i)(ξ·n_i) V / Σ μ (ξ·n_i)² V:
    /// the printed division by (x_j − x_k)·n_i is singular for bonds across the axis).
    pub fn normal_strains(&self, k: usize, body: &Body, positions: &[[f64; 2]]) -> [f64; 2] {
        let (x, y) = (body.reference, positions);
        let mut num = [0.0; 2];
        let mut den = [0.0; 2];
        for b in self.range(k) {
            if self.intact[b] == 0 {
                continue;
            }
            let j = self.neighbors[b] as usize;
            let v = body.volumes[j];
            for i in 0..2 {
                let xi = x[j][i] - x[k][i];
                let du = (y[j][i] - x[j][i]) - (y[k][i] - x[k][i]);
                num[i] += du * xi * v;
                den[i] += xi * xi * v;
            }
        }
        [0, 1].map(|i| if den[i] > 0.0 { num[i] / den[i] } else { 0.0 })
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

/// Weights ω_b = V_b (1 + g_b), g_b = Σ_p c_p q_p(ξ̂_b) over the direction monomials q, with
/// the moments Σ_b ω_b r_b q(ξ̂_b) = target (r_b: `radial`, 1 or |ξ|) and Σ V r g² least (the
/// Gram system). The monomials span the constant (ξ̂ₓ² + ξ̂ᵧ² = 1 and its square), so a
/// particle on a straight free edge gets g = 1 exactly (its half horizon counted twice). Where
/// the Gram matrix is singular or a weight factor would fall below `MIN_WEIGHT_FACTOR`, the one
/// scalar factor that matches the target's trace.
fn moment_fit<const P: usize>(
    geometry: &[([f64; 2], f64)],
    volumes: &[f64],
    monomials: impl Fn(&([f64; 2], f64)) -> SVector<f64, P>,
    radial: impl Fn(&([f64; 2], f64)) -> f64,
    target: SVector<f64, P>,
) -> (Vec<f64>, bool) {
    let q: Vec<SVector<f64, P>> = geometry.iter().map(&monomials).collect();
    let r: Vec<f64> = geometry.iter().map(&radial).collect();
    let mut gram = SMatrix::<f64, P, P>::zeros();
    let mut current = SVector::<f64, P>::zeros();
    for ((qb, &v), &rb) in q.iter().zip(volumes).zip(&r) {
        gram += qb * qb.transpose() * (v * rb);
        current += qb * (v * rb);
    }
    if let Some(chol) = gram.cholesky() {
        let c = chol.solve(&(target - current));
        let factors: Vec<f64> = q.iter().map(|qb| 1.0 + c.dot(qb)).collect();
        if factors.iter().all(|&f| f >= MIN_WEIGHT_FACTOR) {
            return (
                factors.iter().zip(volumes).map(|(f, v)| f * v).collect(),
                false,
            );
        }
    }
    // The scalar fallback: the trace of the moments (xx + yy for θ; the sum of the ξ̂⁴
    // diagonal entries, xxxx + 2 xxyy + yyyy, for the distortion term).
    let trace = |m: &SVector<f64, P>| match P {
        3 => m[0] + m[2],
        _ => m[0] + 2.0 * m[2] + m[4],
    };
    let factor = if trace(&current) > 0.0 {
        trace(&target) / trace(&current)
    } else {
        1.0
    };
    (volumes.iter().map(|v| v * factor).collect(), true)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::osb::OsbMaterial;
    use crate::model::pmb::Plane;

    /// A square lattice of n × n particles at spacing dx, δ = 3.015 dx.
    fn lattice(n: usize, dx: f64) -> (Vec<[f64; 2]>, Vec<f64>) {
        let x = (0..n * n)
            .map(|k| [(k % n) as f64 * dx, (k / n) as f64 * dx])
            .collect();
        (x, vec![dx * dx; n * n])
    }

    #[test]
    fn plain_volumes_miss_the_continuum_moments_by_a_few_percent() {
        // The figures quoted in the module notes: θ's moment −2 %, distortion's +3.7 %.
        let m = OsbMaterial {
            youngs_modulus: 1.0,
            poisson_ratio: 0.25,
            plane: Plane::Stress,
            thickness: 1.0,
            fracture_energy: None,
        };
        let (x, v) = lattice(15, 1.0);
        let constants = vec![m.at(3.015); x.len()];
        let body = Body {
            reference: &x,
            volumes: &v,
            constants: &constants,
            thickness: 1.0,
        };
        let buckets = Buckets::new(&x, 3.1, 0.0);
        let bonds = DualBonds::build(&body, &buckets, BondWeights::Volume);
        let k = 7 * 15 + 7;
        let (mut m2, mut m4) = (0.0, 0.0);
        for b in bonds.range(k) {
            let j = bonds.neighbors[b] as usize;
            let xi = [x[j][0] - x[k][0], x[j][1] - x[k][1]];
            let l = (xi[0] * xi[0] + xi[1] * xi[1]).sqrt();
            m2 += bonds.weight_theta[b] * (xi[0] / l).powi(2);
            m4 += bonds.weight_distortion[b] * l * (xi[0] / l).powi(4);
        }
        let delta: f64 = 3.015;
        let m2_ratio = m2 / (std::f64::consts::PI * delta * delta / 2.0);
        let m4_ratio = m4 / (0.75 * std::f64::consts::PI * delta.powi(3) / 3.0);
        assert!((m2_ratio - 0.9805).abs() < 1e-3, "{m2_ratio}");
        assert!((m4_ratio - 1.0371).abs() < 1e-3, "{m4_ratio}");
        assert_eq!(bonds.range(k).len(), 28);
    }
}
