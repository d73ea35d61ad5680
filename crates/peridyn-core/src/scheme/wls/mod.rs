//! Meshfree WLS collocation scheme (thesis §3.2; seed-thesis-ch2-3 §3, seed-004 §2): a local
//! polynomial fit over a few collocation nodes, with the PD integral over the full ball done
//! analytically (the L operators of seed-thesis-ch2-3 §3.5).
//!
//! Errata followed: (3.28) uses p(x_j − x_i) in A (seed-thesis-ch2-3 erratum 1); the weight (3.26)
//! is evaluated in its stable form; the fit is solved in coordinates scaled by δ, with L scaled to
//! match.

use nalgebra::{DMatrix, DVector};

pub use crate::scene::collocation::{Collocation, MAX_ORBITS, PAPERS_WEIGHT_EXPONENT, Targets};

mod collocation;
mod moments;

pub use collocation::*;
pub use moments::*;

use crate::discretization::family::Families;
use crate::model::pmb::Influence;
use crate::scheme::{Row, ScalarOperator, VectorOperator};

/// Monomials ξ^α of total degree ≤ `order` in `dim` dimensions, ordered by degree and, within
/// a degree, by decreasing x then y exponent: 3D C² is (1, x, y, z, x², xy, xz, y², yz, z²)
/// as in (3.23).
#[derive(Debug, Clone, PartialEq)]
pub struct Basis {
    pub dim: usize,
    pub order: usize,
    pub exponents: Vec<[u32; 3]>,
}

impl Basis {
    pub fn new(dim: usize, order: usize) -> Self {
        let mut exponents = Vec::new();
        for n in 0..=order as u32 {
            match dim {
                1 => exponents.push([n, 0, 0]),
                2 => (0..=n).rev().for_each(|a| exponents.push([a, n - a, 0])),
                _ => {
                    for a in (0..=n).rev() {
                        for b in (0..=n - a).rev() {
                            exponents.push([a, b, n - a - b]);
                        }
                    }
                }
            }
        }
        Basis {
            dim,
            order,
            exponents,
        }
    }

    pub fn len(&self) -> usize {
        self.exponents.len()
    }

    pub fn is_empty(&self) -> bool {
        self.exponents.is_empty()
    }

    /// Row p(ξ) of the monomials at ξ.
    pub fn eval(&self, xi: &[f64], out: &mut [f64]) {
        for (o, alpha) in out.iter_mut().zip(&self.exponents) {
            *o = (0..self.dim).map(|k| xi[k].powi(alpha[k] as i32)).product();
        }
    }

    pub fn degree(&self, m: usize) -> u32 {
        self.exponents[m].iter().sum()
    }
}

/// Why a node's WLS fit cannot be used.
#[derive(Debug, Clone, PartialEq)]
pub struct FitError {
    pub node: usize,
    pub message: String,
}

impl std::fmt::Display for FitError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "WLS fit at node {}: {}", self.node, self.message)
    }
}

/// Largest tolerated condition number of the equilibrated normal matrix A.
pub const MAX_CONDITION: f64 = 1e12;

/// Q_i = A_i⁻¹ B_i (3.27)–(3.31) in coordinates scaled by δ: an n_p × n_c matrix whose
/// column j maps the value at collocation node j to the scaled monomial coefficients.
pub fn fit_matrix<const D: usize>(
    node: usize,
    collocation: &[u32],
    positions: &[[f64; D]],
    basis: &Basis,
    horizon: f64,
    weight_exponent: f64,
) -> Result<DMatrix<f64>, FitError> {
    let (np, nc) = (basis.len(), collocation.len());
    if nc < np {
        return Err(FitError {
            node,
            message: format!(
                "{nc} collocation nodes for {np} basis monomials; use a finer auxiliary grid (larger k_aux) or a lower order"
            ),
        });
    }
    let xi: Vec<[f64; D]> = collocation
        .iter()
        .map(|&j| {
            std::array::from_fn(|a| (positions[j as usize][a] - positions[node][a]) / horizon)
        })
        .collect();
    let r_max = xi
        .iter()
        .map(|x| x.iter().map(|v| v * v).sum::<f64>().sqrt())
        .fold(0.0, f64::max);
    let mut weighted_rows = DMatrix::<f64>::zeros(np, nc); // columns: w̄_j p(ξ_j)ᵀ = B
    let mut row = vec![0.0; np];
    let mut a = DMatrix::<f64>::zeros(np, np);
    for (c, x) in xi.iter().enumerate() {
        basis.eval(x, &mut row);
        let w = weight_with(
            weight_exponent,
            x.iter().map(|v| v * v).sum::<f64>().sqrt(),
            r_max,
        );
        for m in 0..np {
            weighted_rows[(m, c)] = w * row[m];
            for n in 0..np {
                a[(m, n)] += w * row[m] * row[n];
            }
        }
    }
    // Conditioning of the equilibrated matrix (unit diagonal): the monomials' scales are
    // arbitrary, what matters is how independent they are on this set.
    let diag: Vec<f64> = (0..np)
        .map(|m| a[(m, m)].max(f64::MIN_POSITIVE).sqrt())
        .collect();
    let equilibrated = DMatrix::from_fn(np, np, |m, n| a[(m, n)] / (diag[m] * diag[n]));
    let eigen = equilibrated.symmetric_eigen();
    let (lo, hi) = eigen
        .eigenvalues
        .iter()
        .fold((f64::INFINITY, 0.0f64), |(lo, hi), &v| {
            (lo.min(v), hi.max(v))
        });
    if !(lo > 0.0 && hi / lo < MAX_CONDITION) {
        return Err(FitError {
            node,
            message: format!(
                "ill-conditioned collocation set (condition number {:.2e} of A, {nc} nodes for {np} monomials); use a finer auxiliary grid (larger k_aux) or a lower order",
                hi / lo.max(f64::MIN_POSITIVE)
            ),
        });
    }
    let cholesky = a.cholesky().ok_or_else(|| FitError {
        node,
        message:
            "normal matrix is not positive definite; use a finer auxiliary grid or a lower order"
                .into(),
    })?;
    Ok(cholesky.solve(&weighted_rows))
}

/// Scales L entries to the δ-scaled monomials: ξ^α = δ^n (ξ/δ)^α.
pub fn scale_to_fit(basis: &Basis, l: &[f64], horizon: f64) -> DVector<f64> {
    DVector::from_iterator(
        basis.len(),
        l.iter()
            .enumerate()
            .map(|(m, v)| v / horizon.powi(basis.degree(m) as i32)),
    )
}

/// For each node of `rows` (in parallel): its collocation set and fit Q_i, handed to `block`
/// which turns them into that row's weights. The first node whose fit fails is reported.
fn fitted_rows<const D: usize, T: Send>(
    rows: &[u32],
    positions: &[[f64; D]],
    families: &Families,
    basis: &Basis,
    horizon: f64,
    rule: Collocation,
    block: impl Fn(&DMatrix<f64>) -> Vec<T> + Sync,
) -> Result<Vec<Row<T>>, FitError> {
    use rayon::prelude::*;
    collocation_sets(rows, positions, families, horizon, rule)
        .into_par_iter()
        .zip(rows)
        .map(|(set, &i)| {
            let q = fit_matrix(
                i as usize,
                &set,
                positions,
                basis,
                horizon,
                rule.weight_exponent,
            )?;
            Ok((set, block(&q)))
        })
        .collect()
}

/// Per-node weight rows of the WLS diffusion operator (seed-thesis-ch2-3 §3.4): row of node i holds
/// w_ij = (L_C Q_i)_j for its collocation nodes j (seed-004 §2.7 step 2.4).
pub fn diffusion_operator<const D: usize>(
    rows: &[u32],
    positions: &[[f64; D]],
    families: &Families,
    basis: &Basis,
    l: &[f64],
    horizon: f64,
    rule: impl Into<Collocation>,
) -> Result<ScalarOperator, FitError> {
    let rule: Collocation = rule.into();
    let l_scaled = scale_to_fit(basis, l, horizon).transpose();
    let blocks = fitted_rows(rows, positions, families, basis, horizon, rule, |q| {
        (&l_scaled * q).iter().copied().collect()
    })?;
    Ok(ScalarOperator::from_rows(rows, blocks))
}

/// Per-node D × D blocks K_ij = L̄ Q̄_i of a WLS elasticity operator (seed-thesis-ch2-3 §3.5,
/// seed-004 §2.7): `l[k][l][α]` as returned by `bond_l` or `lps_shear_l`. Rows whose collocation
/// sets have the same geometry (relative offsets equal to 10⁻⁹ δ) are fitted once and share their
/// blocks.
pub fn elasticity_operator<const D: usize>(
    rows: &[u32],
    positions: &[[f64; D]],
    families: &Families,
    basis: &Basis,
    l: &[Vec<Vec<f64>>],
    horizon: f64,
    rule: impl Into<Collocation>,
) -> Result<VectorOperator<D>, FitError> {
    let rule: Collocation = rule.into();
    let scaled: Vec<Vec<nalgebra::RowDVector<f64>>> = l
        .iter()
        .map(|row| {
            row.iter()
                .map(|entry| scale_to_fit(basis, entry, horizon).transpose())
                .collect()
        })
        .collect();
    stenciled_operator(rows, positions, families, basis, horizon, rule, |q| {
        let weights: Vec<Vec<nalgebra::RowDVector<f64>>> = scaled
            .iter()
            .map(|row| row.iter().map(|lk| lk * q).collect())
            .collect();
        (0..q.ncols())
            .map(|j| std::array::from_fn(|k| std::array::from_fn(|c| weights[k][c][j])))
            .collect()
    })
}

/// The WLS diffusion operator of [`diffusion_operator`] in stencil form (1 × 1 blocks): rows
/// with the same collocation geometry share their weights, so translated rows form runs
/// ([`crate::scheme::runs::RowRuns`]). The weights are those of the first row of each
/// geometry: equal to the per-row fit's up to rounding.
pub fn diffusion_stencil_operator<const D: usize>(
    rows: &[u32],
    positions: &[[f64; D]],
    families: &Families,
    basis: &Basis,
    l: &[f64],
    horizon: f64,
    rule: impl Into<Collocation>,
) -> Result<VectorOperator<1>, FitError> {
    let rule: Collocation = rule.into();
    let l_scaled = scale_to_fit(basis, l, horizon).transpose();
    stenciled_operator(rows, positions, families, basis, horizon, rule, |q| {
        (&l_scaled * q).iter().map(|&w| [[w]]).collect()
    })
}

/// Collocation sets of `rows`, deduplicated by geometry (relative offsets rounded to 10⁻⁹ δ),
/// each distinct geometry fitted once and turned into E × E blocks by `blocks`.
fn stenciled_operator<const D: usize, const E: usize>(
    rows: &[u32],
    positions: &[[f64; D]],
    families: &Families,
    basis: &Basis,
    horizon: f64,
    rule: Collocation,
    blocks: impl Fn(&DMatrix<f64>) -> Vec<[[f64; E]; E]> + Sync,
) -> Result<VectorOperator<E>, FitError> {
    use rayon::prelude::*;
    use std::collections::HashMap;
    let sets = collocation_sets(rows, positions, families, horizon, rule);
    let key = |i: u32, set: &[u32]| -> Vec<i64> {
        set.iter()
            .flat_map(|&j| {
                (0..D).map(move |a| {
                    ((positions[j as usize][a] - positions[i as usize][a]) / horizon * 1e9).round()
                        as i64
                })
            })
            .collect()
    };
    let mut first_row_of: HashMap<Vec<i64>, u32> = HashMap::new();
    let mut unique: Vec<usize> = Vec::new();
    let stencil_of: Vec<u32> = rows
        .iter()
        .zip(&sets)
        .enumerate()
        .map(|(r, (&i, set))| {
            *first_row_of.entry(key(i, set)).or_insert_with(|| {
                unique.push(r);
                (unique.len() - 1) as u32
            })
        })
        .collect();
    let stencils: Vec<Vec<[[f64; E]; E]>> = unique
        .par_iter()
        .map(|&r| {
            let q = fit_matrix(
                rows[r] as usize,
                &sets[r],
                positions,
                basis,
                horizon,
                rule.weight_exponent,
            )?;
            Ok(blocks(&q))
        })
        .collect::<Result<_, FitError>>()?;
    Ok(VectorOperator::new(
        rows,
        sets.into_iter().zip(stencil_of).collect(),
        stencils,
    ))
}

#[cfg(test)]
mod tests;
