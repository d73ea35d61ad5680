//! Restart files: everything a session needs to continue a run exactly — the run description
//! (preset text, variant, overrides, command log), the current run's number, discretization,
//! cadence and χ, the script lines not yet fired, and the simulation's state. Written
//! atomically (a temporary file renamed into place: the previous checkpoint stays until the
//! new one is complete); read back with a clear refusal of anything else.
//!
//! Layout: the magic bytes, the format version (u32), the payload length (u64), the payload —
//! a TOML header's length and text, then the encoded `solver::State` — and an FNV-1a checksum
//! of everything before it (u64), all little endian.

use std::path::Path;

use serde::{Deserialize, Serialize};

use super::runspec::RunSpec;
use super::script::{Timed, Trigger};
use super::state::Discretization;
use crate::solver::State;

const MAGIC: &[u8; 19] = b"PERIDYN-CHECKPOINT\n";
/// The format this build writes and reads.
pub const FORMAT: u32 = 1;

/// What a checkpoint holds besides the simulation's state.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Header {
    /// The peridyn version that wrote it (for messages).
    pub peridyn: String,
    /// The run description with the command log so far (TOML of `RunSpec`).
    pub spec: String,
    /// The current run (1 = the first; a rebuild starts the next).
    pub run: u32,
    pub m: f64,
    pub dx: f64,
    pub scheme: String,
    /// The grid ratio of a multi-grid scene.
    #[serde(default)]
    pub ratio: Option<usize>,
    /// A fine region or band chosen live (multi-grid scenes).
    #[serde(default)]
    pub region: Option<String>,
    #[serde(default)]
    pub band: Option<String>,
    /// The frame cadence.
    pub every: u64,
    pub chi: f64,
    /// Script lines not yet fired, as `at WHEN COMMAND`.
    pub script: Vec<String>,
    /// The checkpoint cadence, as `N steps` or a time, to go on with after a resume.
    pub checkpoint_every: Option<String>,
}

impl Header {
    /// The values a session takes as they are (the discretization and the script are checked
    /// where they are applied, as a live command's would be).
    fn check(&self) -> Result<(), String> {
        crate::scene::check_chi(self.chi).map_err(|e| format!("chi: {e}"))?;
        if self.run == 0 {
            return Err("run: the runs count from 1, got 0".into());
        }
        if self.every == 0 {
            return Err("every: the frame cadence must be ≥ 1 step, got 0".into());
        }
        if let Some(every) = &self.checkpoint_every {
            cadence(every).map_err(|e| format!("checkpoint_every: {e}"))?;
        }
        Ok(())
    }

    pub fn run_spec(&self) -> Result<RunSpec, String> {
        RunSpec::from_text(&self.spec)
    }

    pub fn discretization(&self) -> Discretization {
        Discretization {
            m: self.m,
            dx: self.dx,
            scheme: self.scheme.clone(),
            ratio: self.ratio,
            region: self.region.clone(),
            band: self.band.clone(),
        }
    }

    /// The script lines not yet fired, parsed again.
    pub fn script(&self) -> Result<Vec<Timed>, String> {
        super::script::parse("checkpoint script", &self.script.join("\n"))
            .map_err(|e| e.to_string())
    }
}

/// A whole checkpoint.
#[derive(Debug, Clone, PartialEq)]
pub struct Checkpoint {
    pub header: Header,
    pub state: State,
}

/// FNV-1a over bytes.
fn checksum(bytes: &[u8]) -> u64 {
    bytes.iter().fold(0xcbf2_9ce4_8422_2325, |h, &b| {
        (h ^ u64::from(b)).wrapping_mul(0x0000_0100_0000_01b3)
    })
}

impl Checkpoint {
    pub fn encode(&self) -> Result<Vec<u8>, String> {
        let header = toml::to_string(&self.header).map_err(|e| e.to_string())?;
        let mut payload = Vec::new();
        payload.extend((header.len() as u64).to_le_bytes());
        payload.extend(header.as_bytes());
        self.state.encode(&mut payload);
        let mut out = Vec::with_capacity(payload.len() + 48);
        out.extend(MAGIC);
        out.extend(FORMAT.to_le_bytes());
        out.extend((payload.len() as u64).to_le_bytes());
        out.extend(payload);
        out.extend(checksum(&out).to_le_bytes());
        Ok(out)
    }

    /// Decodes a checkpoint; the error says what is wrong with the bytes.
    pub fn decode(bytes: &[u8]) -> Result<Checkpoint, String> {
        if bytes.len() < MAGIC.len() || &bytes[..MAGIC.len()] != MAGIC {
            return Err("not a peridyn checkpoint".into());
        }
        let rest = &bytes[MAGIC.len()..];
        if rest.len() < 12 {
            return Err("the checkpoint is truncated (no header)".into());
        }
        let format = u32::from_le_bytes(rest[..4].try_into().unwrap_or_default());
        if format != FORMAT {
            return Err(format!(
                "checkpoint format {format}; this peridyn ({}) reads format {FORMAT}",
                env!("CARGO_PKG_VERSION")
            ));
        }
        let length = u64::from_le_bytes(rest[4..12].try_into().unwrap_or_default());
        // A damaged length may be anything up to 2⁶⁴ − 1: the sum saturates instead of wrapping
        // around to a size that matches.
        let expected = length.saturating_add((MAGIC.len() + 12 + 8) as u64);
        if bytes.len() as u64 != expected {
            return Err(format!(
                "the checkpoint is {} bytes where its header announces {expected}: truncated \
                 or extended",
                bytes.len()
            ));
        }
        let end = bytes.len() - 8;
        let stored = u64::from_le_bytes(bytes[end..].try_into().unwrap_or_default());
        if checksum(&bytes[..end]) != stored {
            return Err("the checkpoint's checksum does not match: it is corrupt".into());
        }
        let payload = &bytes[MAGIC.len() + 12..end];
        let header_len = payload
            .get(..8)
            .map(|b| u64::from_le_bytes(b.try_into().unwrap_or_default()) as usize)
            .filter(|&n| n <= payload.len() - 8)
            .ok_or("the checkpoint's header length is out of range")?;
        let header_text = std::str::from_utf8(&payload[8..8 + header_len])
            .map_err(|_| "the checkpoint's header is not UTF-8")?;
        let header: Header =
            toml::from_str(header_text).map_err(|e| format!("the checkpoint's header: {e}"))?;
        header
            .check()
            .map_err(|e| format!("the checkpoint's header: {e}"))?;
        let state = State::decode(&payload[8 + header_len..])
            .map_err(|e| format!("the checkpoint's state: {e}"))?;
        Ok(Checkpoint { header, state })
    }

    /// Writes atomically: the previous file at `path` stays until this one is complete.
    pub fn write(&self, path: &Path) -> Result<(), String> {
        let bytes = self.encode()?;
        let synced = crate::export::vtu::Durability::Synced;
        crate::export::vtu::atomically(path, synced, |out| std::io::Write::write_all(out, &bytes))
            .map_err(|e| format!("cannot write the checkpoint {}: {e}", path.display()))
    }

    pub fn read(path: &Path) -> Result<Checkpoint, String> {
        let bytes =
            std::fs::read(path).map_err(|e| format!("cannot read {}: {e}", path.display()))?;
        Checkpoint::decode(&bytes).map_err(|e| format!("{}: {e}", path.display()))
    }
}

/// A checkpoint cadence: `N steps`, a bare N (steps) or a time (`20 us`), more than zero.
fn cadence(every: &str) -> Result<Trigger, String> {
    let trimmed = every.trim();
    let every = match trimmed.parse::<u64>() {
        Ok(n) => Trigger::Step(n),
        Err(_) => super::script::parse_when(trimmed)?,
    };
    if matches!(every, Trigger::Step(0)) || matches!(every, Trigger::Time(t) if t <= 0.0) {
        return Err(format!("`{trimmed}`: the cadence must be > 0"));
    }
    Ok(every)
}

/// When to write checkpoints: every N steps or every span of simulated time.
#[derive(Debug, Clone, PartialEq)]
pub struct Plan {
    pub path: std::path::PathBuf,
    pub every: Trigger,
    /// The next step or time at which one is due.
    next: Trigger,
}

impl Plan {
    /// `every` as `N steps`, a bare N (steps) or a time (`20 us`).
    pub fn new(path: std::path::PathBuf, every: &str) -> Result<Plan, String> {
        let every = cadence(every).map_err(|e| format!("--checkpoint-every: {e}"))?;
        Ok(Plan {
            path,
            next: every,
            every,
        })
    }

    /// A new run: its step count starts again at 0.
    pub fn restart(&mut self) {
        self.next = self.every;
    }

    /// The cadence as text (stored in the checkpoint to go on with after a resume).
    pub fn cadence(&self) -> String {
        self.every.to_string()
    }

    /// Whether one is due after the step that reached `step`, `time`; then the next is set.
    pub fn due(&mut self, step: u64, time: f64) -> bool {
        if !self.next.due(step, time) {
            return false;
        }
        self.next = match (self.every, self.next) {
            (Trigger::Step(n), _) => Trigger::Step((step / n + 1) * n),
            (Trigger::Time(span), _) => {
                Trigger::Time(((time / span * (1.0 + 1e-12)).floor() + 1.0) * span)
            }
        };
        true
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sample() -> Checkpoint {
        let mut state = State::default();
        state.put_f64("field", vec![1.0, 2.0]);
        Checkpoint {
            header: Header {
                peridyn: "0.1.0".into(),
                spec: "preset = \"x\"".into(),
                run: 2,
                m: 4.0,
                dx: 1e-3,
                scheme: "standard".into(),
                ratio: None,
                region: None,
                band: Some("8 mm".into()),
                every: 10,
                chi: 0.95,
                script: vec!["at 20 steps set chi 0.9".into()],
                checkpoint_every: Some("100 steps".into()),
            },
            state,
        }
    }

    #[test]
    fn round_trips_and_refuses_damage() {
        let c = sample();
        let bytes = c.encode().unwrap();
        assert_eq!(Checkpoint::decode(&bytes).unwrap(), c);
        assert!(
            Checkpoint::decode(&bytes[..bytes.len() - 3])
                .unwrap_err()
                .contains("truncated")
        );
        let mut flipped = bytes.clone();
        let k = flipped.len() / 2;
        flipped[k] ^= 0x40;
        assert!(
            Checkpoint::decode(&flipped)
                .unwrap_err()
                .contains("corrupt")
        );
        let mut other = bytes.clone();
        other[MAGIC.len()] = 9;
        assert!(Checkpoint::decode(&other).unwrap_err().contains("format 9"));
        assert!(Checkpoint::decode(b"random bytes, not a checkpoint at all").is_err());
        assert_eq!(c.header.script().unwrap().len(), 1);
        let mut huge = bytes.clone();
        huge[MAGIC.len() + 4..MAGIC.len() + 12].copy_from_slice(&u64::MAX.to_le_bytes());
        assert!(
            Checkpoint::decode(&huge)
                .unwrap_err()
                .contains("truncated or extended")
        );
    }

    #[test]
    fn a_sealed_checkpoint_with_values_out_of_range_is_refused() {
        type Damage = fn(&mut Header);
        let cases: [(Damage, &str); 6] = [
            (|h| h.chi = f64::NAN, "chi: χ must be in (0, 1]"),
            (
                |h| h.checkpoint_every = Some("0 steps".into()),
                "checkpoint_every: `0 steps`: the cadence must be > 0",
            ),
            (
                |h| h.checkpoint_every = Some("-5 us".into()),
                "checkpoint_every: `-5` is not a time or step count ≥ 0",
            ),
            (|h| h.chi = 1.5, "chi: χ must be in (0, 1]"),
            (|h| h.every = 0, "every: the frame cadence must be ≥ 1"),
            (|h| h.run = 0, "run: the runs count from 1"),
        ];
        for (damage, needle) in cases {
            let mut c = sample();
            damage(&mut c.header);
            let e = Checkpoint::decode(&c.encode().unwrap()).unwrap_err();
            assert!(e.starts_with("the checkpoint's header: "), "{e}");
            assert!(e.contains(needle), "{e}");
        }
    }

    #[test]
    fn a_failed_write_leaves_the_previous_checkpoint() {
        let dir = std::env::temp_dir().join(format!("peridyn-ckpt-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("run.ckpt");
        sample().write(&path).unwrap();
        let before = std::fs::read(&path).unwrap();
        // A write cut short (the process killed, the disk full) never reaches `path`.
        let synced = crate::export::vtu::Durability::Synced;
        let cut = crate::export::vtu::atomically(&path, synced, |out| {
            std::io::Write::write_all(out, &before[..before.len() / 2])?;
            Err(std::io::Error::other("killed"))
        });
        assert!(cut.is_err());
        assert_eq!(std::fs::read(&path).unwrap(), before);
        assert!(Checkpoint::read(&path).is_ok());
    }

    #[test]
    fn plans_fall_due_on_their_cadence() {
        let mut p = Plan::new("x".into(), "100").unwrap();
        let due: Vec<u64> = (1..=350).filter(|&n| p.due(n, 0.0)).collect();
        assert_eq!(due, [100, 200, 300]);
        let mut p = Plan::new("x".into(), "2 us").unwrap();
        let due: Vec<u64> = (1..=10).filter(|&n| p.due(n, n as f64 * 0.7e-6)).collect();
        assert_eq!(due, [3, 6, 9], "at 2.1, 4.2, 6.3 µs");
        assert!(Plan::new("x".into(), "0").is_err());
        assert!(Plan::new("x".into(), "3 parsecs").is_err());
    }
}
