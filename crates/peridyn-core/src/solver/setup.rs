//! Setup every simulation shares, written once: the run's clock (Δt from the preset by the
//! one Δt policy of `dt`) and the frame cadence.

use super::clock::Clock;
use super::dt::{Asker, Integrator, StableStep, dt_policy};
use crate::scene::{Scene, SceneError};

/// The clock of a scene's run: Δt as the preset gives it, by the one Δt policy
/// ([`super::dt::dt_policy`]: an absolute step above the stable bound is refused unless
/// `time.allow_unstable`; a fraction is taken of the bound), and its end.
pub fn clock(scene: &Scene, bound: &StableStep) -> Result<Clock, SceneError> {
    if bound.integrator == Integrator::Static {
        return Ok(Clock::single_step());
    }
    let t = &scene.time;
    let dt = dt_policy(t.step, bound, t.allow_unstable, Asker::Preset)
        .map_err(|m| scene.error("time.dt", m))?;
    Ok(Clock::new(dt, t.duration))
}

/// Steps between frames: the preset's (or `--every`), else a hundred frames per run.
pub fn frame_every(scene: &Scene, total_steps: u64) -> u64 {
    scene.output_every.unwrap_or((total_steps / 100).max(1))
}
