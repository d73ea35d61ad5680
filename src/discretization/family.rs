//! Neighbor families in CSR form (built with a kiddo k-d tree), the β partial-volume factor
//! (3.2) and pre-crack cuts.

use kiddo::{ImmutableKdTree, SquaredEuclidean};
use rayon::prelude::*;

use crate::scene::{CrackGeometry, FamilyRadius};

/// Families of all nodes in compressed sparse rows: node i's neighbors are
/// `neighbors[offsets[i]..offsets[i + 1]]`, with the reference bond length beside each.
#[derive(Debug, Clone, Default)]
pub struct Families {
    pub offsets: Vec<usize>,
    pub neighbors: Vec<u32>,
    pub lengths: Vec<f64>,
}

impl Families {
    /// Families within `radius` (each node excluded from its own family), sorted by index.
    pub fn build<const D: usize>(positions: &[[f64; D]], radius: f64) -> Self {
        let mut offsets = vec![0];
        if positions.is_empty() {
            return Families {
                offsets,
                neighbors: Vec::new(),
                lengths: Vec::new(),
            };
        }
        let tree: ImmutableKdTree<f64, D> = ImmutableKdTree::new_from_slice(positions)
            .expect("a k-d tree over finite lattice coordinates");
        let r2 = radius * radius;
        // Each family sorted by index as one u64 key per neighbor (index above, its place in
        // the query's answer below): cheaper to sort than (index, length) pairs.
        let rows: Vec<(Vec<u32>, Vec<f64>)> = positions
            .par_iter()
            .enumerate()
            .map(|(i, x)| {
                let found = tree
                    .query(x)
                    .within::<SquaredEuclidean<f64>>(r2)
                    .unsorted()
                    .execute();
                let mut keys: Vec<u64> = found
                    .iter()
                    .enumerate()
                    .filter(|(_, n)| n.item as usize != i)
                    .map(|(k, n)| (u64::from(n.item) << 32) | k as u64)
                    .collect();
                keys.sort_unstable();
                let neighbors = keys.iter().map(|k| (k >> 32) as u32).collect();
                let lengths = keys
                    .iter()
                    .map(|&k| found[(k & 0xffff_ffff) as usize].distance.sqrt())
                    .collect();
                (neighbors, lengths)
            })
            .collect();
        offsets.reserve(rows.len());
        for (row, _) in &rows {
            offsets.push(offsets[offsets.len() - 1] + row.len());
        }
        let total = offsets[rows.len()];
        let mut neighbors = vec![0u32; total];
        let mut lengths = vec![0.0; total];
        // The rows copied into place in parallel, each into its own slice.
        let mut slices = Vec::with_capacity(rows.len());
        let (mut neighbors_rest, mut lengths_rest) =
            (neighbors.as_mut_slice(), lengths.as_mut_slice());
        for (row, _) in &rows {
            let (n, n_rest) = std::mem::take(&mut neighbors_rest).split_at_mut(row.len());
            let (l, l_rest) = std::mem::take(&mut lengths_rest).split_at_mut(row.len());
            slices.push((n, l));
            (neighbors_rest, lengths_rest) = (n_rest, l_rest);
        }
        slices.into_par_iter().zip(rows.par_iter()).for_each(
            |((n, l), (row_neighbors, row_lengths))| {
                n.copy_from_slice(row_neighbors);
                l.copy_from_slice(row_lengths);
            },
        );
        assert!(neighbors.iter().all(|&j| (j as usize) < positions.len()));
        Families {
            offsets,
            neighbors,
            lengths,
        }
    }

    /// The families without the bonds that cross any of `cracks` (a scalar field's
    /// notches: no interaction across a defect, seed-thesis-ch4-5 §3.8, §4.2.7).
    pub fn without_crossing<const D: usize>(
        &self,
        positions: &[[f64; D]],
        cracks: &[CrackGeometry],
    ) -> Families {
        let mut offsets = Vec::with_capacity(self.offsets.len());
        offsets.push(0);
        let mut neighbors = Vec::with_capacity(self.neighbors.len());
        let mut lengths = Vec::with_capacity(self.lengths.len());
        for (i, x) in positions.iter().enumerate() {
            for b in self.range(i) {
                let j = self.neighbors[b];
                let cut = cracks.iter().any(|c| crosses(c, x, &positions[j as usize]));
                if !cut {
                    neighbors.push(j);
                    lengths.push(self.lengths[b]);
                }
            }
            offsets.push(neighbors.len());
        }
        Families {
            offsets,
            neighbors,
            lengths,
        }
    }

    /// The families of two node sets side by side: `b`'s nodes numbered after `a`'s, no bond
    /// between the sets (the two levels of a multi-grid scene).
    pub fn concat(a: &Families, b: &Families) -> Families {
        let shift = a.node_count() as u32;
        let base = a.bond_count();
        let mut offsets = a.offsets.clone();
        offsets.extend(b.offsets[1..].iter().map(|o| o + base));
        let mut neighbors = a.neighbors.clone();
        neighbors.extend(b.neighbors.iter().map(|j| j + shift));
        let mut lengths = a.lengths.clone();
        lengths.extend_from_slice(&b.lengths);
        Families {
            offsets,
            neighbors,
            lengths,
        }
    }

    pub fn node_count(&self) -> usize {
        self.offsets.len() - 1
    }

    pub fn bond_count(&self) -> usize {
        self.neighbors.len()
    }

    pub fn range(&self, i: usize) -> std::ops::Range<usize> {
        self.offsets[i]..self.offsets[i + 1]
    }
}

/// Family search radius: δ plus a small tolerance, or δ + Δx/2.
pub fn search_radius(kind: FamilyRadius, horizon: f64, spacing: f64) -> f64 {
    match kind {
        FamilyRadius::Horizon => horizon * (1.0 + 1e-9),
        FamilyRadius::HorizonPlusHalfSpacing => (horizon + 0.5 * spacing) * (1.0 - 1e-12),
    }
}

/// Volume-reduction factor β (3.2): 1 inside δ − Δx/2, linear to 0 at δ + Δx/2.
#[inline(always)]
pub fn partial_volume(r: f64, horizon: f64, spacing: f64) -> f64 {
    ((horizon + 0.5 * spacing - r) / spacing).clamp(0.0, 1.0)
}

/// True if the bond from `a` to `b` crosses the pre-crack.
pub fn crosses(crack: &CrackGeometry, a: &[f64], b: &[f64]) -> bool {
    match crack {
        CrackGeometry::Point(c) => (a[0] - c) * (b[0] - c) < 0.0,
        CrackGeometry::Segment(p, q) => segments_cross([a[0], a[1]], [b[0], b[1]], *p, *q),
        CrackGeometry::Patch {
            origin,
            edge_a,
            edge_b,
        } => segment_crosses_patch(
            [a[0], a[1], a[2]],
            [b[0], b[1], b[2]],
            origin,
            edge_a,
            edge_b,
        ),
    }
}

/// Distance from `x` to a pre-crack (a point, segment or parallelogram patch).
pub fn distance_to_crack(crack: &CrackGeometry, x: &[f64]) -> f64 {
    let norm = |v: &[f64]| v.iter().map(|c| c * c).sum::<f64>().sqrt();
    match crack {
        CrackGeometry::Point(c) => (x[0] - c).abs(),
        CrackGeometry::Segment(p, q) => {
            let d = [q[0] - p[0], q[1] - p[1]];
            let len2 = d[0] * d[0] + d[1] * d[1];
            let t = if len2 > 0.0 {
                (((x[0] - p[0]) * d[0] + (x[1] - p[1]) * d[1]) / len2).clamp(0.0, 1.0)
            } else {
                0.0
            };
            norm(&[x[0] - p[0] - t * d[0], x[1] - p[1] - t * d[1]])
        }
        CrackGeometry::Patch {
            origin,
            edge_a,
            edge_b,
        } => {
            // Least-squares coordinates on the patch's plane, clamped to the patch.
            let r: Vec<f64> = (0..3).map(|k| x[k] - origin[k]).collect();
            let dot = |u: &[f64], v: &[f64]| u.iter().zip(v).map(|(a, b)| a * b).sum::<f64>();
            let (aa, ab, bb) = (
                dot(edge_a, edge_a),
                dot(edge_a, edge_b),
                dot(edge_b, edge_b),
            );
            let (ra, rb) = (dot(&r, edge_a), dot(&r, edge_b));
            let det = aa * bb - ab * ab;
            let (a, b) = if det > 0.0 {
                (
                    ((ra * bb - rb * ab) / det).clamp(0.0, 1.0),
                    ((rb * aa - ra * ab) / det).clamp(0.0, 1.0),
                )
            } else {
                (0.0, 0.0)
            };
            let diff: Vec<f64> = (0..3)
                .map(|k| r[k] - a * edge_a[k] - b * edge_b[k])
                .collect();
            norm(&diff)
        }
    }
}

/// A lower bound of the distance from `x` to a pre-crack: exact for points and segments, the
/// distance to the patch's plane for a patch (clamped oblique coordinates can overshoot).
pub fn crack_distance_bound(crack: &CrackGeometry, x: &[f64]) -> f64 {
    match crack {
        CrackGeometry::Patch {
            origin,
            edge_a,
            edge_b,
        } => {
            let n = [
                edge_a[1] * edge_b[2] - edge_a[2] * edge_b[1],
                edge_a[2] * edge_b[0] - edge_a[0] * edge_b[2],
                edge_a[0] * edge_b[1] - edge_a[1] * edge_b[0],
            ];
            let norm = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
            if norm == 0.0 {
                return 0.0;
            }
            ((0..3).map(|k| n[k] * (x[k] - origin[k])).sum::<f64>() / norm).abs()
        }
        _ => distance_to_crack(crack, x),
    }
}

fn cross2(o: [f64; 2], a: [f64; 2], b: [f64; 2]) -> f64 {
    (a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0])
}

/// Proper crossing test; a bond end lying exactly on the crack line counts as crossing when the
/// other end is strictly on one side (so nodes placed on a crack line are cut from one side).
fn segments_cross(a: [f64; 2], b: [f64; 2], p: [f64; 2], q: [f64; 2]) -> bool {
    let d1 = cross2(p, q, a);
    let d2 = cross2(p, q, b);
    let d3 = cross2(a, b, p);
    let d4 = cross2(a, b, q);
    let straddles_crack = (d1 > 0.0 && d2 < 0.0)
        || (d1 < 0.0 && d2 > 0.0)
        || (d1 == 0.0) != (d2 == 0.0) && (d1 > 0.0 || d2 > 0.0);
    straddles_crack && ((d3 > 0.0) != (d4 > 0.0) || d3 == 0.0 || d4 == 0.0)
}

fn segment_crosses_patch(
    a: [f64; 3],
    b: [f64; 3],
    origin: &[f64; 3],
    ea: &[f64; 3],
    eb: &[f64; 3],
) -> bool {
    let n = [
        ea[1] * eb[2] - ea[2] * eb[1],
        ea[2] * eb[0] - ea[0] * eb[2],
        ea[0] * eb[1] - ea[1] * eb[0],
    ];
    let side = |x: [f64; 3]| (0..3).map(|k| (x[k] - origin[k]) * n[k]).sum::<f64>();
    let (sa, sb) = (side(a), side(b));
    let straddles = (sa > 0.0 && sb < 0.0)
        || (sa < 0.0 && sb > 0.0)
        || (sa == 0.0) != (sb == 0.0) && (sa > 0.0 || sb > 0.0);
    if !straddles {
        return false;
    }
    let t = sa / (sa - sb);
    let hit: Vec<f64> = (0..3)
        .map(|k| a[k] + t * (b[k] - a[k]) - origin[k])
        .collect();
    // Solve hit = u·ea + v·eb in the least-squares sense (ea, eb span the plane).
    let dot = |x: &[f64], y: &[f64; 3]| (0..3).map(|k| x[k] * y[k]).sum::<f64>();
    let (aa, ab, bb) = (dot(ea, ea), dot(ea, eb), dot(eb, eb));
    let (ha, hb) = (dot(&hit, ea), dot(&hit, eb));
    let det = aa * bb - ab * ab;
    let u = (ha * bb - hb * ab) / det;
    let v = (hb * aa - ha * ab) / det;
    let tol = 1e-12;
    (-tol..=1.0 + tol).contains(&u) && (-tol..=1.0 + tol).contains(&v)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::discretization::grid::Lattice;
    use crate::scene::Solid;

    /// A notch at x = 2.5 across a 5 × 5 lattice (Δx = 1, radius 1.5): exactly the 5
    /// horizontal and 8 diagonal pairs between columns 2 and 3 go, 26 directed bonds, and the
    /// families stay symmetric.
    #[test]
    fn a_notch_removes_exactly_the_bonds_across_it() {
        let positions: Vec<[f64; 2]> = (0..25).map(|k| [(k / 5) as f64, (k % 5) as f64]).collect();
        let all = Families::build(&positions, 1.5);
        let notch = CrackGeometry::Segment([2.5, -1.0], [2.5, 6.0]);
        let cut = all.without_crossing(&positions, &[notch]);
        assert_eq!(all.bond_count() - cut.bond_count(), 26);
        for i in 0..25 {
            for &j in &cut.neighbors[cut.range(i)] {
                let (a, b) = (positions[i][0], positions[j as usize][0]);
                assert!((a - 2.5) * (b - 2.5) > 0.0, "bond {i}–{j} crosses");
                assert!(cut.neighbors[cut.range(j as usize)].contains(&(i as u32)));
            }
        }
    }

    fn family_size_with_self<const D: usize>(m: usize) -> usize {
        let n = 2 * m + 3;
        let solid = Solid::Box {
            min: vec![0.0; D],
            max: vec![n as f64; D],
        };
        let lattice = Lattice::<D>::build(&solid, 1.0, [0.0; 2], 1);
        let centre = [(m + 1) as f64 + 0.0; D];
        let c = lattice
            .positions
            .iter()
            .position(|p| p.iter().zip(&centre).all(|(a, b)| (a - b).abs() < 1e-12))
            .unwrap();
        let fam = Families::build(
            &lattice.positions,
            search_radius(FamilyRadius::Horizon, m as f64, 1.0),
        );
        fam.range(c).len() + 1
    }

    #[test]
    fn neighborhood_counts_match_the_thesis() {
        for m in [1, 3, 8, 33] {
            assert_eq!(family_size_with_self::<1>(m), 2 * m + 1);
        }
        assert_eq!(family_size_with_self::<2>(8), 197);
        assert_eq!(family_size_with_self::<2>(12), 441);
        assert_eq!(family_size_with_self::<2>(24), 1793);
        assert_eq!(family_size_with_self::<3>(6), 925);
        assert_eq!(family_size_with_self::<3>(12), 7153);
    }

    #[test]
    fn families_are_symmetric() {
        let solid = Solid::Box {
            min: vec![0.0; 2],
            max: vec![10.0; 2],
        };
        let lattice = Lattice::<2>::build(&solid, 1.0, [-0.3, 0.3], 3);
        let fam = Families::build(&lattice.positions, 3.0);
        for i in 0..fam.node_count() {
            for b in fam.range(i) {
                let j = fam.neighbors[b] as usize;
                let back = fam.range(j).find(|&k| fam.neighbors[k] as usize == i);
                let k = back.expect("j's family contains i");
                assert_eq!(fam.lengths[k], fam.lengths[b]);
            }
        }
    }

    #[test]
    fn partial_volume_factor() {
        assert_eq!(partial_volume(1.0, 3.0, 1.0), 1.0);
        assert_eq!(partial_volume(2.5, 3.0, 1.0), 1.0);
        assert!((partial_volume(3.0, 3.0, 1.0) - 0.5).abs() < 1e-15);
        assert_eq!(partial_volume(3.5, 3.0, 1.0), 0.0);
    }

    #[test]
    fn crack_crossing() {
        let crack = CrackGeometry::Segment([0.0, 0.0], [1.0, 0.0]);
        assert!(crosses(&crack, &[0.5, -0.1], &[0.5, 0.1]));
        assert!(!crosses(&crack, &[1.5, -0.1], &[1.5, 0.1]));
        assert!(!crosses(&crack, &[0.5, 0.1], &[0.7, 0.2]));
        // A node on the crack line is cut from the upper side only.
        assert!(crosses(&crack, &[0.5, 0.0], &[0.5, 0.1]));
        assert!(!crosses(&crack, &[0.5, 0.0], &[0.5, -0.1]));
        let patch = CrackGeometry::Patch {
            origin: [0.0, 0.0, 0.0],
            edge_a: [1.0, 0.0, 0.0],
            edge_b: [0.0, 1.0, 0.0],
        };
        assert!(crosses(&patch, &[0.5, 0.5, -0.1], &[0.5, 0.5, 0.1]));
        assert!(!crosses(&patch, &[1.5, 0.5, -0.1], &[1.5, 0.5, 0.1]));
        let point = CrackGeometry::Point(0.5);
        assert!(crosses(&point, &[0.0], &[1.0]));
        assert!(!crosses(&point, &[0.6], &[1.0]));
    }
}
