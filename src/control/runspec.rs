//! What a recording needs to be re-run exactly: the preset text as given, the variant, the
//! command-line overrides and the log of commands applied. Stored as TOML in the static
//! document `control/run` of every recording, and read back by `peridyn replay --resimulate`.

use serde::{Deserialize, Serialize};

use super::command::Command;
use super::script::{Timed, Trigger};
use super::state::Applied;
use crate::scene::{Scene, SceneError};

/// The entity holding the run description.
pub const ENTITY: &str = "control/run";

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RunSpec {
    /// Where the preset came from (`builtin:NAME` or a path), for messages.
    pub source: String,
    pub variant: Option<String>,
    /// `--set KEY=VALUE` overrides applied after the variant.
    #[serde(default)]
    pub overrides: Vec<String>,
    /// `--every`, when given.
    pub every: Option<u64>,
    /// `--steps`, when given (a cap per run).
    pub steps: Option<u64>,
    /// Commands applied, one per line: `run R at N steps: COMMAND`.
    #[serde(default)]
    pub commands: Vec<String>,
    pub preset: String,
}

impl RunSpec {
    pub fn new(scene: &Scene, every: Option<u64>, steps: Option<u64>) -> Self {
        RunSpec {
            source: scene.source.clone(),
            variant: scene.variant.clone(),
            overrides: scene.overrides.clone(),
            every,
            steps,
            commands: Vec::new(),
            preset: scene.preset_text.clone(),
        }
    }

    /// The scene as given (before any command), with `--every` applied.
    pub fn scene(&self) -> Result<Scene, SceneError> {
        let table = crate::scene::override_table(&self.source, &self.overrides)?;
        let mut scene =
            Scene::from_text_with(&self.source, &self.preset, self.variant.as_deref(), &table)?;
        scene.overrides = self.overrides.clone();
        if let Some(k) = self.every {
            scene.output_every = Some(k);
        }
        Ok(scene)
    }

    pub fn with_log(&self, log: &[Applied]) -> RunSpec {
        RunSpec {
            commands: log.iter().map(line).collect(),
            ..self.clone()
        }
    }

    pub fn to_text(&self) -> String {
        toml::to_string(self).unwrap_or_default()
    }

    pub fn from_text(text: &str) -> Result<RunSpec, String> {
        toml::from_str(text).map_err(|e| format!("bad `{ENTITY}` document: {e}"))
    }

    /// The command log as applied commands (run, step, command).
    pub fn applied(&self) -> Result<Vec<Applied>, String> {
        self.commands
            .iter()
            .enumerate()
            .map(|(i, text)| {
                let bad = || format!("bad command log line {}: `{text}`", i + 1);
                let (run, step, command) = parse_line(text).ok_or_else(bad)?;
                Ok(Applied {
                    run,
                    step,
                    command: Command::parse(command)
                        .map_err(|e| format!("command log line {}: {e}", i + 1))?,
                })
            })
            .collect()
    }

    /// The command log as a script that reapplies every command at the step it was applied.
    pub fn script(&self) -> Result<Vec<Timed>, String> {
        self.commands
            .iter()
            .enumerate()
            .map(|(i, text)| {
                let (_run, step, command) = parse_line(text)
                    .ok_or_else(|| format!("bad command log line {}: `{text}`", i + 1))?;
                Ok(Timed {
                    at: Trigger::Step(step),
                    command: Command::parse(command)
                        .map_err(|e| format!("command log line {}: {e}", i + 1))?,
                    line: i + 1,
                })
            })
            .collect()
    }
}

/// `run R at N steps: COMMAND`.
pub fn line(a: &Applied) -> String {
    format!("run {} at {} steps: {}", a.run, a.step, a.command)
}

fn parse_line(text: &str) -> Option<(u32, u64, &str)> {
    let rest = text.strip_prefix("run ")?;
    let (run, rest) = rest.split_once(" at ")?;
    let (step, command) = rest.split_once(" steps: ")?;
    Some((run.parse().ok()?, step.parse().ok()?, command))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn round_trips_through_text() {
        let scene = Scene::load("vibrating-plate", Some("small")).unwrap();
        let spec = RunSpec::new(&scene, Some(5), None).with_log(&[
            Applied {
                run: 1,
                step: 10,
                command: Command::SetChi(0.9),
            },
            Applied {
                run: 1,
                step: 20,
                command: Command::SetHorizonFactor(3.0),
            },
        ]);
        let back = RunSpec::from_text(&spec.to_text()).unwrap();
        assert_eq!(back, spec);
        assert_eq!(
            back.applied().unwrap()[1].command,
            Command::SetHorizonFactor(3.0)
        );
        let script = back.script().unwrap();
        assert_eq!(script[1].at, Trigger::Step(20));
        assert_eq!(script[1].command, Command::SetHorizonFactor(3.0));
        assert_eq!(back.scene().unwrap().output_every, Some(5));
    }
}
