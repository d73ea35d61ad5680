//! Time integrators and stable-step estimates.

pub mod adr;
pub mod euler;
pub mod lattice_symbol;
pub mod linear;
pub mod newton;
pub mod stability;
pub mod verlet;

/// Terms per partial sum of [`ordered_sum`].
const SUM_CHUNK: usize = 4096;

/// Σ_{k < n} term(k) (N sums at once), in parallel over fixed chunks added in order: the same
/// bits on any number of threads and in every run (rayon's own `sum` splits where work is
/// stolen, so its float sums vary from run to run).
pub fn ordered_sum<const N: usize>(n: usize, term: impl Fn(usize) -> [f64; N] + Sync) -> [f64; N] {
    use rayon::prelude::*;
    let partial: Vec<[f64; N]> = (0..n.div_ceil(SUM_CHUNK))
        .into_par_iter()
        .map(|c| {
            let mut s = [0.0; N];
            for k in c * SUM_CHUNK..((c + 1) * SUM_CHUNK).min(n) {
                let t = term(k);
                for i in 0..N {
                    s[i] += t[i];
                }
            }
            s
        })
        .collect();
    partial.iter().fold([0.0; N], |mut sum, p| {
        for i in 0..N {
            sum[i] += p[i];
        }
        sum
    })
}

/// Stable step estimate (3.8): min_i √(2ρ / Σ_j ‖C(ξ_ij)‖ β V_j), a Gershgorin bound (see
/// `stability`).
pub fn stable_step(density: f64, stiffness_sums: &[f64]) -> f64 {
    let max = stiffness_sums.iter().copied().fold(0.0, f64::max);
    if max > 0.0 {
        (2.0 * density / max).sqrt()
    } else {
        f64::INFINITY
    }
}
