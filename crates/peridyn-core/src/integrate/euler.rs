//! Forward Euler (3.10), u^{n+1} = u^n + Δt (L u^n + s(t^n)): the explicit driver of the
//! first-order physics (PD diffusion, corrosion). [`step`] owns the sequence — rates, update,
//! held values, the step's closing hooks — the stage timers and the stop after a step the body
//! judges failed; the scheme supplies the rates and the update ([`RateTerms`]), the body its
//! held values and its stop rule ([`EulerBody`]), and plug-ins ([`Adaptation`]) run between
//! the stages: `before_step` on the state at t^n, `after_move` on u^{n+1} with the held values
//! set (fictitious values, a layer's overwrite), `after_step` at the end (a phase change).

use crate::solver::adaptation::{self, Adaptation, Tick};
use crate::solver::{Lap, RunState, SimError, Stages};

/// What a forward-Euler body supplies to [`step`].
pub trait EulerBody {
    /// The held values at `time` (t^{n+1}), after the update.
    fn hold(&mut self, time: f64);
    /// The error that stops the run after step `tick`, from the `measure` its update returned.
    fn stop(&self, measure: f64, tick: Tick) -> Option<SimError>;
}

/// How a body's rates are evaluated and turned into new values (its scheme). A scheme is an
/// [`Adaptation`] too: its hooks run before the plug-ins' at each point.
pub trait RateTerms<B>: Adaptation<B> {
    /// The rates L u^n of every solved row.
    fn rates(&mut self, body: &mut B);
    /// u^{n+1} = u^n + Δt (L u^n + s(t^n)) on every solved row; returns the measure the body's
    /// stop rule judges (the largest |u^{n+1}|).
    fn update(&mut self, body: &mut B, tick: Tick) -> f64;
}

pub const RATES: &str = "rates";
pub const UPDATE: &str = "update";
/// The held values and the plug-ins on the new values.
pub const HOLD: &str = "hold";
/// The step's closing hooks (a phase change).
pub const PHASE_CHANGE: &str = "phase_change";

/// The stages a run of [`step`] times: the driver's own, then those the scheme and plug-ins
/// name.
pub fn stage_names<B: 'static>(
    terms: &dyn RateTerms<B>,
    plugins: &[Box<dyn Adaptation<B>>],
) -> Vec<&'static str> {
    let mut names = vec![RATES, UPDATE, HOLD, PHASE_CHANGE];
    for n in adaptation::named_stages(terms, plugins) {
        if !names.contains(&n) {
            names.push(n);
        }
    }
    names
}

/// One forward-Euler step of `body`: the hooks before the step, rates, the update, held
/// values and the hooks on the new values, the step's closing hooks; then the clock advances,
/// and a step the body's stop rule judges failed stops the run.
pub fn step<B: EulerBody + 'static>(
    body: &mut B,
    terms: &mut dyn RateTerms<B>,
    plugins: &mut [Box<dyn Adaptation<B>>],
    run: &mut RunState,
) -> Result<(), SimError> {
    let tick = Tick::next(&run.clock, run.stable.sharp);
    let stages = &mut run.stages;
    let at = |stages: &Stages, name| stages.index(name).unwrap_or(0);
    let (rates, hold) = (at(stages, RATES), at(stages, HOLD));
    let mut lap = Lap::start();
    adaptation::each(terms, plugins, stages, &mut lap, rates, |p| {
        p.before_step(body, tick)
    });
    terms.rates(body);
    lap.charge(stages, rates);
    let measure = terms.update(body, tick);
    lap.charge(stages, at(stages, UPDATE));
    body.hold(tick.time);
    lap.charge(stages, hold);
    adaptation::each(terms, plugins, stages, &mut lap, hold, |p| {
        p.after_move(body, tick)
    });
    let closing = at(stages, PHASE_CHANGE);
    adaptation::each(terms, plugins, stages, &mut lap, closing, |p| {
        p.after_step(body, tick)
    });
    run.clock.advance();
    match body.stop(measure, tick) {
        Some(error) => Err(error),
        None => Ok(()),
    }
}
