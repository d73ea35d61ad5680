//! Stable time steps of explicit integrators.
//!
//! (3.8) is a Gershgorin bound: with λ_max ≤ max_i 2 Σ_j ‖C_ij‖ β V_j / ρ, velocity-Verlet's
//! limit Δt < 2/√λ_max gives Δt ≥ √(2ρ / Σ_j ‖C_ij‖ β V_j) — guaranteed stable, but in 2D and
//! 3D a vector bond operator's λ_max is well below the Gershgorin value, so (3.8) is
//! conservative (by ≈ 1.5–1.8× in 2D, measured). [derived] The sharp limit 2/√λ_max is
//! estimated with a power iteration on the operator itself, which also serves operators that
//! are not symmetric (the WLS scheme, seed-thesis-ch2-3 §2.2).

use crate::discretization::grid::SplitMix64;

/// Power iterations for a stable-step estimate (the Rayleigh quotient settles well within them
/// on the presets' operators).
pub const POWER_ITERATIONS: usize = 60;

/// Largest eigenvalue of a linear operator on `n` vectors of `D` components that is
/// self-adjoint and positive semi-definite in the inner product weighted by `weights`
/// (node masses). Power iteration from a deterministic random start; returns the Rayleigh
/// quotient, a lower bound of λ_max that converges quickly in value.
pub fn max_eigenvalue<const D: usize>(
    n: usize,
    weights: &[f64],
    iterations: usize,
    mut apply: impl FnMut(&[[f64; D]], &mut [[f64; D]]),
) -> f64 {
    let mut rng = SplitMix64(0x5EED);
    let mut v: Vec<[f64; D]> = (0..n)
        .map(|_| std::array::from_fn(|_| rng.next_f64() - 0.5))
        .collect();
    let mut w = vec![[0.0; D]; n];
    let dot = |a: &[[f64; D]], b: &[[f64; D]]| -> f64 {
        a.iter()
            .zip(b)
            .zip(weights)
            .map(|((x, y), m)| m * (0..D).map(|k| x[k] * y[k]).sum::<f64>())
            .sum()
    };
    let mut lambda = 0.0;
    for _ in 0..iterations {
        let norm = dot(&v, &v).sqrt();
        if norm == 0.0 || !norm.is_finite() {
            break;
        }
        v.iter_mut().flatten().for_each(|x| *x /= norm);
        apply(&v, &mut w);
        lambda = dot(&v, &w);
        std::mem::swap(&mut v, &mut w);
    }
    lambda
}

/// Spectral radius of a general (possibly non-symmetric) operator on a scalar field, by power
/// iteration: the largest growth ‖A v‖/‖v‖ over the last quarter of the iterations (a
/// complex dominant pair makes the ratio oscillate).
pub fn spectral_radius(
    n: usize,
    iterations: usize,
    mut apply: impl FnMut(&[f64], &mut [f64]),
) -> f64 {
    let mut rng = SplitMix64(0xD1FF);
    let mut v: Vec<f64> = (0..n).map(|_| rng.next_f64() - 0.5).collect();
    let mut w = vec![0.0; n];
    let mut radius: f64 = 0.0;
    for it in 0..iterations {
        let norm = v.iter().map(|x| x * x).sum::<f64>().sqrt();
        if norm == 0.0 || !norm.is_finite() {
            break;
        }
        v.iter_mut().for_each(|x| *x /= norm);
        w.iter_mut().for_each(|x| *x = 0.0);
        apply(&v, &mut w);
        let growth = w.iter().map(|x| x * x).sum::<f64>().sqrt();
        if it >= iterations * 3 / 4 {
            radius = radius.max(growth);
        }
        std::mem::swap(&mut v, &mut w);
    }
    radius
}

/// The margin kept on an eigenvalue or spectral radius found by power iteration (which
/// approaches it from below).
pub const SPECTRAL_MARGIN: f64 = 1.02;

/// Velocity-Verlet's stable step from a power-iterated λ_max, with the margin.
pub fn verlet_step(lambda_max: f64) -> f64 {
    verlet_limit(lambda_max * SPECTRAL_MARGIN)
}

/// Forward Euler's stable step from a power-iterated spectral radius, with the margin.
pub fn euler_step(radius: f64) -> f64 {
    euler_limit(radius * SPECTRAL_MARGIN)
}

/// Forward Euler's limit 2/ρ for an operator whose eigenvalues are real and ≤ 0 with
/// spectral radius ρ (diffusion).
pub fn euler_limit(radius: f64) -> f64 {
    if radius > 0.0 {
        2.0 / radius
    } else {
        f64::INFINITY
    }
}

/// Velocity-Verlet's stability limit 2/√λ_max for the largest eigenvalue λ_max of the
/// mass-normalized stiffness.
pub fn verlet_limit(lambda_max: f64) -> f64 {
    if lambda_max > 0.0 {
        2.0 / lambda_max.sqrt()
    } else {
        f64::INFINITY
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A 1D chain of unit masses and springs k: λ_max → 4k (alternating mode).
    #[test]
    fn spring_chain_spectral_radius() {
        let n = 200;
        let k = 3.0;
        let lambda = max_eigenvalue::<1>(n, &vec![1.0; n], 400, |u, out| {
            for i in 0..n {
                let left = if i > 0 { u[i][0] - u[i - 1][0] } else { 0.0 };
                let right = if i + 1 < n {
                    u[i][0] - u[i + 1][0]
                } else {
                    0.0
                };
                out[i][0] = k * (left + right);
            }
        });
        assert!((lambda / (4.0 * k) - 1.0).abs() < 2e-3, "{lambda}");
        assert!(lambda <= 4.0 * k);
    }
}
