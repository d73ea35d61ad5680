//! A rigorous filter for the switching check (3.80): which nodes cannot have a critical bond.
//!
//! At an *epoch* every checked node i records its slack μ_i = min_j (√f·l_ij − r_ij) over the
//! bonds it checks (f = (1 + χ s0)², r the current length), and the positions are kept. Later,
//! with w = y − y_epoch the motion since then, a bond's length has changed by at most
//! |w_j − w_i|. Nodes are binned in cells at least one family radius wide, so i and j lie in
//! the same or adjacent cells; with a representative motion W_c and spread ρ_c = max |w_k − W_c|
//! per cell, |w_j − w_i| ≤ ρ_c + |W_c − W_c'| + ρ_c' ≤ B_c. A node with B_c < μ_i has no bond
//! that can have reached χ·s0, whatever happened in between: only the others are checked
//! exactly. Rigid motion cancels (W is subtracted), so quiet regions cost O(1) per node.
//!
//! On a lattice (`lattice_paths`) a second bound, √D times the largest motion difference of
//! lattice neighbours near the cell, also holds where the lattice is fully populated; the
//! smaller of the two is taken. It does not grow with the cell's size, so a smooth motion
//! (a strain wave) uses up far less of the slack.

use rayon::prelude::*;

use super::lattice_paths::LatticePaths;

/// The largest share of a node's slack the motion bound may take for an epoch to keep the
/// slack (less the bound) instead of recomputing it from the node's bonds. On the
/// Kalthoff–Winkler paper grid (855 steps at 0.7 of the hybrid's stable step), the bonds the
/// check visits: 6.60·10⁹ without keeping, 6.36·10⁹ at 0.05, 6.16·10⁹ at 0.2, 5.67·10⁹ at 0.5
/// (9.5 M slacks kept over 162 epochs, 20 % of the nodes an epoch visits); the wall time of
/// the check did not change measurably (waves fill the plate, so most cells' bounds are large
/// when an epoch is due).
const REUSE_SHARE: f64 = 0.5;

pub struct MotionBound<const D: usize> {
    cell_size: f64,
    /// Flat index offsets of a cell's 3^D neighbours (itself included).
    neighbor_offsets: Vec<isize>,
    /// Node → its cell; cells' nodes in CSR form.
    cell_of: Vec<u32>,
    cell_offsets: Vec<usize>,
    cell_nodes: Vec<u32>,
    /// The cells' *tracked* nodes (CSR): those whose motion can enter a checked bond, the
    /// checked nodes and their family members. Set at each epoch; the bound is taken over
    /// them only, so nodes deep inside Ω_s (a crack opening) do not widen it.
    tracked_offsets: Vec<usize>,
    tracked_nodes: Vec<u32>,
    /// Positions at the epoch, and each node's slack (m); −∞ forces an exact check.
    epoch: Vec<[f64; D]>,
    pub slack: Vec<f64>,
    /// Per cell: representative motion, spread, and the bound B_c.
    representative: Vec<[f64; D]>,
    spread: Vec<f64>,
    bound: Vec<f64>,
    /// Per cell: the least slack of its nodes (a cell whose bound stays below it is skipped
    /// without visiting its nodes).
    least_slack: Vec<f64>,
    /// The f the slacks were computed with (None: no epoch yet, or invalidated).
    factor: Option<f64>,
    /// The nodes' lattice, if they sit on one; per node whether it is tracked, and per cell
    /// the largest lattice-neighbour motion difference among its tracked nodes (Λ_cell).
    lattice: Option<LatticePaths<D>>,
    is_tracked: Vec<bool>,
    step: Vec<f64>,
    /// Per node, the motion since the epoch (set by `update`).
    motion: Vec<[f64; D]>,
    /// Rounding allowance of one lattice step's motion difference (m).
    step_rounding: f64,
}

impl<const D: usize> MotionBound<D> {
    /// Cells of side `reach` (≥ the longest bond) over the reference positions; `shortest`
    /// the shortest bond, which the slacks are scaled by and which is the lattice spacing
    /// where the nodes sit on a lattice.
    pub fn new(reference: &[[f64; D]], reach: f64, shortest: f64) -> Self {
        let mut lo = [f64::INFINITY; D];
        let mut hi = [f64::NEG_INFINITY; D];
        for x in reference {
            for k in 0..D {
                lo[k] = lo[k].min(x[k]);
                hi[k] = hi[k].max(x[k]);
            }
        }
        let cell_size = reach * (1.0 + 1e-9);
        // One empty cell of padding on every side: each node's cell has all 3^D neighbours.
        let dims: [usize; D] =
            std::array::from_fn(|k| ((hi[k] - lo[k]) / cell_size).floor() as usize + 3);
        let cell_of: Vec<u32> = reference
            .iter()
            .map(|x| {
                (0..D).rev().fold(0usize, |acc, k| {
                    let c = (((x[k] - lo[k]) / cell_size).floor() as usize).min(dims[k] - 3);
                    acc * dims[k] + c + 1
                }) as u32
            })
            .collect();
        let mut stride = 1isize;
        let mut neighbor_offsets = vec![0isize];
        for &d in &dims {
            neighbor_offsets = [-stride, 0, stride]
                .iter()
                .flat_map(|&step| neighbor_offsets.iter().map(move |&o| o + step))
                .collect();
            stride *= d as isize;
        }
        let cells: usize = dims.iter().product();
        let mut cell_offsets = vec![0usize; cells + 1];
        for &c in &cell_of {
            cell_offsets[c as usize + 1] += 1;
        }
        for c in 0..cells {
            cell_offsets[c + 1] += cell_offsets[c];
        }
        let mut fill = cell_offsets.clone();
        let mut cell_nodes = vec![0u32; reference.len()];
        for (i, &c) in cell_of.iter().enumerate() {
            cell_nodes[fill[c as usize]] = i as u32;
            fill[c as usize] += 1;
        }
        let lattice = LatticePaths::detect(reference, shortest, reach, cells, |c| {
            &cell_nodes[cell_offsets[c]..cell_offsets[c + 1]]
        });
        let scale = reference
            .iter()
            .flat_map(|x| x.iter().map(|v| v.abs()))
            .fold(0.0f64, f64::max)
            + reach;
        MotionBound {
            lattice,
            is_tracked: vec![false; reference.len()],
            step: vec![0.0; cells],
            motion: vec![[0.0; D]; reference.len()],
            // w = y − y_epoch and the difference of two w, each to a unit roundoff of the
            // coordinates' size.
            step_rounding: 8.0 * f64::EPSILON * scale,
            cell_size,
            neighbor_offsets,
            cell_of,
            tracked_offsets: cell_offsets.clone(),
            tracked_nodes: cell_nodes.clone(),
            cell_offsets,
            cell_nodes,
            epoch: reference.to_vec(),
            slack: vec![f64::NEG_INFINITY; reference.len()],
            representative: vec![[0.0; D]; cells],
            spread: vec![0.0; cells],
            bound: vec![0.0; cells],
            least_slack: vec![f64::NEG_INFINITY; cells],
            factor: None,
        }
    }

    /// Whether the slacks are stale for this f (χ changed, or never computed).
    pub fn needs_epoch(&self, factor: f64) -> bool {
        self.factor != Some(factor)
    }

    /// Whether the lattice-path bound is in use (the nodes sit on a lattice).
    pub fn on_lattice(&self) -> bool {
        self.lattice.is_some()
    }

    /// Drops the lattice-path bound: the cell bound alone (tests and measurements).
    pub fn drop_lattice_paths(&mut self) {
        self.lattice = None;
        self.step.iter_mut().for_each(|s| *s = 0.0);
    }

    pub fn invalidate(&mut self) {
        self.factor = None;
    }

    /// Starts an epoch at `positions`; the caller has filled `slack` for f = `factor` (+∞ for
    /// nodes it never asks about). `tracked(k)` must hold for every node that is checked or
    /// bonded to a checked node until the next epoch (nodes forced later are exempt: they
    /// are always checked exactly).
    pub fn start_epoch(
        &mut self,
        positions: &[[f64; D]],
        factor: f64,
        tracked: impl Fn(usize) -> bool + Sync,
    ) {
        self.epoch.copy_from_slice(positions);
        self.factor = Some(factor);
        self.is_tracked
            .par_iter_mut()
            .enumerate()
            .for_each(|(k, t)| *t = tracked(k));
        self.tracked_nodes.clear();
        self.tracked_offsets.clear();
        self.tracked_offsets.push(0);
        for c in 0..self.cell_offsets.len() - 1 {
            let members = &self.cell_nodes[self.cell_offsets[c]..self.cell_offsets[c + 1]];
            let is_tracked = &self.is_tracked;
            self.tracked_nodes
                .extend(members.iter().filter(|&&k| is_tracked[k as usize]));
            self.tracked_offsets.push(self.tracked_nodes.len());
        }
        let (offsets, nodes, slack) = (&self.cell_offsets, &self.cell_nodes, &self.slack);
        self.least_slack
            .par_iter_mut()
            .enumerate()
            .for_each(|(c, least)| {
                *least = nodes[offsets[c]..offsets[c + 1]]
                    .iter()
                    .map(|&k| slack[k as usize])
                    .fold(f64::INFINITY, f64::min);
            });
    }

    /// The slacks of a new epoch: +∞ for nodes not `checked`, `exact(i)` for the others,
    /// except that with `reuse` (the slacks are for this f and `update` has bounded the
    /// motion since the last epoch) a node whose cell bound B_c is at most `REUSE_SHARE` of
    /// its slack keeps μ_i − B_c without visiting its bonds. That is rigorous: each bond's
    /// stretch slack √f − r/l shrank by at most B_c/l ≤ B_c/l_min since the last epoch, so
    /// l_min · min_j (√f − r_ij/l_ij) ≥ μ_i − B_c now. The reused slack only shrinks, so a
    /// node is revisited once its accumulated bounds exceed the share. `exact` returns the
    /// slack and the work it took (bonds visited); returns the slacks kept and the work summed.
    /// Call `start_epoch` next.
    pub fn refresh_slacks(
        &mut self,
        reuse: bool,
        checked: impl Fn(usize) -> bool + Sync,
        exact: impl Fn(usize) -> (f64, u64) + Sync,
    ) -> (u64, u64) {
        let (bound, cell_of) = (&self.bound, &self.cell_of);
        let margin = 1e-12 * self.cell_size;
        self.slack
            .par_iter_mut()
            .enumerate()
            .with_min_len(1024)
            .map(|(i, s)| {
                if !checked(i) {
                    *s = f64::INFINITY;
                    return (0, 0);
                }
                let b = bound[cell_of[i] as usize] + margin;
                // A NaN bound or a forced slack (−∞) fails the test.
                if reuse && b <= REUSE_SHARE * *s && s.is_finite() {
                    *s -= b;
                    (1, 0)
                } else {
                    let (slack, work) = exact(i);
                    *s = slack;
                    (0, work)
                }
            })
            .reduce(|| (0, 0), |a, b| (a.0 + b.0, a.1 + b.1))
    }

    /// Forces node i's exact check until the next epoch (its checked bonds changed).
    pub fn force(&mut self, i: usize) {
        self.slack[i] = f64::NEG_INFINITY;
        self.least_slack[self.cell_of[i] as usize] = f64::NEG_INFINITY;
    }

    /// Folds `step` over the nodes k with `wanted(k)` that may have a critical bond, in parallel
    /// over the cells whose bound reaches their least slack (the others are skipped without
    /// visiting their nodes); `zero` makes an empty accumulator and `join` merges two. Returns
    /// the number of nodes visited and the accumulator.
    pub fn fold_flagged<T: Send>(
        &self,
        wanted: impl Fn(usize) -> bool + Sync,
        zero: impl Fn() -> T + Sync + Send,
        step: impl Fn(T, usize) -> T + Sync + Send,
        join: impl Fn(T, T) -> T + Sync + Send,
    ) -> (usize, T) {
        let (zero, step, join) = (&zero, &step, &join);
        self.bound
            .par_iter()
            .zip(self.least_slack.par_iter())
            .enumerate()
            .with_min_len(64)
            .filter(|(_, (bound, least))| self.reaches(**bound, **least))
            .fold(
                || (0, zero()),
                |acc, (c, _)| {
                    self.cell_nodes[self.cell_offsets[c]..self.cell_offsets[c + 1]]
                        .iter()
                        .map(|&k| k as usize)
                        .filter(|&k| wanted(k) && self.may_reach(k))
                        .fold(acc, |(n, acc), k| (n + 1, step(acc, k)))
                },
            )
            .reduce(|| (0, zero()), |a, b| (a.0 + b.0, join(a.1, b.1)))
    }

    /// Recomputes the per-cell bounds B_c for the motion since the epoch.
    pub fn update(&mut self, positions: &[[f64; D]]) {
        let epoch = &self.epoch;
        self.motion
            .par_iter_mut()
            .zip(positions.par_iter().zip(epoch))
            .with_min_len(4096)
            .for_each(|(w, (y, e))| *w = std::array::from_fn(|a| y[a] - e[a]));
        let (offsets, nodes, motion) = (&self.tracked_offsets, &self.tracked_nodes, &self.motion);
        let (lattice, is_tracked) = (&self.lattice, &self.is_tracked);
        self.representative
            .par_iter_mut()
            .zip(self.spread.par_iter_mut())
            .zip(self.step.par_iter_mut())
            .enumerate()
            .with_min_len(16)
            .for_each(|(c, ((rep, spread), step))| {
                let members = &nodes[offsets[c]..offsets[c + 1]];
                *step = 0.0;
                if members.is_empty() {
                    *spread = 0.0;
                    return;
                }
                // The motions' bounding box: its centre represents the cell, its half
                // diagonal bounds every member's distance from it.
                let mut lo = [f64::INFINITY; D];
                let mut hi = [f64::NEG_INFINITY; D];
                // Σ w is non-finite if any w is (or overflows: then conservatively so too).
                let mut sum = 0.0;
                for &k in members {
                    let w = motion[k as usize];
                    for a in 0..D {
                        lo[a] = if w[a] < lo[a] { w[a] } else { lo[a] };
                        hi[a] = if w[a] > hi[a] { w[a] } else { hi[a] };
                        sum += w[a];
                    }
                }
                let finite = sum.is_finite();
                *rep = std::array::from_fn(|a| 0.5 * (lo[a] + hi[a]));
                // Rounding of the centre is covered by the relative margin; a non-finite
                // motion makes the bound NaN (every node near it is then checked).
                *spread = if finite {
                    (0..D)
                        .map(|a| (0.5 * (hi[a] - lo[a])).powi(2))
                        .sum::<f64>()
                        .sqrt()
                        * (1.0 + 1e-12)
                } else {
                    f64::NAN
                };
                // Λ_cell: the largest step among the tracked members (a non-finite motion
                // already made the spread NaN, which poisons every bound near it).
                if let Some(lattice) = lattice
                    && finite
                {
                    let largest2 = members
                        .iter()
                        .map(|&k| lattice.step2_of(k as usize, is_tracked, motion))
                        .fold(0.0, f64::max);
                    *step = largest2.sqrt();
                }
            });
        let (reps, spread, least) = (&self.representative, &self.spread, &self.least_slack);
        let neighbors = &self.neighbor_offsets;
        let (lattice, step, rounding) = (&self.lattice, &self.step, self.step_rounding);
        self.bound
            .par_iter_mut()
            .enumerate()
            .with_min_len(256)
            .for_each(|(c, bound)| {
                // Cells without a slack to compare (padding, no checked node) need no bound.
                if least[c] == f64::INFINITY {
                    *bound = 0.0;
                    return;
                }
                let mut far = 0.0f64;
                for &offset in neighbors {
                    let other = c.wrapping_add_signed(offset);
                    if offsets[other] < offsets[other + 1] {
                        let reach = spread[other] + distance(&reps[other], &reps[c]);
                        // NaN-propagating max: a non-finite neighbour poisons the bound.
                        far = if reach.is_nan() || reach > far {
                            reach
                        } else {
                            far
                        };
                    }
                }
                let cells = spread[c] + far;
                *bound = match lattice {
                    Some(lattice) if lattice.complete[c] => {
                        let mut largest = 0.0f64;
                        for &offset in neighbors {
                            let s = step[c.wrapping_add_signed(offset)];
                            largest = if s.is_nan() || s > largest {
                                s
                            } else {
                                largest
                            };
                        }
                        // |w_j − w_i| ≤ √D (l/h) Λ for every checked bond of the cell's nodes,
                        // so each stretch ratio moved by ≤ √D Λ / h ≤ that over the shortest
                        // bond (`lattice_paths`): in the slacks' units, √D Λ.
                        let paths = (D as f64).sqrt() * (largest + rounding) * (1.0 + 1e-12);
                        if cells.is_nan() || paths.is_nan() {
                            f64::NAN
                        } else {
                            cells.min(paths)
                        }
                    }
                    _ => cells,
                };
            });
    }

    /// Whether node i may have a critical bond (its bound reaches its slack); true for forced
    /// slacks (−∞) and non-finite motion. A relative 1e-12 of the cell size covers rounding in w and the slack.
    #[inline]
    pub fn may_reach(&self, i: usize) -> bool {
        self.reaches(self.bound[self.cell_of[i] as usize], self.slack[i])
    }

    #[inline]
    fn reaches(&self, bound: f64, slack: f64) -> bool {
        let bound = bound + 1e-12 * self.cell_size;
        bound.is_nan() || bound >= slack
    }
}

fn distance2<const D: usize>(a: &[f64; D], b: &[f64; D]) -> f64 {
    (0..D).map(|k| (a[k] - b[k]) * (a[k] - b[k])).sum()
}

fn distance<const D: usize>(a: &[f64; D], b: &[f64; D]) -> f64 {
    distance2(a, b).sqrt()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::discretization::Families;
    use crate::discretization::grid::SplitMix64;

    /// The bound is rigorous: on a 2D lattice (Δx = 1, horizon 3.015) under a smooth wave with
    /// noise, and with a jump across a line (an opening crack), every bond's change of
    /// length |w_j − w_i| stays below its node's cell bound times l_ij / l_min (the slacks'
    /// units); and on the smooth field the lattice-path bound is the tighter one.
    #[test]
    fn every_bonds_change_of_length_is_within_its_cells_bound() {
        let n = 40;
        let x: Vec<[f64; 2]> = (0..n * n)
            .map(|k| [0.5 + (k % n) as f64, 0.5 + (k / n) as f64])
            .collect();
        let families = Families::build(&x, 3.015);
        let mut rng = SplitMix64(17);
        let smooth = |p: &[f64; 2]| {
            [
                1e-3 * (0.3 * p[0]).sin(),
                2e-3 * (0.2 * p[1] + 0.1 * p[0]).cos(),
            ]
        };
        // A smooth wave with noise, the same with a jump across y = 17 (an opening crack), and
        // w = a (x + y) ê, where a diagonal bond's change meets the bound (|q|₁ = √2 |q|₂).
        for (case, jump) in [("smooth", 0.0), ("jump", 5e-2), ("staircase", 0.0)] {
            let y: Vec<[f64; 2]> = x
                .iter()
                .map(|p| {
                    if case == "staircase" {
                        let w = 1e-3 * (p[0] + p[1]);
                        return [p[0] + 0.6 * w, p[1] + 0.8 * w];
                    }
                    let s = smooth(p);
                    let noise = [1e-5 * (rng.next_f64() - 0.5), 1e-5 * (rng.next_f64() - 0.5)];
                    let crack = if p[1] > 17.0 { jump } else { 0.0 };
                    [p[0] + s[0] + noise[0], p[1] + s[1] + noise[1] + crack]
                })
                .collect();
            let mut bound = MotionBound::new(&x, families.longest(), families.shortest());
            assert!(bound.on_lattice());
            bound.slack.iter_mut().for_each(|s| *s = 1.0);
            bound.start_epoch(&x, 1.0, |_| true);
            bound.update(&y);
            let mut tighter = 0;
            let mut complete = 0;
            let mut tightest = 0.0f64;
            for i in 0..x.len() {
                let c = bound.cell_of[i] as usize;
                let b = bound.bound[c];
                for k in families.range(i) {
                    let j = families.neighbors[k] as usize;
                    let l = families.length(i, k);
                    let w: [f64; 2] =
                        std::array::from_fn(|a| (y[j][a] - x[j][a]) - (y[i][a] - x[i][a]));
                    let change = (w[0] * w[0] + w[1] * w[1]).sqrt() / l * families.shortest();
                    assert!(
                        change <= b,
                        "{case}: node {i}, bond to {j}: {change:e} > {b:e}"
                    );
                    tightest = tightest.max(change / b);
                }
                if bound.lattice.as_ref().unwrap().complete[c] {
                    complete += 1;
                    let occupied =
                        |d: usize| bound.tracked_offsets[d] < bound.tracked_offsets[d + 1];
                    let far = bound
                        .neighbor_offsets
                        .iter()
                        .map(|&o| c.wrapping_add_signed(o))
                        .filter(|&d| occupied(d))
                        .map(|d| {
                            bound.spread[d]
                                + distance(&bound.representative[d], &bound.representative[c])
                        })
                        .fold(0.0, f64::max);
                    let cells = bound.spread[c] + far;
                    if b < 0.5 * cells {
                        tighter += 1;
                    }
                }
            }
            assert!(complete > x.len() / 4, "{complete} nodes in complete cells");
            if jump == 0.0 {
                assert_eq!(
                    tighter, complete,
                    "the lattice-path bound is at least 2× tighter"
                );
            }
        }
    }
}
