//! Patch tests of the standard bond-based operator: rigid motions give no force, a homogeneous
//! strain gives no net force on bulk nodes and the classical strain-energy density.

use crate::common;

use peridyn_core::model::pmb::Plane;
use peridyn_core::model::pmb::poisson_ratio;
use peridyn_core::sim::DynamicSimulation;

/// Index of the node nearest the centre of the block.
fn centre<const D: usize>(sim: &DynamicSimulation<D>) -> usize {
    let n = sim.reference().len();
    let mut c = [0.0; D];
    for p in sim.reference() {
        for k in 0..D {
            c[k] += p[k] / n as f64;
        }
    }
    (0..n)
        .min_by(|&a, &b| {
            let d = |i: usize| {
                (0..D)
                    .map(|k| (sim.reference()[i][k] - c[k]).powi(2))
                    .sum::<f64>()
            };
            d(a).total_cmp(&d(b))
        })
        .unwrap()
}

/// Nodes at least `margin` away from every face.
fn bulk<const D: usize>(sim: &DynamicSimulation<D>, margin: f64) -> Vec<usize> {
    let (lo, hi) = sim.scene.solid.bounds();
    (0..sim.reference().len())
        .filter(|&i| {
            (0..D).all(|k| {
                let x = sim.reference()[i][k];
                x >= lo[k] + margin && x <= hi[k] - margin
            })
        })
        .collect()
}

fn deform<const D: usize>(sim: &mut DynamicSimulation<D>, map: impl Fn([f64; D]) -> [f64; D]) {
    let mapped: Vec<[f64; D]> = sim.reference().iter().map(|&x| map(x)).collect();
    sim.positions_mut().copy_from_slice(&mapped);
    sim.refresh_forces();
}

fn max_force<const D: usize>(
    sim: &DynamicSimulation<D>,
    nodes: impl Iterator<Item = usize>,
) -> f64 {
    nodes
        .map(|i| {
            sim.force_density()[i]
                .iter()
                .map(|f| f * f)
                .sum::<f64>()
                .sqrt()
        })
        .fold(0.0, f64::max)
}

/// Classical energy density ½ λ tr(ε)² + μ ε:ε with the Poisson ratio bond-based PD implies.
fn classical_energy<const D: usize>(e: f64, nu: f64, plane: Plane, eps: [[f64; D]; D]) -> f64 {
    let mu = e / (2.0 * (1.0 + nu));
    let lambda = if D == 2 && plane == Plane::Stress {
        e * nu / (1.0 - nu * nu)
    } else {
        e * nu / ((1.0 + nu) * (1.0 - 2.0 * nu))
    };
    let tr: f64 = (0..D).map(|k| eps[k][k]).sum();
    let ee: f64 = (0..D)
        .flat_map(|a| (0..D).map(move |b| (a, b)))
        .map(|(a, b)| eps[a][b] * eps[a][b])
        .sum();
    0.5 * lambda * tr * tr + mu * ee
}

/// The β quadrature (3.2) over the whole band δ ± Δx/2 (family radius δ + Δx/2). With the
/// thesis's family radius δ the band beyond δ is lost and W is 7–14 % low at m = 4–8.
fn homogeneous_strain_case<const D: usize>(
    plane: &str,
    m: f64,
    n: usize,
    eps: [[f64; D]; D],
) -> (f64, f64, f64) {
    let scene = common::block(
        D,
        n,
        m,
        plane,
        "family_radius = \"horizon-plus-half-spacing\"",
    );
    let mut sim = DynamicSimulation::<D>::new(&scene).unwrap();
    deform(&mut sim, |x| {
        let mut y = x;
        for a in 0..D {
            for b in 0..D {
                y[a] += eps[a][b] * x[b];
            }
        }
        y
    });
    let margin = scene.horizon + 0.5e-3 * 1.01;
    let inner = bulk(&sim, margin);
    assert!(!inner.is_empty());
    let boundary_force = max_force(&sim, 0..sim.reference().len());
    let bulk_force = max_force(&sim, inner.iter().copied());
    let c = centre(&sim);
    let pd = sim.energy_density(c);
    let plane = sim.scene.material.as_ref().unwrap().constants.plane;
    let classical = classical_energy::<D>(1e9, poisson_ratio(D, plane), plane, eps);
    (bulk_force / boundary_force, pd, classical)
}

#[test]
fn homogeneous_strain_2d_plane_stress() {
    let eps = [[1.0e-4, 0.3e-4], [0.3e-4, -0.5e-4]];
    let (ratio, pd, classical) = homogeneous_strain_case::<2>("stress", 8.0, 40, eps);
    assert!(ratio < 1e-10, "bulk force / boundary force = {ratio:e}");
    let err = (pd / classical - 1.0).abs();
    assert!(
        err < 0.01,
        "plane stress: W_pd = {pd:e}, W = {classical:e}, rel. error {err:e}"
    );
}

#[test]
fn homogeneous_strain_2d_plane_strain() {
    let eps = [[0.7e-4, -0.2e-4], [-0.2e-4, 1.2e-4]];
    let (ratio, pd, classical) = homogeneous_strain_case::<2>("strain", 8.0, 40, eps);
    assert!(ratio < 1e-10, "bulk force / boundary force = {ratio:e}");
    let err = (pd / classical - 1.0).abs();
    assert!(
        err < 0.01,
        "plane strain: W_pd = {pd:e}, W = {classical:e}, rel. error {err:e}"
    );
}

#[test]
fn homogeneous_strain_3d() {
    let eps = [
        [1.0e-4, 0.2e-4, 0.0],
        [0.2e-4, -0.3e-4, 0.1e-4],
        [0.0, 0.1e-4, 0.5e-4],
    ];
    let (ratio, pd, classical) = homogeneous_strain_case::<3>("strain", 8.0, 18, eps);
    assert!(ratio < 1e-10, "bulk force / boundary force = {ratio:e}");
    let err = (pd / classical - 1.0).abs();
    assert!(
        err < 0.01,
        "3D: W_pd = {pd:e}, W = {classical:e}, rel. error {err:e}"
    );
}

#[test]
fn rigid_motions_give_no_force() {
    let scene = common::block(2, 20, 4.0, "strain", "");
    let mut sim = DynamicSimulation::<2>::new(&scene).unwrap();
    // Reference force scale: a 1e-4 uniaxial stretch.
    deform(&mut sim, |x| [x[0] * (1.0 + 1e-4), x[1]]);
    let scale = max_force(&sim, 0..sim.reference().len());
    let (s, c) = 0.4f64.sin_cos();
    deform(&mut sim, |x| {
        [c * x[0] - s * x[1] + 0.3, s * x[0] + c * x[1] - 0.2]
    });
    let rigid = max_force(&sim, 0..sim.reference().len());
    assert!(
        rigid < 1e-7 * scale,
        "rigid motion force {rigid:e} vs stretch force {scale:e}"
    );
    assert!(sim.strain_energy().abs() < 1e-20, "{}", sim.strain_energy());

    let scene = common::block(3, 8, 3.0, "strain", "");
    let mut sim = DynamicSimulation::<3>::new(&scene).unwrap();
    deform(&mut sim, |x| [x[0] * (1.0 + 1e-4), x[1], x[2]]);
    let scale = max_force(&sim, 0..sim.reference().len());
    // Rotation about the axis (1, 1, 1)/√3 by 0.5 rad, plus a translation.
    let (s, c) = 0.5f64.sin_cos();
    let k = [1.0 / 3f64.sqrt(); 3];
    deform(&mut sim, |x| {
        let kx = [
            k[1] * x[2] - k[2] * x[1],
            k[2] * x[0] - k[0] * x[2],
            k[0] * x[1] - k[1] * x[0],
        ];
        let kd: f64 = (0..3).map(|i| k[i] * x[i]).sum();
        let mut y = [0.0; 3];
        for i in 0..3 {
            y[i] = x[i] * c + kx[i] * s + k[i] * kd * (1.0 - c) + 0.01;
        }
        y
    });
    let rigid = max_force(&sim, 0..sim.reference().len());
    assert!(
        rigid < 1e-7 * scale,
        "3D rigid motion force {rigid:e} vs {scale:e}"
    );
}
