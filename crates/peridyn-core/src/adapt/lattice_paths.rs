//! Lattice paths for the motion bound of the switching check (`motion`): on a regular lattice,
//! a bond's change of length is bounded by the motion's largest nearest-neighbour difference.
//!
//! Two nodes i, j with integer lattice offset q = (p_j − p_i) are joined by a staircase of
//! |q|₁ ≤ √D |q|₂ unit steps, all inside the box spanned by p_i and p_j. Every point of that box
//! is within ‖x_j − x_i‖ of x_i, so when the lattice is fully populated around i the steps run
//! between i's family members, and with w the motion since an epoch,
//! |w_j − w_i| ≤ Σ_steps |Δw| ≤ |q|₁ Λ ≤ √D (l_ij / h) Λ, Λ the largest |w_k' − w_k| over
//! lattice neighbours (k, k') within reach of i. So each bond's stretch ratio r/l moved by at
//! most √D Λ / h, the same for every bond length: uniform strain no longer counts at the
//! scale of a cell (the cell bound's |W_c − W_c'|) but at the scale of one spacing, and long
//! bonds are not charged the shortest bond's slack.

/// Nodes on a lattice of spacing h: each node's neighbour one step up each axis, and per cell
/// (of the motion bound's grid) whether the lattice is fully populated within reach of every
/// node of the cell.
pub struct LatticePaths<const D: usize> {
    /// Per node and axis, the node one lattice step up (u32::MAX: none).
    up: Vec<[u32; D]>,
    /// Per cell: every lattice point within reach of the cell's nodes is a node.
    pub complete: Vec<bool>,
}

/// A lattice box larger than this many times the node count is too sparse to index densely.
const SPARSE: usize = 8;

impl<const D: usize> LatticePaths<D> {
    /// The lattice of spacing `spacing` through the first node, if every node sits on it (one
    /// node per point); `reach` the longest bond; `cell_nodes(c)` lists cell c's nodes.
    pub fn detect<'a>(
        reference: &[[f64; D]],
        spacing: f64,
        reach: f64,
        cells: usize,
        cell_nodes: impl Fn(usize) -> &'a [u32],
    ) -> Option<Self> {
        let points = crate::discretization::grid::lattice_points(reference, spacing)?;
        let lo: [i64; D] = std::array::from_fn(|a| points.iter().map(|p| p[a]).min().unwrap_or(0));
        let hi: [i64; D] = std::array::from_fn(|a| points.iter().map(|p| p[a]).max().unwrap_or(0));
        let dims: [usize; D] = std::array::from_fn(|a| (hi[a] - lo[a] + 1) as usize);
        let total = dims
            .iter()
            .try_fold(1usize, |acc, &d| acc.checked_mul(d))
            .filter(|&t| t <= SPARSE * reference.len() + 1024)?;
        let index = |p: &[i64; D]| -> usize {
            (0..D)
                .rev()
                .fold(0usize, |acc, a| acc * dims[a] + (p[a] - lo[a]) as usize)
        };
        let mut grid = vec![u32::MAX; total];
        for (k, p) in points.iter().enumerate() {
            let slot = &mut grid[index(p)];
            if *slot != u32::MAX {
                return None;
            }
            *slot = k as u32;
        }
        let up = points
            .iter()
            .map(|p| {
                std::array::from_fn(|a| {
                    let mut next = *p;
                    next[a] += 1;
                    if next[a] > hi[a] {
                        u32::MAX
                    } else {
                        grid[index(&next)]
                    }
                })
            })
            .collect();
        // Summed occupancy: filled[index(p)] = number of nodes in the box lo ..= p.
        let mut filled: Vec<u32> = grid.iter().map(|&k| u32::from(k != u32::MAX)).collect();
        let mut stride = 1usize;
        for &extent in &dims {
            for s in 0..total {
                if !(s / stride).is_multiple_of(extent) {
                    filled[s] += filled[s - stride];
                }
            }
            stride *= extent;
        }
        let box_count = |from: [i64; D], to: [i64; D]| -> u64 {
            // Inclusion–exclusion over the 2^D corners of the box from ..= to.
            (0..1usize << D)
                .map(|corner| {
                    let mut p = to;
                    let mut sign = 1i64;
                    for a in 0..D {
                        if corner >> a & 1 == 1 {
                            p[a] = from[a] - 1;
                            sign = -sign;
                        }
                    }
                    if p.iter().zip(&lo).any(|(v, l)| v < l) {
                        0
                    } else {
                        sign * i64::from(filled[index(&p)])
                    }
                })
                .sum::<i64>() as u64
        };
        let radius = (reach / spacing * (1.0 + 1e-9)).ceil() as i64;
        let complete = (0..cells)
            .map(|c| {
                let members = cell_nodes(c);
                if members.is_empty() {
                    return false;
                }
                let mut from = [i64::MAX; D];
                let mut to = [i64::MIN; D];
                for &k in members {
                    for a in 0..D {
                        from[a] = from[a].min(points[k as usize][a] - radius);
                        to[a] = to[a].max(points[k as usize][a] + radius);
                    }
                }
                let inside = (0..D).all(|a| from[a] >= lo[a] && to[a] <= hi[a]);
                let volume: u64 = (0..D).map(|a| (to[a] - from[a] + 1) as u64).product();
                inside && box_count(from, to) == volume
            })
            .collect();
        Some(LatticePaths { up, complete })
    }

    /// Node k's largest |w_k' − w_k|² over its up-neighbours k' (both `tracked`), w the
    /// `motion` (finite); 0 for none.
    #[inline]
    pub fn step2_of(&self, k: usize, tracked: &[bool], motion: &[[f64; D]]) -> f64 {
        let w = motion[k];
        let mut largest = 0.0f64;
        if !tracked[k] {
            return largest;
        }
        for &next in &self.up[k] {
            if next != u32::MAX && tracked[next as usize] {
                let v = motion[next as usize];
                largest = largest.max((0..D).map(|a| (v[a] - w[a]).powi(2)).sum::<f64>());
            }
        }
        largest
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn square(n: usize) -> Vec<[f64; 2]> {
        (0..n * n)
            .map(|k| [0.5 + (k % n) as f64, 0.5 + (k / n) as f64])
            .collect()
    }

    #[test]
    fn a_lattice_is_found_with_its_neighbours_and_complete_cells() {
        let x = square(12);
        // Cells of 3 × 3 nodes; reach 2: only the centre 2 × 2 cells have every point within
        // 2 of their nodes inside the 12 × 12 square.
        let cell_of = |k: usize| (k % 12) / 3 + 4 * ((k / 12) / 3);
        let lists = |count: u32, cell: &dyn Fn(usize) -> usize| -> Vec<Vec<u32>> {
            (0..16)
                .map(|c| (0..count).filter(|&k| cell(k as usize) == c).collect())
                .collect()
        };
        let cells = lists(144, &cell_of);
        let lattice = LatticePaths::detect(&x, 1.0, 2.0, 16, |c| &cells[c][..]).expect("a lattice");
        assert_eq!(lattice.up[0], [1, 12]);
        assert_eq!(lattice.up[11], [u32::MAX, 23]);
        let complete: Vec<usize> = (0..16).filter(|&c| lattice.complete[c]).collect();
        assert_eq!(complete, vec![5, 6, 9, 10]);
        // A hole at node 5 · 12 + 5 spoils the cells within reach of it.
        let holed: Vec<[f64; 2]> = x.iter().copied().filter(|p| *p != [5.5, 5.5]).collect();
        let shift = |k: usize| if k >= 65 { k + 1 } else { k };
        let cells = lists(143, &|k| cell_of(shift(k)));
        let lattice =
            LatticePaths::detect(&holed, 1.0, 2.0, 16, |c| &cells[c][..]).expect("a lattice");
        assert!((0..16).all(|c| !lattice.complete[c]));
    }

    #[test]
    fn off_lattice_or_doubled_points_are_not_a_lattice() {
        let mut x = square(6);
        let nodes = |_: usize| &[][..];
        assert!(LatticePaths::detect(&x, 1.0, 1.0, 0, nodes).is_some());
        x[7][0] += 1e-3;
        assert!(LatticePaths::detect(&x, 1.0, 1.0, 0, nodes).is_none());
        x[7] = x[8];
        assert!(LatticePaths::detect(&x, 1.0, 1.0, 0, nodes).is_none());
    }
}
