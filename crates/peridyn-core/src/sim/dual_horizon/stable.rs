//! The stiffness of a particle body about its reference configuration: velocity-Verlet's stable
//! step and adaptive dynamic relaxation's fictitious density (zeng2024 Sect. 4.1).

use super::body::ParticleBody;
use crate::discretization::NodeValue;
use crate::integrate::adr::{self, Relaxation};
use crate::integrate::stability::{self, POWER_ITERATIONS};
use crate::scheme::dual_horizon::ParticleTerms;
use crate::solver::{Integrator, StableStep};

/// λ_max of W⁻¹K for the weights W (masses: Verlet's limit; ADR's diagonal: its density
/// scale), by power iteration on K u = −F(x + εu)/ε about the reference configuration (where
/// F = 0), ε keeping the largest displacement at 10⁻⁶ of the smallest cell.
fn stiffness_eigenvalue(body: &mut ParticleBody, weights: &[f64]) -> f64 {
    let n = body.len();
    let smallest = body
        .spacings()
        .iter()
        .copied()
        .fold(f64::INFINITY, f64::min);
    let mut y = vec![[0.0; 2]; n];
    let mut terms = vec![ParticleTerms::EMPTY; n];
    // Probing must not touch the bond states: the tiny strains stay far below s_c.
    let states = body.bonds.intact.clone();
    let (particles, bonds) = body.body_and_bonds();
    let lambda = stability::max_eigenvalue::<2>(n, weights, POWER_ITERATIONS, |u, out| {
        let largest = u
            .iter()
            .map(|v| v[0].abs().max(v[1].abs()))
            .fold(0.0, f64::max);
        if largest == 0.0 {
            out.fill([0.0; 2]);
            return;
        }
        let eps = 1e-6 * smallest / largest;
        for ((y, x), u) in y.iter_mut().zip(particles.reference).zip(u) {
            *y = [x[0] + eps * u[0], x[1] + eps * u[1]];
        }
        bonds.evaluate(&particles, &y, &mut terms);
        for ((o, t), w) in out.iter_mut().zip(&terms).zip(weights) {
            *o = [-t.force[0] / (eps * w), -t.force[1] / (eps * w)];
        }
    });
    bonds.intact.copy_from_slice(&states);
    lambda
}

/// Velocity-Verlet's stable step: the power-iterated sharp limit and a Gershgorin-type
/// estimate from the stiffness row sums. A scene that refines deeper than the particles it
/// starts with has the smallest level's limit, 2⁻ˡ of the present one (the lattice stiffness
/// per mass scales with 1/Δ² at δ ∝ Δ).
pub(super) fn stable_step(body: &mut ParticleBody) -> StableStep {
    let density = body.density;
    let masses: Vec<f64> = body.volumes().iter().map(|v| v * density).collect();
    let lambda = stiffness_eigenvalue(body, &masses);
    let diagonal = body.bonds.stiffness_rows(&body.body());
    let gershgorin = masses
        .iter()
        .zip(&diagonal)
        .map(|(m, d)| 2.0 * (m / d).sqrt())
        .fold(f64::INFINITY, f64::min);
    let present = body.levels().iter().copied().max().unwrap_or(0);
    let deeper = body
        .spec
        .refinement
        .map_or(0, |r| r.levels.saturating_sub(present));
    let factor = 0.5f64.powi(i32::from(deeper));
    StableStep {
        sharp: stability::verlet_step(lambda) * factor,
        guaranteed: gershgorin * factor,
        integrator: Integrator::Verlet,
    }
}

/// ADR's fictitious density Λ: the stiffness row sums scaled by λ_max of their D⁻¹K.
pub(super) fn relaxation_of(body: &mut ParticleBody) -> Relaxation {
    let diagonal = body.bonds.stiffness_rows(&body.body());
    let lambda = stiffness_eigenvalue(body, &diagonal);
    Relaxation::new(adr::scale_density(&diagonal, lambda), lambda)
}

/// ADR's density for the rows of a grown body, from the measured scale: no new eigenvalue
/// estimate, the row sums keep the shape, so λ_max(D⁻¹K) stays (never below 1, the bound of
/// exact absolute row sums).
pub(super) fn relaxation_after_split(body: &ParticleBody, lambda: f64) -> Relaxation {
    let diagonal = body.bonds.stiffness_rows(&body.body());
    Relaxation::new(adr::scale_density(&diagonal, lambda.max(1.0)), lambda)
}
