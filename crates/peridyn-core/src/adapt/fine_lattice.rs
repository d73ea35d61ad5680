//! The fine lattice of the multi-adaptive scheme (`super::multiadaptive`) as points only: where
//! fine nodes can be, the family a new fine node gets (the bits a k-d tree query over the whole
//! lattice gives, from the coarse cells around it), and its transfer weights from the coarse level
//! (thesis (3.85)–(3.88): IDW, or linear-exact weights as an option).

use kiddo::{ImmutableKdTree, SquaredEuclidean};
use rayon::prelude::*;

use super::multigrid::idw;
use crate::scene::Transfer;

/// Where fine nodes can be: the whole fine lattice as positions (by key), and what gives a new
/// node its family and its transfer weights.
pub(super) struct FineLattice<const D: usize> {
    pub(super) positions: Vec<[f64; D]>,
    pub(super) coarse: Vec<[f64; D]>,
    pub(super) coarse_tree: ImmutableKdTree<f64, D>,
    /// rᵈ: fine points per coarse cell.
    pub(super) cells: usize,
    /// The fine families' squared search radius.
    pub(super) radius2: f64,
    /// The squared distance between coarse nodes within which their cells' fine points can
    /// be within the search radius of each other: (radius + Δx⁺√D)², rounded up.
    pub(super) cell_reach2: f64,
    pub(super) coarse_spacing: f64,
    pub(super) volume: f64,
    pub(super) transfer: Transfer,
}

impl<const D: usize> FineLattice<D> {
    /// The coarse cells whose fine points can lie within the search radius of a fine point of
    /// cell c (c included), ascending.
    fn cells_near(&self, c: usize) -> Vec<u32> {
        let mut near: Vec<u32> = self
            .coarse_tree
            .query(&self.coarse[c])
            .within::<SquaredEuclidean<f64>>(self.cell_reach2)
            .unsorted()
            .execute()
            .iter()
            .map(|n| n.item)
            .collect();
        near.sort_unstable();
        near
    }

    /// The family of fine point `key` among the fine points of `cells` (ascending, covering
    /// its reach): neighbor keys ascending and their lengths. The same as a k-d tree query
    /// over the whole fine lattice gives (`Families::build`): the squared distance summed
    /// axis by axis from zero as kiddo sums it, compared with the same radius.
    fn family_among(&self, key: u32, cells: &[u32]) -> (Vec<u32>, Vec<f64>) {
        let p = &self.positions[key as usize];
        let (mut keys, mut lengths) = (Vec::new(), Vec::new());
        for &c in cells {
            let first = c * self.cells as u32;
            for k in first..first + self.cells as u32 {
                let q = &self.positions[k as usize];
                let mut squared = 0.0;
                for a in 0..D {
                    let d = q[a] - p[a];
                    squared += d * d;
                }
                if squared <= self.radius2 && k != key {
                    keys.push(k);
                    lengths.push(squared.sqrt());
                }
            }
        }
        (keys, lengths)
    }

    /// The family of fine point `key` (see [`Self::family_among`]).
    pub(super) fn family(&self, key: u32) -> (Vec<u32>, Vec<f64>) {
        self.family_among(key, &self.cells_near(key as usize / self.cells))
    }

    /// The families of the fine points of coarse cells `cells`, cell by cell, in key order.
    pub(super) fn families_of_cells(&self, cells: &[usize]) -> Vec<(Vec<u32>, Vec<f64>)> {
        cells
            .par_iter()
            .flat_map_iter(|&c| {
                let near = self.cells_near(c);
                let first = (c * self.cells) as u32;
                (first..first + self.cells as u32)
                    .map(move |k| self.family_among(k, &near))
                    .collect::<Vec<_>>()
            })
            .collect()
    }

    /// The transfer weights of fine point `key` from the coarse level (lattice ids).
    pub(super) fn weights(&self, key: u32) -> Vec<(u32, f64)> {
        let x = &self.positions[key as usize];
        match self.transfer {
            Transfer::Idw => idw(&self.coarse_tree, x, 1 << D, 0),
            Transfer::Multilinear => {
                multilinear(&self.coarse_tree, &self.coarse, x, self.coarse_spacing)
            }
        }
    }
}

/// The shortest bond of a whole level on `points` (each point's nearest other point in
/// `tree`), the unit its families' lengths are snapped to.
pub(super) fn shortest_bond<const D: usize>(
    points: &[[f64; D]],
    tree: &ImmutableKdTree<f64, D>,
) -> f64 {
    let two = std::num::NonZero::new(2).expect("2 ≥ 1");
    points
        .par_iter()
        .map(|x| {
            tree.query(x)
                .nearest_n::<SquaredEuclidean<f64>>(two)
                .execute()
                .iter()
                .map(|n| n.distance)
                .filter(|&d| d > 0.0)
                .fold(f64::INFINITY, f64::min)
        })
        .reduce(|| f64::INFINITY, f64::min)
        .sqrt()
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

#[cfg(test)]
mod tests {
    use super::super::multigrid::tree;
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
