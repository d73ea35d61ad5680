//! Setup every simulation shares, written once: the time step from the preset against the
//! stable bound (and its refusal), the run's clock and the frame cadence.

use super::clock::Clock;
use crate::scene::{Scene, SceneError, StepSize};

/// The stable step of a scene's operator and how it was found (for messages and `check`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StableStep {
    /// The limit `dt = "F stable"` refers to and an absolute Δt is checked against.
    pub sharp: f64,
    /// A guaranteed but conservative bound: (3.8) or Gershgorin discs.
    pub guaranteed: f64,
    pub integrator: Integrator,
}

/// The explicit integrator whose limit a stable step is.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Integrator {
    /// 2/√λ_max of the mass-normalized stiffness.
    Verlet,
    /// 2/ρ of the (diffusion) operator.
    Euler,
    /// One global solve: no step limit.
    Static,
    /// Semi-implicit (Newton) steps: no step limit, any Δt.
    Implicit,
}

impl StableStep {
    /// No limit (a static solve).
    pub const NONE: StableStep = StableStep {
        sharp: f64::INFINITY,
        guaranteed: f64::INFINITY,
        integrator: Integrator::Static,
    };

    fn describe(&self) -> String {
        match self.integrator {
            Integrator::Verlet => format!(
                "velocity-Verlet's 2/√λ_max, λ_max by power iteration; the conservative (3.8) \
                 estimate is {:.4e} s",
                self.guaranteed
            ),
            Integrator::Euler => "forward Euler's 2/ρ, ρ the operator's spectral radius (power \
                                  iteration or Gershgorin discs)"
                .into(),
            Integrator::Static => "no limit".into(),
            Integrator::Implicit => "no limit (an implicit step)".into(),
        }
    }
}

/// The clock of a scene's run: Δt as the preset gives it (an absolute step is refused above the
/// stable bound unless `time.allow_unstable`; a fraction is taken of the bound) and its end.
pub fn clock(scene: &Scene, bound: &StableStep) -> Result<Clock, SceneError> {
    if bound.integrator == Integrator::Static {
        return Ok(Clock::single_step());
    }
    let dt = match scene.time.step {
        StepSize::Absolute(dt) => {
            if dt > bound.sharp && !scene.time.allow_unstable {
                return Err(scene.error(
                    "time.dt",
                    format!(
                        "{dt:.4e} s is {:.2}× the stable bound {:.4e} s ({}); lower it, use \
                         dt = \"0.9 stable\", or set time.allow_unstable = true",
                        dt / bound.sharp,
                        bound.sharp,
                        bound.describe()
                    ),
                ));
            }
            dt
        }
        StepSize::FractionOfStable(f) if bound.integrator == Integrator::Implicit => {
            // The fraction refers to explicit Euler's bound, kept in `guaranteed`.
            f * bound.guaranteed
        }
        StepSize::FractionOfStable(f) => f * bound.sharp,
    };
    Ok(Clock::new(dt, scene.time.duration))
}

/// Steps between frames: the preset's (or `--every`), else a hundred frames per run.
pub fn frame_every(scene: &Scene, total_steps: u64) -> u64 {
    scene.output_every.unwrap_or((total_steps / 100).max(1))
}
