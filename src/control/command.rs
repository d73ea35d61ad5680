//! The commands a user (panel, script) can give a running simulation, and their text form.
//!
//! The text form is the one scripts use and recordings store: `play`, `pause`, `step [N]`,
//! `reset`, `set chi 0.9`, `set dt 2 ns [override]`, `set dt 0.5 stable`, `set m 3 [restart]`,
//! `set dx 0.5 mm [restart]`, `set scheme standard [restart]`, `set ratio 2 [restart]`,
//! `set region { box = { min = ["0 mm"], max = ["2 mm"] } } [restart]`, `set band 8 mm [restart]`,
//! `set every 10`,
//! `save start FILE.rrd`, `save stop`. `Display` writes the canonical text, which parses back
//! to the same command.

use std::fmt;
use std::path::PathBuf;

use crate::scene::StepSize;
use crate::scene::units::parse_quantity;

/// A time step as given: seconds, or a fraction of the stable bound.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum DtValue {
    Seconds(f64),
    Stable(f64),
}

impl DtValue {
    /// The step as a preset gives it, for the one Δt policy (`solver::dt_policy`).
    pub fn step_size(self) -> StepSize {
        match self {
            DtValue::Seconds(s) => StepSize::Absolute(s),
            DtValue::Stable(f) => StepSize::FractionOfStable(f),
        }
    }
}

#[derive(Debug, Clone, PartialEq)]
pub enum Command {
    Play,
    Pause,
    /// Advance this many steps, then pause.
    Step(u64),
    /// Restart the current configuration from t = 0 as a new recording.
    Reset,
    /// Switching margin χ of the hybrid scheme, in (0, 1].
    SetChi(f64),
    /// φ_c of particle splitting (zeng2024 (15)), in [0, 1).
    SetSplitDamage(f64),
    /// α of particle splitting (zeng2024 (16)), in (0, 1).
    SetSplitStrain(f64),
    /// φ_applied of an NNPP scene's overpotential (3.102), in volts.
    SetAppliedPotential(f64),
    /// A new time step; above the stable bound only with `allow_unstable`.
    SetDt {
        value: DtValue,
        allow_unstable: bool,
    },
    /// Horizon factor m = δ/Δx (rebuild).
    SetHorizonFactor(f64),
    /// Lattice spacing Δx in metres (rebuild).
    SetSpacing(f64),
    /// Spatial scheme by its preset name (rebuild).
    SetScheme(String),
    /// Grid ratio Δx⁺/Δx⁻ of a multi-grid scene (rebuild).
    SetGridRatio(usize),
    /// The fine region Ω⁻ of a multi-grid diffusion or corrosion scene, as the preset's
    /// `multigrid.region` shape (an inline TOML table; rebuild).
    SetFineRegion(String),
    /// The initial fine band of a multi-adaptive scene, as the preset's `multigrid.band`
    /// ("8 mm", "2 horizon"; rebuild).
    SetFineBand(String),
    /// Log a frame every this many steps.
    SetEvery(u64),
    StartSaving(PathBuf),
    StopSaving,
    /// Send a saved recording to the session's viewer, beside the live runs.
    Replay(PathBuf),
    /// Start a new session on another preset (built-in name or file) and variant.
    Load {
        preset: String,
        variant: Option<String>,
    },
}

/// The command forms, for error messages.
pub const FORMS: &str = "play, pause, step [N], reset, set chi X, set phi_c X, set alpha X, \
                         set potential VOLTAGE (`-300 mV`), \
                         set dt VALUE [override] \
                         (VALUE: a time like `2 ns` or `0.5 stable`), set m X [restart], \
                         set dx LENGTH [restart], set scheme NAME [restart], set every K, \
                         set ratio N [restart], set region {SHAPE} [restart], \
                         set band LENGTH [restart], \
                         save start FILE.rrd, save stop, replay FILE.rrd, \
                         load PRESET [VARIANT]";

impl Command {
    /// Whether the command rebuilds the discretization (and so starts a new recording).
    pub fn rebuilds(&self) -> bool {
        matches!(
            self,
            Command::Reset
                | Command::SetHorizonFactor(_)
                | Command::SetSpacing(_)
                | Command::SetScheme(_)
                | Command::SetGridRatio(_)
                | Command::SetFineRegion(_)
                | Command::SetFineBand(_)
        )
    }

    /// Parses the text form; the error names the allowed forms or values.
    pub fn parse(text: &str) -> Result<Command, String> {
        let words: Vec<&str> = text.split_whitespace().collect();
        let rest = |from: usize| words.get(from..).map(|w| w.join(" ")).unwrap_or_default();
        let number = |s: &str, what: &str| -> Result<f64, String> {
            s.parse::<f64>()
                .ok()
                .filter(|v| v.is_finite())
                .ok_or_else(|| format!("{what}: expected a number, got `{s}`"))
        };
        // Rebuild commands accept a trailing `restart` (they always restart).
        let strip_restart = |from: usize| -> Vec<&str> {
            let mut w: Vec<&str> = words.get(from..).unwrap_or_default().to_vec();
            if w.last() == Some(&"restart") {
                w.pop();
            }
            w
        };
        match words.as_slice() {
            [] => Err(format!("empty command; expected one of: {FORMS}")),
            ["play"] => Ok(Command::Play),
            ["pause"] => Ok(Command::Pause),
            ["reset"] | ["restart"] => Ok(Command::Reset),
            ["step"] => Ok(Command::Step(1)),
            ["step", n] => n
                .parse::<u64>()
                .ok()
                .filter(|&n| n >= 1)
                .map(Command::Step)
                .ok_or_else(|| format!("step: expected a whole number ≥ 1, got `{n}`")),
            ["save", "stop"] => Ok(Command::StopSaving),
            ["replay", ..] if words.len() > 1 => Ok(Command::Replay(PathBuf::from(rest(1)))),
            ["load", preset] => Ok(Command::Load {
                preset: preset.to_string(),
                variant: None,
            }),
            ["load", preset, variant] => Ok(Command::Load {
                preset: preset.to_string(),
                variant: Some(variant.to_string()),
            }),
            ["save", "start", ..] if words.len() > 2 => {
                Ok(Command::StartSaving(PathBuf::from(rest(2))))
            }
            ["set", "chi" | "χ", v] => Ok(Command::SetChi(number(v, "chi")?)),
            ["set", "phi_c" | "φ_c", v] => Ok(Command::SetSplitDamage(number(v, "phi_c")?)),
            ["set", "alpha" | "α", v] => Ok(Command::SetSplitStrain(number(v, "alpha")?)),
            ["set", "potential", ..] if words.len() > 2 => {
                let v = parse_with_unit(&rest(2), POTENTIAL_UNITS)
                    .map_err(|e| format!("potential: {e} (e.g. `set potential -300 mV`)"))?;
                Ok(Command::SetAppliedPotential(v))
            }
            ["set", "every", k] => k
                .parse::<u64>()
                .map(Command::SetEvery)
                .map_err(|_| format!("every: expected a whole number ≥ 1, got `{k}`")),
            ["set", "m", ..] => match strip_restart(2).as_slice() {
                [v] => Ok(Command::SetHorizonFactor(number(v, "m")?)),
                _ => Err("set m: expected one number, e.g. `set m 3 restart`".into()),
            },
            ["set", "dx", ..] => {
                let value = strip_restart(2).join(" ");
                let dx = parse_with_unit(&value, LENGTH_UNITS)
                    .map_err(|e| format!("dx: {e} (e.g. `set dx 0.5 mm`)"))?;
                Ok(Command::SetSpacing(dx))
            }
            ["set", "ratio", ..] => match strip_restart(2).as_slice() {
                [v] => v
                    .parse::<usize>()
                    .map(Command::SetGridRatio)
                    .map_err(|_| format!("ratio: expected a whole number (Δx⁺/Δx⁻), got `{v}`")),
                _ => Err("set ratio: expected one whole number, e.g. `set ratio 2 restart`".into()),
            },
            ["set", "region", ..] => {
                let shape = strip_restart(2).join(" ");
                let parsed = toml::from_str::<toml::Table>(&format!("region = {shape}"));
                match parsed.as_ref().map(|t| t.get("region")) {
                    Ok(Some(toml::Value::Table(_))) => Ok(Command::SetFineRegion(shape)),
                    _ => Err(format!(
                        "set region: expected a shape as an inline table, e.g. \
                         `set region {{ box = {{ min = [\"0 mm\"], max = [\"2 mm\"] }} }}`, got `{shape}`"
                    )),
                }
            }
            ["set", "band", ..] => {
                let band = strip_restart(2).join(" ");
                match crate::scene::units::parse_measure(&band) {
                    Ok(_) => Ok(Command::SetFineBand(band)),
                    Err(e) => Err(format!(
                        "set band: {e} (a length like `8 mm` or `2 horizon`)"
                    )),
                }
            }
            ["set", "scheme", ..] => match strip_restart(2).as_slice() {
                [name] => Ok(Command::SetScheme(name.to_string())),
                _ => Err("set scheme: expected one name, e.g. `set scheme standard`".into()),
            },
            ["set", "dt", ..] => {
                let mut w = words[2..].to_vec();
                let allow_unstable = w.last() == Some(&"override");
                if allow_unstable {
                    w.pop();
                }
                let value =
                    match w.as_slice() {
                        [f, "stable"] => DtValue::Stable(number(f, "dt")?),
                        [] => return Err(
                            "set dt: expected a value, e.g. `set dt 2 ns` or `set dt 0.5 stable`"
                                .into(),
                        ),
                        _ => DtValue::Seconds(
                            parse_with_unit(&w.join(" "), TIME_UNITS)
                                .map_err(|e| format!("dt: {e} (e.g. `2 ns` or `0.5 stable`)"))?,
                        ),
                    };
                Ok(Command::SetDt {
                    value,
                    allow_unstable,
                })
            }
            ["set", what, ..] => Err(format!(
                "unknown setting `{what}`; allowed: chi, dt, m, dx, scheme, every, ratio, region, band"
            )),
            [first, ..] => {
                let known = [
                    "play", "pause", "step", "reset", "restart", "save", "set", "replay", "load",
                ];
                if known.contains(first) {
                    Err(format!(
                        "malformed `{}`; expected one of: {FORMS}",
                        text.trim()
                    ))
                } else {
                    Err(format!(
                        "unknown command `{first}`; expected one of: {FORMS}"
                    ))
                }
            }
        }
    }
}

const TIME_UNITS: &[&str] = &["s", "ms", "us", "µs", "ns", "ps"];
const LENGTH_UNITS: &[&str] = &["m", "cm", "mm", "um", "µm", "nm"];
const POTENTIAL_UNITS: &[&str] = &["V", "mV", "uV", "µV"];

/// A number with an optional unit from `units` (none means SI), converted to SI.
fn parse_with_unit(text: &str, units: &[&str]) -> Result<f64, String> {
    let text = text.trim();
    let unit = text
        .trim_start_matches(|c: char| c.is_ascii_digit() || "+-.eE ".contains(c))
        .trim();
    if !unit.is_empty() && !units.contains(&unit) {
        return Err(format!(
            "unit `{unit}` not allowed here; allowed: {}",
            units.join(", ")
        ));
    }
    parse_quantity(text)
}

impl fmt::Display for Command {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        // `{:?}` on f64 prints the shortest text that parses back to the same bits.
        match self {
            Command::Play => write!(f, "play"),
            Command::Pause => write!(f, "pause"),
            Command::Step(n) => write!(f, "step {n}"),
            Command::Reset => write!(f, "reset"),
            Command::SetChi(x) => write!(f, "set chi {x:?}"),
            Command::SetSplitDamage(x) => write!(f, "set phi_c {x:?}"),
            Command::SetSplitStrain(x) => write!(f, "set alpha {x:?}"),
            Command::SetAppliedPotential(v) => write!(f, "set potential {v:?} V"),
            Command::SetDt {
                value,
                allow_unstable,
            } => {
                match value {
                    DtValue::Seconds(s) => write!(f, "set dt {s:?} s")?,
                    DtValue::Stable(x) => write!(f, "set dt {x:?} stable")?,
                }
                if *allow_unstable {
                    write!(f, " override")?;
                }
                Ok(())
            }
            Command::SetHorizonFactor(m) => write!(f, "set m {m:?} restart"),
            Command::SetSpacing(dx) => write!(f, "set dx {dx:?} m restart"),
            Command::SetScheme(s) => write!(f, "set scheme {s} restart"),
            Command::SetGridRatio(r) => write!(f, "set ratio {r} restart"),
            Command::SetFineRegion(shape) => write!(f, "set region {shape} restart"),
            Command::SetFineBand(band) => write!(f, "set band {band} restart"),
            Command::SetEvery(k) => write!(f, "set every {k}"),
            Command::StartSaving(p) => write!(f, "save start {}", p.display()),
            Command::StopSaving => write!(f, "save stop"),
            Command::Replay(p) => write!(f, "replay {}", p.display()),
            Command::Load { preset, variant } => match variant {
                Some(v) => write!(f, "load {preset} {v}"),
                None => write!(f, "load {preset}"),
            },
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn forms_parse() {
        assert_eq!(Command::parse("play").unwrap(), Command::Play);
        assert_eq!(Command::parse(" step ").unwrap(), Command::Step(1));
        assert_eq!(Command::parse("step 5").unwrap(), Command::Step(5));
        assert_eq!(Command::parse("set chi 0.9").unwrap(), Command::SetChi(0.9));
        for (text, command) in [
            ("set phi_c 0.35", Command::SetSplitDamage(0.35)),
            ("set α 0.25", Command::SetSplitStrain(0.25)),
            ("set potential -300 mV", Command::SetAppliedPotential(-0.3)),
            ("set potential 0.05", Command::SetAppliedPotential(0.05)),
        ] {
            assert_eq!(Command::parse(text).unwrap(), command);
            assert_eq!(Command::parse(&command.to_string()).unwrap(), command);
        }
        assert_eq!(
            Command::parse("set dt 2 ns").unwrap(),
            Command::SetDt {
                value: DtValue::Seconds(2e-9),
                allow_unstable: false
            }
        );
        assert_eq!(
            Command::parse("set dt 0.5 stable override").unwrap(),
            Command::SetDt {
                value: DtValue::Stable(0.5),
                allow_unstable: true
            }
        );
        assert_eq!(
            Command::parse("set m 3 restart").unwrap(),
            Command::SetHorizonFactor(3.0)
        );
        assert_eq!(
            Command::parse("set dx 0.5 mm").unwrap(),
            Command::SetSpacing(0.0005)
        );
        assert!(Command::parse("set region box").is_err());
        assert!(Command::parse("set band wide").is_err());
        assert_eq!(
            Command::parse("save start out dir/a.rrd").unwrap(),
            Command::StartSaving("out dir/a.rrd".into())
        );
    }

    #[test]
    fn canonical_text_round_trips() {
        for text in [
            "play",
            "pause",
            "step 3",
            "reset",
            "set chi 0.85",
            "set dt 1.7e-9 s override",
            "set dt 0.45 stable",
            "set m 3.0 restart",
            "set dx 0.0005 m restart",
            "set region { box = { min = [-5.25], max = [5.25] } } restart",
            "set band 2 horizon restart",
            "set scheme standard restart",
            "set ratio 2 restart",
            "set every 7",
            "save start a.rrd",
            "save stop",
            "replay old runs/a.rrd",
            "load kalthoff-winkler small",
            "load presets/x.toml",
        ] {
            let c = Command::parse(text).unwrap();
            assert_eq!(Command::parse(&c.to_string()).unwrap(), c, "{text}");
        }
    }

    #[test]
    fn bad_commands_name_what_is_allowed() {
        let e = Command::parse("set colour red").unwrap_err();
        assert!(e.contains("chi, dt, m, dx, scheme, every"), "{e}");
        let e = Command::parse("jump").unwrap_err();
        assert!(e.contains("play, pause"), "{e}");
        let e = Command::parse("set chi abc").unwrap_err();
        assert!(e.contains("number"), "{e}");
        let e = Command::parse("set dt 3 furlongs").unwrap_err();
        assert!(e.contains("dt"), "{e}");
        let e = Command::parse("step 0").unwrap_err();
        assert!(e.contains("≥ 1"), "{e}");
        let e = Command::parse("play now").unwrap_err();
        assert!(e.contains("malformed"), "{e}");
    }
}
