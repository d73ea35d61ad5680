//! WLS elasticity operators (seed-004 §2.3, §2.5): the assembled bond-based operator equals
//! Navier's on quadratic fields (2D, ν = 1/3 plane stress), and the linearized LPS operator
//! (two passes: nodal dilatation, then I + J) gives G∇²u + (K + G/3)∇θ (3D).

use nalgebra::DVector;

use peridyn::discretization::Families;
use peridyn::discretization::grid::{Lattice, SplitMix64};
use peridyn::model::pmb::micromodulus;
use peridyn::model::pmb::{Influence, Plane};
use peridyn::scene::Solid;
use peridyn::scheme::wls::{self, Basis};

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
            let q = wls::fit_matrix(j as usize, &cs, &lat.positions, &basis, m).unwrap();
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
    let q = wls::fit_matrix(centre as usize, &set, &lat.positions, &basis, m).unwrap();
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
