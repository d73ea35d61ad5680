//! Velocity-Verlet, thesis (3.5)–(3.6), (3.9): half kick, drift, force, half kick.

use rayon::prelude::*;

/// u̇ += (Δt/2) ü.
pub fn half_kick<const D: usize>(velocity: &mut [[f64; D]], acceleration: &[[f64; D]], dt: f64) {
    velocity
        .par_iter_mut()
        .zip(acceleration)
        .with_min_len(4096)
        .for_each(|(v, a)| {
            for k in 0..D {
                v[k] += 0.5 * dt * a[k];
            }
        });
}

/// Second half kick of one node, u̇ += (Δt/2) ü; returns its squared speed (the caller
/// fuses this into the pass that computes ü).
#[inline(always)]
pub fn kick_node<const D: usize>(velocity: &mut [f64; D], acceleration: &[f64; D], dt: f64) -> f64 {
    let mut s2 = 0.0;
    for k in 0..D {
        velocity[k] += 0.5 * dt * acceleration[k];
        s2 += velocity[k] * velocity[k];
    }
    s2
}

/// max(a, b), NaN if either is NaN (a blow-up check must see a NaN speed).
#[inline]
pub fn max_or_nan(a: f64, b: f64) -> f64 {
    if a.is_nan() || b.is_nan() {
        f64::NAN
    } else {
        a.max(b)
    }
}

/// y += Δt u̇.
pub fn drift<const D: usize>(position: &mut [[f64; D]], velocity: &[[f64; D]], dt: f64) {
    position
        .par_iter_mut()
        .zip(velocity)
        .with_min_len(4096)
        .for_each(|(y, v)| {
            for k in 0..D {
                y[k] += dt * v[k];
            }
        });
}
