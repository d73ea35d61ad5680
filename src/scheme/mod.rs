//! Spatial discretizations as operators.

use rayon::prelude::*;

pub mod standard;
pub mod wls;

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
    pub fn from_rows(rows: &[u32], blocks: Vec<(Vec<u32>, Vec<f64>)>) -> Self {
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

    /// out[r] = Σ_j w_rj values[j], one entry per row, in parallel.
    pub fn apply_rows(&self, values: &[f64], out: &mut [f64]) {
        out.par_iter_mut().enumerate().for_each(|(r, o)| {
            let range = self.offsets[r]..self.offsets[r + 1];
            *o = self.columns[range.clone()]
                .iter()
                .zip(&self.weights[range])
                .map(|(&j, w)| w * values[j as usize])
                .sum();
        });
    }

    /// out[rows[r]] = Σ_j w_rj values[j] for every row; other entries are left alone.
    pub fn apply(&self, values: &[f64], out: &mut [f64]) {
        for (r, &i) in self.rows.iter().enumerate() {
            let range = self.offsets[r]..self.offsets[r + 1];
            out[i as usize] = self.columns[range.clone()]
                .iter()
                .zip(&self.weights[range])
                .map(|(&j, w)| w * values[j as usize])
                .sum();
        }
    }
}
