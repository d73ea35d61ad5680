//! Drives a live simulation by commands: applies what `ControlState` accepts to the running
//! simulation (Δt, cadence, single steps), rebuilds and restarts it as a new recording when the
//! discretization changes, and logs every applied command and the run description into the
//! recording. Used headless (`peridyn record --script`, `peridyn replay --resimulate`) and by
//! the panel's simulation thread.

use std::time::Instant;

use super::checkpoint::{Checkpoint, Header, Plan};
use super::command::Command;
use super::rescene;
use super::runspec::{self, RunSpec};
use super::script::Timed;
use super::state::{ControlState, Effect};
use crate::export::VtuSeries;
use crate::frame::Frame;
use crate::record::{Outlet, RerunSink};
use crate::runner::{FrameSink, RunSummary};
use crate::scene::Scene;
use crate::sim;
use crate::solver::{Param, SimError, Stepper};

/// Where a session writes besides its recording.
#[derive(Debug, Clone, Default)]
pub struct Outputs {
    /// A `.vtu` series per run in this folder (`--vtu DIR`).
    pub vtu: Option<std::path::PathBuf>,
}

pub struct Driver {
    pub state: ControlState,
    outputs: Outputs,
    /// The current run's VTU series, with `outputs.vtu`.
    vtu: Option<VtuSeries>,
    spec: RunSpec,
    /// The scene as given, before any command.
    base: Scene,
    outlet: Outlet,
    sim: Box<dyn Stepper>,
    sink: Option<RerunSink>,
    /// Single steps still to take before pausing again.
    pending: u64,
    started: Instant,
    frames: u64,
    frame_seconds: f64,
    last_frame: Option<Frame>,
    /// (wall time, step) of the previous rate measurement.
    rate_mark: (Instant, u64),
}

impl Driver {
    /// Builds the first run. Errors are bad input (the preset or the discretization).
    pub fn start(spec: RunSpec, outlet: Outlet, session: &str) -> Result<Driver, String> {
        Driver::start_with(spec, outlet, session, Outputs::default())
    }

    /// Continues a checkpointed session: the scene of its current run rebuilt from the stored
    /// preset and choices, the simulation's state restored, the command log and settings as
    /// they were; the run goes on as a new recording from the checkpoint's step. Returns the
    /// script lines that had not fired yet.
    pub fn resume(
        checkpoint: &Checkpoint,
        outlet: Outlet,
        session: &str,
        outputs: Outputs,
    ) -> Result<(Driver, Vec<Timed>), String> {
        let header = &checkpoint.header;
        let spec = header.run_spec()?;
        let base = spec.scene().map_err(|e| e.to_string())?;
        let choice = header.discretization();
        let scene = rescene::with_discretization(&base, &choice).map_err(|e| e.to_string())?;
        let mut sim = sim::build(&scene).map_err(|e| e.to_string())?;
        sim.restore_state(&checkpoint.state)
            .map_err(|e| format!("the checkpoint does not fit its own preset: {e}"))?;
        let mut state = ControlState::for_scene(session, &sim.info(), &base);
        state.log = spec.applied()?;
        state.run = header.run;
        state.discretization = choice;
        state.chi = header.chi;
        let mut driver = Driver::new(state, spec, base, outlet, sim, outputs);
        driver.open_run(&scene)?;
        driver.state.every = header.every;
        driver.message(
            "info",
            &format!(
                "resumed from a checkpoint at step {} (t = {:.4e} s)",
                driver.steps_done(),
                driver.time()
            ),
        );
        Ok((driver, header.script()?))
    }

    /// A session around a built simulation, before its first run is opened.
    fn new(
        state: ControlState,
        spec: RunSpec,
        base: Scene,
        outlet: Outlet,
        sim: Box<dyn Stepper>,
        outputs: Outputs,
    ) -> Driver {
        Driver {
            state,
            outputs,
            vtu: None,
            spec,
            base,
            outlet,
            sim,
            sink: None,
            pending: 0,
            started: Instant::now(),
            frames: 0,
            frame_seconds: 0.0,
            last_frame: None,
            rate_mark: (Instant::now(), 0),
        }
    }

    /// Writes a checkpoint of the session as it stands (between steps): the run description
    /// and log, the current run's settings, the script lines not yet fired, the state.
    pub fn checkpoint(&self, plan: &Plan, remaining: &[Timed]) -> Result<(), String> {
        let d = &self.state.discretization;
        let header = Header {
            peridyn: env!("CARGO_PKG_VERSION").into(),
            spec: self.spec.with_log(&self.state.log).to_text(),
            run: self.state.run,
            m: d.m,
            dx: d.dx,
            scheme: d.scheme.clone(),
            ratio: d.ratio,
            region: d.region.clone(),
            band: d.band.clone(),
            every: self.state.every,
            chi: self.state.chi,
            script: remaining.iter().map(Timed::to_line).collect(),
            checkpoint_every: Some(plan.cadence()),
        };
        Checkpoint {
            header,
            state: self.sim.save_state(),
        }
        .write(&plan.path)
    }

    /// [`Driver::start`], also writing `outputs`.
    pub fn start_with(
        spec: RunSpec,
        outlet: Outlet,
        session: &str,
        outputs: Outputs,
    ) -> Result<Driver, String> {
        let base = spec.scene().map_err(|e| e.to_string())?;
        let sim = sim::build(&base).map_err(|e| e.to_string())?;
        let state = ControlState::for_scene(session, &sim.info(), &base);
        let mut driver = Driver::new(state, spec, base, outlet, sim, outputs);
        let scene = driver.base.clone();
        driver.open_run(&scene)?;
        Ok(driver)
    }

    fn open_run(&mut self, scene: &Scene) -> Result<(), String> {
        let info = self.sim.info();
        let mut sink = RerunSink::start_in(&self.outlet, &self.state.recording_id(), scene, &info)?;
        let run = self.spec.with_log(&self.state.log).to_text();
        sink.document(runspec::ENTITY, &run);
        self.sink = Some(sink);
        if let Some(dir) = &self.outputs.vtu {
            let prefix = format!("{}_run{}", scene.name, self.state.run);
            self.vtu = Some(VtuSeries::start(dir, &prefix, run)?);
        }
        self.state.on_built(&info);
        self.state.metrics.total_steps = self.total_steps();
        self.started = Instant::now();
        self.rate_mark = (Instant::now(), 0);
        self.emit();
        Ok(())
    }

    /// Steps of the current run: the scene's, capped by `--steps`.
    pub fn total_steps(&self) -> u64 {
        // From the clock, not `info()`: this runs every step, and a simulation's notes (an
        // absorbing layer's stability report) are built when `info()` is asked for.
        let total = self.sim.run().clock.total_steps();
        self.spec.steps.map_or(total, |cap| cap.min(total))
    }

    /// The session's scene as given, before any command.
    pub fn scene(&self) -> &Scene {
        &self.base
    }

    /// The current run's facts (size, Δt, its bound).
    pub fn info(&self) -> crate::solver::SimInfo {
        self.sim.info()
    }

    pub fn steps_done(&self) -> u64 {
        self.sim.steps_done()
    }

    pub fn time(&self) -> f64 {
        self.sim.time()
    }

    /// At the step cap, or an iterative solve (dynamic relaxation) has met its tolerance.
    pub fn done(&self) -> bool {
        self.sim.steps_done() >= self.total_steps() || self.sim.converged()
    }

    /// Whether the simulation should advance now (playing, or single steps pending).
    pub fn wants_step(&self) -> bool {
        !self.done() && (self.state.running || self.pending > 0)
    }

    /// One step, with a frame when the cadence or the end says so.
    pub fn step(&mut self) -> Result<(), SimError> {
        // The live cadence, so the step knows whether a frame will read what it computes.
        self.sim.run_mut().frame_every = self.state.every;
        if let Err(e) = self.sim.step() {
            self.message("error", &e.to_string());
            return Err(e);
        }
        let n = self.sim.steps_done();
        if self.pending > 0 {
            self.pending -= 1;
        }
        let converged = self.sim.converged();
        if n.is_multiple_of(self.state.every) || n == self.total_steps() || converged {
            self.emit();
        } else {
            self.state.metrics.step = n;
            self.state.metrics.time = self.sim.time();
        }
        if converged {
            self.message("info", &format!("converged after {n} iterations"));
        }
        Ok(())
    }

    fn emit(&mut self) {
        let t = Instant::now();
        let frame = self.sim.frame();
        let (mark, mark_step) = self.rate_mark;
        let steps = frame.step.saturating_sub(mark_step);
        let rate = if steps > 0 {
            steps as f64 / mark.elapsed().as_secs_f64().max(1e-9)
        } else {
            self.state.metrics.steps_per_second
        };
        self.rate_mark = (Instant::now(), frame.step);
        self.state.observe(&frame, self.total_steps(), rate);
        if frame.step == self.total_steps() || self.sim.converged() {
            self.last_frame = Some(frame.clone());
        }
        if let Some(vtu) = &mut self.vtu {
            vtu.send(frame.clone());
        }
        if let Some(sink) = &mut self.sink {
            sink.send(frame);
        }
        self.frames += 1;
        self.frame_seconds += t.elapsed().as_secs_f64();
    }

    pub fn message(&mut self, level: &str, text: &str) {
        if let Some(sink) = &mut self.sink {
            sink.message(level, text);
        }
    }

    /// Applies a command. A refusal is returned (and shown in `state.message` and the log);
    /// the simulation keeps running either way.
    pub fn command(&mut self, command: Command) -> Result<(), String> {
        let before = self.state.clone();
        self.state.set_step(self.sim.steps_done(), self.sim.time());
        let effect = match self.state.apply(command) {
            Ok(effect) => effect,
            Err(msg) => {
                self.message("warn", &msg);
                return Err(msg);
            }
        };
        // The command, if the state logged it (replays and loads are not logged).
        let applied = if self.state.log.len() > before.log.len() {
            self.state.log.last().cloned()
        } else {
            None
        };
        let result = match effect {
            Effect::Play | Effect::Pause => Ok(()),
            Effect::Tune(param) => {
                // Where the scene has no use for it, the parameter is only recorded.
                if let Err(note) = self.sim.tune(param) {
                    self.message("info", &note);
                }
                Ok(())
            }
            Effect::Step(n) => {
                self.pending = n;
                Ok(())
            }
            Effect::SetDt(dt) => {
                self.sim.set_dt(dt);
                self.state.metrics.total_steps = self.total_steps();
                Ok(())
            }
            Effect::SetEvery(_) => Ok(()),
            Effect::StartSaving(path) => self.save(Some(&path)),
            Effect::StopSaving => self.save(None),
            Effect::Replay(path) => crate::replay::send(&path, &self.outlet)
                .map(|_| ())
                .map_err(|e| e.to_string()),
            Effect::Load { preset, variant } => self.load(&preset, variant.as_deref()),
            Effect::Rebuild => self.rebuild(&before),
        };
        if let Err(e) = result {
            let msg = format!("refused: {e}");
            self.state.revert(before, &msg);
            self.message("warn", &msg);
            return Err(msg);
        }
        if let Some(applied) = applied
            && !applied.command.rebuilds()
        {
            self.log_applied(&applied);
        }
        Ok(())
    }

    /// Closes the current run's recording (and VTU series).
    fn close_run(&mut self) -> Result<(), String> {
        if let Some(vtu) = self.vtu.take() {
            vtu.finish()?;
        }
        if let Some(sink) = self.sink.take() {
            sink.finish()?;
        }
        Ok(())
    }

    fn save(&mut self, path: Option<&std::path::Path>) -> Result<(), String> {
        match &mut self.sink {
            Some(sink) => sink.save(path),
            None => Err("no recording is open".into()),
        }
    }

    fn log_applied(&mut self, applied: &super::state::Applied) {
        let doc = self.spec.with_log(&self.state.log).to_text();
        if let Some(sink) = &mut self.sink {
            sink.command(applied.step, &runspec::line(applied));
            sink.document(runspec::ENTITY, &doc);
        }
    }

    /// A new session on another preset: built first; only if that works is the current run
    /// closed. The new session's recordings describe only it (its preset, its commands).
    fn load(&mut self, preset: &str, variant: Option<&str>) -> Result<(), String> {
        let scene = Scene::load(preset, variant).map_err(|e| e.to_string())?;
        let spec = RunSpec::new(&scene, self.spec.every, self.spec.steps);
        let scene = spec.scene().map_err(|e| e.to_string())?;
        let sim = sim::build(&scene).map_err(|e| e.to_string())?;
        self.close_run()?;
        let saving = self.state.saving.clone();
        let running = self.state.running;
        self.state =
            ControlState::for_scene(crate::record::recording_id(&scene), &sim.info(), &scene);
        self.state.saving = saving;
        self.state.running = running;
        self.sim = sim;
        self.pending = 0;
        self.spec = spec;
        self.base = scene.clone();
        self.open_run(&scene)
    }

    /// Builds the new configuration first; only if that works is the current run closed.
    fn rebuild(&mut self, before: &ControlState) -> Result<(), String> {
        let scene = rescene::with_discretization(&self.base, &self.state.discretization)
            .map_err(|e| e.to_string())?;
        let sim = sim::build(&scene).map_err(|e| e.to_string())?;
        // Close the current run: its last state as a frame, the command that ended it.
        let step = self.sim.steps_done();
        if !step.is_multiple_of(before.every) && step != self.total_steps() {
            self.emit();
        }
        if let Some(applied) = self.state.log.last().cloned() {
            self.log_applied(&applied);
        }
        self.close_run()?;
        self.sim = sim;
        self.carry_live_parameters();
        self.pending = 0;
        self.open_run(&scene)
    }

    /// The live parameters the state holds (χ, φ_c, α, φ_applied) set on a rebuilt simulation, so a
    /// rebuild keeps what the user tuned; a scene without a use for one ignores it.
    fn carry_live_parameters(&mut self) {
        let mut params = vec![Param::Chi(self.state.chi)];
        if let Some(rule) = self.state.split {
            params.push(Param::SplitDamage(rule.damage));
            params.push(Param::SplitStrain(rule.strain_factor));
        }
        if let Some(v) = self.state.applied_potential {
            params.push(Param::AppliedPotential(v));
        }
        for param in params {
            // Err is the note that the scene has no use for the parameter.
            let _ = self.sim.tune(param);
        }
    }

    /// Ends the session: closes the recording and reports the last run.
    pub fn finish(
        mut self,
        interrupted: bool,
        error: Option<SimError>,
    ) -> Result<RunSummary, String> {
        if interrupted {
            let text = format!("interrupted at step {}", self.sim.steps_done());
            self.message("warn", &text);
        }
        self.close_run()?;
        self.outlet.stop_saving();
        let wall = self.started.elapsed().as_secs_f64();
        let last_frame = self.last_frame.take();
        Ok(RunSummary::of(
            self.sim.as_mut(),
            self.frames,
            wall,
            self.frame_seconds,
            interrupted,
            error,
            last_frame,
        ))
    }
}

/// What a headless scripted run did.
pub struct ScriptOutcome {
    pub summary: RunSummary,
    /// Script lines that were refused, with the reason.
    pub refused: Vec<(usize, String)>,
    /// Script lines that never fired (the run ended first).
    pub unfired: Vec<usize>,
    pub runs: u32,
}

/// Runs a session headless, giving the script's commands in order as their time comes.
/// With `checkpoints`, a restart file is written on its cadence (the step count starts again
/// with each new run).
pub fn run_script(
    mut driver: Driver,
    script: &[Timed],
    mut checkpoints: Option<Plan>,
    stop: &std::sync::atomic::AtomicBool,
    progress: &mut dyn FnMut(u64, u64),
) -> Result<ScriptOutcome, String> {
    let mut next = 0;
    let mut refused = Vec::new();
    let mut error = None;
    let mut interrupted = false;
    let mut run = driver.state.run;
    loop {
        while let Some(line) = script.get(next) {
            if !line.at.due(driver.steps_done(), driver.time()) {
                break;
            }
            if let Err(e) = driver.command(line.command.clone()) {
                refused.push((line.line, e));
            }
            next += 1;
        }
        if driver.done() {
            break;
        }
        if stop.load(std::sync::atomic::Ordering::Relaxed) {
            interrupted = true;
            break;
        }
        if let Err(e) = driver.step() {
            error = Some(e);
            break;
        }
        if let Some(plan) = checkpoints.as_mut() {
            if driver.state.run != run {
                run = driver.state.run;
                plan.restart();
            }
            if plan.due(driver.steps_done(), driver.time()) {
                driver.checkpoint(plan, &script[next..])?;
            }
        }
        progress(driver.steps_done(), driver.total_steps());
    }
    let unfired = script[next..].iter().map(|t| t.line).collect();
    let runs = driver.state.run;
    let summary = driver.finish(interrupted, error)?;
    Ok(ScriptOutcome {
        summary,
        refused,
        unfired,
        runs,
    })
}

/// FNV-1a over the bits of a field: equal hashes mean equal fields, bit for bit.
pub fn field_hash(values: impl IntoIterator<Item = u64>) -> u64 {
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    for v in values {
        for b in v.to_le_bytes() {
            h ^= b as u64;
            h = h.wrapping_mul(0x0000_0100_0000_01b3);
        }
    }
    h
}
