//! Stable time steps of explicit integrators.
//!
//! (3.8) is a Gershgorin bound: with λ_max ≤ max_i 2 Σ_j ‖C_ij‖ β V_j / ρ, velocity-Verlet's
//! limit Δt < 2/√λ_max gives Δt ≥ √(2ρ / Σ_j ‖C_ij‖ β V_j) — guaranteed stable, but in 2D and
//! 3D a vector bond operator's λ_max is well below the Gershgorin value, so (3.8) is
//! conservative (by ≈ 1.5–1.8× in 2D, measured). [derived] The sharp limit 2/√λ_max is
//! estimated with a power iteration on the operator itself, which also serves operators that
//! are not symmetric (the WLS scheme, seed-thesis-ch2-3 §2.2).

use rayon::prelude::*;

use crate::discretization::grid::SplitMix64;

/// The most operator applications a stable-step estimate of a symmetric operator makes
/// (Lanczos, `max_eigenvalue`; it usually stops well before).
pub const POWER_ITERATIONS: usize = 60;

/// Lanczos stops once its largest Ritz value has grown by less than this (relative) over
/// `SETTLED_OVER` iterations. On the Kalthoff–Winkler `medium` lattice (a slowly converging,
/// clustered top) it stops after 26 applications 0.2 % below the value reached at 55 (1e-4),
/// where 60 power iterations were 0.9 % below it; `SPECTRAL_MARGIN` covers either.
const SETTLED_TOLERANCE: f64 = 1e-3;
const SETTLED_OVER: usize = 4;

/// Largest eigenvalue of a linear operator on `n` vectors of `D` components that is
/// self-adjoint and positive semi-definite in the inner product weighted by `weights`
/// (node masses), by Lanczos iteration from a deterministic random start (Golub & Van Loan,
/// Matrix Computations, §10.1): the largest Ritz value of the tridiagonal T_j grows
/// monotonically to λ_max from below, much faster than power iteration's Rayleigh quotient
/// (an eigenvalue cluster at the top of the spectrum, as a lattice's, slows the latter most).
/// No reorthogonalization: only the largest Ritz value is used, which loss of orthogonality
/// does not spoil (it brings copies of converged values, not wrong ones). Stops when that
/// value has settled (`SETTLED_TOLERANCE`), on an invariant subspace, or after `iterations`
/// applications; returns a lower bound of λ_max (the caller keeps `SPECTRAL_MARGIN`).
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
    let mut previous = vec![[0.0; D]; n];
    let mut w = vec![[0.0; D]; n];
    let dot = |a: &[[f64; D]], b: &[[f64; D]]| -> f64 {
        a.iter()
            .zip(b)
            .zip(weights)
            .map(|((x, y), m)| m * (0..D).map(|k| x[k] * y[k]).sum::<f64>())
            .sum()
    };
    let norm = dot(&v, &v).sqrt();
    if norm == 0.0 || !norm.is_finite() {
        return 0.0;
    }
    v.iter_mut().flatten().for_each(|x| *x /= norm);
    let (mut alphas, mut betas) = (Vec::new(), Vec::new());
    let mut ritz: Vec<f64> = Vec::new();
    let mut beta_previous = 0.0;
    for _ in 0..iterations {
        apply(&v, &mut w);
        let alpha = dot(&v, &w);
        for ((w, v), p) in w.iter_mut().zip(&v).zip(&previous) {
            for k in 0..D {
                w[k] -= alpha * v[k] + beta_previous * p[k];
            }
        }
        let beta = dot(&w, &w).sqrt();
        alphas.push(alpha);
        let theta = largest_tridiagonal_eigenvalue(&alphas, &betas);
        ritz.push(theta);
        let settled = ritz.len() > SETTLED_OVER
            && theta - ritz[ritz.len() - 1 - SETTLED_OVER] <= SETTLED_TOLERANCE * theta.abs();
        if settled || !beta.is_finite() || beta <= 1e-12 * theta.abs() {
            break;
        }
        betas.push(beta);
        std::mem::swap(&mut previous, &mut v);
        for (v, w) in v.iter_mut().zip(&w) {
            for k in 0..D {
                v[k] = w[k] / beta;
            }
        }
        beta_previous = beta;
    }
    ritz.last().copied().unwrap_or(0.0)
}

/// The largest eigenvalue of the symmetric tridiagonal matrix with diagonal `alphas` and
/// off-diagonal `betas` (one shorter), by bisection on the Sturm count (the number of
/// eigenvalues below a shift is the number of negative pivots of T − σ I).
fn largest_tridiagonal_eigenvalue(alphas: &[f64], betas: &[f64]) -> f64 {
    let m = alphas.len();
    // Gershgorin interval.
    let radius = |i: usize| {
        (if i > 0 { betas[i - 1].abs() } else { 0.0 })
            + (if i + 1 < m { betas[i].abs() } else { 0.0 })
    };
    let mut low = (0..m)
        .map(|i| alphas[i] - radius(i))
        .fold(f64::INFINITY, f64::min);
    let mut high = (0..m)
        .map(|i| alphas[i] + radius(i))
        .fold(f64::NEG_INFINITY, f64::max);
    let below = |shift: f64| -> usize {
        let mut count = 0;
        let mut pivot = 1.0;
        for i in 0..m {
            let coupling = if i > 0 {
                betas[i - 1] * betas[i - 1]
            } else {
                0.0
            };
            pivot = alphas[i] - shift - coupling / pivot;
            if pivot == 0.0 {
                pivot = -f64::EPSILON * (shift.abs() + 1.0);
            }
            if pivot < 0.0 {
                count += 1;
            }
        }
        count
    };
    // λ_max is the smallest shift with all m eigenvalues below it.
    for _ in 0..200 {
        let mid = 0.5 * (low + high);
        if mid <= low || mid >= high {
            break;
        }
        if below(mid) == m {
            high = mid;
        } else {
            low = mid;
        }
    }
    high
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

/// Spectral radius of a general (possibly non-symmetric) operator on a scalar field, by
/// Arnoldi iteration with `dimension` Krylov vectors (modified Gram–Schmidt, a deterministic
/// random start; Saad, Numerical Methods for Large Eigenvalue Problems, §6.2): the largest
/// modulus among the eigenvalues of the Hessenberg matrix H_m, whose outer eigenvalues
/// converge to the operator's outermost, complex pairs included, in far fewer applications
/// than power iteration needs. Holds `dimension + 1` vectors of `n`.
pub fn arnoldi_spectral_radius(
    n: usize,
    dimension: usize,
    mut apply: impl FnMut(&[f64], &mut [f64]),
) -> f64 {
    let mut rng = SplitMix64(0xD1FF);
    let mut basis: Vec<Vec<f64>> = Vec::with_capacity(dimension + 1);
    let start: Vec<f64> = (0..n).map(|_| rng.next_f64() - 0.5).collect();
    let norm = start.iter().map(|x| x * x).sum::<f64>().sqrt();
    if n == 0 || norm == 0.0 {
        return 0.0;
    }
    basis.push(start.iter().map(|x| x / norm).collect());
    let mut hessenberg = nalgebra::DMatrix::<f64>::zeros(dimension + 1, dimension);
    let mut size = 0;
    for j in 0..dimension {
        let mut w = vec![0.0; n];
        apply(&basis[j], &mut w);
        // Modified Gram–Schmidt, each subtraction fused with the next inner product.
        let mut h = inner_product(&basis[0], &w);
        for i in 0..=j {
            hessenberg[(i, j)] = h;
            h = subtract_then_inner(&mut w, h, &basis[i], basis.get(i + 1).map(Vec::as_slice));
        }
        // The last pass returned w·w.
        let beta = h.sqrt();
        hessenberg[(j + 1, j)] = beta;
        size = j + 1;
        let scale = hessenberg.column(j).amax();
        if !beta.is_finite() || beta <= 1e-12 * scale {
            break;
        }
        w.par_iter_mut()
            .with_min_len(INNER_CHUNK)
            .for_each(|x| *x /= beta);
        basis.push(w);
    }
    let square = hessenberg.view((0, 0), (size, size)).into_owned();
    square
        .complex_eigenvalues()
        .iter()
        .map(|z| z.norm())
        .fold(0.0, f64::max)
}

/// Elements per partial sum of Arnoldi's inner products: fixed, so the sums, and the stable
/// steps drawn from them, are the same bits on any number of threads.
const INNER_CHUNK: usize = 4096;

/// a·b in parallel, summed in fixed chunks in order (thread-count independent).
fn inner_product(a: &[f64], b: &[f64]) -> f64 {
    let partial: Vec<f64> = a
        .par_chunks(INNER_CHUNK)
        .zip(b.par_chunks(INNER_CHUNK))
        .map(|(a, b)| a.iter().zip(b).map(|(x, y)| x * y).sum::<f64>())
        .collect();
    partial.iter().sum()
}

/// w ← w − h v, then the inner product of the new w with `next` (with itself if none), in
/// one pass over the vectors, summed as `inner_product` sums.
fn subtract_then_inner(w: &mut [f64], h: f64, v: &[f64], next: Option<&[f64]>) -> f64 {
    let partial: Vec<f64> = w
        .par_chunks_mut(INNER_CHUNK)
        .zip(v.par_chunks(INNER_CHUNK))
        .enumerate()
        .map(|(c, (w, v))| {
            for (x, y) in w.iter_mut().zip(v) {
                *x -= h * y;
            }
            let other = next.map_or(&*w, |u| &u[c * INNER_CHUNK..c * INNER_CHUNK + w.len()]);
            w.iter().zip(other).map(|(x, y)| x * y).sum::<f64>()
        })
        .collect();
    partial.iter().sum()
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

    /// A 1D chain of unit masses and springs k: λ_max → 4k (alternating mode; the top of the
    /// spectrum is a dense cluster).
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
        // Within a quarter of the margin the step keeps, from below.
        let allowed = (SPECTRAL_MARGIN - 1.0) / 4.0;
        assert!((lambda / (4.0 * k) - 1.0).abs() < allowed, "{lambda}");
        assert!(lambda <= 4.0 * k);
    }

    /// The Sturm bisection against a closed form: the n × n tridiagonal (2, −1) matrix has
    /// eigenvalues 2 − 2 cos(jπ/(n + 1)).
    #[test]
    fn tridiagonal_largest_eigenvalue() {
        for n in [1usize, 2, 5, 40] {
            let largest = largest_tridiagonal_eigenvalue(&vec![2.0; n], &vec![-1.0; n - 1]);
            let exact = 2.0 - 2.0 * (n as f64 * std::f64::consts::PI / (n as f64 + 1.0)).cos();
            assert!(
                (largest - exact).abs() < 1e-12,
                "n = {n}: {largest} against {exact}"
            );
        }
    }

    /// Arnoldi on a non-symmetric operator whose outermost eigenvalues are a complex pair
    /// (the case that makes power iteration's growth oscillate): 2 × 2 rotation-scaling blocks
    /// r_i (cos φ_i, −sin φ_i; sin φ_i, cos φ_i) plus an upper coupling, radius max r_i,
    /// found within a quarter of the margin in 40 applications (Arnoldi gives no side).
    #[test]
    fn arnoldi_finds_a_complex_outer_pair() {
        let blocks = 500;
        let radii: Vec<f64> = (0..blocks)
            .map(|b| 1.0 + 4.0 * (b as f64 / blocks as f64).sqrt())
            .collect();
        let top = radii[blocks - 1];
        let radius = arnoldi_spectral_radius(2 * blocks, 40, |v, out| {
            for b in 0..blocks {
                let (r, phi) = (radii[b], 0.3 + b as f64 * 1e-3);
                let (x, y) = (v[2 * b], v[2 * b + 1]);
                out[2 * b] = r * (phi.cos() * x - phi.sin() * y);
                out[2 * b + 1] = r * (phi.sin() * x + phi.cos() * y);
                if b + 1 < blocks {
                    out[2 * b] += 0.05 * v[2 * b + 2];
                }
            }
        });
        let allowed = (SPECTRAL_MARGIN - 1.0) / 4.0;
        assert!(
            (radius / top - 1.0).abs() < allowed,
            "{radius} against {top}"
        );
    }

    /// Lanczos on a diagonal operator with a cluster at the top (the hard case for power
    /// iteration): from below, within a quarter of the margin the step keeps, in fewer than
    /// 60 applications.
    #[test]
    fn lanczos_finds_the_top_of_a_clustered_spectrum() {
        let n = 2000;
        let diagonal: Vec<f64> = (0..n)
            .map(|i| 1.0 + 9.0 * (i as f64 / n as f64).sqrt())
            .collect();
        let top = diagonal[n - 1];
        let mut applications = 0;
        let lambda = max_eigenvalue::<1>(n, &vec![2.0; n], POWER_ITERATIONS, |u, out| {
            applications += 1;
            for i in 0..n {
                out[i][0] = diagonal[i] * u[i][0];
            }
        });
        assert!(lambda <= top * (1.0 + 1e-12), "{lambda} above {top}");
        let allowed = (SPECTRAL_MARGIN - 1.0) / 4.0;
        assert!(
            lambda / top > 1.0 - allowed && applications < POWER_ITERATIONS,
            "{lambda} against {top} after {applications}"
        );
    }
}
