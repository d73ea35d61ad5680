//! Meshfree WLS collocation scheme (thesis §3.2; seed-thesis-ch2-3 §3, seed-004 §2): a local
//! polynomial fit over a few collocation nodes, with the PD integral over the full ball done
//! analytically (the L operators of seed-thesis-ch2-3 §3.5).
//!
//! Errata followed: (3.28) uses p(x_j − x_i) in A (seed-thesis-ch2-3 erratum 1); the weight (3.26)
//! is evaluated in its stable form; the fit is solved in coordinates scaled by δ, with L scaled to
//! match.

use nalgebra::{DMatrix, DVector};

pub use crate::scene::collocation::{Collocation, MAX_ORBITS, PAPERS_WEIGHT_EXPONENT, Targets};

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

/// WLS weight (3.26), w̄(d) = (1 − e^{64 − 16 d²/r̄²})/(1 − e^{64}), in the equivalent form
/// (e^{−16 d²/r̄²} − e^{−64})/(1 − e^{−64}) that does not overflow.
pub fn weight(d: f64, r_max: f64) -> f64 {
    weight_with(PAPERS_WEIGHT_EXPONENT, d, r_max)
}

/// The weight (3.26) with exponent a in place of 16: (e^{−a d²/r̄²} − e^{−4a})/(1 − e^{−4a}),
/// so that w̄(0) = 1 and w̄(2 r̄) = 0 as in the papers' form.
pub fn weight_with(a: f64, d: f64, r_max: f64) -> f64 {
    let floor = (-4.0 * a).exp();
    ((-a * d * d / (r_max * r_max)).exp() - floor) / (1.0 - floor)
}

/// Radial moment R(s) = ∫_0^δ ω(r) r^s dr (seed-thesis-ch2-3 §3.5), s > −1.
pub fn radial_moment(s: f64, horizon: f64, influence: Influence) -> f64 {
    match influence {
        Influence::Constant => horizon.powf(s + 1.0) / (s + 1.0),
        Influence::Linear => horizon.powf(s + 1.0) / ((s + 1.0) * (s + 2.0)),
    }
}

/// Γ(m/2) for a whole m ≥ 1.
fn gamma_half(m: u32) -> f64 {
    let (mut x, mut g) = if m.is_multiple_of(2) {
        (1.0, 1.0) // Γ(1)
    } else {
        (0.5, std::f64::consts::PI.sqrt()) // Γ(1/2)
    };
    while (2.0 * x) < m as f64 {
        g *= x;
        x += 1.0;
    }
    g
}

/// Angular moment S(β) = ∫ over the unit sphere of θ^β (seed-thesis-ch2-3 §3.5): 2 Π Γ((β_i+1)/2) /
/// Γ((|β|+n_d)/2) if every β_i is even, else 0; in 1D, 2 for even β.
pub fn angular_moment(beta: [u32; 3], dim: usize) -> f64 {
    if beta[..dim].iter().any(|b| b % 2 == 1) {
        return 0.0;
    }
    let total: u32 = beta[..dim].iter().sum();
    2.0 * beta[..dim]
        .iter()
        .map(|&b| gamma_half(b + 1))
        .product::<f64>()
        / gamma_half(total + dim as u32)
}

/// One L entry per monomial of degree n ≥ 1; the constant monomial gives 0
/// (seed-thesis-ch2-3 §3.5).
fn per_monomial(basis: &Basis, entry: impl Fn([u32; 3], u32) -> f64) -> Vec<f64> {
    basis
        .exponents
        .iter()
        .map(|&alpha| {
            let n: u32 = alpha.iter().sum();
            if n == 0 { 0.0 } else { entry(alpha, n) }
        })
        .collect()
}

/// L_C of diffusion with kernel κ ω ‖ξ‖^{−q} (3.60)–(3.67): L_C[α] = κ R(n − q + n_d − 1) S(α).
pub fn diffusion_l(
    basis: &Basis,
    kappa: f64,
    q: f64,
    horizon: f64,
    influence: Influence,
) -> Vec<f64> {
    let nd = basis.dim as f64;
    per_monomial(basis, |alpha, n| {
        kappa
            * radial_moment(n as f64 - q + nd - 1.0, horizon, influence)
            * angular_moment(alpha, basis.dim)
    })
}

/// Blocks [k][l][α] = factor · R(n + n_d − 1 − p) S(α + e_k + e_l) of a pair kernel
/// factor · ω ξ⊗ξ/‖ξ‖^(1+p) acting on (u' − u) (seed-thesis-ch2-3 §3.5).
fn pair_l(
    basis: &Basis,
    factor: f64,
    p: f64,
    horizon: f64,
    influence: Influence,
) -> Vec<Vec<Vec<f64>>> {
    let d = basis.dim;
    (0..d)
        .map(|k| {
            (0..d)
                .map(|l| {
                    per_monomial(basis, |alpha, n| {
                        let mut beta = alpha;
                        beta[k] += 1;
                        beta[l] += 1;
                        factor
                            * radial_moment(n as f64 + d as f64 - 1.0 - p, horizon, influence)
                            * angular_moment(beta, d)
                    })
                })
                .collect()
        })
        .collect()
}

/// L blocks of linearized bond-based elasticity (3.54)–(3.56): entry [k][l][α] is the
/// coefficient of the α-monomial of displacement component l in force component k,
/// c R(n + n_d − 2) S(α + e_k + e_l) (kernel c ω ξ⊗ξ/‖ξ‖³).
pub fn bond_l(basis: &Basis, c: f64, horizon: f64, influence: Influence) -> Vec<Vec<Vec<f64>>> {
    pair_l(basis, c, 1.0, horizon, influence)
}

/// Collocation set of a node (seed-thesis-ch2-3 §3.1, seed-004 §2.2): for each point of an
/// auxiliary grid of spacing δ/k_aux centred at the node and inside the ball, the nearest family
/// node (the node itself included) not already chosen; ties go to the lower index. The node itself
/// comes first.
pub fn collocation_set<const D: usize>(
    i: usize,
    positions: &[[f64; D]],
    families: &Families,
    horizon: f64,
    rule: impl Into<Collocation>,
) -> Vec<u32> {
    let rule: Collocation = rule.into();
    let candidates = collocation_candidates(i, families);
    select_collocation_set(i, &candidates, positions, horizon, rule)
}

/// A node's collocation candidates: itself and its family, in index order.
fn collocation_candidates(i: usize, families: &Families) -> Vec<u32> {
    let mut candidates: Vec<u32> = families.range(i).map(|b| families.neighbors[b]).collect();
    // Families are kept in index order: the node goes in at its place.
    if candidates.is_sorted() {
        candidates.insert(candidates.partition_point(|&j| j < i as u32), i as u32);
    } else {
        candidates.push(i as u32);
        candidates.sort_unstable();
    }
    candidates
}

/// [`collocation_set`] among given `candidates` (in index order, the node included).
fn select_collocation_set<const D: usize>(
    i: usize,
    candidates: &[u32],
    positions: &[[f64; D]],
    horizon: f64,
    rule: Collocation,
) -> Vec<u32> {
    let h = rule.cell(horizon);
    let mut chosen = vec![i as u32];
    let mut taken = vec![false; candidates.len()];
    if let Ok(self_slot) = candidates.binary_search(&(i as u32)) {
        taken[self_slot] = true;
    }
    // Candidates bucketed by their offset rounded to cells of side h: a target's nearest
    // candidate is searched in the 3^D cells around it first. Anything outside them is at
    // least 1.5 h away on some axis, so a hit closer than that is the exact nearest (ties
    // included); otherwise the whole family is scanned.
    // Dense buckets (a head per cell, a chain through `next`), cells within reach of the node.
    let reach = (horizon / h).ceil() as i64 + 2;
    let side = (2 * reach + 1) as usize;
    let cell_index = |cell: [i64; D]| -> Option<usize> {
        cell.iter().try_fold(0usize, |acc, &c| {
            (c.abs() <= reach).then(|| acc * side + (c + reach) as usize)
        })
    };
    let mut head = vec![usize::MAX; side.pow(D as u32)];
    let mut next = vec![usize::MAX; candidates.len()];
    for (slot, &j) in candidates.iter().enumerate() {
        let cell: [i64; D] = std::array::from_fn(|a| {
            ((positions[j as usize][a] - positions[i][a]) / h).round() as i64
        });
        if let Some(c) = cell_index(cell) {
            next[slot] = head[c];
            head[c] = slot;
        }
    }
    let distance2 = |slot: usize, target: &[f64; D]| -> f64 {
        let j = candidates[slot] as usize;
        (0..D).map(|a| (positions[j][a] - target[a]).powi(2)).sum()
    };
    let closer = |a: &(f64, usize), b: &(f64, usize)| nearer(a, b, h);
    let exact_within = (1.5 * h).powi(2);
    for offset in rule.target_offsets::<D>(horizon) {
        let target: [f64; D] = std::array::from_fn(|a| positions[i][a] + offset[a]);
        let centre: [i64; D] = std::array::from_fn(|a| (offset[a] / h).round() as i64);
        let mut near: Option<(f64, usize)> = None;
        for code in 0..3usize.pow(D as u32) {
            let mut c = code;
            let cell: [i64; D] = std::array::from_fn(|a| {
                let v = centre[a] + (c % 3) as i64 - 1;
                c /= 3;
                v
            });
            let mut slot = cell_index(cell).map_or(usize::MAX, |c| head[c]);
            while slot != usize::MAX {
                if !taken[slot] {
                    let cand = (distance2(slot, &target), slot);
                    if near.is_none_or(|n| closer(&cand, &n).is_lt()) {
                        near = Some(cand);
                    }
                }
                slot = next[slot];
            }
        }
        let best = near.filter(|n| n.0 < exact_within).or_else(|| {
            (0..candidates.len())
                .filter(|&slot| !taken[slot])
                .map(|slot| (distance2(slot, &target), slot))
                .min_by(closer)
        });
        if let Some((_, slot)) = best {
            taken[slot] = true;
            chosen.push(candidates[slot]);
        }
    }
    chosen
}

/// Collocation sets of `rows` (in parallel), each equal to [`collocation_set`]. On a uniform
/// lattice most rows are translates of each other: a row whose candidates (node and family in
/// index order) have, slot by slot, the offsets of the first largest row's candidates to
/// 10⁻¹² δ gets that row's choice of slots without a search. The choice depends only on the
/// offsets and the slot order (ties go to the lower slot), so it is the same set; any other
/// row (boundaries, holes, perturbed lattices) is searched in full.
pub fn collocation_sets<const D: usize>(
    rows: &[u32],
    positions: &[[f64; D]],
    families: &Families,
    horizon: f64,
    rule: impl Into<Collocation>,
) -> Vec<Vec<u32>> {
    let rule: Collocation = rule.into();
    collocation_sets_counted(rows, positions, families, horizon, rule).0
}

/// [`collocation_sets`] and how many rows took the translated template.
fn collocation_sets_counted<const D: usize>(
    rows: &[u32],
    positions: &[[f64; D]],
    families: &Families,
    horizon: f64,
    rule: Collocation,
) -> (Vec<Vec<u32>>, usize) {
    use rayon::prelude::*;
    let largest = rows.iter().map(|&i| i as usize).reduce(|a, b| {
        if families.range(b).len() > families.range(a).len() {
            b
        } else {
            a
        }
    });
    let Some(t) = largest else {
        return (Vec::new(), 0);
    };
    let template = collocation_candidates(t, families);
    let offset = |i: usize, j: u32| -> [f64; D] {
        std::array::from_fn(|a| positions[j as usize][a] - positions[i][a])
    };
    let template_offsets: Vec<[f64; D]> = template.iter().map(|&j| offset(t, j)).collect();
    let template_slots: Vec<usize> = select_collocation_set(t, &template, positions, horizon, rule)
        .iter()
        .filter_map(|j| template.binary_search(j).ok())
        .collect();
    let tolerance = 1e-12 * horizon;
    let sets: Vec<(Vec<u32>, bool)> = rows
        .par_iter()
        .map(|&i| {
            let i = i as usize;
            let candidates = collocation_candidates(i, families);
            let translated = candidates.len() == template.len()
                && candidates.iter().zip(&template_offsets).all(|(&j, o)| {
                    let d = offset(i, j);
                    (0..D).all(|a| (d[a] - o[a]).abs() <= tolerance)
                });
            let set = if translated {
                template_slots.iter().map(|&s| candidates[s]).collect()
            } else {
                select_collocation_set(i, &candidates, positions, horizon, rule)
            };
            (set, translated)
        })
        .collect();
    let translated = sets.iter().filter(|(_, t)| *t).count();
    (sets.into_iter().map(|(set, _)| set).collect(), translated)
}

/// Order of two (squared distance, slot) candidates of a collocation target on an auxiliary
/// grid of spacing h. Distances equal to 10⁻¹⁰ h² are ties, and ties go to the lower slot (the
/// lower node index): on a uniform lattice the geometric ties then break the same way at every
/// node, whatever the rounding of its absolute coordinates, so translated nodes get translated
/// collocation sets in the same order (one shared stencil, and the product's fast runs).
fn nearer(a: &(f64, usize), b: &(f64, usize), h: f64) -> std::cmp::Ordering {
    if (a.0 - b.0).abs() <= 1e-10 * h * h {
        a.1.cmp(&b.1)
    } else {
        a.0.total_cmp(&b.0)
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

/// Weighted volume m̄ = ∫_H ω ‖ξ‖² dV (LPS).
pub fn weighted_volume(dim: usize, horizon: f64, influence: Influence) -> f64 {
    radial_moment(dim as f64 + 1.0, horizon, influence) * angular_moment([0; 3], dim)
}

/// L_J of the linearized LPS shear term J = ∫ 30G/m̄ ω ξ⊗ξ/‖ξ‖² (u' − u) dV (seed-004 §2.5,
/// thesis (3.51)): entry [k][l][α] = 30G/m̄ R(n + n_d − 1) S(α + e_k + e_l) — "seed-004 (51) with
/// λ → 6G" (u = (x², 0, 0) gives 6G).
pub fn lps_shear_l(
    basis: &Basis,
    shear_modulus: f64,
    horizon: f64,
    influence: Influence,
) -> Vec<Vec<Vec<f64>>> {
    let factor = 30.0 * shear_modulus / weighted_volume(basis.dim, horizon, influence);
    pair_l(basis, factor, 0.0, horizon, influence)
}

/// L_θ of the linearized dilatation θ = 3/m̄ ∫ ω ξ·(u' − u) dV: entry [l][α] =
/// 3/m̄ R(n + n_d) S(α + e_l). With the 3/m̄ prefactor (seed-thesis-ch2-3 erratum 3; seed-004 §2.5)
/// the C² rows are exactly 1 at the linear monomials: θ = a_x + a_y + a_z.
pub fn lps_dilatation_l(basis: &Basis, horizon: f64, influence: Influence) -> Vec<Vec<f64>> {
    let d = basis.dim;
    let factor = 3.0 / weighted_volume(d, horizon, influence);
    (0..d)
        .map(|l| {
            per_monomial(basis, |alpha, n| {
                let mut beta = alpha;
                beta[l] += 1;
                factor
                    * radial_moment(n as f64 + d as f64, horizon, influence)
                    * angular_moment(beta, d)
            })
        })
        .collect()
}

/// L_I of the dilatation term I = ∫ (3K − 5G)/m̄ ω (θ + θ') ξ dV fitted on the nodal θ
/// (seed-004 §2.5; seed-thesis-ch2-3 erratum 2: (3.51)'s first term reads L_I Q_i Θ_i): entry
/// [k][α] = (3K − 5G)/m̄ R(n + n_d) S(α + e_k), = (3K − 5G)/3 at α = e_k.
pub fn lps_dilatation_force_l(
    basis: &Basis,
    bulk_modulus: f64,
    shear_modulus: f64,
    horizon: f64,
    influence: Influence,
) -> Vec<Vec<f64>> {
    let scale = (3.0 * bulk_modulus - 5.0 * shear_modulus) / 3.0;
    lps_dilatation_l(basis, horizon, influence)
        .into_iter()
        .map(|row| row.into_iter().map(|v| v * scale).collect())
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::discretization::grid::{Lattice, SplitMix64};
    use crate::scene::Solid;

    fn centre_node<const D: usize>(lattice: &Lattice<D>, at: f64) -> usize {
        (0..lattice.len())
            .min_by(|&a, &b| {
                let d = |i: usize| {
                    lattice.positions[i]
                        .iter()
                        .map(|v| (v - at).powi(2))
                        .sum::<f64>()
                };
                d(a).total_cmp(&d(b))
            })
            .unwrap()
    }

    /// The fit with the papers' weight (3.26).
    fn papers_fit<const D: usize>(
        c: usize,
        set: &[u32],
        positions: &[[f64; D]],
        basis: &Basis,
        horizon: f64,
    ) -> DMatrix<f64> {
        fit_matrix(c, set, positions, basis, horizon, PAPERS_WEIGHT_EXPONENT).unwrap()
    }

    fn setup<const D: usize>(m: usize, perturbation: f64) -> (Lattice<D>, Families, usize) {
        let n = 2 * m + 4;
        let solid = Solid::Box {
            min: vec![0.0; D],
            max: vec![n as f64; D],
        };
        let lattice = Lattice::<D>::build(&solid, 1.0, [-perturbation, perturbation], 11);
        let families = Families::build(&lattice.positions, m as f64 * (1.0 + 1e-9));
        let c = centre_node(&lattice, (n / 2) as f64);
        (lattice, families, c)
    }

    /// The bucketed search picks exactly what a scan of the whole family picks, on perturbed
    /// lattices (targets off the nodes, ties, edges of the body) in 2D and 3D.
    #[test]
    fn collocation_set_equals_a_full_scan() {
        fn full_scan<const D: usize>(
            i: usize,
            positions: &[[f64; D]],
            families: &Families,
            horizon: f64,
            k_aux: usize,
        ) -> Vec<u32> {
            let (h, k) = (horizon / k_aux as f64, k_aux as i64);
            let mut candidates: Vec<u32> = std::iter::once(i as u32)
                .chain(families.range(i).map(|b| families.neighbors[b]))
                .collect();
            candidates.sort_unstable();
            let mut chosen = vec![i as u32];
            let mut taken: Vec<bool> = candidates.iter().map(|&j| j as usize == i).collect();
            let offsets: Vec<[i64; D]> = (0..(2 * k + 1).pow(D as u32))
                .map(|code| {
                    let mut c = code;
                    std::array::from_fn(|_| {
                        let v = c % (2 * k + 1) - k;
                        c /= 2 * k + 1;
                        v
                    })
                })
                .collect();
            for index in offsets {
                let n2: i64 = index.iter().map(|v| v * v).sum();
                if n2 == 0 || n2 > k * k {
                    continue;
                }
                let target: [f64; D] =
                    std::array::from_fn(|a| positions[i][a] + index[a] as f64 * h);
                let best = (0..candidates.len())
                    .filter(|&s| !taken[s])
                    .map(|s| {
                        let j = candidates[s] as usize;
                        let d2: f64 = (0..D).map(|a| (positions[j][a] - target[a]).powi(2)).sum();
                        (d2, s)
                    })
                    .min_by(|a, b| super::nearer(a, b, h));
                if let Some((_, s)) = best {
                    taken[s] = true;
                    chosen.push(candidates[s]);
                }
            }
            chosen
        }
        fn check<const D: usize>(m: usize, perturbation: f64, k_aux: usize) {
            let (lattice, families, _) = setup::<D>(m, perturbation);
            for i in (0..lattice.len()).step_by(7) {
                assert_eq!(
                    collocation_set(i, &lattice.positions, &families, m as f64, k_aux),
                    full_scan(i, &lattice.positions, &families, m as f64, k_aux),
                    "node {i}, {D}D, m = {m}, perturbation {perturbation}, k_aux {k_aux}"
                );
            }
        }
        check::<2>(4, 0.0, 3);
        check::<2>(4, 0.3, 3);
        check::<2>(5, 0.45, 4);
        check::<3>(3, 0.0, 3);
        check::<3>(3, 0.3, 3);
    }

    /// The translated-template shortcut of `collocation_sets` gives every row the set its own
    /// search gives, on uniform lattices (where it serves most rows) and perturbed ones (where
    /// it serves none), and in a body with a hole.
    #[test]
    fn collocation_sets_equal_the_search_row_by_row() {
        fn check<const D: usize>(solid: Solid, m: usize, perturbation: f64, k_aux: usize) {
            let lattice = Lattice::<D>::build(&solid, 1.0, [-perturbation, perturbation], 5);
            let horizon = m as f64;
            let families = Families::build(&lattice.positions, horizon * (1.0 + 1e-9));
            let rows: Vec<u32> = (0..lattice.len() as u32).collect();
            let (sets, translated) = collocation_sets_counted(
                &rows,
                &lattice.positions,
                &families,
                horizon,
                k_aux.into(),
            );
            eprintln!(
                "{D}D, perturbation {perturbation}: {translated} of {} rows translated",
                rows.len()
            );
            if perturbation == 0.0 {
                assert!(
                    translated > rows.len() / 10,
                    "the shortcut serves the interior"
                );
            } else {
                assert!(translated <= 1, "only the template itself");
            }
            for (&i, set) in rows.iter().zip(&sets) {
                assert_eq!(
                    set,
                    &collocation_set(i as usize, &lattice.positions, &families, horizon, k_aux),
                    "node {i}, {D}D, m = {m}, perturbation {perturbation}"
                );
            }
        }
        let plate = Solid::Box {
            min: vec![0.0, 0.0],
            max: vec![24.0, 16.0],
        };
        check::<2>(plate.clone(), 4, 0.0, 3);
        check::<2>(plate, 4, 0.3, 3);
        let holed = Solid::Difference {
            base: Box::new(Solid::Box {
                min: vec![0.0; 3],
                max: vec![16.0; 3],
            }),
            minus: vec![Solid::Sphere {
                center: vec![8.0; 3],
                radius: 2.0,
            }],
        };
        check::<3>(holed, 3, 0.0, 3);
    }

    #[test]
    fn basis_sizes_and_order() {
        assert_eq!(
            Basis::new(3, 2).exponents[4..],
            [
                [2, 0, 0],
                [1, 1, 0],
                [1, 0, 1],
                [0, 2, 0],
                [0, 1, 1],
                [0, 0, 2]
            ]
        );
        assert_eq!(Basis::new(2, 2).len(), 6);
        assert_eq!(Basis::new(2, 4).len(), 15);
        assert_eq!(Basis::new(1, 6).len(), 7);
        assert_eq!(Basis::new(3, 2).len(), 10);
    }

    #[test]
    fn weight_function_values() {
        assert!((weight(0.0, 1.0) - 1.0).abs() < 1e-15);
        assert!((weight(0.5, 1.0) - 0.0183).abs() < 1e-4);
        assert!((weight(1.0, 1.0) - 1.1e-7).abs() < 0.1e-7);
    }

    #[test]
    fn collocation_counts_match_the_papers() {
        let (l1, f1, c1) = setup::<1>(12, 0.0);
        for (k, n) in [(2, 5), (6, 13)] {
            assert_eq!(collocation_set(c1, &l1.positions, &f1, 12.0, k).len(), n);
        }
        let (l1, f1, c1) = setup::<1>(10, 0.0);
        assert_eq!(collocation_set(c1, &l1.positions, &f1, 10.0, 5).len(), 11);
        let (l2, f2, c2) = setup::<2>(12, 0.0);
        assert_eq!(collocation_set(c2, &l2.positions, &f2, 12.0, 3).len(), 29);
        assert_eq!(collocation_set(c2, &l2.positions, &f2, 12.0, 4).len(), 49);
        let (l3, f3, c3) = setup::<3>(6, 0.0);
        let set = collocation_set(c3, &l3.positions, &f3, 6.0, 3);
        assert_eq!(set.len(), 123);
        assert_eq!(set[0] as usize, c3);
        let mut unique = set.clone();
        unique.sort_unstable();
        unique.dedup();
        assert_eq!(unique.len(), set.len(), "no node chosen twice");
    }

    #[test]
    fn closed_forms_of_the_l_operators() {
        use std::f64::consts::PI;
        let (d, q, kappa, c) = (0.7, 1.0, 2.0, 3.0);
        let b3 = Basis::new(3, 2);
        let l = diffusion_l(&b3, kappa, q, d, Influence::Constant);
        let lc = 4.0 * PI * kappa * d.powf(5.0 - q) / (15.0 - 3.0 * q);
        assert_eq!(l.iter().filter(|v| v.abs() > 0.0).count(), 3);
        for m in [4, 7, 9] {
            assert!((l[m] / lc - 1.0).abs() < 1e-12, "(3.66)");
        }
        let l = diffusion_l(&b3, kappa, q, d, Influence::Linear);
        let lc = 4.0 * PI * kappa * d.powf(5.0 - q) / (3.0 * q * q - 33.0 * q + 90.0);
        assert!((l[4] / lc - 1.0).abs() < 1e-12, "(3.67)");
        let lb = bond_l(&b3, c, d, Influence::Constant);
        let lambda = PI * c * d.powi(4) / 5.0;
        // (3.58): L_u row x = λ (.., 1 at x², 1/3 at y², 1/3 at z²); row y = λ/3 at xy.
        assert!((lb[0][0][4] / lambda - 1.0).abs() < 1e-12);
        assert!((lb[0][0][7] / lambda - 1.0 / 3.0).abs() < 1e-12);
        assert!((lb[1][0][5] / lambda - 1.0 / 3.0).abs() < 1e-12);
        assert_eq!(lb[0][0][5], 0.0);
        let lb = bond_l(&b3, c, d, Influence::Linear);
        assert!((lb[0][0][4] / (PI * c * d.powi(4) / 25.0) - 1.0).abs() < 1e-12);
        // 1D: L = (0, 0, c δ²) for ω0.
        let l1 = bond_l(&Basis::new(1, 2), c, d, Influence::Constant);
        assert!((l1[0][0][2] / (c * d * d) - 1.0).abs() < 1e-12);
        // 2D disc: λ2 = π c δ³ / 4.
        let l2 = bond_l(&Basis::new(2, 2), c, d, Influence::Constant);
        assert!((l2[0][0][3] / (PI * c * d.powi(3) / 4.0) - 1.0).abs() < 1e-12);
    }

    /// For every dimension and order, a random polynomial of degree ≤ k pushed through the
    /// fit and L equals the analytic PD integral L·a (a = its Taylor coefficients at x_i), on
    /// a perturbed lattice; the weights of every node sum to zero.
    fn reproduction<const D: usize>(order: usize, m: usize, rule: impl Into<Collocation>) {
        let rule: Collocation = rule.into();
        let (lattice, families, c) = setup::<D>(m, 0.2);
        let horizon = m as f64;
        let basis = Basis::new(D, order);
        let set = collocation_set(c, &lattice.positions, &families, horizon, rule);
        let q = fit_matrix(
            c,
            &set,
            &lattice.positions,
            &basis,
            horizon,
            rule.weight_exponent,
        )
        .unwrap();
        let l = diffusion_l(&basis, 1.0, 1.0, horizon, Influence::Constant);
        let weights = scale_to_fit(&basis, &l, horizon).transpose() * &q;
        let sum: f64 = weights.iter().sum();
        let scale: f64 = weights.iter().map(|w| w.abs()).sum();
        assert!(sum.abs() < 1e-11 * scale, "weights sum to {sum:e}");
        let mut rng = SplitMix64(order as u64 * 7 + D as u64);
        let coeffs: Vec<f64> = (0..basis.len()).map(|_| rng.next_f64() - 0.5).collect();
        let xc = lattice.positions[c];
        let mut row = vec![0.0; basis.len()];
        let values: Vec<f64> = set
            .iter()
            .map(|&j| {
                let xi: Vec<f64> = (0..D)
                    .map(|a| lattice.positions[j as usize][a] - xc[a])
                    .collect();
                basis.eval(&xi, &mut row);
                row.iter().zip(&coeffs).map(|(p, a)| p * a).sum()
            })
            .collect();
        let wls: f64 = weights.iter().zip(&values).map(|(w, v)| w * v).sum();
        let exact: f64 = l.iter().zip(&coeffs).map(|(l, a)| l * a).sum();
        let size: f64 = l.iter().zip(&coeffs).map(|(l, a)| (l * a).abs()).sum();
        assert!(
            (wls - exact).abs() <= 1e-9 * size,
            "{D}D order {order}: WLS {wls:e} vs analytic {exact:e}"
        );
    }

    #[test]
    fn polynomial_reproduction_1d() {
        reproduction::<1>(2, 12, 6);
        reproduction::<1>(4, 12, 6);
        reproduction::<1>(6, 12, 6);
    }

    #[test]
    fn polynomial_reproduction_2d() {
        reproduction::<2>(2, 6, 3);
        reproduction::<2>(4, 8, 4);
    }

    #[test]
    fn polynomial_reproduction_3d() {
        reproduction::<3>(2, 6, 3);
    }

    /// The wide stencils of issue 14 (orbits of lattice offsets, weight exponent 6 and 8)
    /// reproduce quadratics like the papers' grid, on a perturbed lattice (setup: ±0.2 Δx).
    #[test]
    fn orbit_stencils_reproduce_quadratics() {
        for (m, orbits, a) in [
            (4, &[[1u8, 1], [2, 1], [3, 0]][..], 6.0),
            (8, &[[3, 3], [4, 1], [4, 2]][..], 6.0),
            (8, &[[4, 1], [4, 2]][..], 8.0),
        ] {
            reproduction::<2>(2, m, Collocation::orbits(1.0, orbits, a).unwrap());
        }
    }

    /// Orbit sets hold the node and every orbit's 4 or 8 points; the papers' grid rule is
    /// unchanged by the generalisation (29 nodes at δ/3).
    #[test]
    fn orbit_stencil_counts() {
        let (lattice, families, c) = setup::<2>(4, 0.0);
        let rule = Collocation::orbits(1.0, &[[1, 1], [2, 1], [3, 0]], 6.0).unwrap();
        let set = collocation_set(c, &lattice.positions, &families, 4.0, rule);
        assert_eq!(set.len(), 1 + 4 + 8 + 4);
        let offsets: Vec<[i64; 2]> = set
            .iter()
            .map(|&j| {
                std::array::from_fn(|a| {
                    (lattice.positions[j as usize][a] - lattice.positions[c][a]).round() as i64
                })
            })
            .collect();
        for o in [[0, 0], [1, 1], [-1, 1], [2, 1], [1, -2], [3, 0], [0, -3]] {
            assert!(offsets.contains(&o), "{o:?} missing from {offsets:?}");
        }
        assert!(Collocation::orbits(1.0, &[[0, 0]], 6.0).is_err());
        assert!(Collocation::orbits(1.0, &[[1, 0]], 70.0).is_err());
    }

    /// Bond-based WLS on quadratic displacements equals Navier's operator with the Poisson
    /// ratio of bond-based PD: ν = 1/3 with the plane-stress c, ν = 1/4 with the plane-strain
    /// c (2D), and in 3D u = (x², 0, 0) gives ρü_x = λ = π c δ⁴/5 (3.58).
    #[test]
    fn bond_based_wls_is_navier_on_quadratics() {
        use crate::model::pmb::Plane;
        use crate::model::pmb::micromodulus;
        let (lattice, families, c) = setup::<2>(6, 0.2);
        let horizon = 6.0;
        let basis = Basis::new(2, 2);
        let set = collocation_set(c, &lattice.positions, &families, horizon, 3);
        let q = papers_fit(c, &set, &lattice.positions, &basis, horizon);
        let xc = lattice.positions[c];
        // u = (a x² + b xy + e y², f x² + g xy + h y²) about x_c.
        let (a, b, e, f, g, h) = (0.3, -0.2, 0.5, 0.1, 0.4, -0.6);
        let field = |x: &[f64; 2]| {
            let (x, y) = (x[0] - xc[0], x[1] - xc[1]);
            [
                a * x * x + b * x * y + e * y * y,
                f * x * x + g * x * y + h * y * y,
            ]
        };
        let values: Vec<[f64; 2]> = set
            .iter()
            .map(|&j| field(&lattice.positions[j as usize]))
            .collect();
        let youngs = 1.0;
        for (plane, nu) in [(Plane::Stress, 1.0 / 3.0), (Plane::Strain, 0.25)] {
            let cm = micromodulus(youngs, horizon, 2, plane, Influence::Constant);
            let l = bond_l(&basis, cm, horizon, Influence::Constant);
            let mut force = [0.0; 2];
            for k in 0..2 {
                for comp in 0..2 {
                    let lk = scale_to_fit(&basis, &l[k][comp], horizon);
                    let u = DVector::from_iterator(set.len(), values.iter().map(|v| v[comp]));
                    force[k] += (lk.transpose() * &q * u)[(0, 0)];
                }
            }
            let mu = youngs / (2.0 * (1.0 + nu));
            let lambda = if plane == Plane::Stress {
                youngs * nu / (1.0 - nu * nu)
            } else {
                youngs * nu / ((1.0 + nu) * (1.0 - 2.0 * nu))
            };
            // μ ∇²u + (λ + μ) ∇(∇·u) for the quadratic field.
            let (uxx, uyy, vxy, vxx, vyy, uxy) = (2.0 * a, 2.0 * e, g, 2.0 * f, 2.0 * h, b);
            let navier = [
                mu * (uxx + uyy) + (lambda + mu) * (uxx + vxy),
                mu * (vxx + vyy) + (lambda + mu) * (uxy + vyy),
            ];
            for k in 0..2 {
                assert!(
                    (force[k] - navier[k]).abs() < 1e-9,
                    "{plane:?}: {force:?} vs {navier:?}"
                );
            }
        }

        let (lattice, families, c) = setup::<3>(6, 0.2);
        let basis = Basis::new(3, 2);
        let set = collocation_set(c, &lattice.positions, &families, horizon, 3);
        let q = papers_fit(c, &set, &lattice.positions, &basis, horizon);
        let xc = lattice.positions[c];
        let cm = 1.0;
        let l = bond_l(&basis, cm, horizon, Influence::Constant);
        let u = DVector::from_iterator(
            set.len(),
            set.iter()
                .map(|&j| (lattice.positions[j as usize][0] - xc[0]).powi(2)),
        );
        let coeffs = &q * u;
        let fx = (scale_to_fit(&basis, &l[0][0], horizon).transpose() * &coeffs)[(0, 0)];
        let lambda = std::f64::consts::PI * cm * horizon.powi(4) / 5.0;
        assert!((fx / lambda - 1.0).abs() < 1e-9, "{fx} vs λ = {lambda}");
    }

    /// On the interior of a perturbed 2D lattice, the assembled diffusion operator applied to
    /// C = x² + 3y² gives L_C·a = λ_C2 (1 + 3) with λ_C2 = π κ δ^{4−q}/(4−q)
    /// (seed-thesis-ch2-3 §3.4, 2D).
    #[test]
    fn assembled_diffusion_operator_on_a_quadratic() {
        let m = 4usize;
        let solid = Solid::Box {
            min: vec![0.0; 2],
            max: vec![20.0; 2],
        };
        let lattice = Lattice::<2>::build(&solid, 1.0, [-0.3, 0.3], 2);
        let horizon = m as f64;
        let families = Families::build(&lattice.positions, horizon);
        let interior: Vec<u32> = (0..lattice.len() as u32)
            .filter(|&i| {
                lattice.positions[i as usize]
                    .iter()
                    .all(|&x| x > horizon + 1.0 && x < 20.0 - horizon - 1.0)
            })
            .collect();
        let basis = Basis::new(2, 2);
        let (kappa, q) = (1.5, 2.0);
        let l = diffusion_l(&basis, kappa, q, horizon, Influence::Constant);
        let op = diffusion_operator(
            &interior,
            &lattice.positions,
            &families,
            &basis,
            &l,
            horizon,
            4,
        )
        .unwrap();
        let c: Vec<f64> = lattice
            .positions
            .iter()
            .map(|p| p[0] * p[0] + 3.0 * p[1] * p[1])
            .collect();
        let mut rate = vec![f64::NAN; lattice.len()];
        op.apply(&c, &mut rate);
        let expected = std::f64::consts::PI * kappa * horizon.powf(4.0 - q) / (4.0 - q) * 4.0;
        for &i in &interior {
            let r = rate[i as usize];
            assert!(
                (r / expected - 1.0).abs() < 1e-9,
                "node {i}: {r} vs {expected}"
            );
        }
    }

    #[test]
    fn too_few_collocation_nodes_name_the_node_and_the_fix() {
        let (lattice, families, c) = setup::<2>(6, 0.0);
        let basis = Basis::new(2, 4);
        let set = collocation_set(c, &lattice.positions, &families, 6.0, 1);
        let err = fit_matrix(
            c,
            &set,
            &lattice.positions,
            &basis,
            6.0,
            PAPERS_WEIGHT_EXPONENT,
        )
        .unwrap_err();
        assert_eq!(err.node, c);
        let text = err.to_string();
        assert!(
            text.contains(&format!("node {c}")) && text.contains("k_aux"),
            "{text}"
        );
    }
}
