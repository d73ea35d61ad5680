//! WLS elasticity operators (seed-004 §2.3, §2.5): the assembled bond-based operator equals
//! Navier's on quadratic fields (2D, ν = 1/3 plane stress), and the linearized LPS operator
//! (two passes: nodal dilatation, then I + J) gives G∇²u + (K + G/3)∇θ (3D).

use nalgebra::DVector;

use peridyn_core::discretization::Families;
use peridyn_core::discretization::grid::{Lattice, SplitMix64};
use peridyn_core::model::pmb::micromodulus;
use peridyn_core::model::pmb::{Influence, Plane};
use peridyn_core::scene::Solid;
use peridyn_core::scheme::wls::{self, Basis};

/// A random quadratic vector field: coefficients [component][monomial of 1, x, y, z, x², …].
struct Quadratic<const D: usize> {
    c: [[f64; 10]; D],
}

impl<const D: usize> Quadratic<D> {
    fn random(seed: u64) -> Self {
        let mut rng = SplitMix64(seed);
        Quadratic {
            c: std::array::from_fn(|_| std::array::from_fn(|_| rng.next_f64() - 0.5)),
        }
    }
    /// Second derivatives H[k][a][b] of component k (monomials x_a x_b, a ≤ b, in order).
    #[allow(clippy::needless_range_loop)]
    fn hessian(&self) -> [[[f64; 3]; 3]; D] {
        std::array::from_fn(|k| {
            let mut h = [[0.0; 3]; 3];
            let mut m = 1 + D;
            for a in 0..D {
                for b in a..D {
                    let v = self.c[k][m] * if a == b { 2.0 } else { 1.0 };
                    h[a][b] = v;
                    h[b][a] = v;
                    m += 1;
                }
            }
            h
        })
    }
    fn eval(&self, x: &[f64; D]) -> [f64; D] {
        std::array::from_fn(|k| {
            let c = &self.c[k];
            let mut v = c[0];
            for a in 0..D {
                v += c[1 + a] * x[a];
            }
            let mut m = 1 + D;
            for a in 0..D {
                for b in a..D {
                    v += c[m] * x[a] * x[b];
                    m += 1;
                }
            }
            v
        })
    }
    /// ∇·u at x.
    fn divergence(&self, x: &[f64; D]) -> f64 {
        let h = self.hessian();
        (0..D)
            .map(|k| self.c[k][1 + k] + (0..D).map(|b| h[k][k][b] * x[b]).sum::<f64>())
            .sum()
    }
    /// μ ∇²u + (λ + μ) ∇(∇·u) (constant for a quadratic field).
    fn navier(&self, mu: f64, lambda_plus_mu: f64) -> [f64; D] {
        let h = self.hessian();
        std::array::from_fn(|k| {
            let laplacian: f64 = (0..D).map(|a| h[k][a][a]).sum();
            let grad_div: f64 = (0..D).map(|l| h[l][l][k]).sum();
            mu * laplacian + lambda_plus_mu * grad_div
        })
    }
}

fn lattice<const D: usize>(side: f64, perturbation: f64) -> Lattice<D> {
    let solid = Solid::Box {
        min: vec![0.0; D],
        max: vec![side; D],
    };
    Lattice::<D>::build(&solid, 1.0, [-perturbation, perturbation], 5)
}

fn interior<const D: usize>(l: &Lattice<D>, side: f64, margin: f64) -> Vec<u32> {
    (0..l.len() as u32)
        .filter(|&i| {
            l.positions[i as usize]
                .iter()
                .all(|&x| x > margin && x < side - margin)
        })
        .collect()
}

#[test]
fn bond_based_2d_operator_is_navier_on_quadratic_fields() {
    let (m, side) = (4.0, 24.0);
    let lat = lattice::<2>(side, 0.25);
    let families = Families::build(&lat.positions, m * (1.0 + 1e-9));
    let rows = interior(&lat, side, m + 1.0);
    let basis = Basis::new(2, 2);
    let (youngs, nu) = (2.0, 1.0 / 3.0);
    let c = micromodulus(youngs, m, 2, Plane::Stress, Influence::Constant);
    let l = wls::bond_l(&basis, c, m, Influence::Constant);
    let op = wls::elasticity_operator(&rows, &lat.positions, &families, &basis, &l, m, 3).unwrap();
    // 29 collocation nodes (δ/3 auxiliary grid).
    assert_eq!(op.offsets[1] - op.offsets[0], 29);
    let field = Quadratic::<2>::random(3);
    let u: Vec<[f64; 2]> = lat.positions.iter().map(|x| field.eval(x)).collect();
    let mut out = vec![[0.0; 2]; rows.len()];
    op.apply_rows(&u, &mut out);
    let mu = youngs / (2.0 * (1.0 + nu));
    let lambda = youngs * nu / (1.0 - nu * nu);
    let expected = field.navier(mu, lambda + mu);
    for (r, f) in out.iter().enumerate() {
        for k in 0..2 {
            assert!(
                (f[k] - expected[k]).abs() < 1e-9,
                "row {r}: {f:?} vs {expected:?}"
            );
        }
    }
    // Rigid translation gives no force.
    let shifted: Vec<[f64; 2]> = u.iter().map(|v| [v[0] + 3.0, v[1] - 1.0]).collect();
    let mut out2 = vec![[0.0; 2]; rows.len()];
    op.apply_rows(&shifted, &mut out2);
    for (a, b) in out.iter().zip(&out2) {
        assert!((a[0] - b[0]).abs() < 1e-9 && (a[1] - b[1]).abs() < 1e-9);
    }
}

#[test]
fn lps_3d_operator_gives_the_navier_operator() {
    let (m, side) = (4.0, 20.0);
    let lat = lattice::<3>(side, 0.2);
    let families = Families::build(&lat.positions, m * (1.0 + 1e-9));
    let basis = Basis::new(3, 2);
    let (bulk, shear) = (2.0, 1.3);
    let influence = Influence::Constant;
    let centre = (0..lat.len())
        .min_by(|&a, &b| {
            let d = |i: usize| {
                lat.positions[i]
                    .iter()
                    .map(|x| (x - side / 2.0).powi(2))
                    .sum::<f64>()
            };
            d(a).total_cmp(&d(b))
        })
        .unwrap() as u32;
    let field = Quadratic::<3>::random(11);
    let u: Vec<[f64; 3]> = lat.positions.iter().map(|x| field.eval(x)).collect();

    // Pass 1: nodal dilatations θ_j = L_θ Q̄_j Ū_j at the centre's collocation nodes.
    let k_aux = 3;
    let set = wls::collocation_set(centre as usize, &lat.positions, &families, m, k_aux);
    let l_theta = wls::lps_dilatation_l(&basis, m, influence);
    let theta: Vec<f64> = set
        .iter()
        .map(|&j| {
            let cs = wls::collocation_set(j as usize, &lat.positions, &families, m, k_aux);
            let q = wls::fit_matrix(
                j as usize,
                &cs,
                &lat.positions,
                &basis,
                m,
                wls::PAPERS_WEIGHT_EXPONENT,
            )
            .unwrap();
            (0..3)
                .map(|l| {
                    let values =
                        DVector::from_iterator(cs.len(), cs.iter().map(|&n| u[n as usize][l]));
                    (wls::scale_to_fit(&basis, &l_theta[l], m).transpose() * &q * values)[(0, 0)]
                })
                .sum()
        })
        .collect();
    for (&j, t) in set.iter().zip(&theta) {
        let exact = field.divergence(&lat.positions[j as usize]);
        assert!((t - exact).abs() < 1e-9, "θ at {j}: {t} vs {exact}");
    }

    // Pass 2: J from the shear operator, I from the fitted dilatations.
    let l_shear = wls::lps_shear_l(&basis, shear, m, influence);
    let op = wls::elasticity_operator(
        &[centre],
        &lat.positions,
        &families,
        &basis,
        &l_shear,
        m,
        k_aux,
    )
    .unwrap();
    assert_eq!(op.columns.len(), 123, "123 collocation nodes (δ/3) in 3D");
    let mut j_force = [[0.0; 3]];
    op.apply_rows(&u, &mut j_force);
    let q = wls::fit_matrix(
        centre as usize,
        &set,
        &lat.positions,
        &basis,
        m,
        wls::PAPERS_WEIGHT_EXPONENT,
    )
    .unwrap();
    let l_i = wls::lps_dilatation_force_l(&basis, bulk, shear, m, influence);
    let theta = DVector::from_vec(theta);
    let force: Vec<f64> = (0..3)
        .map(|k| {
            j_force[0][k]
                + (wls::scale_to_fit(&basis, &l_i[k], m).transpose() * &q * &theta)[(0, 0)]
        })
        .collect();
    let expected = field.navier(shear, bulk + shear / 3.0);
    for k in 0..3 {
        assert!(
            (force[k] - expected[k]).abs() < 1e-8,
            "{force:?} vs {expected:?}"
        );
    }
}

/// Issue 14: a collocation stencil whose offsets are all multiples of 2Δx (the papers' rule
/// "auxiliary points on lattice nodes" at δ/2 and m = 4) sees only its own sub-lattice, so a
/// displacement alternating node by node, u = e cos(k·x) with k = (π/Δx, 0), gives no force at
/// all: a zero-energy mode that the hybrid's Ω_w then carries unchecked (measured: spurious far-
/// edge cracks on Kalthoff–Winkler). The orbit stencils couple every sub-lattice: at every
/// lattice wave number with |k| ≥ π/(2Δx) sampled here their restoring force stays above a
/// fifth of the bond-based PD operator's (the independent reference: Σ_j c ξ⊗ξ/|ξ|³
/// (1 − cos k·ξ) V_j over the family, evaluated directly).
#[test]
fn wide_stencils_keep_every_sub_lattice_coupled() {
    let horizon_cells = |m: usize| m as f64;
    let cases: [(usize, wls::Collocation, f64); 4] = [
        (4, wls::Collocation::grid(2), 0.0),
        (
            4,
            wls::Collocation::orbits(1.0, &[[1, 1], [2, 1], [3, 0]], 6.0).unwrap(),
            0.2,
        ),
        (
            8,
            wls::Collocation::orbits(1.0, &[[3, 3], [4, 1], [4, 2]], 6.0).unwrap(),
            0.2,
        ),
        (8, wls::Collocation::grid(2), 0.0),
    ];
    for (m, rule, floor) in cases {
        let n = 4 * m + 2;
        let solid = Solid::Box {
            min: vec![0.0; 2],
            max: vec![n as f64; 2],
        };
        let lat = Lattice::<2>::build(&solid, 1.0, [0.0, 0.0], 1);
        let horizon = horizon_cells(m);
        let families = Families::build(&lat.positions, horizon * (1.0 + 1e-9));
        let centre = (0..lat.len())
            .min_by(|&a, &b| {
                let d = |i: usize| {
                    (lat.positions[i][0] - n as f64 / 2.0).powi(2)
                        + (lat.positions[i][1] - n as f64 / 2.0).powi(2)
                };
                d(a).total_cmp(&d(b))
            })
            .unwrap();
        let basis = Basis::new(2, 2);
        let cm = micromodulus(1.0, horizon, 2, Plane::Strain, Influence::Constant);
        let l = wls::bond_l(&basis, cm, horizon, Influence::Constant);
        let op = wls::elasticity_operator(
            &[centre as u32],
            &lat.positions,
            &families,
            &basis,
            &l,
            horizon,
            rule,
        )
        .unwrap();
        let xc = lat.positions[centre];
        let pi = std::f64::consts::PI;
        let mut least = f64::INFINITY;
        for k in [
            [pi, 0.0],
            [0.0, pi],
            [pi, pi],
            [pi / 2.0, 0.0],
            [pi / 2.0, pi / 2.0],
            [pi, pi / 2.0],
            [3.0 * pi / 4.0, pi / 4.0],
        ] {
            for e in [[1.0, 0.0], [0.0, 1.0]] {
                let phase = |x: &[f64; 2]| (k[0] * (x[0] - xc[0]) + k[1] * (x[1] - xc[1])).cos();
                let f = op.apply_row_with(0, |j| {
                    let c = phase(&lat.positions[j]);
                    [e[0] * c, e[1] * c]
                });
                let wls_restoring = -(f[0] * e[0] + f[1] * e[1]);
                // The PD operator's restoring force for the same mode at the same node.
                let pd: f64 = families
                    .range(centre)
                    .map(|b| {
                        let j = families.neighbors[b] as usize;
                        let xi = [lat.positions[j][0] - xc[0], lat.positions[j][1] - xc[1]];
                        let r = (xi[0] * xi[0] + xi[1] * xi[1]).sqrt();
                        let proj = xi[0] * e[0] + xi[1] * e[1];
                        cm * proj * proj / r.powi(3) * (1.0 - phase(&lat.positions[j]))
                    })
                    .sum();
                assert!(pd > 0.0);
                least = least.min(wls_restoring / pd);
            }
        }
        if floor == 0.0 {
            assert!(
                least.abs() < 1e-9,
                "m = {m}, {rule:?}: the δ/2 grid should decouple sub-lattices (least ratio {least:e})"
            );
        } else {
            assert!(
                least >= floor,
                "m = {m}, {rule:?}: least restoring ratio {least:.3} below {floor}"
            );
        }
        eprintln!("m = {m}, {rule:?}: least WLS/PD restoring ratio {least:.3}");
    }
}
