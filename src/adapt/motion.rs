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

use rayon::prelude::*;

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
}

impl<const D: usize> MotionBound<D> {
    /// Cells of side `reach` (≥ the longest bond) over the reference positions.
    pub fn new(reference: &[[f64; D]], reach: f64) -> Self {
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
        MotionBound {
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
        tracked: impl Fn(usize) -> bool,
    ) {
        self.epoch.copy_from_slice(positions);
        self.factor = Some(factor);
        self.tracked_nodes.clear();
        self.tracked_offsets.clear();
        self.tracked_offsets.push(0);
        for c in 0..self.cell_offsets.len() - 1 {
            let members = &self.cell_nodes[self.cell_offsets[c]..self.cell_offsets[c + 1]];
            self.tracked_nodes
                .extend(members.iter().filter(|&&k| tracked(k as usize)));
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
        let (offsets, nodes, epoch) = (&self.tracked_offsets, &self.tracked_nodes, &self.epoch);
        let motion =
            |k: usize| -> [f64; D] { std::array::from_fn(|a| positions[k][a] - epoch[k][a]) };
        self.representative
            .par_iter_mut()
            .zip(self.spread.par_iter_mut())
            .enumerate()
            .for_each(|(c, (rep, spread))| {
                let members = &nodes[offsets[c]..offsets[c + 1]];
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
                    let w = motion(k as usize);
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
            });
        let (reps, spread, least) = (&self.representative, &self.spread, &self.least_slack);
        let neighbors = &self.neighbor_offsets;
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
                *bound = spread[c] + far;
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
