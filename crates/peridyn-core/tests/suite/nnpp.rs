//! The nonlocal Nernst–Planck–Poisson operators against their local limits (issue 18's Taylor
//! check; thesis (2.63)–(2.64), (2.69)–(2.76), seed-thesis-ch2-3 §1.7 with its erratum on
//! K2): on smooth fields whose wavelengths are long against δ, the horizon integrals of
//! `model::nernst_planck`'s bond law reproduce D ∇²C + D (zF/RT)(C ∇²φ + ∇C·∇φ) and −σ ∇²φ
//! to 1e-3 relative in 1D, 2D and 3D. The difference is O((kδ)²): kδ = 0.03 puts it near
//! 1e-4 (measured 1.6e-5 – 6.6e-5); with the thesis's printed (2.77), K2 = K1, the 1D
//! Nernst–Planck difference is 0.80. The integrals are taken here by Gauss–Legendre in r and a symmetric rule over the
//! directions, independent of the meshfree discretization.

use peridyn_core::model::nernst_planck::{
    NnppKernel, Species, poisson_bond_term, species_bond_rate,
};
use peridyn_core::model::pmb::Influence;

/// Gauss–Legendre nodes and weights on (−1, 1) (Newton on P_n).
fn gauss_legendre(n: usize) -> Vec<(f64, f64)> {
    (0..n)
        .map(|i| {
            let mut x = (std::f64::consts::PI * (i as f64 + 0.75) / (n as f64 + 0.5)).cos();
            loop {
                let (mut p0, mut p1) = (1.0, x);
                for k in 2..=n {
                    let p2 = ((2 * k - 1) as f64 * x * p1 - (k - 1) as f64 * p0) / k as f64;
                    (p0, p1) = (p1, p2);
                }
                let dp = n as f64 * (x * p1 - p0) / (x * x - 1.0);
                let dx = p1 / dp;
                x -= dx;
                if dx.abs() < 1e-15 {
                    let w = 2.0 / ((1.0 - x * x) * dp * dp);
                    return (x, w);
                }
            }
        })
        .collect()
}

/// Directions ê with weights summing to the unit sphere's area (symmetric: −ê is a node too).
fn directions(dim: usize) -> Vec<([f64; 3], f64)> {
    let pi = std::f64::consts::PI;
    match dim {
        1 => vec![([1.0, 0.0, 0.0], 1.0), ([-1.0, 0.0, 0.0], 1.0)],
        2 => {
            let n = 64;
            (0..n)
                .map(|i| {
                    let t = 2.0 * pi * (i as f64 + 0.5) / n as f64;
                    ([t.cos(), t.sin(), 0.0], 2.0 * pi / n as f64)
                })
                .collect()
        }
        _ => {
            let n = 48;
            gauss_legendre(24)
                .into_iter()
                .flat_map(|(z, wz)| {
                    let s = (1.0 - z * z).sqrt();
                    (0..n).map(move |i| {
                        let t = 2.0 * pi * (i as f64 + 0.5) / n as f64;
                        ([s * t.cos(), s * t.sin(), z], wz * 2.0 * pi / n as f64)
                    })
                })
                .collect()
        }
    }
}

/// ∫_H f(r, ê) dV over the horizon δ in `dim` dimensions.
fn horizon_integral(dim: usize, delta: f64, f: impl Fn(f64, [f64; 3]) -> f64) -> f64 {
    let radial = gauss_legendre(40);
    let dirs = directions(dim);
    let mut sum = 0.0;
    for &(t, wt) in &radial {
        let r = 0.5 * delta * (t + 1.0);
        let jacobian = 0.5 * delta * wt * r.powi(dim as i32 - 1);
        for &(e, we) in &dirs {
            sum += jacobian * we * f(r, e);
        }
    }
    sum
}

fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

fn add(x: [f64; 3], r: f64, e: [f64; 3]) -> [f64; 3] {
    [x[0] + r * e[0], x[1] + r * e[1], x[2] + r * e[2]]
}

#[test]
fn nonlocal_nernst_planck_and_poisson_reproduce_their_local_limits() {
    let delta = 0.45e-3;
    let species = Species {
        diffusivity: 7.98e-10,
        valence: 2.0,
        temperature: 298.15,
    };
    let sigma = 3.0;
    for dim in 1..=3 {
        for influence in [Influence::Constant, Influence::Linear] {
            // Different exponents per operator, all q ≤ 0 (smooth radial integrands).
            let kernel = NnppKernel::new(dim, influence, delta, [0.0, -0.5, -0.25]).unwrap();
            let k = kernel.constants();
            // C = 1 + a sin(kc·x + p), φ = b cos(kp·x), |kc| δ = |kp| δ = 0.03.
            let unit = |v: [f64; 3]| {
                let v: Vec<f64> = v.iter().take(dim).copied().collect();
                let n = v.iter().map(|c| c * c).sum::<f64>().sqrt();
                let mut out = [0.0; 3];
                for (o, c) in out.iter_mut().zip(&v) {
                    *o = 0.03 / delta * c / n;
                }
                out
            };
            let (kc, kp) = (unit([1.0, 0.6, -0.3]), unit([-0.4, 1.0, 0.7]));
            let (a, p, b) = (0.3, 0.4, 0.02);
            let c = |x: [f64; 3]| 1.0 + a * (dot(kc, x) + p).sin();
            let phi = |x: [f64; 3]| b * dot(kp, x).cos();
            let zf = species.mobility_factor();
            let (mut worst_np, mut worst_poisson) = (0.0f64, 0.0f64);
            for point in 0..5 {
                let s = point as f64 * 7.3 * delta;
                let x = [s, -0.5 * s, 0.25 * s];
                let nonlocal_np = horizon_integral(dim, delta, |r, e| {
                    let y = add(x, r, e);
                    species_bond_rate(&kernel, &k, &species, r, [c(x), c(y)], [phi(x), phi(y)])
                });
                let arg = dot(kc, x) + p;
                let grad_c = kc.map(|v| a * v * arg.cos());
                let lap_c = -a * dot(kc, kc) * arg.sin();
                let grad_phi = kp.map(|v| -b * v * dot(kp, x).sin());
                let lap_phi = -b * dot(kp, kp) * dot(kp, x).cos();
                let local_np =
                    species.diffusivity * (lap_c + zf * (c(x) * lap_phi + dot(grad_c, grad_phi)));
                let scale_np =
                    species.diffusivity * (a * dot(kc, kc) + zf * (1.0 + a) * b * dot(kp, kp));
                worst_np = worst_np.max((nonlocal_np - local_np).abs() / scale_np);
                let nonlocal_poisson = horizon_integral(dim, delta, |r, e| {
                    poisson_bond_term(&kernel, &k, sigma, r, [phi(x), phi(add(x, r, e))])
                });
                let local_poisson = -sigma * lap_phi;
                let scale_poisson = sigma * b * dot(kp, kp);
                worst_poisson =
                    worst_poisson.max((nonlocal_poisson - local_poisson).abs() / scale_poisson);
            }
            eprintln!(
                "{dim}D {influence:?}: largest relative difference from the local operator: \
                 Nernst–Planck {worst_np:.2e}, Poisson {worst_poisson:.2e}"
            );
            assert!(worst_np < 1e-3, "{dim}D {influence:?}: {worst_np:e}");
            assert!(
                worst_poisson < 1e-3,
                "{dim}D {influence:?}: {worst_poisson:e}"
            );
        }
    }
}

/// Per bond the species rate is antisymmetric in its ends (the (C' + C) form of the
/// electromigration term): swapping the ends flips its sign exactly, so any symmetric sum
/// conserves Σ C V.
#[test]
fn the_species_bond_rate_is_antisymmetric() {
    let kernel = NnppKernel::new(2, Influence::Linear, 1e-3, [0.0, 0.5, 0.0]).unwrap();
    let k = kernel.constants();
    let s = Species {
        diffusivity: 1e-9,
        valence: -1.0,
        temperature: 300.0,
    };
    for (c, phi) in [([0.2, 1.3], [0.01, -0.03]), ([5.0, 0.0], [0.0, 0.2])] {
        let forward = species_bond_rate(&kernel, &k, &s, 4e-4, c, phi);
        let backward = species_bond_rate(&kernel, &k, &s, 4e-4, [c[1], c[0]], [phi[1], phi[0]]);
        assert_eq!(forward, -backward);
        assert!(forward != 0.0);
    }
}
