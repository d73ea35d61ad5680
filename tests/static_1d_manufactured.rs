//! 1D static PD elasticity with a manufactured solution (thesis §3.2.5; seed §4.1):
//! Ω = (−100, 100), E = 1, c = 2E/δ², ω0, u = sin(x/10), Dirichlet layers of width δ outside Ω,
//! one global linear solve. Standard scheme against WLS-2/4/6 (5/11/13 collocation nodes).
//!
//! In 1D the bond-based operator is the diffusion operator with κ = c and q = 1, so both
//! schemes come from their diffusion assemblers.

use nalgebra::{DMatrix, DVector};

use peridyn::family::Families;
use peridyn::model::diffusion::DiffusionKernel;
use peridyn::scene::Influence;
use peridyn::scheme::ScalarOperator;
use peridyn::scheme::standard::{self, Quadrature};
use peridyn::scheme::wls::{self, Basis};

#[derive(Clone, Copy, Debug)]
enum Scheme {
    Standard,
    /// The standard scheme without the partial-volume factor β.
    StandardWithoutBeta,
    /// (order, auxiliary grid factor k_aux)
    Wls(usize, usize),
}

const WLS2: Scheme = Scheme::Wls(2, 2);
const WLS4: Scheme = Scheme::Wls(4, 5);
const WLS6: Scheme = Scheme::Wls(6, 6);

/// ∫_0^a (1 − cos t)/t dt = γ − Ci(a) + ln a (erratum 4: γ is Euler–Mascheroni), by series.
fn one_minus_cos_integral(a: f64) -> f64 {
    let (mut sum, mut term_fact, mut k) = (0.0, 1.0, 1);
    loop {
        term_fact *= ((2 * k - 1) * (2 * k)) as f64; // (2k)!
        let term = a.powi(2 * k) / (2.0 * k as f64 * term_fact);
        sum += if k % 2 == 1 { term } else { -term };
        if term < 1e-18 {
            return sum;
        }
        k += 1;
    }
}

/// Relative ℓ² error (3.79) over the unknown nodes, solving 0 = L u + b.
fn solve(horizon: f64, m: usize, scheme: Scheme, body: impl Fn(f64, f64) -> f64, c: f64) -> f64 {
    solve_with(horizon, m, scheme, body, c, |k, rhs| {
        k.lu().solve(&rhs).expect("a regular stiffness matrix")
    })
}

/// Banded LU without pivoting (the standard scheme's matrix is symmetric negative definite);
/// `band` is the half bandwidth.
fn banded_solve(mut a: DMatrix<f64>, mut b: DVector<f64>, band: usize) -> DVector<f64> {
    let n = b.len();
    for p in 0..n {
        let end = (p + band + 1).min(n);
        for r in p + 1..end {
            let f = a[(r, p)] / a[(p, p)];
            if f == 0.0 {
                continue;
            }
            for col in p..end {
                a[(r, col)] -= f * a[(p, col)];
            }
            b[r] -= f * b[p];
        }
    }
    let mut x = DVector::<f64>::zeros(n);
    for p in (0..n).rev() {
        let end = (p + band + 1).min(n);
        let sum: f64 = (p + 1..end).map(|col| a[(p, col)] * x[col]).sum();
        x[p] = (b[p] - sum) / a[(p, p)];
    }
    x
}

fn solve_with(
    horizon: f64,
    m: usize,
    scheme: Scheme,
    body: impl Fn(f64, f64) -> f64,
    c: f64,
    linear_solve: impl Fn(DMatrix<f64>, DVector<f64>) -> DVector<f64>,
) -> f64 {
    let dx = horizon / m as f64;
    let n_in = (200.0 / dx).round() as usize + 1;
    let layer = m; // nodes per Dirichlet layer of width δ
    let positions: Vec<[f64; 1]> = (0..n_in + 2 * layer)
        .map(|i| [-100.0 - layer as f64 * dx + i as f64 * dx])
        .collect();
    // Unknowns strictly inside (−100, 100); the end nodes at ±100 carry u exactly too.
    let unknown: Vec<u32> = (layer as u32 + 1..(layer + n_in - 1) as u32).collect();
    let families = Families::build(&positions, horizon * (1.0 + 1e-9));
    let op: ScalarOperator = match scheme {
        Scheme::Standard | Scheme::StandardWithoutBeta => {
            let kernel = DiffusionKernel {
                diffusivity: c,
                exponent: 1.0,
                influence: Influence::Constant,
                horizon,
            };
            let quadrature = Quadrature {
                spacing: dx,
                horizon,
                volume_correction: matches!(scheme, Scheme::Standard),
            };
            let volumes = vec![dx; positions.len()];
            standard::diffusion_operator::<1>(&unknown, &volumes, &families, &quadrature, &kernel)
        }
        Scheme::Wls(order, k_aux) => {
            let basis = Basis::new(1, order);
            let l = wls::diffusion_l(&basis, c, 1.0, horizon, Influence::Constant);
            wls::diffusion_operator(&unknown, &positions, &families, &basis, &l, horizon, k_aux)
                .unwrap()
        }
    };
    let exact = |x: f64| (x / 10.0).sin();
    let index_of = |node: u32| unknown.binary_search(&node).ok();
    let n = unknown.len();
    let mut k = DMatrix::<f64>::zeros(n, n);
    let mut rhs = DVector::<f64>::zeros(n);
    for (r, &i) in op.rows.iter().enumerate() {
        rhs[r] = -body(positions[i as usize][0], horizon);
        for e in op.offsets[r]..op.offsets[r + 1] {
            let j = op.columns[e];
            match index_of(j) {
                Some(col) => k[(r, col)] += op.weights[e],
                None => rhs[r] -= op.weights[e] * exact(positions[j as usize][0]),
            }
        }
    }
    let u = linear_solve(k, rhs);
    let (mut num, mut den) = (0.0, 0.0);
    for (r, &i) in unknown.iter().enumerate() {
        let e = exact(positions[i as usize][0]);
        num += (u[r] - e).powi(2);
        den += e * e;
    }
    (num / den).sqrt()
}

/// m-convergence at δ = 6: body force (3.74) balances the PD operator on sin(x/10) exactly.
fn m_error(m: usize, scheme: Scheme) -> f64 {
    let horizon = 6.0;
    let c = 2.0 / (horizon * horizon);
    let b = 2.0 * c * one_minus_cos_integral(horizon / 10.0);
    solve(horizon, m, scheme, |x, _| b * (x / 10.0).sin(), c)
}

#[test]
fn body_force_constant_matches_the_note() {
    let c = 2.0 / 36.0;
    let b = 2.0 * c * one_minus_cos_integral(0.6);
    assert!((b - 0.00985).abs() < 0.00001, "{b}");
}

#[test]
fn m_convergence() {
    let ms = [6, 12, 24, 33];
    let mut table = Vec::new();
    for &m in &ms {
        let row: Vec<f64> = [Scheme::Standard, WLS2, WLS4, WLS6]
            .iter()
            .map(|&s| m_error(m, s))
            .collect();
        eprintln!(
            "m = {m:2}: standard {:.3e}  WLS-2 {:.3e}  WLS-4 {:.3e}  WLS-6 {:.3e}",
            row[0], row[1], row[2], row[3]
        );
        table.push(row);
    }
    // The standard scheme's error falls as m grows.
    for w in table.windows(2) {
        assert!(w[1][0] < w[0][0], "standard: {:?}", table);
    }
    for row in &table {
        assert!(row[2] * 10.0 <= row[1], "WLS-4 ≥ 10× WLS-2: {row:?}");
        assert!(row[3] * 1e3 <= row[1], "WLS-6 ≥ 10³× WLS-2: {row:?}");
    }
    // The WLS errors plateau: set by the basis order, not by m (within 3×: at m = 33 the
    // auxiliary points of WLS-2 fall half-way between nodes and the tie rule picks an
    // asymmetric set).
    for s in 1..4 {
        let (lo, hi) = table
            .iter()
            .map(|r| r[s])
            .fold((f64::INFINITY, 0.0f64), |(lo, hi), v| {
                (lo.min(v), hi.max(v))
            });
        assert!(hi < 3.0 * lo, "WLS column {s} should plateau: {table:?}");
    }
    // Not asserted (it does not hold here): the papers' "WLS-2 on a coarse grid beats the
    // standard scheme with 67 family nodes". WLS-2 is C², i.e. E u'' locally, and misses the
    // nonlocal terms c δ⁴ u⁗ / 48 + … of the PD solution (≈ 1 % at δ = 6), while the
    // standard scheme converges to the PD solution as m grows.
}

/// δ-convergence at m = 12 towards the local problem 0 = u'' + sin(x/10)/100: every WLS
/// error falls monotonically as δ shrinks.
#[test]
fn delta_convergence() {
    let m = 12;
    let deltas = [8.0, 4.0, 2.0, 1.0];
    let mut table = Vec::new();
    for &d in &deltas {
        let c = 2.0 / (d * d);
        let row: Vec<f64> = [Scheme::Standard, WLS2, WLS4, WLS6]
            .iter()
            .map(|&s| solve(d, m, s, |x, _| (x / 10.0).sin() / 100.0, c))
            .collect();
        eprintln!(
            "δ = {d}: standard {:.3e}  WLS-2 {:.3e}  WLS-4 {:.3e}  WLS-6 {:.3e}",
            row[0], row[1], row[2], row[3]
        );
        table.push(row);
    }
    for s in 1..4 {
        for w in table.windows(2) {
            assert!(w[1][s] < w[0][s], "WLS column {s}: {table:?}");
        }
    }
    // The standard scheme's behaviour at small δ needs more unknowns and a
    // banded solve: see `standard_scheme_under_delta_refinement`.
}

/// Under δ-refinement at m = 12 (δ = 1 … 0.25, up to 9 600 unknowns, banded solve) the
/// standard scheme WITH β converges at second order: in 1D at integer m, β(δ) = ½ makes the
/// discrete second moment Σ β_n n Δx² = δ²/2 exact, so the u'' coefficient is exact. WITHOUT β
/// the moment is m(m+1)/2 Δx² (1/m too large) and the error stalls: that scheme is not
/// asymptotically compatible. (The thesis reports non-convergence for its standard scheme.)
#[test]
fn standard_scheme_under_delta_refinement() {
    let m = 12;
    let errors = |scheme: Scheme| -> Vec<f64> {
        [1.0f64, 0.5, 0.25]
            .iter()
            .map(|&d| {
                let c = 2.0 / (d * d);
                let e = solve_with(
                    d,
                    m,
                    scheme,
                    |x, _| (x / 10.0).sin() / 100.0,
                    c,
                    |k, r| banded_solve(k, r, m),
                );
                eprintln!("δ = {d}: {scheme:?} {e:.3e}");
                e
            })
            .collect()
    };
    let with_beta = errors(Scheme::Standard);
    for w in with_beta.windows(2) {
        assert!(w[1] < w[0] / 3.0, "second order with β: {with_beta:?}");
    }
    let without_beta = errors(Scheme::StandardWithoutBeta);
    assert!(
        without_beta[2] > 0.5 * without_beta[0],
        "stalls without β: {without_beta:?}"
    );
    assert!(without_beta[2] > 100.0 * with_beta[2]);
}
