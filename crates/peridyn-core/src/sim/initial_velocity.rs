//! The scene's `[[initial.velocity]]` fields, which every elastic body starts with.

use crate::scene::{InitialVelocity, Scene};

/// Adds the scene's `[[initial.velocity]]` fields at the reference positions.
pub fn add_initial_velocity<const D: usize>(
    scene: &Scene,
    reference: &[[f64; D]],
    velocities: &mut [[f64; D]],
) {
    let (lo, hi) = scene.solid.bounds();
    for field in &scene.initial_velocity {
        for (v, x) in velocities.iter_mut().zip(reference) {
            match *field {
                InitialVelocity::Uniform(ref value) => {
                    for k in 0..D {
                        v[k] += value[k];
                    }
                }
                InitialVelocity::Ramp {
                    component,
                    axis,
                    from,
                    to,
                } => {
                    let t = (x[axis] - lo[axis]) / (hi[axis] - lo[axis]);
                    v[component] += from + t * (to - from);
                }
                InitialVelocity::Sine {
                    component,
                    axis,
                    amplitude,
                    modes,
                } => {
                    let t = (x[axis] - lo[axis]) / (hi[axis] - lo[axis]);
                    v[component] += amplitude * (std::f64::consts::PI * modes * t).sin();
                }
            }
        }
    }
}
