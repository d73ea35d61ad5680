//! `[time]`: the step (absolute, or a fraction of the stable bound, checked against it when
//! the run is built by `solver::dt_policy`) and the end (a time or a step count).

use super::checks::positive;
use super::error::{ErrorContext, SceneError};
use super::schema::{self, IntegratorKind, Physics, Preset};
use super::spec::{Duration, StepSize, TimeSpec};
use super::units::{Measure, Relative};

/// `[time]`, which every scene but a static one (one global solve) needs.
pub(super) fn time(p: &Preset, ctx: &ErrorContext) -> Result<TimeSpec, SceneError> {
    Ok(match (&p.time, p.physics) {
        (Some(t), _) => time_spec(t, ctx)?,
        // A static scene is one global solve.
        (None, Physics::Static) => TimeSpec {
            step: StepSize::Absolute(1.0),
            duration: Duration::Steps(1),
            allow_unstable: false,
        },
        (None, _) => return Err(ctx.error("time", "give a [time] table with `dt` and `end`")),
    })
}

fn time_spec(t: &schema::TimeSpec, ctx: &ErrorContext) -> Result<TimeSpec, SceneError> {
    let adr = t.integrator == Some(IntegratorKind::Adr);
    let dt = match (t.dt, adr) {
        (Some(dt), _) => dt,
        // Dynamic relaxation iterates with a unit pseudo step.
        (None, true) => Measure::Si(1.0),
        (None, false) => {
            return Err(ctx.error(
                "time.dt",
                "give the time step, e.g. \"2 ns\" or \"0.7 stable\"",
            ));
        }
    };
    let step = match dt {
        Measure::Si(dt) => StepSize::Absolute(positive(ctx, "time.dt", dt)?),
        Measure::Relative(f, Relative::StableStep) => {
            StepSize::FractionOfStable(positive(ctx, "time.dt", f)?)
        }
        Measure::Relative(_, r) => {
            return Err(ctx.error(
                "time.dt",
                format!(
                    "`{}` is not a time step: give e.g. \"2 ns\" or \"0.5 stable\"",
                    r.unit()
                ),
            ));
        }
    };
    if let StepSize::FractionOfStable(f) = step
        && f > 1.0
        && !t.allow_unstable
    {
        return Err(ctx.error(
            "time.dt",
            format!(
                "{f} stable is above the stable bound (3.8); use a value ≤ 1 or set time.allow_unstable = true"
            ),
        ));
    }
    let duration = match t.end {
        Measure::Si(end) => Duration::End(positive(ctx, "time.end", end)?),
        Measure::Relative(n, Relative::Steps) if n >= 1.0 && n.fract() == 0.0 => {
            Duration::Steps(n as u64)
        }
        Measure::Relative(n, Relative::Steps) => {
            return Err(ctx.error("time.end", format!("{n} steps: must be a whole number ≥ 1")));
        }
        Measure::Relative(_, r) => {
            return Err(ctx.error(
                "time.end",
                format!(
                    "`{}` is not a duration: give e.g. \"87 us\" or \"2000 steps\"",
                    r.unit()
                ),
            ));
        }
    };
    Ok(TimeSpec {
        step,
        duration,
        allow_unstable: t.allow_unstable,
    })
}
