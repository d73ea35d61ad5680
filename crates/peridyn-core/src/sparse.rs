//! Sparse linear systems with a fixed pattern (the NNPP species and Poisson systems of
//! seed-thesis-ch2-3 §2.3): rows in CSR, refilled each step, solved either by faer's sparse LU
//! with partial pivoting (the symbolic analysis done once per pattern and reused) or, for 3D
//! systems whose LU fill does not fit, by faer's BiCGSTAB with a Jacobi (diagonal)
//! preconditioner on both sides. A system may carry a rank-one term u vᵀ (the conservative
//! multi-grid balance): the LU solves it by Sherman–Morrison, BiCGSTAB applies it in its
//! products. Every solve reports its relative residual ‖(A + u vᵀ) x − b‖ / ‖b‖, computed
//! here, not taken from the solver.

use faer::dyn_stack::{MemBuffer, MemStack, StackReq};
use faer::linalg::solvers::Solve;
use faer::matrix_free::bicgstab::{BicgParams, bicgstab, bicgstab_scratch};
use faer::matrix_free::{InitialGuessStatus, LinOp};
use faer::reborrow::ReborrowMut;
use faer::sparse::linalg::solvers::{Lu, SymbolicLu};
use faer::sparse::{SparseColMatRef, SymbolicSparseColMatRef};
use faer::{MatMut, MatRef, Par};
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
        self.relative_residual_with(None, x, b)
    }

    /// out = (A + u vᵀ) x.
    pub fn apply_with(&self, update: Option<&RankOne>, x: &[f64], out: &mut [f64]) {
        self.apply(x, out);
        if let Some(r) = update {
            r.add_to(x, out);
        }
    }

    /// ‖(A + u vᵀ) x − b‖₂ / ‖b‖₂ (the absolute norm when b = 0).
    pub fn relative_residual_with(&self, update: Option<&RankOne>, x: &[f64], b: &[f64]) -> f64 {
        let mut ax = vec![0.0; b.len()];
        self.apply_with(update, x, &mut ax);
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

/// A rank-one term u vᵀ, both vectors sparse as (index, value) pairs.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct RankOne {
    pub u: Vec<(usize, f64)>,
    pub v: Vec<(usize, f64)>,
}

impl RankOne {
    /// vᵀ x.
    pub fn dot(&self, x: &[f64]) -> f64 {
        self.v.iter().map(|&(i, v)| v * x[i]).sum()
    }

    /// out += u (vᵀ x).
    pub fn add_to(&self, x: &[f64], out: &mut [f64]) {
        let s = self.dot(x);
        for &(i, u) in &self.u {
            out[i] += u * s;
        }
    }
}

/// Why a sparse solve failed.
#[derive(Debug, Clone, PartialEq)]
pub enum SparseError {
    /// The factorization broke down (a structurally or numerically singular matrix).
    Singular(String),
    /// The iteration stopped above its tolerance.
    NoConvergence { iterations: usize, residual: f64 },
}

impl std::fmt::Display for SparseError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            SparseError::Singular(why) => write!(
                f,
                "the sparse LU failed ({why}): every unknown needs a path to a held value or \
                 a nonzero diagonal"
            ),
            SparseError::NoConvergence {
                iterations,
                residual,
            } => write!(
                f,
                "BiCGSTAB stopped at relative residual {residual:e} after {iterations} \
                 iterations: raise `nernst_planck.linear_iterations` or use \
                 `linear_solver = \"direct\"`"
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
    /// Solves (A + u vᵀ) x = b in place of `rhs` (b on entry, x on return); returns the
    /// relative residual of the solution. With u vᵀ: x = A⁻¹b − A⁻¹u vᵀA⁻¹b / (1 + vᵀA⁻¹u)
    /// (Sherman–Morrison, one factorization, two solves).
    pub fn solve(
        &mut self,
        a: &SparseMatrix,
        update: Option<&RankOne>,
        rhs: &mut [f64],
    ) -> Result<f64, SparseError> {
        if a.is_empty() {
            return Ok(0.0);
        }
        let b = rhs.to_vec();
        let lu = self.factor(a)?;
        lu.solve_transpose_in_place(faer::ColMut::from_slice_mut(rhs));
        if let Some(r) = update {
            let mut y = vec![0.0; rhs.len()];
            for &(i, u) in &r.u {
                y[i] += u;
            }
            lu.solve_transpose_in_place(faer::ColMut::from_slice_mut(&mut y));
            let denominator = 1.0 + r.dot(&y);
            if denominator.abs() < 1e-14 {
                return Err(SparseError::Singular(
                    "the rank-one update makes the system singular".into(),
                ));
            }
            let factor = r.dot(rhs) / denominator;
            for (x, y) in rhs.iter_mut().zip(&y) {
                *x -= factor * y;
            }
        }
        if rhs.iter().any(|x| !x.is_finite()) {
            return Err(SparseError::Singular("a non-finite solution".into()));
        }
        Ok(a.relative_residual_with(update, rhs, &b))
    }

    /// The LU of A (Aᵀ's, read from the CSR), the symbolic part reused.
    fn factor(&mut self, a: &SparseMatrix) -> Result<Lu<usize, f64>, SparseError> {
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
        Lu::try_new_with_symbolic(symbolic.clone(), transpose)
            .map_err(|e| SparseError::Singular(format!("{e:?}")))
    }

    /// Forgets the symbolic analysis (the pattern changed).
    pub fn reset(&mut self) {
        self.symbolic = None;
    }
}

/// A's rows (plus u vᵀ) as faer's matrix-free operator (the product by
/// `SparseMatrix::apply_with`).
#[derive(Debug)]
struct Rows<'a>(&'a SparseMatrix, Option<&'a RankOne>);

impl LinOp<f64> for Rows<'_> {
    fn apply_scratch(&self, _rhs_ncols: usize, _par: Par) -> StackReq {
        StackReq::EMPTY
    }
    fn nrows(&self) -> usize {
        self.0.len()
    }
    fn ncols(&self) -> usize {
        self.0.len()
    }
    fn apply(&self, mut out: MatMut<'_, f64>, rhs: MatRef<'_, f64>, _par: Par, _: &mut MemStack) {
        // One right side, in contiguous columns (faer's temporaries are column-major).
        let x = rhs.col(0).try_as_col_major().expect("a contiguous column");
        let y = out.rb_mut().col_mut(0);
        let y = y.try_as_col_major_mut().expect("a contiguous column");
        self.0.apply_with(self.1, x.as_slice(), y.as_slice_mut());
    }
    fn conj_apply(&self, out: MatMut<'_, f64>, rhs: MatRef<'_, f64>, par: Par, s: &mut MemStack) {
        self.apply(out, rhs, par, s);
    }
}

/// How a system is solved.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum LinearMethod {
    /// Sparse LU (exact up to round-off; the fill grows fast in 3D).
    Direct,
    /// Jacobi-preconditioned BiCGSTAB to a relative residual.
    Iterative {
        tolerance: f64,
        max_iterations: usize,
    },
}

/// A solver for one pattern by the chosen method; the LU's symbolic analysis is kept.
pub struct LinearSolver {
    pub method: LinearMethod,
    direct: DirectSolver,
    /// Iterations of the last iterative solve.
    pub iterations: usize,
}

impl LinearSolver {
    pub fn new(method: LinearMethod) -> LinearSolver {
        LinearSolver {
            method,
            direct: DirectSolver::default(),
            iterations: 0,
        }
    }

    /// Solves A x = b in place of `rhs`; returns the relative residual.
    pub fn solve(&mut self, a: &SparseMatrix, rhs: &mut [f64]) -> Result<f64, SparseError> {
        self.solve_with(a, None, rhs)
    }

    /// Solves (A + u vᵀ) x = b in place of `rhs`; returns the relative residual.
    pub fn solve_with(
        &mut self,
        a: &SparseMatrix,
        update: Option<&RankOne>,
        rhs: &mut [f64],
    ) -> Result<f64, SparseError> {
        match self.method {
            LinearMethod::Direct => self.direct.solve(a, update, rhs),
            LinearMethod::Iterative {
                tolerance,
                max_iterations,
            } => {
                let (residual, iterations) =
                    iterative_solve(a, update, rhs, tolerance, max_iterations)?;
                self.iterations = iterations;
                Ok(residual)
            }
        }
    }

    /// Forgets pattern-dependent state (the pattern changed).
    pub fn reset(&mut self) {
        self.direct.reset();
    }
}

/// BiCGSTAB from x = 0 with the inverse diagonal as left and right preconditioner (a zero
/// diagonal entry is left unscaled). Returns the relative residual and the iterations.
fn iterative_solve(
    a: &SparseMatrix,
    update: Option<&RankOne>,
    rhs: &mut [f64],
    tolerance: f64,
    max_iterations: usize,
) -> Result<(f64, usize), SparseError> {
    let n = a.len();
    if n == 0 {
        return Ok((0.0, 0));
    }
    // The square root of the inverse diagonal on each side: the preconditioned operator is
    // D^{-1/2} A D^{-1/2}, symmetric where A is.
    let scale = faer::Col::<f64>::from_fn(n, |i| {
        let d = a.entry(i, i).map_or(0.0, |e| a.values[e]).abs();
        if d > 0.0 { 1.0 / d.sqrt() } else { 1.0 }
    })
    .into_diagonal();
    let op = Rows(a, update);
    let b = faer::Mat::<f64>::from_fn(n, 1, |i, _| rhs[i]);
    let mut x = faer::Mat::<f64>::zeros(n, 1);
    let params = BicgParams {
        // x starts at 0, but `Zero` leaves bicgstab's residual r uninitialized in faer 0.23.2
        // (its r = b − A x is only formed for `MaybeNonZero`): one extra product instead.
        initial_guess: InitialGuessStatus::MaybeNonZero,
        rel_tolerance: tolerance,
        max_iters: max_iterations,
        ..Default::default()
    };
    let par = Par::rayon(0);
    let mut buffer = MemBuffer::new(bicgstab_scratch(&scale, &scale, &op, 1, par));
    let outcome = bicgstab(
        x.as_mut(),
        &scale,
        &scale,
        &op,
        b.as_ref(),
        params,
        |_| {},
        par,
        MemStack::new(&mut buffer),
    );
    let original = rhs.to_vec();
    for (i, r) in rhs.iter_mut().enumerate() {
        *r = x[(i, 0)];
    }
    if rhs.iter().any(|v| !v.is_finite()) {
        return Err(SparseError::Singular("BiCGSTAB broke down".into()));
    }
    let residual = a.relative_residual_with(update, rhs, &original);
    match outcome {
        Ok(info) => Ok((residual, info.iter_count)),
        Err(_) if residual <= tolerance => Ok((residual, max_iterations)),
        Err(_) => Err(SparseError::NoConvergence {
            iterations: max_iterations,
            residual,
        }),
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
        let residual = solver.solve(&a, None, &mut b).unwrap();
        assert!(residual < 1e-14, "{residual:e}");
        let err = b
            .iter()
            .zip(&exact)
            .map(|(x, e)| (x - e).abs())
            .fold(0.0, f64::max);
        assert!(err < 1e-13, "{err:e}");
    }

    /// The tridiagonal pattern of order n, values zero.
    fn tridiagonal(n: usize) -> SparseMatrix {
        SparseMatrix::with_pattern(
            (0..n)
                .map(|i| {
                    [i.wrapping_sub(1), i, i + 1]
                        .into_iter()
                        .filter(|&j| j < n)
                        .collect()
                })
                .collect(),
        )
    }

    /// BiCGSTAB meets its tolerance on the same system and agrees with the LU.
    #[test]
    fn bicgstab_reaches_its_tolerance() {
        let n: usize = 300;
        let mut a = tridiagonal(n);
        for i in 0..n {
            for (j, v) in [
                (i.wrapping_sub(1), -1.2),
                (i, 2.5 + 0.01 * i as f64),
                (i + 1, -0.8),
            ] {
                if let Some(e) = a.entry(i, j) {
                    a.values[e] = v;
                }
            }
        }
        let exact: Vec<f64> = (0..n).map(|i| (i as f64 * 0.05).cos()).collect();
        let mut b = vec![0.0; n];
        a.apply(&exact, &mut b);
        let mut direct = b.clone();
        LinearSolver::new(LinearMethod::Direct)
            .solve(&a, &mut direct)
            .unwrap();
        let mut solver = LinearSolver::new(LinearMethod::Iterative {
            tolerance: 1e-12,
            max_iterations: 1000,
        });
        let residual = solver.solve(&a, &mut b).unwrap();
        assert!(residual < 1e-12, "{residual:e}");
        assert!(solver.iterations > 0);
        let err = b
            .iter()
            .zip(&direct)
            .map(|(x, e)| (x - e).abs())
            .fold(0.0, f64::max);
        assert!(err < 1e-10, "{err:e}");
        // Too few iterations is an error that says so.
        let mut b2 = vec![1.0; n];
        let e = LinearSolver::new(LinearMethod::Iterative {
            tolerance: 1e-14,
            max_iterations: 2,
        })
        .solve(&a, &mut b2)
        .unwrap_err();
        assert!(e.to_string().contains("BiCGSTAB"), "{e}");
    }

    /// A tridiagonal A plus a rank-one u vᵀ coupling far rows (a dense term in the
    /// product): the LU (Sherman–Morrison) and BiCGSTAB both recover a known x, the right side
    /// formed entry by entry here.
    #[test]
    fn a_rank_one_update_is_solved_by_both_methods() {
        let n: usize = 120;
        let mut a = tridiagonal(n);
        let coefficient = |i: usize, j: usize| -> f64 {
            if i == j {
                3.0
            } else if j + 1 == i {
                -1.0
            } else {
                -0.7
            }
        };
        for i in 0..n {
            for e in a.offsets[i]..a.offsets[i + 1] {
                a.values[e] = coefficient(i, a.columns[e]);
            }
        }
        let update = RankOne {
            u: vec![(3, 0.5), (60, -0.25), (110, 1.0)],
            v: vec![(0, 0.4), (59, 0.3), (119, -0.6)],
        };
        let exact: Vec<f64> = (0..n).map(|i| 1.0 + (i as f64 * 0.07).sin()).collect();
        let vx = 0.4 * exact[0] + 0.3 * exact[59] - 0.6 * exact[119];
        let b: Vec<f64> = (0..n)
            .map(|i| {
                let tri: f64 = (i.saturating_sub(1)..(i + 2).min(n))
                    .map(|j| coefficient(i, j) * exact[j])
                    .sum();
                let u = update.u.iter().find(|p| p.0 == i).map_or(0.0, |p| p.1);
                tri + u * vx
            })
            .collect();
        for method in [
            LinearMethod::Direct,
            LinearMethod::Iterative {
                tolerance: 1e-13,
                max_iterations: 500,
            },
        ] {
            let mut x = b.clone();
            let residual = LinearSolver::new(method)
                .solve_with(&a, Some(&update), &mut x)
                .unwrap();
            assert!(residual < 1e-12, "{method:?}: {residual:e}");
            let err = x
                .iter()
                .zip(&exact)
                .map(|(x, e)| (x - e).abs())
                .fold(0.0, f64::max);
            assert!(err < 1e-11, "{method:?}: {err:e}");
        }
    }
}
