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
            let target: [f64; D] = std::array::from_fn(|a| positions[i][a] + index[a] as f64 * h);
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
        let (sets, translated) =
            collocation_sets_counted(&rows, &lattice.positions, &families, horizon, k_aux.into());
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
