//! Spatial discretizations as operators.

use rayon::prelude::*;

pub mod dual_horizon;
pub mod nnpp;
pub mod runs;
pub mod standard;
pub mod wls;
pub mod wls_rows;

/// A per-node flag of the standard bond loop: rows whose entry is `skipped` are left to
/// another scheme (the hybrid's Ω_w).
pub trait RowMask: Copy + Send + Sync {
    fn skipped(self) -> bool;
}

/// 0: evaluate the row; anything else: skip it.
impl RowMask for u8 {
    #[inline(always)]
    fn skipped(self) -> bool {
        self != 0
    }
}

/// Rows one rayon task takes at least: a small operator (a 1D line of a few hundred nodes)
/// runs on one thread instead of paying the pool's wake-up every step (measured on the
/// 481-node S1 line: 48 µs per step split, most of it in the pool).
pub const MIN_ROWS_PER_TASK: usize = 2048;

/// A linear operator on a scalar node field, stored as sparse rows: for each node of `rows`,
/// out_i = Σ_j w_ij values_j over its `columns`. Both schemes assemble their diffusion
/// operators into this form, so integrators and stability estimates serve either.
#[derive(Debug, Clone, PartialEq)]
pub struct ScalarOperator {
    pub rows: Vec<u32>,
    pub offsets: Vec<usize>,
    pub columns: Vec<u32>,
    pub weights: Vec<f64>,
}

impl ScalarOperator {
    /// From per-row (columns, weights) blocks, in the order of `rows`.
    pub fn from_rows(rows: &[u32], blocks: Vec<Row<f64>>) -> Self {
        let mut offsets = Vec::with_capacity(rows.len() + 1);
        offsets.push(0);
        let (mut columns, mut weights) = (Vec::new(), Vec::new());
        for (set, w) in blocks {
            columns.extend(set);
            weights.extend(w);
            offsets.push(columns.len());
        }
        ScalarOperator {
            rows: rows.to_vec(),
            offsets,
            columns,
            weights,
        }
    }

    /// `a`'s rows then `b`'s (over one node index space).
    pub fn concat(a: ScalarOperator, b: ScalarOperator) -> ScalarOperator {
        let base = a.columns.len();
        let mut out = a;
        out.rows.extend(b.rows);
        out.offsets.extend(b.offsets[1..].iter().map(|o| o + base));
        out.columns.extend(b.columns);
        out.weights.extend(b.weights);
        out
    }

    /// out[r] = Σ_j w_rj values[j], one entry per row, in parallel.
    pub fn apply_rows(&self, values: &[f64], out: &mut [f64]) {
        out.par_iter_mut()
            .with_min_len(MIN_ROWS_PER_TASK)
            .enumerate()
            .for_each(|(r, o)| {
                let range = self.offsets[r]..self.offsets[r + 1];
                *o = self.columns[range.clone()]
                    .iter()
                    .zip(&self.weights[range])
                    .map(|(&j, w)| w * values[j as usize])
                    .sum();
            });
    }

    /// max_r Σ_j |w_rj|: every eigenvalue lies in a Gershgorin disc of at most this radius.
    pub fn max_absolute_row_sum(&self) -> f64 {
        (0..self.rows.len())
            .into_par_iter()
            .map(|r| {
                self.weights[self.offsets[r]..self.offsets[r + 1]]
                    .iter()
                    .map(|w| w.abs())
                    .sum::<f64>()
            })
            .reduce(|| 0.0, f64::max)
    }

    /// out[r] = Σ_{j ≠ i} κ(i, j) w_rj (values[j] − values[i]) for row r of node i: the bond
    /// sum of a diffusion operator assembled with κ = 1 (its first entry per row is the node
    /// itself, (3.4)) whose bonds carry their own diffusivity (corrosion's bond classes).
    pub fn apply_rows_bond_weighted(
        &self,
        values: &[f64],
        out: &mut [f64],
        kappa: impl Fn(usize, usize) -> f64 + Sync,
    ) {
        out.par_iter_mut()
            .with_min_len(MIN_ROWS_PER_TASK)
            .enumerate()
            .for_each(|(r, o)| {
                let i = self.rows[r] as usize;
                let c_i = values[i];
                let range = self.offsets[r] + 1..self.offsets[r + 1];
                *o = self.columns[range.clone()]
                    .iter()
                    .zip(&self.weights[range])
                    .map(|(&j, w)| {
                        let j = j as usize;
                        kappa(i, j) * w * (values[j] - c_i)
                    })
                    .sum();
            });
    }

    /// out[rows[r]] = Σ_j w_rj values[j] for every row; other entries are left alone.
    /// Allocates the row values (meant for setup work such as power iterations).
    pub fn apply(&self, values: &[f64], out: &mut [f64]) {
        let mut rows = vec![0.0; self.rows.len()];
        self.apply_rows(values, &mut rows);
        for (&i, v) in self.rows.iter().zip(rows) {
            out[i as usize] = v;
        }
    }
}

/// One row of a sparse operator: its columns and their weights (scalars or blocks).
pub type Row<T> = (Vec<u32>, Vec<T>);

/// A linear operator on a vector node field (D components per node), as sparse rows of D × D
/// blocks: out_i = Σ_j K_ij values_j. The WLS elasticity operator K_ij = L̄ Q̄_i
/// (seed-thesis-ch2-3 §3.5). Rows whose collocation geometry is the same (a uniform lattice away
/// from its boundaries) share one block set ("stencil"), so a row costs 4 bytes per entry to
/// stream, not 36.
#[derive(Debug, Clone, PartialEq)]
pub struct VectorOperator<const D: usize> {
    pub rows: Vec<u32>,
    pub offsets: Vec<usize>,
    pub columns: Vec<u32>,
    /// Per row, the index of its stencil.
    pub stencil_of: Vec<u32>,
    /// Stencil s's blocks are blocks[stencil_offsets[s]..stencil_offsets[s + 1]], in the order
    /// of the row's columns; blocks[e][k][l]: force component k from displacement component l.
    pub stencil_offsets: Vec<usize>,
    pub blocks: Vec<[[f64; D]; D]>,
}

impl<const D: usize> VectorOperator<D> {
    /// From per-row columns and a stencil index, and the stencils' blocks.
    pub fn new(
        rows: &[u32],
        columns_per_row: Vec<(Vec<u32>, u32)>,
        stencils: Vec<Vec<[[f64; D]; D]>>,
    ) -> Self {
        let mut offsets = Vec::with_capacity(rows.len() + 1);
        offsets.push(0);
        let mut columns = Vec::new();
        let mut stencil_of = Vec::with_capacity(rows.len());
        for (set, s) in columns_per_row {
            columns.extend(set);
            stencil_of.push(s);
            offsets.push(columns.len());
        }
        let mut stencil_offsets = vec![0];
        let mut blocks = Vec::new();
        for b in stencils {
            blocks.extend(b);
            stencil_offsets.push(blocks.len());
        }
        VectorOperator {
            rows: rows.to_vec(),
            offsets,
            columns,
            stencil_of,
            stencil_offsets,
            blocks,
        }
    }

    /// Number of distinct stencils (block sets).
    /// Row r's blocks, in the order of its columns.
    #[inline]
    pub fn row_blocks(&self, r: usize) -> &[[[f64; D]; D]] {
        let first = self.stencil_offsets[self.stencil_of[r] as usize];
        &self.blocks[first..first + (self.offsets[r + 1] - self.offsets[r])]
    }

    /// max_r Σ_j Σ_kl |K_rj[k][l]|: a Gershgorin bound on the spectral radius.
    pub fn max_absolute_row_sum(&self) -> f64 {
        (0..self.rows.len())
            .into_par_iter()
            .map(|r| {
                self.row_blocks(r)
                    .iter()
                    .flatten()
                    .flatten()
                    .map(|w| w.abs())
                    .sum::<f64>()
            })
            .reduce(|| 0.0, f64::max)
    }

    pub fn stencil_count(&self) -> usize {
        self.stencil_offsets.len() - 1
    }

    /// Σ_j K_rj values[j] for row r.
    #[inline]
    pub fn apply_row(&self, r: usize, values: &[[f64; D]]) -> [f64; D] {
        self.apply_row_with(r, |j| values[j])
    }

    /// Σ_j K_rj value(j) for row r. Four partial sums break the chain of dependent additions
    /// (a row is latency-bound otherwise); they are added in a fixed order, so the result is
    /// deterministic.
    #[inline(always)]
    pub fn apply_row_with(&self, r: usize, value: impl Fn(usize) -> [f64; D]) -> [f64; D] {
        const PARTIALS: usize = 4;
        let mut acc = [[0.0; D]; PARTIALS];
        let columns = &self.columns[self.offsets[r]..self.offsets[r + 1]];
        let blocks = self.row_blocks(r);
        let add = |acc: &mut [f64; D], j: u32, block: &[[f64; D]; D]| {
            let u = value(j as usize);
            for k in 0..D {
                for l in 0..D {
                    acc[k] += block[k][l] * u[l];
                }
            }
        };
        let column_chunks = columns.chunks_exact(PARTIALS);
        let block_chunks = blocks.chunks_exact(PARTIALS);
        for (&j, block) in column_chunks
            .remainder()
            .iter()
            .zip(block_chunks.remainder())
        {
            add(&mut acc[0], j, block);
        }
        for (cs, bs) in column_chunks.zip(block_chunks) {
            for p in 0..PARTIALS {
                add(&mut acc[p], cs[p], &bs[p]);
            }
        }
        std::array::from_fn(|k| (acc[0][k] + acc[1][k]) + (acc[2][k] + acc[3][k]))
    }

    /// out[r] = Σ_j K_rj values[j], one entry per row, in parallel; no allocation.
    pub fn apply_rows(&self, values: &[[f64; D]], out: &mut [[f64; D]]) {
        out.par_iter_mut()
            .enumerate()
            .for_each(|(r, o)| *o = self.apply_row(r, values));
    }
}
