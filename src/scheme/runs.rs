//! Translation runs of a [`VectorOperator`]: consecutive rows of consecutive nodes that share a
//! stencil and whose columns all shift by one from row to row (a lattice row away from
//! boundaries and switched nodes). Over a run, K u is a sum of shifted axpys; evaluated
//! `CHUNK` rows at a time on component arrays (SoA), every load is contiguous, the column
//! list is read once per chunk instead of once per row, and the lane loops become SIMD. Rows
//! outside runs (and run tails) use the operator's row product.

use rayon::prelude::*;

use super::VectorOperator;

/// Rows evaluated together inside a run.
const CHUNK: usize = 8;
/// Rows per parallel task; runs are split at its multiples so tasks own disjoint outputs.
const BLOCK: usize = 256;

/// The runs of one operator, grouped by blocks of `BLOCK` rows.
#[derive(Debug, Clone, PartialEq)]
pub struct RowRuns {
    /// Runs as (first row, length), in row order, covering every row once.
    runs: Vec<(u32, u32)>,
    /// Block b's runs are runs[block_first[b]..block_first[b + 1]].
    block_first: Vec<usize>,
}

impl RowRuns {
    pub fn new<const D: usize>(op: &VectorOperator<D>) -> Self {
        let shifted = |r: usize| {
            let (a, b) = (
                op.offsets[r]..op.offsets[r + 1],
                op.offsets[r + 1]..op.offsets[r + 2],
            );
            op.rows[r + 1] == op.rows[r] + 1
                && op.stencil_of[r + 1] == op.stencil_of[r]
                && a.len() == b.len()
                && op.columns[a]
                    .iter()
                    .zip(&op.columns[b])
                    .all(|(&j, &k)| k == j + 1)
        };
        let n = op.rows.len();
        let mut runs = Vec::new();
        let mut block_first = Vec::with_capacity(n / BLOCK + 2);
        let mut r = 0;
        while r < n {
            if r % BLOCK == 0 {
                block_first.push(runs.len());
            }
            let block_end = (r / BLOCK + 1) * BLOCK;
            let mut end = r + 1;
            while end < n.min(block_end) && shifted(end - 1) {
                end += 1;
            }
            runs.push((r as u32, (end - r) as u32));
            r = end;
        }
        block_first.push(runs.len());
        RowRuns { runs, block_first }
    }

    /// Fraction of rows that lie in full chunks of a run (the fast path).
    pub fn chunked_fraction(&self) -> f64 {
        let rows: usize = self.runs.iter().map(|&(_, len)| len as usize).sum();
        let fast: usize = self
            .runs
            .iter()
            .map(|&(_, len)| len as usize / CHUNK * CHUNK)
            .sum();
        fast as f64 / rows.max(1) as f64
    }

    /// out[r] = Σ_j K_rj u_j for every row r with `wanted(r)` (other entries are left alone or
    /// overwritten), u given by components (`u[l][j]`). Parallel over blocks, no allocation;
    /// deterministic (each row's sum has a fixed order).
    pub fn apply<const D: usize>(
        &self,
        op: &VectorOperator<D>,
        u: [&[f64]; D],
        wanted: impl Fn(usize) -> bool + Sync,
        out: &mut [[f64; D]],
    ) {
        #[cfg(target_arch = "x86_64")]
        let avx2 = std::arch::is_x86_feature_detected!("avx2");
        out.par_chunks_mut(BLOCK)
            .enumerate()
            .for_each(|(block, out)| {
                let runs = &self.runs[self.block_first[block]..self.block_first[block + 1]];
                let base = block * BLOCK;
                #[cfg(target_arch = "x86_64")]
                if avx2 {
                    // SAFETY: the CPU supports AVX2 (detected above).
                    unsafe { block_avx2(op, runs, base, u, &wanted, out) };
                    return;
                }
                block_portable(op, runs, base, u, &wanted, out);
            });
    }
}

/// `block_portable` compiled for AVX2 (4-wide lanes). No FMA is enabled, so the results are
/// bit-identical to the portable code.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx,avx2")]
fn block_avx2<const D: usize>(
    op: &VectorOperator<D>,
    runs: &[(u32, u32)],
    base: usize,
    u: [&[f64]; D],
    wanted: &impl Fn(usize) -> bool,
    out: &mut [[f64; D]],
) {
    block_portable(op, runs, base, u, wanted, out)
}

#[inline(always)]
fn block_portable<const D: usize>(
    op: &VectorOperator<D>,
    runs: &[(u32, u32)],
    base: usize,
    u: [&[f64]; D],
    wanted: &impl Fn(usize) -> bool,
    out: &mut [[f64; D]],
) {
    let component = |j: usize| -> [f64; D] { std::array::from_fn(|l| u[l][j]) };
    for &(first, len) in runs {
        let (first, len) = (first as usize, len as usize);
        let mut r = first;
        while r + CHUNK <= first + len {
            if (r..r + CHUNK).any(wanted) {
                let chunk: &mut [[f64; D]; CHUNK] = (&mut out[r - base..r - base + CHUNK])
                    .try_into()
                    .expect("a chunk of CHUNK rows");
                chunk_product(op, r, u, chunk);
            }
            r += CHUNK;
        }
        for r in r..first + len {
            if wanted(r) {
                out[r - base] = op.apply_row_with(r, component);
            }
        }
    }
}

/// Rows r … r + CHUNK − 1 of a run: out[t] = Σ_e K_e u(c_e + t), c_e the columns of row r.
#[inline(always)]
fn chunk_product<const D: usize>(
    op: &VectorOperator<D>,
    r: usize,
    u: [&[f64]; D],
    out: &mut [[f64; D]; CHUNK],
) {
    let columns = &op.columns[op.offsets[r]..op.offsets[r + 1]];
    let first = op.stencil_offsets[op.stencil_of[r] as usize];
    let blocks = &op.blocks[first..first + columns.len()];
    let mut acc = [[0.0; CHUNK]; D];
    for (&c, block) in columns.iter().zip(blocks) {
        let c = c as usize;
        for l in 0..D {
            let lane = &u[l][c..c + CHUNK];
            for k in 0..D {
                let w = block[k][l];
                for t in 0..CHUNK {
                    acc[k][t] += w * lane[t];
                }
            }
        }
    }
    for (t, o) in out.iter_mut().enumerate() {
        *o = std::array::from_fn(|k| acc[k][t]);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::family::Families;
    use crate::grid::Lattice;
    use crate::scene::Solid;
    use crate::scheme::wls;

    #[test]
    fn runs_give_the_row_products() {
        // A 2D lattice whose WLS rows mix interior runs, boundary rows and a gap.
        let solid = Solid::Box {
            min: vec![0.0, 0.0],
            max: vec![40.0, 11.0],
        };
        let lattice = Lattice::<2>::build(&solid, 1.0, [0.0, 0.0], 1);
        let horizon = 3.0;
        let families = Families::build(&lattice.positions, horizon * (1.0 + 1e-9));
        let rows: Vec<u32> = (0..lattice.positions.len() as u32)
            .filter(|&i| i % 97 != 5)
            .collect();
        let basis = wls::Basis::new(2, 2);
        let l = wls::bond_l(&basis, 1.0, horizon, Default::default());
        let op =
            wls::elasticity_operator(&rows, &lattice.positions, &families, &basis, &l, horizon, 3)
                .unwrap();
        let runs = RowRuns::new(&op);
        assert!(runs.chunked_fraction() > 0.3, "{}", runs.chunked_fraction());
        let n = lattice.positions.len();
        let u: Vec<[f64; 2]> = (0..n)
            .map(|i| [(i as f64 * 0.37).sin(), (i as f64 * 0.11).cos()])
            .collect();
        let components: [Vec<f64>; 2] = std::array::from_fn(|l| u.iter().map(|v| v[l]).collect());
        let mut fast = vec![[f64::NAN; 2]; rows.len()];
        runs.apply(&op, [&components[0], &components[1]], |_| true, &mut fast);
        let mut reference = vec![[0.0; 2]; rows.len()];
        op.apply_rows(&u, &mut reference);
        let scale = reference
            .iter()
            .flatten()
            .fold(0.0f64, |m, x| m.max(x.abs()));
        for (a, b) in fast.iter().zip(&reference) {
            for k in 0..2 {
                assert!((a[k] - b[k]).abs() <= 1e-12 * scale, "{a:?} vs {b:?}");
            }
        }
    }
}
