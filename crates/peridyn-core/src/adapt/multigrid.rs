//! Multi-grid coupling with a predefined fine region (thesis §3.4; seed-thesis-ch2-3 §6): a
//! coarse lattice Ω⁺ (spacing Δx⁺, the scene's `discretization.spacing`) and, in the region
//! Ω⁻, a fine one (Δx⁻ = Δx⁺/r), the same horizon δ on both. Every coarse node sits at the
//! centre of its cell; a coarse cell whose node lies in the region is split into rᵈ fine cells,
//! so the cells of active fine and active coarse nodes tile the body (Σ C V over active nodes
//! is the total mass). Near the interface each level has fictitious nodes — the other level's
//! cells within δ of one of its active nodes — that complete the families of active nodes;
//! their values come by inverse-distance weighting (3.85)–(3.88) from the 2ᵈ surrounding nodes
//! of the other level (2 in 1D, 4 in 2D, 8 in 3D; a node at distance 0 gives its value
//! directly). Choice: a coarse fictitious node takes the nearest fine *active* nodes, a fine
//! fictitious node the nearest coarse nodes active or fictitious (seed-thesis-ch2-3 §6 suggests
//! the nearest active ones; those all lie on one side of a fine fictitious node, and the
//! one-sided average lost 8 % of the mass of `corrosion-1d` in 200 s). Inactive nodes (the
//! other level's cells farther inside) are not stored.

use kiddo::{ImmutableKdTree, SquaredEuclidean};
use rayon::prelude::*;

use super::masks::GridClass;
use crate::discretization::{Discretization, Families, Interpolation, Lattice, Quadrature, family};
use crate::scene::{MultigridSpec, Refinement, Scene, SceneError};

/// The two levels' nodes in one index space, and the fictitious nodes' interpolation.
#[derive(Debug, Clone)]
pub struct MultiGrid<const D: usize> {
    pub positions: Vec<[f64; D]>,
    pub volumes: Vec<f64>,
    pub class: Vec<GridClass>,
    /// Families within each level (a node's neighbours are of its own level).
    pub families: Families,
    pub ratio: usize,
    pub coarse: Quadrature,
    pub fine: Quadrature,
    /// The fictitious nodes' values from the other level (coarse fictitious rows first).
    pub interpolation: Interpolation,
}

/// A k-d tree over points (finite lattice coordinates).
pub(crate) fn tree<const D: usize>(points: &[[f64; D]]) -> Option<ImmutableKdTree<f64, D>> {
    (!points.is_empty()).then(|| ImmutableKdTree::new_from_slice(points).expect("finite points"))
}

/// Whether each point lies within `reach` of one of `of` (false where `of` is empty).
fn within<const D: usize>(points: &[[f64; D]], of: &[[f64; D]], reach: f64) -> Vec<bool> {
    let Some(t) = tree(of) else {
        return vec![false; points.len()];
    };
    let r2 = reach * reach * (1.0 + 1e-9);
    points
        .par_iter()
        .map(|x| {
            t.query(x)
                .nearest_one::<SquaredEuclidean<f64>>()
                .execute()
                .distance
                <= r2
        })
        .collect()
}

/// The fine cell centres of a coarse cell centred at `x`.
pub(crate) fn subcells<const D: usize>(x: &[f64; D], coarse: f64, ratio: usize) -> Vec<[f64; D]> {
    let fine = coarse / ratio as f64;
    let count = ratio.pow(D as u32);
    (0..count)
        .map(|mut code| {
            let mut y = *x;
            for v in y.iter_mut() {
                let k = code % ratio;
                code /= ratio;
                *v += -0.5 * coarse + (k as f64 + 0.5) * fine;
            }
            y
        })
        .collect()
}

/// Inverse-distance weights of the `n` nearest of `sources` (indices into the union via
/// `offset`) to `x`: 1/d each, normalized; a source at distance 0 takes all the weight.
pub(crate) fn idw<const D: usize>(
    t: &ImmutableKdTree<f64, D>,
    x: &[f64; D],
    n: usize,
    offset: u32,
) -> Vec<(u32, f64)> {
    let nearest = t
        .query(x)
        .nearest_n::<SquaredEuclidean<f64>>(std::num::NonZero::new(n).expect("n ≥ 1"))
        .execute();
    if let Some(hit) = nearest.iter().find(|h| h.distance == 0.0) {
        return vec![(offset + hit.item, 1.0)];
    }
    let inverse: Vec<f64> = nearest.iter().map(|h| 1.0 / h.distance.sqrt()).collect();
    let total: f64 = inverse.iter().sum();
    nearest
        .iter()
        .zip(inverse)
        .map(|(h, w)| (offset + h.item, w / total))
        .collect()
}

impl<const D: usize> MultiGrid<D> {
    /// The two levels of `scene` with its predefined fine region.
    pub fn build(scene: &Scene, spec: &MultigridSpec) -> Result<Self, SceneError> {
        let Refinement::Region(region) = &spec.refinement else {
            return Err(scene.error(
                "multigrid",
                "a predefined fine region is built for diffusion and corrosion; dynamics \
                 refines adaptively",
            ));
        };
        let coarse_lattice = Lattice::<D>::of_scene(scene)?;
        let (dx, delta) = (scene.spacing, scene.horizon);
        let r = spec.ratio;
        let eps = 1e-9 * dx;
        let inside: Vec<bool> = coarse_lattice
            .positions
            .iter()
            .map(|x| region.contains(x, eps))
            .collect();
        let split = |want: bool| -> Vec<[f64; D]> {
            coarse_lattice
                .positions
                .iter()
                .zip(&inside)
                .filter(|(_, i)| **i == want)
                .map(|(x, _)| *x)
                .collect()
        };
        let (refined, outside) = (split(true), split(false));
        if refined.is_empty() {
            return Err(scene.error(
                "multigrid.region",
                "holds no coarse node: nothing is refined; widen the region",
            ));
        }
        if outside.is_empty() {
            return Err(scene.error(
                "multigrid.region",
                "covers the whole body: use a uniform grid of the fine spacing instead",
            ));
        }
        // Coarse: active outside the region; fictitious inside, within δ of an active one.
        let coarse_fictitious: Vec<[f64; D]> = {
            let near = within(&refined, &outside, delta);
            refined
                .iter()
                .zip(near)
                .filter(|(_, n)| *n)
                .map(|(x, _)| *x)
                .collect()
        };
        // Fine: active in the refined cells; fictitious in the outside cells within δ of one.
        let fine_active: Vec<[f64; D]> = refined.iter().flat_map(|x| subcells(x, dx, r)).collect();
        let fine_fictitious: Vec<[f64; D]> = {
            let candidates: Vec<[f64; D]> = {
                let near = within(&outside, &refined, delta + dx);
                outside
                    .iter()
                    .zip(near)
                    .filter(|(_, n)| *n)
                    .flat_map(|(x, _)| subcells(x, dx, r))
                    .collect()
            };
            let near = within(&candidates, &fine_active, delta);
            candidates
                .into_iter()
                .zip(near)
                .filter(|(_, n)| *n)
                .map(|(x, _)| x)
                .collect()
        };
        let groups: [(&[[f64; D]], GridClass); 4] = [
            (&outside, GridClass::CoarseActive),
            (&coarse_fictitious, GridClass::CoarseFictitious),
            (&fine_active, GridClass::FineActive),
            (&fine_fictitious, GridClass::FineFictitious),
        ];
        let fine_dx = dx / r as f64;
        let mut positions = Vec::new();
        let mut volumes = Vec::new();
        let mut class = Vec::new();
        for (points, c) in groups {
            let h = if c.is_fine() { fine_dx } else { dx };
            positions.extend_from_slice(points);
            volumes.extend(std::iter::repeat_n(h.powi(D as i32), points.len()));
            class.extend(std::iter::repeat_n(c, points.len()));
        }
        let coarse_count = outside.len() + coarse_fictitious.len();
        let coarse_radius = family::search_radius(scene.family_radius, delta, dx);
        let fine_radius = family::search_radius(scene.family_radius, delta, fine_dx);
        let families = Families::concat(
            &Families::build(&positions[..coarse_count], coarse_radius),
            &Families::build(&positions[coarse_count..], fine_radius),
        );
        // Interpolation of each fictitious node from the other level. A coarse fictitious node
        // lies among fine active ones (the refined cells); a fine fictitious one lies outside
        // the refined cells, between coarse active and coarse fictitious nodes: it takes the
        // coarse nodes around it whatever their role (the coarse fictitious ones are
        // interpolated first, from fine active nodes only), so that in 1D its value is the
        // linear interpolation of its two neighbours rather than an extrapolation from the
        // active side (which biases the flux across the interface).
        let n = 1usize << D;
        let coarse_tree = tree(&positions[..coarse_count]).expect("coarse nodes exist");
        let fine_tree = tree(&fine_active).expect("fine active nodes exist");
        let fine_offset = coarse_count as u32;
        let mut interpolation = Interpolation::new();
        for (i, c) in class.iter().enumerate() {
            let pairs = match c {
                GridClass::CoarseFictitious => idw(&fine_tree, &positions[i], n, fine_offset),
                GridClass::FineFictitious => idw(&coarse_tree, &positions[i], n, 0),
                _ => continue,
            };
            interpolation.push(i as u32, pairs);
        }
        let quadrature = Quadrature::of_scene(scene);
        Ok(MultiGrid {
            positions,
            volumes,
            class,
            families,
            ratio: r,
            coarse: quadrature,
            fine: Quadrature {
                spacing: fine_dx,
                ..quadrature
            },
            interpolation,
        })
    }

    /// The two levels of `scene` as one discretization (their positions, volumes and
    /// families moved into it) and the levels' classes and interpolation.
    pub fn discretize(
        scene: &Scene,
        spec: &MultigridSpec,
    ) -> Result<(Discretization<D>, MultiGrid<D>), SceneError> {
        let mut grid = MultiGrid::<D>::build(scene, spec)?;
        let positions = std::mem::take(&mut grid.positions);
        let volumes = std::mem::take(&mut grid.volumes);
        let families = std::mem::take(&mut grid.families);
        let d = Discretization::of_nodes(scene, positions, volumes, families)?;
        Ok((d, grid))
    }

    /// Node counts: (coarse active, fine active, fictitious of both levels).
    pub fn counts(&self) -> (usize, usize, usize) {
        GridClass::counts(&self.class)
    }

    /// The active nodes of one level (fine or coarse), in increasing order.
    pub fn active(&self, fine: bool) -> Vec<u32> {
        let want = if fine {
            GridClass::FineActive
        } else {
            GridClass::CoarseActive
        };
        (0..self.class.len() as u32)
            .filter(|&i| self.class[i as usize] == want)
            .collect()
    }

    /// Each node's volume (`volumes`, the union's) where it is active, 0 where fictitious:
    /// Σ C V over these is the body's total.
    pub fn active_volumes(&self, volumes: &[f64]) -> Vec<f64> {
        GridClass::active_volumes(&self.class, volumes)
    }

    /// The fictitious values from the other level, (3.85)–(3.88): coarse fictitious nodes
    /// first (they come first, and fine fictitious nodes read them).
    pub fn transfer(&self, values: &mut [f64]) {
        self.interpolation.transfer(values);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A constant is interpolated exactly; a node on a source takes its value; weights sum to 1.
    #[test]
    fn inverse_distance_weights() {
        let sources: Vec<[f64; 1]> = vec![[0.0], [1.0], [3.0]];
        let t = tree(&sources).unwrap();
        let w = idw(&t, &[0.25], 2, 10);
        assert_eq!(w.len(), 2);
        assert!((w.iter().map(|p| p.1).sum::<f64>() - 1.0).abs() < 1e-15);
        // 1/0.25 : 1/0.75 = 3 : 1
        assert!((w.iter().find(|p| p.0 == 10).unwrap().1 - 0.75).abs() < 1e-15);
        assert_eq!(idw(&t, &[1.0], 2, 0), [(1, 1.0)]);
    }

    #[test]
    fn subcells_tile_their_cell() {
        let cells = subcells(&[1.0, 2.0], 0.5, 2);
        assert_eq!(
            cells,
            [
                [0.875, 1.875],
                [1.125, 1.875],
                [0.875, 2.125],
                [1.125, 2.125]
            ]
        );
    }
}
