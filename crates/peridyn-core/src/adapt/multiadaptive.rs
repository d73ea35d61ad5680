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

use kiddo::{ImmutableKdTree, SquaredEuclidean};
use rayon::prelude::*;

use super::bonds::{BondView, Measure, bond_squares};
use super::hybrid;
use super::masks::{GridClass, SchemeClass};
use super::multigrid::{idw, subcells, tree};
use crate::discretization::{Families, Lattice, Quadrature, family};
use crate::scene::{MultigridSpec, Refinement, Scene, SceneError, Transfer};

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

/// The two levels' nodes, laid out as all coarse nodes first, then the fine sub-cells of coarse
/// node c at `coarse_count + c·rᵈ + k`.
#[derive(Debug, Clone)]
pub struct MultiAdaptive<const D: usize> {
    pub ratio: usize,
    pub coarse_count: usize,
    /// rᵈ: fine cells per coarse cell.
    cells: usize,
    pub class: Vec<GridClass>,
    /// Per coarse node: its cell is refined.
    refined: Vec<bool>,
    pub rows: LevelRows,
    /// Every node's IDW sources on the other level: `sources[offsets[i]..offsets[i + 1]]`.
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
}

/// What `MultiAdaptive::build` hands to the discretization: every node of both levels.
pub struct Levels<const D: usize> {
    pub positions: Vec<[f64; D]>,
    pub volumes: Vec<f64>,
    pub families: Families,
}

/// Tensor-product linear weights at `x` from the coarse lattice (spacing `dx`): per axis, the
/// coarse node of x's cell and its neighbour on x's side (the far-side one, extrapolating, at
/// the body's edge); a node with no neighbour either way in an axis takes that axis constant,
/// and one whose corner node is missing falls back to IDW.
fn multilinear<const D: usize>(
    t: &ImmutableKdTree<f64, D>,
    coarse: &[[f64; D]],
    x: &[f64; D],
    dx: f64,
) -> Vec<(u32, f64)> {
    let own = t
        .query(x)
        .nearest_one::<SquaredEuclidean<f64>>()
        .execute()
        .item as usize;
    let base = coarse[own];
    let exists = |p: &[f64; D]| {
        t.query(p)
            .nearest_one::<SquaredEuclidean<f64>>()
            .execute()
            .distance
            < (1e-6 * dx).powi(2)
    };
    // Per axis: (step to the partner node in units of dx, weight of the partner).
    let axes: [(f64, f64); D] = std::array::from_fn(|k| {
        let offset = (x[k] - base[k]) / dx;
        let side = if offset >= 0.0 { 1.0 } else { -1.0 };
        let mut towards = base;
        towards[k] += side * dx;
        let mut away = base;
        away[k] -= side * dx;
        if exists(&towards) {
            (side, offset.abs())
        } else if exists(&away) {
            (-side, -offset.abs())
        } else {
            (0.0, 0.0)
        }
    });
    let mut out = Vec::with_capacity(1 << D);
    for corner in 0..(1usize << D) {
        let mut p = base;
        let mut w = 1.0;
        for (k, &(step, partner)) in axes.iter().enumerate() {
            if corner >> k & 1 == 1 {
                if step == 0.0 {
                    w = 0.0;
                }
                p[k] += step * dx;
                w *= partner;
            } else {
                w *= 1.0 - partner;
            }
        }
        if w != 0.0 {
            if !exists(&p) {
                // A missing corner (a body that is not a box there): the thesis's IDW.
                return idw(t, x, 1 << D, 0);
            }
            let j = t
                .query(&p)
                .nearest_one::<SquaredEuclidean<f64>>()
                .execute()
                .item;
            out.push((j, w));
        }
    }
    out
}

impl<const D: usize> MultiAdaptive<D> {
    /// Both levels of `scene` over the whole body, refined within the spec's band.
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
        let families = Families::concat(
            &Families::build(&coarse, coarse_radius),
            &Families::build(&fine, fine_radius),
        );
        // IDW sources of every node on the other level, once: the lattices never move.
        let n = 1usize << D;
        let (coarse_tree, fine_tree) = (
            tree(&coarse).expect("the lattice holds nodes"),
            tree(&fine).expect("the lattice holds nodes"),
        );
        let pairs: Vec<Vec<(u32, f64)>> = coarse
            .par_iter()
            .map(|x| idw(&fine_tree, x, n, coarse_count as u32))
            .chain(fine.par_iter().map(|x| match transfer {
                Transfer::Idw => idw(&coarse_tree, x, n, 0),
                Transfer::Multilinear => multilinear(&coarse_tree, &coarse, x, dx),
            }))
            .collect();
        let mut offsets = Vec::with_capacity(pairs.len() + 1);
        offsets.push(0);
        let (mut sources, mut weights) = (Vec::new(), Vec::new());
        for p in &pairs {
            for &(s, w) in p {
                sources.push(s);
                weights.push(w);
            }
            offsets.push(sources.len());
        }
        let refined: Vec<bool> =
            hybrid::initial_mask(&coarse, &scene.solid, &scene.precracks, band, dx)
                .into_iter()
                .map(|c| c == SchemeClass::Standard)
                .collect();
        let volumes: Vec<f64> = std::iter::repeat_n(dx.powi(D as i32), coarse_count)
            .chain(std::iter::repeat_n(fine_dx.powi(D as i32), fine.len()))
            .collect();
        let mut positions = coarse;
        positions.extend_from_slice(&fine);
        let total = positions.len();
        let quadrature = Quadrature::of_scene(scene);
        let mut grid = MultiAdaptive {
            ratio: r,
            coarse_count,
            cells,
            class: vec![GridClass::CoarseActive; total],
            refined,
            rows: LevelRows::default(),
            offsets,
            sources,
            weights,
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
        };
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

    /// The coarse cell a node belongs to (itself for a coarse node).
    fn cell_of(&self, i: usize) -> usize {
        if i < self.coarse_count {
            i
        } else {
            (i - self.coarse_count) / self.cells
        }
    }

    /// The fine nodes of coarse cell `c`.
    fn fine_of(&self, c: usize) -> std::ops::Range<usize> {
        let first = self.coarse_count + c * self.cells;
        first..first + self.cells
    }

    /// Every node's class from the refined cells: active by the cell's state, fictitious where
    /// a family neighbour (same level) is active, inactive otherwise.
    fn classify(&mut self, families: &Families) {
        let active: Vec<bool> = (0..self.class.len())
            .into_par_iter()
            .map(|i| (i < self.coarse_count) != self.refined[self.cell_of(i)])
            .collect();
        let coarse_count = self.coarse_count;
        self.class = (0..active.len())
            .into_par_iter()
            .map(|i| {
                let fine = i >= coarse_count;
                let near = || {
                    families
                        .range(i)
                        .any(|b| active[families.neighbors[b] as usize])
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
            .collect();
        self.refresh_lists();
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
            let v = value(self.sources[s] as usize);
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

    /// Refines the cells of H₁ ∪ H₂ of every critical bond: the newly active fine nodes take
    /// the IDW of the coarse solution, the classes are updated locally (the nodes within one
    /// family of a changed cell), and the nodes that leave the active coarse set lose their
    /// force. Returns the fine nodes activated (their forces are computed by the next pass).
    #[allow(clippy::too_many_arguments)]
    pub fn refine(
        &mut self,
        step: u64,
        time: f64,
        critical: &[(u32, u32)],
        families: &Families,
        reference: &[[f64; D]],
        positions: &mut [[f64; D]],
        velocities: &mut [[f64; D]],
    ) -> Vec<u32> {
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
            return Vec::new();
        }
        let mut activated = Vec::with_capacity(cells.len() * self.cells);
        for &c in &cells {
            self.refined[c] = true;
            self.class[c] = GridClass::CoarseInactive;
            activated.extend(self.fine_of(c).map(|f| f as u32));
        }
        // Initialized from the coarse level before any class changes (every coarse node
        // carries a current value).
        for &f in &activated {
            self.set_from_other_level(f as usize, reference, positions, velocities);
        }
        for &f in &activated {
            self.class[f as usize] = GridClass::FineActive;
        }
        for &f in &activated {
            for b in families.range(f as usize) {
                let j = families.neighbors[b] as usize;
                if self.class[j] == GridClass::FineInactive {
                    self.class[j] = GridClass::FineFictitious;
                }
            }
        }
        // Coarse roles change only within one family of a newly refined cell.
        let mut near: Vec<usize> = cells.clone();
        for &c in &cells {
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
        self.events.push(RefineEvent {
            step,
            time,
            cells: cells.len(),
            critical_bonds: critical.len(),
        });
        activated
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

    /// The refined cells, one byte per coarse node (checkpoints).
    pub fn refined_cells(&self) -> Vec<u8> {
        self.refined.iter().map(|&r| u8::from(r)).collect()
    }

    /// Restores the refined cells of a checkpoint and every class from them.
    pub fn restore_refined(&mut self, cells: &[u8], families: &Families) -> Result<(), String> {
        if cells.len() != self.coarse_count {
            return Err(format!(
                "the checkpoint refines {} coarse cells, this scene has {}",
                cells.len(),
                self.coarse_count
            ));
        }
        self.refined = cells.iter().map(|&c| c != 0).collect();
        self.classify(families);
        Ok(())
    }

    /// Class consistency: the locally updated classes equal a classification from scratch.
    pub fn classes_from_scratch(&self, families: &Families) -> Vec<GridClass> {
        let mut copy = self.clone();
        copy.classify(families);
        copy.class
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn lattice(n: usize) -> Vec<[f64; 2]> {
        (0..n * n)
            .map(|k| [(k % n) as f64, (k / n) as f64])
            .collect()
    }

    /// Multilinear weights reproduce linear fields exactly, inside and (extrapolating) at the
    /// lattice's edge; IDW does not (the reason the option exists).
    #[test]
    fn multilinear_weights_are_linear_exact() {
        let coarse = lattice(5);
        let t = tree(&coarse).unwrap();
        let f = |p: &[f64; 2]| 0.3 + 2.0 * p[0] - 1.5 * p[1];
        let value =
            |w: &[(u32, f64)]| -> f64 { w.iter().map(|&(j, w)| w * f(&coarse[j as usize])).sum() };
        for x in [[1.25, 2.75], [0.25, 0.25], [-0.25, 3.25], [4.25, -0.25]] {
            let w = multilinear(&t, &coarse, &x, 1.0);
            assert!((w.iter().map(|p| p.1).sum::<f64>() - 1.0).abs() < 1e-14);
            assert!(
                (value(&w) - f(&x)).abs() < 1e-13,
                "{x:?}: {}",
                value(&w) - f(&x)
            );
        }
        let inside = multilinear(&t, &coarse, &[1.25, 1.25], 1.0);
        let mut weights: Vec<f64> = inside.iter().map(|p| p.1).collect();
        weights.sort_by(f64::total_cmp);
        assert_eq!(weights, [1.0 / 16.0, 3.0 / 16.0, 3.0 / 16.0, 9.0 / 16.0]);
        let by_idw = idw(&t, &[1.25, 1.25], 4, 0);
        assert!((value(&by_idw) - f(&[1.25, 1.25])).abs() > 1e-3);
    }
}
