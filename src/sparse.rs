//! Sparse linear systems with a fixed pattern (the NNPP species and Poisson systems of
//! seed-thesis-ch2-3 §2.3): rows in CSR, refilled each step, factored by faer's sparse LU with
//! partial pivoting. The symbolic analysis is done once per pattern and reused; every solve
//! reports its relative residual ‖A x − b‖ / ‖b‖.

use faer::linalg::solvers::Solve;
use faer::sparse::linalg::solvers::{Lu, SymbolicLu};
use faer::sparse::{SparseColMatRef, SymbolicSparseColMatRef};
use rayon::prelude::*;

/// A square sparse matrix in CSR with sorted columns per row; the pattern is fixed, the
/// values are rewritten in place.
#[derive(Debug, Clone)]
pub struct SparseMatrix {
    pub offsets: Vec<usize>,
    pub columns: Vec<usize>,
    pub values: Vec<f64>,
}

impl SparseMatrix {
    /// The pattern of `rows` (each row's columns, any order, no duplicates), values zero.
    pub fn with_pattern(rows: Vec<Vec<usize>>) -> SparseMatrix {
        let mut offsets = Vec::with_capacity(rows.len() + 1);
        offsets.push(0);
        let mut columns = Vec::with_capacity(rows.iter().map(Vec::len).sum());
        for mut row in rows {
            row.sort_unstable();
            columns.extend_from_slice(&row);
            offsets.push(columns.len());
        }
        let values = vec![0.0; columns.len()];
        SparseMatrix {
            offsets,
            columns,
            values,
        }
    }

    pub fn len(&self) -> usize {
        self.offsets.len() - 1
    }

    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// The entry index of (row, column) in `values`, if the pattern has it.
    pub fn entry(&self, row: usize, column: usize) -> Option<usize> {
        let range = self.offsets[row]..self.offsets[row + 1];
        self.columns[range.clone()]
            .binary_search(&column)
            .ok()
            .map(|k| range.start + k)
    }

    /// out = A x.
    pub fn apply(&self, x: &[f64], out: &mut [f64]) {
        out.par_iter_mut().enumerate().for_each(|(i, o)| {
            let range = self.offsets[i]..self.offsets[i + 1];
            *o = self.columns[range.clone()]
                .iter()
                .zip(&self.values[range])
                .map(|(&j, &a)| a * x[j])
                .sum();
        });
    }

    /// ‖A x − b‖₂ / ‖b‖₂ (the absolute norm when b = 0).
    pub fn relative_residual(&self, x: &[f64], b: &[f64]) -> f64 {
        let mut ax = vec![0.0; b.len()];
        self.apply(x, &mut ax);
        let r: f64 = ax.iter().zip(b).map(|(a, b)| (a - b) * (a - b)).sum();
        let n: f64 = b.iter().map(|b| b * b).sum();
        if n > 0.0 { (r / n).sqrt() } else { r.sqrt() }
    }

    /// faer's view of the pattern: CSR of A read as CSC, i.e. Aᵀ.
    /// (`with_pattern` gives sorted, in-range columns, which `new_checked` requires.)
    fn transpose_symbolic(&self) -> SymbolicSparseColMatRef<'_, usize> {
        let n = self.len();
        SymbolicSparseColMatRef::new_checked(n, n, &self.offsets, None, &self.columns)
    }
}

/// Why a sparse solve failed.
#[derive(Debug, Clone, PartialEq)]
pub enum SparseError {
    /// The factorization broke down (a structurally or numerically singular matrix).
    Singular(String),
}

impl std::fmt::Display for SparseError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            SparseError::Singular(why) => write!(
                f,
                "the sparse LU failed ({why}): every unknown needs a path to a held value or \
                 a nonzero diagonal"
            ),
        }
    }
}

/// A direct solver for one pattern: the symbolic LU computed on first use and kept while the
/// pattern stays the same.
#[derive(Default)]
pub struct DirectSolver {
    symbolic: Option<(usize, usize, SymbolicLu<usize>)>,
}

impl DirectSolver {
    /// Solves A x = b in place of `rhs` (b on entry, x on return); returns the relative
    /// residual of the solution.
    pub fn solve(&mut self, a: &SparseMatrix, rhs: &mut [f64]) -> Result<f64, SparseError> {
        if a.is_empty() {
            return Ok(0.0);
        }
        let b = rhs.to_vec();
        let symbolic_ref = a.transpose_symbolic();
        let key = (a.len(), a.columns.len());
        if self.symbolic.as_ref().map(|(n, nnz, _)| (*n, *nnz)) != Some(key) {
            let symbolic = SymbolicLu::try_new(symbolic_ref)
                .map_err(|e| SparseError::Singular(format!("{e:?}")))?;
            self.symbolic = Some((key.0, key.1, symbolic));
        }
        let Some((_, _, symbolic)) = &self.symbolic else {
            unreachable!("set above")
        };
        let transpose = SparseColMatRef::new(symbolic_ref, &a.values);
        let lu = Lu::try_new_with_symbolic(symbolic.clone(), transpose)
            .map_err(|e| SparseError::Singular(format!("{e:?}")))?;
        lu.solve_transpose_in_place(faer::ColMut::from_slice_mut(rhs));
        if rhs.iter().any(|x| !x.is_finite()) {
            return Err(SparseError::Singular("a non-finite solution".into()));
        }
        Ok(a.relative_residual(rhs, &b))
    }

    /// Forgets the symbolic analysis (the pattern changed).
    pub fn reset(&mut self) {
        self.symbolic = None;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A non-symmetric tridiagonal system with a known solution.
    #[test]
    fn solves_a_nonsymmetric_system_to_round_off() {
        let n = 200;
        let rows: Vec<Vec<usize>> = (0..n)
            .map(|i| {
                let mut r = vec![i];
                if i > 0 {
                    r.push(i - 1);
                }
                if i + 1 < n {
                    r.push(i + 1);
                }
                r
            })
            .collect();
        let mut a = SparseMatrix::with_pattern(rows);
        for i in 0..n {
            {
                let e = a.entry(i, i).unwrap();
                a.values[e] = 4.0;
            }
            if i > 0 {
                {
                    let e = a.entry(i, i - 1).unwrap();
                    a.values[e] = -1.5;
                }
            }
            if i + 1 < n {
                {
                    let e = a.entry(i, i + 1).unwrap();
                    a.values[e] = -0.5;
                }
            }
        }
        let exact: Vec<f64> = (0..n).map(|i| (i as f64 * 0.1).sin()).collect();
        let mut b = vec![0.0; n];
        a.apply(&exact, &mut b);
        let mut solver = DirectSolver::default();
        let residual = solver.solve(&a, &mut b).unwrap();
        assert!(residual < 1e-14, "{residual:e}");
        let err = b
            .iter()
            .zip(&exact)
            .map(|(x, e)| (x - e).abs())
            .fold(0.0, f64::max);
        assert!(err < 1e-13, "{err:e}");
    }
}
