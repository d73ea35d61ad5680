//! The multi-adaptive scheme for dynamic fracture (thesis §3.5; seed-thesis-ch2-3 §7, its
//! per-step algorithm): two lattices over the whole body, coarse Ω⁺ (the scene's spacing Δx⁺)
//! and fine Ω⁻ (Δx⁻ = Δx⁺/r), the same horizon δ on both, both standard-scheme levels here.
//! A coarse cell is either *refined* (its rᵈ fine sub-cells active, the coarse node not) or not
//! (the coarse node active, its sub-cells not), so the cells of active nodes tile the body.
//! Refined at the start: the coarse cells within a band of boundaries and pre-cracks
//! (`hybrid::initial_mask`, the thesis's Fig. 3.31). Then, before each force pass, every bond of
//! an active coarse node is checked on u^{n+1}: one whose stretch reaches χ·s0 (3.80) refines
//! the coarse cells of H₁ ∪ H₂, its ends' neighbourhoods (seed-thesis-ch2-3 §7 step 6).
//!
//! Node roles per level (`GridClass`): active; fictitious — not active but in the family of an
//! active node of its level, its u and u̇ interpolated by inverse-distance weighting from the
//! 2ᵈ nearest nodes of the other level (3.85)–(3.88); inactive — neither. Choices the thesis
//! leaves open, kept here:
//! - every refined coarse node (fictitious or inactive) takes the IDW of its own sub-cells
//!   (its 2ᵈ nearest fine nodes, all active), so every coarse node always carries a current
//!   value; fine fictitious and newly activated fine nodes then take the IDW of their 2ᵈ
//!   nearest coarse nodes whatever their role (the same choice as the predefined multi-grid,
//!   `adapt::multigrid`);
//! - a newly activated fine node is initialized by that IDW of the coarse solution (u and
//!   u̇^{n+½}); its bonds start intact unless a pre-crack cuts them (seed-thesis-ch2-3 §7:
//!   [inferred]);
//! - the fine level only grows: fine nodes are never deactivated (the thesis's Table 3.8 shows
//!   Ω⁻ growing and Ω⁺ shrinking only).
//!
//! The fine level is built where it is used, not over the whole body: a fine node exists once
//! its cell is refined (active, with its family) or once it falls in an active fine node's
//! family (fictitious, without a family of its own: its row is never evaluated). A cell that
//! refines appends its rᵈ nodes with their families and the nodes of their families not yet
//! there (`Growth`); a fictitious node that becomes active is appended anew with its family and
//! its old entry retired (class inactive, in no family: the families that held it point to the
//! new entry), so the rows stay in node order, each row in lattice order. Every row, length,
//! transfer weight and force is the one a level built whole gives (families from the same k-d
//! tree query over the whole fine lattice's positions, sorted by lattice index, lengths
//! snapped to the same shortest bond), so the fields are the same bit for bit; frames list
//! the nodes in lattice order, coarse first.

use rayon::prelude::*;

use super::bonds::{BondView, Measure, bond_squares};
use super::fine_lattice::{FineLattice, shortest_bond};
use super::hybrid;
use super::masks::{GridClass, SchemeClass};
use super::multigrid::{idw, subcells, tree};
use crate::discretization::{Families, Lattice, Quadrature, family};
use crate::scene::{MultigridSpec, Refinement, Scene, SceneError};

/// Row masks of the two force passes: 0 where the pass evaluates the row (`RowMask` for u8).
#[derive(Debug, Clone, Default)]
pub struct LevelRows {
    pub coarse: Vec<u8>,
    pub fine: Vec<u8>,
}

/// One refinement event: coarse cells refined before the force pass of `step`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RefineEvent {
    pub step: u64,
    pub time: f64,
    pub cells: usize,
    pub critical_bonds: usize,
}

impl std::fmt::Display for RefineEvent {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "t = {:.4e} s (step {}): {} coarse bonds reached χ·s0; {} coarse cells refined",
            self.time, self.step, self.critical_bonds, self.cells
        )
    }
}

/// No node (a fine lattice point not built yet).
const NONE: u32 = u32::MAX;

/// The two levels' nodes: all coarse nodes first, then the fine nodes built so far. A fine
/// lattice point has a key, `c·rᵈ + k` for sub-cell k of coarse cell c; the transfer weights
/// name their sources by lattice id (a coarse node's index, or `coarse_count` + a fine key).
pub struct MultiAdaptive<const D: usize> {
    pub ratio: usize,
    pub coarse_count: usize,
    /// rᵈ: fine cells per coarse cell.
    cells: usize,
    pub class: Vec<GridClass>,
    /// Per coarse node: its cell is refined.
    refined: Vec<bool>,
    pub rows: LevelRows,
    /// Every node's IDW sources on the other level (lattice ids): `sources[offsets[i]..
    /// offsets[i + 1]]`.
    offsets: Vec<usize>,
    sources: Vec<u32>,
    weights: Vec<f64>,
    /// The nodes `transfer` refreshes, refined coarse nodes first, then fine fictitious ones.
    interpolated: Vec<u32>,
    /// `transfer`'s values of one phase (kept: no allocation per step).
    scratch: Vec<([f64; D], [f64; D])>,
    pub chi: f64,
    pub coarse: Quadrature,
    pub fine: Quadrature,
    events: Vec<RefineEvent>,
    /// Coarse cells refined by the switch so far (not counting the initial band).
    pub refined_by_switch: u64,
    lattice: FineLattice<D>,
    /// Per fine key: its node, or `NONE`.
    node_of: Vec<u32>,
    /// Per fine node (index − `coarse_count`): its key (a retired entry keeps it).
    key_of: Vec<u32>,
    /// The cells of each refinement by the switch, in order (a checkpoint replays them).
    log: Vec<Vec<u32>>,
}

/// New fine nodes of a refinement, for the body to append (`ElasticBody::grow`): their
/// reference positions, each one's family (empty for a fictitious node) as node indices and
/// lengths, and the bonds of present families that now point to a re-entered node.
pub struct Growth<const D: usize> {
    pub reference: Vec<[f64; D]>,
    pub volume: f64,
    pub rows: Vec<(Vec<u32>, Vec<f64>)>,
    /// (bond, new neighbor).
    pub rewrites: Vec<(usize, u32)>,
    /// The nodes that become active (their families are in `rows`).
    pub activated: Vec<u32>,
    /// The cells refined.
    cells: Vec<usize>,
    critical_bonds: usize,
}

/// What `MultiAdaptive::build` hands to the discretization: every node of both levels.
pub struct Levels<const D: usize> {
    pub positions: Vec<[f64; D]>,
    pub volumes: Vec<f64>,
    pub families: Families,
}

impl<const D: usize> MultiAdaptive<D> {
    /// Both levels of `scene`: the coarse level over the whole body, the fine level over the
    /// cells refined within the spec's band and the fictitious nodes around them.
    pub fn build(scene: &Scene, spec: &MultigridSpec) -> Result<(Self, Levels<D>), SceneError> {
        let Refinement::Adaptive {
            band,
            chi,
            transfer,
        } = spec.refinement
        else {
            return Err(scene.error(
                "multigrid",
                "the multi-adaptive scheme refines from a band; a predefined region belongs to \
                 diffusion and corrosion",
            ));
        };
        let lattice = Lattice::<D>::of_scene(scene)?;
        let (dx, delta, r) = (scene.spacing, scene.horizon, spec.ratio);
        let fine_dx = dx / r as f64;
        let coarse = lattice.positions;
        let coarse_count = coarse.len();
        let cells = r.pow(D as u32);
        let fine: Vec<[f64; D]> = coarse
            .par_iter()
            .flat_map_iter(|x| subcells(x, dx, r))
            .collect();
        let coarse_radius = family::search_radius(scene.family_radius, delta, dx);
        let fine_radius = family::search_radius(scene.family_radius, delta, fine_dx);
        let (coarse_tree, fine_tree) = (
            tree(&coarse).expect("the lattice holds nodes"),
            tree(&fine).expect("the lattice holds nodes"),
        );
        // A refined coarse node takes the IDW of its nearest fine points (its sub-cells).
        let coarse_weights: Vec<Vec<(u32, f64)>> = coarse
            .par_iter()
            .map(|x| idw(&fine_tree, x, 1 << D, coarse_count as u32))
            .collect();
        let refined: Vec<bool> =
            hybrid::initial_mask(&coarse, &scene.solid, &scene.precracks, band, dx)
                .into_iter()
                .map(|c| c == SchemeClass::Standard)
                .collect();
        let coarse_families = Families::build(&coarse, coarse_radius);
        let quadrature = Quadrature::of_scene(scene);
        let mut grid = MultiAdaptive {
            ratio: r,
            coarse_count,
            cells,
            class: vec![GridClass::CoarseActive; coarse_count],
            refined,
            rows: LevelRows::default(),
            offsets: vec![0],
            sources: Vec::new(),
            weights: Vec::new(),
            interpolated: Vec::new(),
            scratch: Vec::new(),
            chi,
            coarse: quadrature,
            fine: Quadrature {
                spacing: fine_dx,
                ..quadrature
            },
            events: Vec::new(),
            refined_by_switch: 0,
            lattice: FineLattice {
                positions: fine,
                coarse,
                coarse_tree,
                cells,
                radius2: fine_radius * fine_radius,
                cell_reach2: ((fine_radius + dx * (D as f64).sqrt()) * (1.0 + 1e-9)).powi(2),
                coarse_spacing: dx,
                volume: fine_dx.powi(D as i32),
                transfer,
            },
            node_of: Vec::new(),
            key_of: Vec::new(),
            log: Vec::new(),
        };
        grid.node_of = vec![NONE; grid.lattice.positions.len()];
        grid.push_weights(coarse_weights);
        // The lengths of both levels snapped to the fine level's shortest bond, as the union
        // of two whole levels' families would snap them.
        let unit = shortest_bond(&grid.lattice.positions, &fine_tree);
        drop(fine_tree);
        let mut families = coarse_families.resnapped(unit);
        let initial: Vec<usize> = (0..coarse_count).filter(|&c| grid.refined[c]).collect();
        let growth = grid.grow(&initial, &families);
        families.append_rows(&growth.rows);
        let mut positions = grid.lattice.coarse.clone();
        positions.extend_from_slice(&growth.reference);
        let volumes: Vec<f64> = std::iter::repeat_n(dx.powi(D as i32), coarse_count)
            .chain(std::iter::repeat_n(growth.volume, growth.reference.len()))
            .collect();
        grid.classify(&families);
        Ok((
            grid,
            Levels {
                positions,
                volumes,
                families,
            },
        ))
    }

    /// Appends transfer weights, one node's per entry.
    fn push_weights(&mut self, per_node: Vec<Vec<(u32, f64)>>) {
        for p in per_node {
            for (s, w) in p {
                self.sources.push(s);
                self.weights.push(w);
            }
            self.offsets.push(self.sources.len());
        }
    }

    /// The node of lattice id `s` (a coarse index, or `coarse_count` + a fine key).
    fn node(&self, s: u32) -> usize {
        let s = s as usize;
        if s < self.coarse_count {
            s
        } else {
            self.node_of[s - self.coarse_count] as usize
        }
    }

    /// The fine key of fine node `i`.
    fn key(&self, i: usize) -> u32 {
        self.key_of[i - self.coarse_count]
    }

    /// Whether fine node `i` was replaced by a new entry (its cell refined after it was made
    /// fictitious).
    fn retired(&self, i: usize) -> bool {
        i >= self.coarse_count && self.node_of[self.key(i) as usize] as usize != i
    }

    /// The coarse cell a node belongs to (itself for a coarse node).
    fn cell_of(&self, i: usize) -> usize {
        if i < self.coarse_count {
            i
        } else {
            self.key(i) as usize / self.cells
        }
    }

    /// The fine keys of coarse cell `c`.
    fn keys_of(&self, c: usize) -> std::ops::Range<u32> {
        let first = (c * self.cells) as u32;
        first..first + self.cells as u32
    }

    /// The fine nodes for `cells` (just refined): each of their rᵈ points is entered anew
    /// with its family (a fictitious entry it had is retired), and the points of those
    /// families not built yet are entered as fictitious nodes, all with their transfer
    /// weights; `families` (the present ones) give the bonds to re-point. The new nodes are
    /// numbered from `self.class.len()` on, the newly active ones first.
    fn grow(&mut self, cells: &[usize], families: &Families) -> Growth<D> {
        let active: Vec<u32> = cells.iter().flat_map(|&c| self.keys_of(c)).collect();
        let rows = self.lattice.families_of_cells(cells);
        // The points of the new families not built yet, each once (`taken`: new already).
        let mut taken = vec![false; self.node_of.len()];
        for &k in &active {
            taken[k as usize] = true;
        }
        let mut ring = Vec::new();
        for &k in rows.iter().flat_map(|(keys, _)| keys) {
            if self.node_of[k as usize] == NONE && !std::mem::replace(&mut taken[k as usize], true)
            {
                ring.push(k);
            }
        }
        ring.sort_unstable();
        let old: Vec<u32> = active.iter().map(|&k| self.node_of[k as usize]).collect();
        let first = self.class.len();
        for (n, &k) in active.iter().chain(&ring).enumerate() {
            self.node_of[k as usize] = (first + n) as u32;
            self.key_of.push(k);
        }
        // Present families that held a re-entered node's old entry: those of its active
        // neighbors, each row in key order.
        let this = &*self;
        let rewrites: Vec<(usize, u32)> = (0..active.len())
            .into_par_iter()
            .filter(|&a| old[a] != NONE)
            .flat_map_iter(|a| {
                let k = active[a];
                rows[a].0.iter().filter_map(move |&nk| {
                    let j = this.node_of[nk as usize] as usize;
                    if j >= first || this.class[j] != GridClass::FineActive {
                        return None;
                    }
                    let row = &families.neighbors[families.range(j)];
                    let at = row
                        .binary_search_by_key(&k, |&m| this.key(m as usize))
                        .expect("an active fine node's family holds every fine node within δ");
                    Some((families.offsets[j] + at, this.node_of[k as usize]))
                })
            })
            .collect();
        for &o in old.iter().filter(|&&o| o != NONE) {
            self.class[o as usize] = GridClass::FineInactive;
        }
        let node_of = &self.node_of;
        let mut rows: Vec<(Vec<u32>, Vec<f64>)> = rows
            .into_par_iter()
            .map(|(keys, lengths)| (keys.iter().map(|&k| node_of[k as usize]).collect(), lengths))
            .collect();
        rows.resize(rows.len() + ring.len(), (Vec::new(), Vec::new()));
        let new: Vec<u32> = active.iter().chain(&ring).copied().collect();
        let lattice = &self.lattice;
        let weights: Vec<Vec<(u32, f64)>> = new.par_iter().map(|&k| lattice.weights(k)).collect();
        self.push_weights(weights);
        self.class
            .extend(std::iter::repeat_n(GridClass::FineInactive, new.len()));
        Growth {
            reference: new
                .iter()
                .map(|&k| self.lattice.positions[k as usize])
                .collect(),
            volume: self.lattice.volume,
            rows,
            rewrites,
            activated: (first..first + active.len()).map(|i| i as u32).collect(),
            cells: cells.to_vec(),
            critical_bonds: 0,
        }
    }

    /// Every node's class from the refined cells: active by the cell's state (a retired
    /// entry never), fictitious where a family neighbour (same level) is active, inactive
    /// otherwise. A fine node has no family until it is active: its neighbours are looked up
    /// on the lattice.
    fn classify(&mut self, families: &Families) {
        self.class = self.classes(families);
        self.refresh_lists();
    }

    /// The classes [`Self::classify`] sets.
    fn classes(&self, families: &Families) -> Vec<GridClass> {
        let count = self.class.len();
        let active: Vec<bool> = (0..count)
            .into_par_iter()
            .map(|i| (i < self.coarse_count) != self.refined[self.cell_of(i)] && !self.retired(i))
            .collect();
        let coarse_count = self.coarse_count;
        let this = self;
        (0..count)
            .into_par_iter()
            .map(|i| {
                let fine = i >= coarse_count;
                let near = || {
                    if !fine {
                        return families
                            .range(i)
                            .any(|b| active[families.neighbors[b] as usize]);
                    }
                    !this.retired(i)
                        && this.lattice.family(this.key(i)).0.iter().any(|&k| {
                            let j = this.node_of[k as usize];
                            j != NONE && active[j as usize]
                        })
                };
                match (fine, active[i], !active[i] && near()) {
                    (false, true, _) => GridClass::CoarseActive,
                    (true, true, _) => GridClass::FineActive,
                    (false, false, true) => GridClass::CoarseFictitious,
                    (true, false, true) => GridClass::FineFictitious,
                    (false, false, false) => GridClass::CoarseInactive,
                    (true, false, false) => GridClass::FineInactive,
                }
            })
            .collect()
    }

    /// Row masks and the interpolated list from `class`.
    fn refresh_lists(&mut self) {
        let mask = |want: GridClass| -> Vec<u8> {
            self.class
                .par_iter()
                .map(|&c| u8::from(c != want))
                .collect()
        };
        self.rows = LevelRows {
            coarse: mask(GridClass::CoarseActive),
            fine: mask(GridClass::FineActive),
        };
        let coarse_count = self.coarse_count as u32;
        self.interpolated = (0..coarse_count)
            .filter(|&i| self.refined[i as usize])
            .chain(
                (coarse_count..self.class.len() as u32)
                    .filter(|&i| self.class[i as usize] == GridClass::FineFictitious),
            )
            .collect();
    }

    /// The IDW value at node `i` of a per-node quantity (interpolating what `value` returns).
    fn interpolate(&self, i: usize, value: impl Fn(usize) -> [f64; D]) -> [f64; D] {
        let mut out = [0.0; D];
        for s in self.offsets[i]..self.offsets[i + 1] {
            let v = value(self.node(self.sources[s]));
            for k in 0..D {
                out[k] += self.weights[s] * v[k];
            }
        }
        out
    }
    /// Refreshes the interpolated nodes (3.85)–(3.88): displacements (positions y = x + u are
    /// stored) and velocities, refined coarse nodes first (from the fine level), then fine
    /// fictitious nodes (from the coarse level, read after their update). Each phase computes
    /// its values in parallel into a kept buffer, then writes them.
    pub fn transfer(
        &mut self,
        reference: &[[f64; D]],
        positions: &mut [[f64; D]],
        velocities: &mut [[f64; D]],
    ) {
        let split = self
            .interpolated
            .partition_point(|&i| (i as usize) < self.coarse_count);
        let mut scratch = std::mem::take(&mut self.scratch);
        for range in [0..split, split..self.interpolated.len()] {
            let phase = &self.interpolated[range];
            scratch.clear();
            scratch.par_extend(phase.par_iter().with_min_len(1024).map(|&i| {
                self.value_from_other_level(i as usize, reference, positions, velocities)
            }));
            for (&i, &(y, v)) in phase.iter().zip(&scratch) {
                (positions[i as usize], velocities[i as usize]) = (y, v);
            }
        }
        self.scratch = scratch;
    }

    /// Sets the interpolated nodes of a per-node field (a displacement) from the other level,
    /// in `transfer`'s order (refined coarse nodes first).
    pub fn interpolate_in_place(&self, u: &mut [[f64; D]]) {
        for &i in &self.interpolated {
            let value = self.interpolate(i as usize, |j| u[j]);
            u[i as usize] = value;
        }
    }

    /// The whole fine lattice's points (built or not), by key.
    pub fn fine_lattice(&self) -> &[[f64; D]] {
        &self.lattice.positions
    }

    /// Node i's position and velocity by IDW of the other level's displacements and
    /// velocities.
    fn value_from_other_level(
        &self,
        i: usize,
        reference: &[[f64; D]],
        positions: &[[f64; D]],
        velocities: &[[f64; D]],
    ) -> ([f64; D], [f64; D]) {
        let u = self.interpolate(i, |j| {
            std::array::from_fn(|k| positions[j][k] - reference[j][k])
        });
        (
            std::array::from_fn(|k| reference[i][k] + u[k]),
            self.interpolate(i, |j| velocities[j]),
        )
    }

    fn set_from_other_level(
        &self,
        i: usize,
        reference: &[[f64; D]],
        positions: &mut [[f64; D]],
        velocities: &mut [[f64; D]],
    ) {
        (positions[i], velocities[i]) =
            self.value_from_other_level(i, reference, positions, velocities);
    }

    /// The bonds of active coarse nodes whose stretch reaches χ·s0 at `positions`: (i, j).
    /// Each bond between two active nodes is checked once (from its lower end), a bond to a
    /// fictitious node from its active end; the stretch test compares squared lengths,
    /// ‖y_j − y_i‖² ≥ ((1 + χ s0) ‖ξ‖)², so no square root is taken.
    pub fn critical_bonds(
        &self,
        reference: &[[f64; D]],
        positions: &[[f64; D]],
        families: &Families,
        critical_stretch: f64,
    ) -> Vec<(u32, u32)> {
        let factor = (1.0 + self.chi * critical_stretch).powi(2);
        let class = &self.class;
        let bonds = BondView::new(reference, positions, families);
        let margin = Measure::Margin(factor);
        // Every bond of every active coarse node, in SIMD lanes and without allocating: the
        // common case finds nothing (a bond between two active nodes is seen from both ends).
        let critical_nodes: Vec<usize> = (0..self.coarse_count)
            .into_par_iter()
            .with_min_len(256)
            .filter(|&i| {
                class[i] == GridClass::CoarseActive
                    && bonds.least(i, &families.neighbors[families.range(i)], margin) <= 0.0
            })
            .collect();
        let mut pairs: Vec<(u32, u32)> = critical_nodes
            .iter()
            .flat_map(|&i| {
                families.neighbors[families.range(i)]
                    .iter()
                    .filter(move |&&j| {
                        let (r2, l2) = bond_squares(i, j as usize, reference, positions);
                        margin.of(r2, l2) <= 0.0
                    })
                    .map(move |&j| (i as u32, j))
            })
            .map(|(i, j)| {
                // Each bond once, from its lower-index end when both ends are active.
                if j < i && class[j as usize] == GridClass::CoarseActive {
                    (j, i)
                } else {
                    (i, j)
                }
            })
            .collect();
        pairs.sort_unstable();
        pairs.dedup();
        pairs
    }

    /// The cells of H₁ ∪ H₂ of every critical bond not refined yet, and what refining them
    /// adds to the fine level (`None` if every such cell is refined). The body appends the
    /// growth (`ElasticBody::grow`), then [`Self::activate`] brings the new nodes in.
    pub fn refine(&mut self, critical: &[(u32, u32)], families: &Families) -> Option<Growth<D>> {
        let mut cells: Vec<usize> = Vec::new();
        for &(i, j) in critical {
            for end in [i as usize, j as usize] {
                cells.push(end);
                cells.extend(families.range(end).map(|b| families.neighbors[b] as usize));
            }
        }
        cells.sort_unstable();
        cells.dedup();
        cells.retain(|&c| !self.refined[c]);
        if cells.is_empty() {
            return None;
        }
        let mut growth = self.grow(&cells, families);
        growth.critical_bonds = critical.len();
        Some(growth)
    }

    /// Refines the cells of `growth`, appended to the body: the newly active fine nodes take
    /// the IDW of the coarse solution, the classes are updated locally (the nodes within one
    /// family of a changed cell), and the nodes that leave the active coarse set lose their
    /// force (their forces are computed by the next pass).
    pub fn activate(
        &mut self,
        (step, time): (u64, f64),
        growth: &Growth<D>,
        families: &Families,
        reference: &[[f64; D]],
        positions: &mut [[f64; D]],
        velocities: &mut [[f64; D]],
    ) {
        let cells = &growth.cells;
        for &c in cells {
            self.refined[c] = true;
            self.class[c] = GridClass::CoarseInactive;
        }
        // Initialized from the coarse level before any class changes (every coarse node
        // carries a current value).
        for &f in &growth.activated {
            self.set_from_other_level(f as usize, reference, positions, velocities);
        }
        for &f in &growth.activated {
            self.class[f as usize] = GridClass::FineActive;
        }
        for &f in &growth.activated {
            for b in families.range(f as usize) {
                let j = families.neighbors[b] as usize;
                if self.class[j] == GridClass::FineInactive {
                    self.class[j] = GridClass::FineFictitious;
                }
            }
        }
        // Coarse roles change only within one family of a newly refined cell.
        let mut near: Vec<usize> = cells.clone();
        for &c in cells {
            near.extend(families.range(c).map(|b| families.neighbors[b] as usize));
        }
        near.sort_unstable();
        near.dedup();
        for &c in &near {
            if !self.refined[c] {
                continue;
            }
            let has_active = families
                .range(c)
                .any(|b| self.class[families.neighbors[b] as usize] == GridClass::CoarseActive);
            self.class[c] = if has_active {
                GridClass::CoarseFictitious
            } else {
                GridClass::CoarseInactive
            };
        }
        self.refresh_lists();
        self.refined_by_switch += cells.len() as u64;
        self.log.push(cells.iter().map(|&c| c as u32).collect());
        self.events.push(RefineEvent {
            step,
            time,
            cells: cells.len(),
            critical_bonds: growth.critical_bonds,
        });
    }

    /// The coarse nodes whose cells are refined (they left the active set at some point).
    pub fn refined_coarse(&self) -> impl Iterator<Item = usize> + '_ {
        (0..self.coarse_count).filter(|&c| self.refined[c])
    }

    pub fn take_events(&mut self) -> Vec<RefineEvent> {
        std::mem::take(&mut self.events)
    }

    /// Node counts: (coarse active, fine active, fictitious of both levels).
    pub fn counts(&self) -> (usize, usize, usize) {
        GridClass::counts(&self.class)
    }

    /// Each node's volume where it is active, 0 elsewhere: Σ ρ V over these is the body's mass.
    pub fn active_volumes(&self, volumes: &[f64]) -> Vec<f64> {
        GridClass::active_volumes(&self.class, volumes)
    }

    /// The cells each refinement by the switch refined, in order (checkpoints).
    pub fn refinements(&self) -> impl Iterator<Item = &[u32]> {
        self.log.iter().map(Vec::as_slice)
    }

    /// A checkpoint's refinements (see [`Self::refinements`]) checked: each event's cells
    /// ascending, unrefined so far, within the coarse level.
    pub fn check_refinements(&self, events: &[Vec<u32>]) -> Result<(), String> {
        let mut refined = self.refined.clone();
        for cells in events {
            let ordered = cells.windows(2).all(|w| w[0] < w[1]);
            let outside = |c: u32| c as usize >= self.coarse_count;
            if !ordered || cells.iter().any(|&c| outside(c) || refined[c as usize]) {
                return Err(
                    "`multigrid/refine_log` refines a cell twice or one outside this scene".into(),
                );
            }
            for &c in cells {
                refined[c as usize] = true;
            }
        }
        Ok(())
    }

    /// The growth that refining `cells` (one event of a checkpoint's log) adds.
    pub fn replay(&mut self, cells: &[usize], families: &Families) -> Growth<D> {
        self.grow(cells, families)
    }

    /// Class consistency: the locally updated classes equal a classification from scratch.
    pub fn classes_from_scratch(&self, families: &Families) -> Vec<GridClass> {
        self.classes(families)
    }

    /// The nodes a frame shows (not inactive), in lattice order: coarse nodes, then fine
    /// nodes by key (the order of a level built whole).
    pub fn shown_in_lattice_order(&self) -> Vec<u32> {
        let shown = |i: usize| !self.class[i].is_inactive();
        (0..self.coarse_count as u32)
            .filter(|&i| shown(i as usize))
            .chain(
                self.node_of
                    .iter()
                    .copied()
                    .filter(|&i| i != NONE && shown(i as usize)),
            )
            .collect()
    }

    /// Every fine node in use (not retired) with its fine lattice key (its point in
    /// [`Self::fine_lattice`]).
    pub fn fine_nodes(&self) -> impl Iterator<Item = (usize, u32)> + '_ {
        (self.coarse_count..self.class.len())
            .filter(|&i| !self.retired(i))
            .map(|i| (i, self.key(i)))
    }
}
