//! Plug-ins between a driver's stages (DESIGN.md, "Adaptation"): whatever changes a running
//! simulation besides its integrator — a scheme switch, a level transfer, particle splitting,
//! a phase change, an absorbing layer — implements [`Adaptation`] over the simulation's body
//! type `B` and is called by the driver at fixed points of every step. A simulation holds a
//! list of them; adding one adds no branch to the simulation or the driver.

use crate::frame::Frame;
use crate::solver::{Clock, Lap, Param, Stages, State};

/// The step a hook runs in: the step being completed (n + 1), its start t^n and end t^{n+1},
/// the step size, and the run's stable step (damped bands set their rate from it).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Tick {
    pub step: u64,
    pub start: f64,
    pub time: f64,
    pub dt: f64,
    pub stable_dt: f64,
}

impl Tick {
    /// The step that follows the clock's present one.
    pub fn next(clock: &Clock, stable_dt: f64) -> Tick {
        Tick {
            step: clock.step() + 1,
            start: clock.time(),
            time: clock.next_time(),
            dt: clock.dt(),
            stable_dt,
        }
    }
}

/// One plug-in (`Any`: a caller that knows the concrete type may reach it by downcasting).
/// Every hook defaults to doing nothing; a driver calls them in this order within
/// a step: `before_step` (state at t^n), `after_move` (the new positions or values u^{n+1} are
/// set, before the forces or rates that read them), `damp` (after the new velocities),
/// `after_constraints` (held values applied), `after_step` (the step's results complete).
pub trait Adaptation<B>: Send + Sync + std::any::Any {
    /// The stage its stepping work is timed in (listed by the run's stage timers); `None`:
    /// the driver's stage at the hook.
    fn stage(&self) -> Option<&'static str> {
        None
    }

    fn before_step(&mut self, _body: &mut B, _tick: Tick) {}

    fn after_move(&mut self, _body: &mut B, _tick: Tick) {}

    fn damp(&mut self, _body: &mut B, _tick: Tick) {}

    fn after_constraints(&mut self, _body: &mut B, _tick: Tick) {}

    fn after_step(&mut self, _body: &mut B, _tick: Tick) {}

    /// Adds its scalars, classes and events to a frame of the body at `clock`'s time.
    fn frame(&mut self, _body: &B, _clock: &Clock, _frame: &mut Frame) {}

    /// Its part of a checkpoint.
    fn save(&self, _body: &B, _state: &mut State) {}

    /// Restores its part of a checkpoint of the same scene; an error (nothing changed) if the
    /// state does not fit.
    fn restore(&mut self, _body: &mut B, _state: &State) -> Result<(), String> {
        Ok(())
    }

    /// Whether a checkpoint section is this plug-in's (see [`refuse_foreign_sections`]).
    fn owns_section(&self, _section: &str) -> bool {
        false
    }

    /// A live parameter it acts on in place: `None` if the parameter is not its own.
    fn tune(&mut self, _body: &mut B, _param: Param) -> Option<Result<(), String>> {
        None
    }

    /// Lines for `check` (a layer's conditioning).
    fn notes(&self) -> Vec<String> {
        Vec::new()
    }
}

/// The checkpoint sections that only a plug-in writes, and what a scene without it lacks: a
/// checkpoint holding one that no plug-in of this scene owns is refused by name.
const PLUG_IN_SECTIONS: &[(&str, &str)] = &[
    (
        "hybrid/mask",
        "the checkpoint is of a hybrid scene; this scene has none",
    ),
    (
        "multigrid/refined",
        "the checkpoint is of a multi-grid scene; this scene has one grid",
    ),
    (
        "absorbing/previous_displacement",
        "the checkpoint is of a scene with an absorbing layer; this one has none",
    ),
    (
        "phase",
        "the checkpoint is of a corrosion scene; this scene is not",
    ),
];

/// Refuses a checkpoint carrying a plug-in's section that none of `owners` claims.
pub fn refuse_foreign_sections<'a>(
    state: &State,
    mut owned: impl FnMut(&str) -> bool + 'a,
) -> Result<(), String> {
    for (section, message) in PLUG_IN_SECTIONS {
        if state.has(section) && !owned(section) {
            return Err((*message).to_string());
        }
    }
    Ok(())
}

/// The scheme's and then every plug-in's tuning of `param` in turn: the first that owns it
/// decides; none owning it gives the parameter's note.
pub fn tune_each<B: 'static>(
    scheme: &mut dyn Adaptation<B>,
    plugins: &mut [Box<dyn Adaptation<B>>],
    body: &mut B,
    param: Param,
) -> Result<(), String> {
    if let Some(result) = scheme.tune(body, param) {
        return result;
    }
    for p in plugins.iter_mut() {
        if let Some(result) = p.tune(body, param) {
            return result;
        }
    }
    Err(param.unused_note().into())
}

/// The stages the scheme and then the plug-ins name, in that order (repeats included: a
/// driver lists each once, after its own).
pub fn named_stages<B: 'static>(
    scheme: &dyn Adaptation<B>,
    plugins: &[Box<dyn Adaptation<B>>],
) -> Vec<&'static str> {
    scheme
        .stage()
        .into_iter()
        .chain(plugins.iter().filter_map(|p| p.stage()))
        .collect()
}

/// Runs `hook` on the scheme and then each plug-in, timing each in its own stage (`default`
/// for those that name none).
pub fn each<B: 'static>(
    scheme: &mut dyn Adaptation<B>,
    plugins: &mut [Box<dyn Adaptation<B>>],
    stages: &mut Stages,
    lap: &mut Lap,
    default: usize,
    mut hook: impl FnMut(&mut dyn Adaptation<B>),
) {
    let mut timed = |p: &mut dyn Adaptation<B>| {
        let stage = p.stage().and_then(|s| stages.index(s)).unwrap_or(default);
        hook(p);
        lap.charge(stages, stage);
    };
    timed(scheme);
    for p in plugins.iter_mut() {
        timed(&mut **p);
    }
}

/// Saves the scheme's (if any) and then every plug-in's checkpoint sections.
pub fn save_each<B: 'static>(
    scheme: Option<&dyn Adaptation<B>>,
    plugins: &[Box<dyn Adaptation<B>>],
    body: &B,
    state: &mut State,
) {
    for p in scheme.into_iter().chain(plugins.iter().map(|p| &**p)) {
        p.save(body, state);
    }
}

/// Refuses a checkpoint carrying a section that neither the scheme (if any) nor a plug-in
/// owns, then restores the scheme's and every plug-in's sections; each validates its sections
/// in full before it changes anything of its own.
pub fn restore_each<B: 'static>(
    mut scheme: Option<&mut dyn Adaptation<B>>,
    plugins: &mut [Box<dyn Adaptation<B>>],
    body: &mut B,
    state: &State,
) -> Result<(), String> {
    let owned = |s: &str| {
        scheme.as_ref().is_some_and(|p| p.owns_section(s))
            || plugins.iter().any(|p| p.owns_section(s))
    };
    refuse_foreign_sections(state, owned)?;
    if let Some(p) = scheme.as_mut() {
        p.restore(body, state)?;
    }
    for p in plugins.iter_mut() {
        p.restore(body, state)?;
    }
    Ok(())
}

/// Every plug-in's notes for `check`, in order.
pub fn notes_of<B: 'static>(plugins: &[Box<dyn Adaptation<B>>]) -> Vec<String> {
    plugins.iter().flat_map(|p| p.notes()).collect()
}
