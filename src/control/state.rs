//! `ControlState`: what the panel shows and the commands change, as plain data. It validates
//! every command and says what the driver must do (`Effect`); it never touches a simulation,
//! so it is tested without one and rendered by any front end.

use std::path::{Path, PathBuf};

use super::command::Command;
// The choices live with the rebuild that reads them; named here too, where the state holds them.
pub use super::rescene::Discretization;
use super::rescene::discretization_of;
use crate::frame::Frame;
use crate::scene::Scene;
use crate::scene::schema::SchemeKind;
use crate::solver::{Asker, Param, SimInfo, StableStep, dt_policy};

/// What the driver must do after a command was accepted.
#[derive(Debug, Clone, PartialEq)]
pub enum Effect {
    /// Tune the running simulation in place (where the scene has no use for the parameter,
    /// it is only recorded).
    Tune(Param),
    Play,
    Pause,
    /// Advance this many steps, then pause.
    Step(u64),
    /// Use this time step from the next step on.
    SetDt(f64),
    /// Log a frame every this many steps.
    SetEvery(u64),
    /// Rebuild the scene with the state's discretization and restart it as a new recording
    /// (`ControlState::recording_id` is already the new one).
    Rebuild,
    StartSaving(PathBuf),
    StopSaving,
    Replay(PathBuf),
    /// Start a new session on this preset and variant (a new `ControlState`).
    Load {
        preset: String,
        variant: Option<String>,
    },
}

/// Live figures shown by the panel, updated from frames.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct LiveMetrics {
    pub step: u64,
    pub time: f64,
    pub total_steps: u64,
    pub steps_per_second: f64,
    pub bond_evaluations_per_second: f64,
    pub kinetic: f64,
    pub strain: f64,
    /// Nodes with damage ≥ 0.35 (a crack).
    pub damaged_nodes: usize,
    pub broken_bonds: f64,
    /// Fraction of nodes in the standard-scheme region Ω_s; None without a hybrid scheme
    /// (the standard scheme everywhere).
    pub standard_fraction: Option<f64>,
}

/// One applied command: the run it was applied in (1 = the first) and the step of that run.
#[derive(Debug, Clone, PartialEq)]
pub struct Applied {
    pub run: u32,
    pub step: u64,
    pub command: Command,
}

#[derive(Debug, Clone)]
pub struct ControlState {
    /// Prefix of every recording id of this session.
    pub session: String,
    /// The session's preset (a built-in name or a file) and variant.
    pub preset: String,
    pub variant: Option<String>,
    /// 1 for the first run; each rebuild or reset starts the next.
    pub run: u32,
    pub running: bool,
    pub chi: f64,
    /// φ_c and α of a scene that splits particles (`None` elsewhere).
    pub split: Option<crate::scene::SplitRule>,
    /// φ_applied of an NNPP scene with reactions (`None` elsewhere), V.
    pub applied_potential: Option<f64>,
    pub dt: f64,
    /// The bound a live Δt is checked against (the run's).
    pub stable: StableStep,
    pub discretization: Discretization,
    pub every: u64,
    pub saving: Option<PathBuf>,
    pub nodes: usize,
    pub bonds: usize,
    pub metrics: LiveMetrics,
    /// The last refusal or notice, shown by the panel until the next command.
    pub message: Option<String>,
    /// Every accepted command, in order: the log stored with recordings.
    pub log: Vec<Applied>,
}

/// The largest |φ_applied| a live command takes (V): electrochemical potentials are a few volts.
pub const MAX_APPLIED_POTENTIAL: f64 = 10.0;

/// Damage at which a node counts as cracked.
pub const CRACK_DAMAGE: f64 = 0.35;

impl ControlState {
    /// The state of a freshly built run of `scene`: its discretization and χ (the preset's, or
    /// the default where it has none); `session` prefixes every recording id.
    pub fn for_scene(session: impl Into<String>, info: &SimInfo, scene: &Scene) -> Self {
        let adaptive_chi = scene.multigrid.as_ref().and_then(|g| match g.refinement {
            crate::scene::Refinement::Adaptive { chi, .. } => Some(chi),
            crate::scene::Refinement::Region(_) => None,
        });
        let chi = scene
            .hybrid
            .map(|h| h.chi)
            .or(adaptive_chi)
            .unwrap_or(crate::scene::DEFAULT_CHI);
        let discretization = discretization_of(scene);
        ControlState {
            preset: scene
                .source
                .strip_prefix("builtin:")
                .unwrap_or(&scene.source)
                .to_string(),
            variant: scene.variant.clone(),
            split: scene.state_based.as_ref().and_then(|s| s.refinement),
            applied_potential: scene
                .nernst_planck
                .as_ref()
                .and_then(|n| n.reactions.as_ref())
                .map(|r| r.applied_potential),
            ..ControlState::new(session, info, discretization, chi)
        }
    }

    /// The state of a freshly built run; `session` prefixes every recording id.
    pub fn new(
        session: impl Into<String>,
        info: &SimInfo,
        discretization: Discretization,
        chi: f64,
    ) -> Self {
        ControlState {
            session: session.into(),
            preset: String::new(),
            variant: None,
            run: 1,
            running: true,
            chi,
            split: None,
            applied_potential: None,
            dt: info.dt,
            stable: info.stable_step(),
            discretization,
            every: info.frame_every,
            saving: None,
            nodes: info.nodes,
            bonds: info.bonds,
            metrics: LiveMetrics {
                total_steps: info.total_steps,
                ..LiveMetrics::default()
            },
            message: None,
            log: Vec::new(),
        }
    }

    /// The recording id of the current run: runs of one session sit side by side in a viewer.
    pub fn recording_id(&self) -> String {
        format!("{}-run{}", self.session, self.run)
    }

    /// Validates and applies a command. A refused command changes nothing but `message`.
    pub fn apply(&mut self, command: Command) -> Result<Effect, String> {
        match self.check(&command) {
            Ok(effect) => {
                self.message = None;
                self.commit(&command, &effect);
                // A replay shows an old recording and a load starts a new session: neither
                // is part of this session's history.
                if !matches!(command, Command::Replay(_) | Command::Load { .. }) {
                    self.log.push(Applied {
                        run: self.run_of(&command),
                        step: self.metrics.step,
                        command,
                    });
                }
                Ok(effect)
            }
            Err(e) => {
                let msg = format!("refused `{command}`: {e}");
                self.message = Some(msg.clone());
                Err(msg)
            }
        }
    }

    /// A rebuild command is logged in the run it ends (at the step it was given).
    fn run_of(&self, command: &Command) -> u32 {
        if command.rebuilds() {
            self.run - 1
        } else {
            self.run
        }
    }

    /// Takes back the last command (a rebuild whose scene could not be built) and shows why.
    pub fn revert(&mut self, before: ControlState, reason: &str) {
        *self = before;
        self.message = Some(reason.to_string());
    }

    /// After a (re)build: the new run's time step, bound, cadence and size.
    pub fn on_built(&mut self, info: &SimInfo) {
        self.dt = info.dt;
        self.stable = info.stable_step();
        // A cadence set by a command outlives restarts.
        if !self
            .log
            .iter()
            .any(|a| matches!(a.command, Command::SetEvery(_)))
        {
            self.every = info.frame_every;
        }
        self.nodes = info.nodes;
        self.bonds = info.bonds;
        self.metrics = LiveMetrics {
            total_steps: info.total_steps,
            ..LiveMetrics::default()
        };
    }

    /// Updates the live figures from a frame and the measured rate.
    pub fn observe(&mut self, frame: &Frame, total_steps: u64, steps_per_second: f64) {
        let m = &mut self.metrics;
        m.step = frame.step;
        m.time = frame.time;
        m.total_steps = total_steps;
        m.steps_per_second = steps_per_second;
        m.bond_evaluations_per_second = steps_per_second * self.bonds as f64;
        m.kinetic = frame.scalar("energy/kinetic").unwrap_or(0.0);
        m.strain = frame.scalar("energy/strain").unwrap_or(0.0);
        m.broken_bonds = frame.scalar("bonds/broken").unwrap_or(0.0);
        m.standard_fraction = frame.scalar("hybrid/omega_s_fraction");
        if let Some(d) = frame.fields.iter().find(|f| f.name == "damage") {
            m.damaged_nodes = d.values.iter().filter(|&&v| v >= CRACK_DAMAGE).count();
        }
    }

    /// Steps done in the current run, for commands given outside a frame (scripts).
    pub fn set_step(&mut self, step: u64, time: f64) {
        self.metrics.step = step;
        self.metrics.time = time;
    }

    fn check(&self, command: &Command) -> Result<Effect, String> {
        Ok(match command {
            Command::Play => Effect::Play,
            Command::Pause => Effect::Pause,
            Command::Step(n) => {
                if *n == 0 {
                    return Err("steps must be ≥ 1".into());
                }
                Effect::Step(*n)
            }
            Command::Reset => Effect::Rebuild,
            Command::SetChi(chi) => {
                crate::scene::check_chi(*chi)?;
                Effect::Tune(Param::Chi(*chi))
            }
            Command::SetSplitDamage(phi) => {
                crate::scene::check_split_damage(*phi)?;
                Effect::Tune(Param::SplitDamage(*phi))
            }
            Command::SetSplitStrain(alpha) => {
                crate::scene::check_split_strain(*alpha)?;
                Effect::Tune(Param::SplitStrain(*alpha))
            }
            Command::SetAppliedPotential(v) => {
                if !(v.is_finite() && v.abs() <= MAX_APPLIED_POTENTIAL) {
                    return Err(format!(
                        "potential: a voltage within ±{MAX_APPLIED_POTENTIAL} V, got {v}"
                    ));
                }
                Effect::Tune(Param::AppliedPotential(*v))
            }
            Command::SetDt {
                value,
                allow_unstable,
            } => Effect::SetDt(dt_policy(
                value.step_size(),
                &self.stable,
                *allow_unstable,
                Asker::Command,
            )?),
            Command::SetHorizonFactor(m) => {
                if !(m.is_finite() && *m >= 1.0) {
                    return Err(format!("m = {m} must be ≥ 1"));
                }
                Effect::Rebuild
            }
            Command::SetSpacing(dx) => {
                if !(dx.is_finite() && *dx > 0.0) {
                    return Err(format!("Δx = {dx:e} m must be > 0"));
                }
                Effect::Rebuild
            }
            Command::SetGridRatio(r) => {
                if self.discretization.ratio.is_none() {
                    return Err(
                        "this scene has one grid: the grid ratio applies to scenes with a \
                                [multigrid] fine region"
                            .into(),
                    );
                }
                if !(2..=16).contains(r) {
                    return Err(format!(
                        "the grid ratio must be a whole number in 2..=16, got {r}"
                    ));
                }
                Effect::Rebuild
            }
            Command::SetFineRegion(_) | Command::SetFineBand(_) => {
                if self.discretization.ratio.is_none() {
                    return Err(
                        "this scene has one grid: a fine region or band applies to scenes with \
                         a [multigrid] table"
                            .into(),
                    );
                }
                Effect::Rebuild
            }
            Command::SetScheme(name) => {
                check_scheme(name)?;
                Effect::Rebuild
            }
            Command::SetEvery(k) => {
                if *k == 0 {
                    return Err("the frame cadence must be ≥ 1 step".into());
                }
                Effect::SetEvery(*k)
            }
            Command::StartSaving(path) => {
                if self.saving.is_some() {
                    return Err("already saving; `save stop` first".into());
                }
                check_rrd_path(path)?;
                Effect::StartSaving(path.clone())
            }
            Command::StopSaving => {
                if self.saving.is_none() {
                    return Err("not saving".into());
                }
                Effect::StopSaving
            }
            Command::Replay(path) => {
                if !path.is_file() {
                    return Err(format!("no recording `{}`", path.display()));
                }
                Effect::Replay(path.clone())
            }
            Command::Load { preset, variant } => {
                if preset.is_empty() {
                    return Err("which preset?".into());
                }
                Effect::Load {
                    preset: preset.clone(),
                    variant: variant.clone(),
                }
            }
        })
    }

    fn commit(&mut self, command: &Command, effect: &Effect) {
        match command {
            Command::Play => self.running = true,
            Command::Pause | Command::Step(_) => self.running = false,
            Command::SetChi(chi) => self.chi = *chi,
            Command::SetSplitDamage(phi) => {
                if let Some(rule) = &mut self.split {
                    rule.damage = *phi;
                }
            }
            Command::SetSplitStrain(alpha) => {
                if let Some(rule) = &mut self.split {
                    rule.strain_factor = *alpha;
                }
            }
            Command::SetAppliedPotential(v) => {
                if let Some(p) = &mut self.applied_potential {
                    *p = *v;
                }
            }
            Command::SetDt { .. } => {
                if let Effect::SetDt(dt) = effect {
                    self.dt = *dt;
                }
            }
            Command::SetHorizonFactor(m) => self.discretization.m = *m,
            Command::SetSpacing(dx) => self.discretization.dx = *dx,
            Command::SetScheme(s) => self.discretization.scheme = s.clone(),
            Command::SetGridRatio(r) => self.discretization.ratio = Some(*r),
            Command::SetFineRegion(shape) => self.discretization.region = Some(shape.clone()),
            Command::SetFineBand(band) => self.discretization.band = Some(band.clone()),
            Command::SetEvery(k) => self.every = *k,
            Command::StartSaving(p) => self.saving = Some(p.clone()),
            Command::StopSaving => self.saving = None,
            Command::Reset | Command::Replay(_) | Command::Load { .. } => {}
        }
        if command.rebuilds() {
            self.run += 1;
        }
    }
}

/// A scheme name as the preset schema accepts it (its error lists the allowed names).
fn check_scheme(name: &str) -> Result<(), String> {
    use serde::Deserialize;
    SchemeKind::deserialize(toml::Value::String(name.to_string()))
        .map(|_| ())
        .map_err(|e| format!("scheme: {}", e.to_string().trim()))
}

fn check_rrd_path(path: &Path) -> Result<(), String> {
    if path.extension().and_then(|e| e.to_str()) != Some("rrd") {
        return Err(format!("`{}` must end in .rrd", path.display()));
    }
    let parent = path.parent().filter(|p| !p.as_os_str().is_empty());
    if let Some(dir) = parent
        && !dir.is_dir()
    {
        return Err(format!("folder `{}` does not exist", dir.display()));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::control::command::DtValue;

    /// A real simulation's facts with round numbers (no literal: `SimInfo` grows fields).
    fn info() -> SimInfo {
        let scene = crate::scene::Scene::load("vibrating-plate", Some("small")).unwrap();
        let mut info = crate::sim::build(&scene).unwrap().info();
        info.nodes = 100;
        info.bonds = 2000;
        info.dt = 1e-8;
        info.stable_dt = 2e-8;
        info.total_steps = 50;
        info.frame_every = 5;
        info
    }

    fn state() -> ControlState {
        ControlState::new(
            "s",
            &info(),
            Discretization {
                m: 4.0,
                dx: 1e-3,
                scheme: "standard".into(),
                ratio: None,
                region: None,
                band: None,
            },
            crate::scene::DEFAULT_CHI,
        )
    }

    /// The state with the fields a command may change blanked, for comparisons.
    fn fingerprint(s: &ControlState) -> String {
        let mut s = s.clone();
        s.log.clear();
        s.message = None;
        format!("{s:?}")
    }

    /// Applies `command` and checks that only the `changed` fields moved.
    fn only_changes(command: Command, changed: impl Fn(&mut ControlState)) -> Effect {
        let mut s = state();
        let mut expected = s.clone();
        changed(&mut expected);
        let effect = s.apply(command.clone()).unwrap();
        assert_eq!(fingerprint(&s), fingerprint(&expected), "{command}");
        assert_eq!(s.log.last().map(|a| &a.command), Some(&command));
        effect
    }

    #[test]
    fn every_command_changes_exactly_what_it_names() {
        assert_eq!(
            only_changes(Command::Pause, |s| s.running = false),
            Effect::Pause
        );
        let mut paused = state();
        paused.apply(Command::Pause).unwrap();
        assert_eq!(paused.apply(Command::Play), Ok(Effect::Play));
        assert!(paused.running);
        assert_eq!(
            only_changes(Command::Step(3), |s| s.running = false),
            Effect::Step(3)
        );
        assert_eq!(
            only_changes(Command::SetChi(0.8), |s| s.chi = 0.8),
            Effect::Tune(Param::Chi(0.8))
        );
        assert_eq!(
            only_changes(
                Command::SetDt {
                    value: DtValue::Seconds(1.5e-8),
                    allow_unstable: false
                },
                |s| s.dt = 1.5e-8
            ),
            Effect::SetDt(1.5e-8)
        );
        assert_eq!(
            only_changes(
                Command::SetDt {
                    value: DtValue::Stable(0.5),
                    allow_unstable: false
                },
                |s| s.dt = 1e-8
            ),
            Effect::SetDt(1e-8)
        );
        assert_eq!(
            only_changes(
                Command::SetDt {
                    value: DtValue::Stable(1.5),
                    allow_unstable: true
                },
                |s| s.dt = 1.5 * 2e-8
            ),
            Effect::SetDt(1.5 * 2e-8)
        );
        assert_eq!(
            only_changes(Command::SetEvery(9), |s| s.every = 9),
            Effect::SetEvery(9)
        );
        assert_eq!(
            only_changes(Command::SetHorizonFactor(3.0), |s| {
                s.discretization.m = 3.0;
                s.run = 2;
            }),
            Effect::Rebuild
        );
        assert_eq!(
            only_changes(Command::SetSpacing(5e-4), |s| {
                s.discretization.dx = 5e-4;
                s.run = 2;
            }),
            Effect::Rebuild
        );
        assert_eq!(
            only_changes(Command::SetScheme("standard".into()), |s| s.run = 2),
            Effect::Rebuild
        );
        assert_eq!(only_changes(Command::Reset, |s| s.run = 2), Effect::Rebuild);
        let file = std::env::temp_dir().join("x.rrd");
        assert_eq!(
            only_changes(Command::StartSaving(file.clone()), |s| s.saving =
                Some(file.clone())),
            Effect::StartSaving(file.clone())
        );
        let replayed = std::env::current_exe().unwrap();
        let mut s = state();
        let before = fingerprint(&s);
        assert_eq!(
            s.apply(Command::Replay(replayed.clone())),
            Ok(Effect::Replay(replayed))
        );
        assert_eq!(fingerprint(&s), before);
        assert!(
            s.log.is_empty(),
            "a replay is not part of the run's history"
        );
        let mut saving = state();
        saving.apply(Command::StartSaving(file)).unwrap();
        assert_eq!(saving.apply(Command::StopSaving), Ok(Effect::StopSaving));
        assert_eq!(saving.saving, None);
    }

    #[test]
    fn rebuild_commands_give_a_new_recording_id_and_live_ones_do_not() {
        let mut s = state();
        let mut seen = vec![s.recording_id()];
        for c in [
            Command::SetChi(0.5),
            Command::SetEvery(2),
            Command::Pause,
            Command::Play,
            Command::Step(1),
            Command::SetDt {
                value: DtValue::Stable(0.9),
                allow_unstable: false,
            },
        ] {
            s.apply(c).unwrap();
            assert_eq!(s.recording_id(), seen[0]);
        }
        for c in [
            Command::SetHorizonFactor(3.0),
            Command::SetSpacing(2e-3),
            Command::SetScheme("standard".into()),
            Command::Reset,
        ] {
            s.apply(c.clone()).unwrap();
            assert!(!seen.contains(&s.recording_id()), "{c}");
            seen.push(s.recording_id());
        }
    }

    #[test]
    fn invalid_values_are_refused_with_a_message_and_change_nothing() {
        let refused = [
            (Command::SetChi(0.0), "(0, 1]"),
            (Command::SetChi(1.01), "(0, 1]"),
            (Command::SetChi(f64::NAN), "(0, 1]"),
            (Command::SetHorizonFactor(0.5), "≥ 1"),
            (Command::SetSpacing(0.0), "> 0"),
            (Command::SetSpacing(-1e-3), "> 0"),
            (
                Command::SetDt {
                    value: DtValue::Seconds(0.0),
                    allow_unstable: true,
                },
                "> 0",
            ),
            (
                Command::SetDt {
                    value: DtValue::Seconds(-1e-9),
                    allow_unstable: false,
                },
                "> 0",
            ),
            (
                Command::SetDt {
                    value: DtValue::Seconds(3e-8),
                    allow_unstable: false,
                },
                "stable bound 2.0000e-8 s",
            ),
            (
                Command::SetDt {
                    value: DtValue::Stable(1.01),
                    allow_unstable: false,
                },
                "override",
            ),
            (Command::SetEvery(0), "≥ 1"),
            (Command::Step(0), "≥ 1"),
            (Command::StartSaving("a.txt".into()), ".rrd"),
            (
                Command::StartSaving("/no/such/dir/a.rrd".into()),
                "does not exist",
            ),
            (Command::StopSaving, "not saving"),
            (Command::SetGridRatio(2), "one grid"),
            (Command::SetFineBand("8 mm".into()), "one grid"),
            (Command::SetScheme("nope".into()), "standard"),
            (Command::Replay("/no/such.rrd".into()), "no recording"),
        ];
        for (command, needle) in refused {
            let mut s = state();
            let before = fingerprint(&s);
            let err = s.apply(command.clone()).unwrap_err();
            assert!(err.contains(needle), "{command}: {err}");
            assert_eq!(fingerprint(&s), before, "{command} changed the state");
            assert!(s.log.is_empty(), "refused commands are not logged");
            assert_eq!(
                s.message.as_deref(),
                Some(err.as_str()),
                "shown in the panel"
            );
            assert!(s.running, "the simulation keeps running");
        }
    }

    #[test]
    fn the_next_accepted_command_clears_the_message() {
        let mut s = state();
        s.apply(Command::SetChi(2.0)).unwrap_err();
        assert!(s.message.is_some());
        s.apply(Command::SetChi(0.9)).unwrap();
        assert_eq!(s.message, None);
    }

    #[test]
    fn rebuild_commands_are_logged_in_the_run_they_end() {
        let mut s = state();
        s.set_step(7, 7e-8);
        s.apply(Command::SetHorizonFactor(3.0)).unwrap();
        assert_eq!(
            s.log[0],
            Applied {
                run: 1,
                step: 7,
                command: Command::SetHorizonFactor(3.0)
            }
        );
        assert_eq!(s.run, 2);
    }
}
