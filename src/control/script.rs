//! Timed command scripts for headless runs: one command per line, `at WHEN COMMAND`, where
//! WHEN is a step count (`2000 steps`) or a simulated time (`20 us`, `1.5e-5 s`) on the clock
//! of the current run (a restart starts it again at 0). Lines fire in order, each at the first
//! step boundary at or after its time. `#` starts a comment.
//!
//! ```text
//! at 20 us set chi 0.9
//! at 100 steps set dt 0.5 stable
//! at 2000 steps set m 3 restart
//! ```

use super::command::Command;

/// When a line fires.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Trigger {
    Step(u64),
    Time(f64),
}

impl Trigger {
    pub fn due(&self, step: u64, time: f64) -> bool {
        match *self {
            Trigger::Step(n) => step >= n,
            // A relative tolerance, so `at 20 us` fires at the step that lands on 20 µs.
            Trigger::Time(t) => time >= t * (1.0 - 1e-12),
        }
    }
}

#[derive(Debug, Clone, PartialEq)]
pub struct Timed {
    pub at: Trigger,
    pub command: Command,
    /// 1-based line in the script.
    pub line: usize,
}

/// A script error: file, line and what is allowed.
#[derive(Debug, Clone, PartialEq)]
pub struct ScriptError {
    pub file: String,
    pub line: usize,
    pub message: String,
}

impl std::fmt::Display for ScriptError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}:{}: {}", self.file, self.line, self.message)
    }
}

impl std::error::Error for ScriptError {}

/// Commands a headless script may give (a headless run always plays).
pub const SCRIPT_COMMANDS: &str = "set chi X, set dt VALUE [override], set m X [restart], set dx LENGTH [restart], \
     set scheme NAME [restart], set ratio N [restart], set every K, reset";

/// Time units and how many of them make a second (dividing keeps `20 us` = 2e-5 exactly).
const TIME_UNITS: &[(&str, f64)] = &[
    ("s", 1.0),
    ("ms", 1e3),
    ("us", 1e6),
    ("µs", 1e6),
    ("ns", 1e9),
];

/// Reads and parses a script file.
pub fn load(path: &std::path::Path) -> Result<Vec<Timed>, ScriptError> {
    let file = path.display().to_string();
    let text = std::fs::read_to_string(path).map_err(|e| ScriptError {
        file: file.clone(),
        line: 0,
        message: format!("cannot read the script: {e}"),
    })?;
    parse(&file, &text)
}

pub fn parse(file: &str, text: &str) -> Result<Vec<Timed>, ScriptError> {
    let mut out = Vec::new();
    for (i, raw) in text.lines().enumerate() {
        let line = i + 1;
        let content = raw.split('#').next().unwrap_or_default().trim();
        if content.is_empty() {
            continue;
        }
        let error = |message: String| ScriptError {
            file: file.to_string(),
            line,
            message,
        };
        let (at, command_text) = split_trigger(content).map_err(error)?;
        let command = Command::parse(command_text).map_err(error)?;
        if matches!(
            command,
            Command::Play
                | Command::Pause
                | Command::Step(_)
                | Command::StartSaving(_)
                | Command::StopSaving
                | Command::Replay(_)
                | Command::Load { .. }
        ) {
            return Err(error(format!(
                "`{command}` is for the live panel; a script may give: {SCRIPT_COMMANDS}"
            )));
        }
        out.push(Timed { at, command, line });
    }
    Ok(out)
}

const WHEN: &str = "WHEN being `N steps` or a time like `20 us`";

/// Splits `at WHEN COMMAND` into the trigger and the command text.
fn split_trigger(content: &str) -> Result<(Trigger, &str), String> {
    let expected = format!("expected `at WHEN COMMAND`, {WHEN}");
    let rest = content.strip_prefix("at ").ok_or(expected)?.trim_start();
    let (trigger, command, when) = when_prefix(rest)?;
    if command.trim().is_empty() {
        return Err(format!("no command after `at {when}`"));
    }
    Ok((trigger, command.trim()))
}

/// A step count or a simulated time on its own: `500 steps`, `20 us`, `1.5e-5 s`.
pub fn parse_when(text: &str) -> Result<Trigger, String> {
    let (trigger, rest, when) = when_prefix(text.trim())?;
    if !rest.trim().is_empty() {
        return Err(format!(
            "unexpected `{}` after `{when}`; {WHEN}",
            rest.trim()
        ));
    }
    Ok(trigger)
}

/// The WHEN at the start of `text`: the trigger, the text after it, and the WHEN as written.
fn when_prefix(text: &str) -> Result<(Trigger, &str, String), String> {
    let number_end = text
        .find(|c: char| !(c.is_ascii_digit() || ".eE+-".contains(c)))
        .unwrap_or(text.len());
    let number = &text[..number_end];
    let after = text[number_end..].trim_start();
    let (unit, rest) = after.split_once(char::is_whitespace).unwrap_or((after, ""));
    let value: f64 = number
        .parse()
        .ok()
        .filter(|v: &f64| v.is_finite() && *v >= 0.0)
        .ok_or_else(|| format!("`{number}` is not a time or step count ≥ 0; {WHEN}"))?;
    let trigger = match unit {
        "steps" | "step" => {
            if value.fract() != 0.0 {
                return Err(format!("`{number} {unit}`: a step count is a whole number"));
            }
            Trigger::Step(value as u64)
        }
        _ => match TIME_UNITS.iter().find(|(u, _)| *u == unit) {
            Some((_, per_second)) => Trigger::Time(value / per_second),
            None => {
                let allowed: Vec<&str> = TIME_UNITS.iter().map(|(u, _)| *u).collect();
                return Err(format!(
                    "unknown unit `{unit}` after `{number}`; allowed: steps, {}",
                    allowed.join(", ")
                ));
            }
        },
    };
    Ok((trigger, rest, format!("{number} {unit}")))
}

/// `N steps` or the time in seconds (round-trip exact): what `parse_when` reads.
impl std::fmt::Display for Trigger {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Trigger::Step(n) => write!(f, "{n} steps"),
            Trigger::Time(t) => write!(f, "{t:?} s"),
        }
    }
}

impl Timed {
    /// The line as a script would give it.
    pub fn to_line(&self) -> String {
        format!("at {} {}", self.at, self.command)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::control::command::DtValue;

    #[test]
    fn lines_parse_in_order_with_comments() {
        let s = parse(
            "s.txt",
            "# a script\n\nat 20us set chi 0.9\nat 100 steps set dt 0.5 stable # halve\nat 2000 steps set m 3 restart\nat 1.5e-5 s reset\n",
        )
        .unwrap();
        assert_eq!(s.len(), 4);
        assert_eq!(s[0].at, Trigger::Time(20e-6));
        assert_eq!(s[0].command, Command::SetChi(0.9));
        assert_eq!(s[0].line, 3);
        assert_eq!(s[1].at, Trigger::Step(100));
        assert_eq!(
            s[1].command,
            Command::SetDt {
                value: DtValue::Stable(0.5),
                allow_unstable: false
            }
        );
        assert_eq!(s[2].command, Command::SetHorizonFactor(3.0));
        assert_eq!(s[3].at, Trigger::Time(1.5e-5));
        assert_eq!(s[3].command, Command::Reset);
    }

    #[test]
    fn errors_name_the_file_the_line_and_what_is_allowed() {
        let cases = [
            ("set chi 0.9", "at WHEN COMMAND"),
            ("at 20 parsecs set chi 0.9", "allowed: steps, s, ms, us"),
            ("at 2.5 steps set chi 0.9", "whole number"),
            ("at -3 steps set chi 0.9", "≥ 0"),
            ("at 10 steps", "no command"),
            (
                "at 10 steps set colour red",
                "chi, dt, m, dx, scheme, every",
            ),
            ("at 10 steps pause", "set chi X"),
            ("at 10 steps fly", "unknown command"),
        ];
        for (line, needle) in cases {
            let e = parse("bad.txt", &format!("# header\n{line}\n")).unwrap_err();
            assert_eq!((e.file.as_str(), e.line), ("bad.txt", 2), "{line}");
            let shown = e.to_string();
            assert!(shown.starts_with("bad.txt:2: "), "{shown}");
            assert!(shown.contains(needle), "{line}: {shown}");
        }
    }

    #[test]
    fn triggers_fire_at_or_after_their_time() {
        assert!(!Trigger::Step(5).due(4, 0.0));
        assert!(Trigger::Step(5).due(5, 0.0));
        assert!(Trigger::Time(2e-5).due(0, 10.0 * 2e-6));
        assert!(!Trigger::Time(2e-5).due(0, 1.9e-5));
    }
}
