//! Time integrators and stable-step estimates.

pub mod adr;
pub mod lattice_symbol;
pub mod linear;
pub mod newton;
pub mod stability;
pub mod verlet;

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
