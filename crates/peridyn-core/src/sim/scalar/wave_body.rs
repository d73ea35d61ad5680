//! The body of a scalar wave (2.37)–(2.40): the field body with the velocity state of damped
//! velocity-Verlet (4.62), and its forces — the operator's rates — for the velocity-Verlet
//! driver (`integrate::verlet`).

use std::ops::{Deref, DerefMut};

use super::body::FieldBody;
use crate::integrate::verlet::{ForceTerms, VerletBody};
use crate::solver::{Adaptation, SimError, Tick};

/// The velocity state of damped velocity-Verlet (4.62) for a scalar wave, and the previous
/// time level the absorbing layer fits on.
pub struct Wave {
    pub damping: f64,
    pub velocity: Vec<f64>,
    pub previous_field: Vec<f64>,
    pub previous_velocity: Vec<f64>,
    /// Per operator row: v^n + Δt/2 a^n between the two half steps.
    pub half: Vec<f64>,
    /// The rate buffer holds L u of the current field.
    pub forces_fresh: bool,
}

impl Wave {
    pub fn new(damping: f64, field: &[f64], rows: usize) -> Wave {
        Wave {
            damping,
            velocity: vec![0.0; field.len()],
            // At rest before t = 0 (the far field is at rest; u̇0 = 0 in every example).
            previous_field: field.to_vec(),
            previous_velocity: vec![0.0; field.len()],
            half: vec![0.0; rows],
            forces_fresh: false,
        }
    }
}

pub struct WaveBody<const D: usize> {
    pub base: FieldBody<D>,
    pub wave: Wave,
}

impl<const D: usize> Deref for WaveBody<D> {
    type Target = FieldBody<D>;

    fn deref(&self) -> &FieldBody<D> {
        &self.base
    }
}

impl<const D: usize> DerefMut for WaveBody<D> {
    fn deref_mut(&mut self) -> &mut FieldBody<D> {
        &mut self.base
    }
}

impl<const D: usize> VerletBody for WaveBody<D> {
    /// u^{n+1} = u + Δt u̇ + Δt²/2 a and the half step u̇ + Δt/2 a on the operator's rows, with
    /// a = L u − 2 d u̇ (4.62); t^n's state kept as the previous level.
    fn kick_drift(&mut self, dt: f64) {
        if !self.wave.forces_fresh {
            self.base.rates();
        }
        let (base, w) = (&mut self.base, &mut self.wave);
        let d = w.damping;
        let field = base.discretization.nodes.fields.get_mut(base.values);
        w.previous_field.copy_from_slice(field);
        w.previous_velocity.copy_from_slice(&w.velocity);
        for (r, &i) in base.operator.rows.iter().enumerate() {
            let i = i as usize;
            let acceleration = base.rate[r] - 2.0 * d * w.velocity[i];
            field[i] += dt * w.velocity[i] + 0.5 * dt * dt * acceleration;
            w.half[r] = w.velocity[i] + 0.5 * dt * acceleration;
        }
    }

    /// A wave's held nodes keep their initial values: nothing to apply.
    fn constraints(&mut self) {}

    fn stop(&self, measure: f64, tick: Tick) -> Option<SimError> {
        self.base.diverged(measure, tick)
    }
}

/// A wave's forces: L u on the operator's rows.
pub struct WaveForces;

impl<const D: usize> Adaptation<WaveBody<D>> for WaveForces {}

impl<const D: usize> ForceTerms<WaveBody<D>> for WaveForces {
    fn forces(&mut self, body: &mut WaveBody<D>, _energy: bool) {
        body.base.rates();
        body.wave.forces_fresh = true;
    }

    /// u̇^{n+1} = (u̇ + Δt/2 a^n + Δt/2 L u^{n+1}) / (1 + Δt d); returns max |u^{n+1}| (the
    /// divergence check's measure).
    fn kick(&mut self, body: &mut WaveBody<D>, dt: f64) -> f64 {
        let (base, w) = (&body.base, &mut body.wave);
        let d = w.damping;
        for (r, &i) in base.operator.rows.iter().enumerate() {
            w.velocity[i as usize] = (w.half[r] + 0.5 * dt * base.rate[r]) / (1.0 + dt * d);
        }
        base.field().iter().fold(0.0, |m: f64, v| m.max(v.abs()))
    }
}
