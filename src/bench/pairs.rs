//! `peridyn bench --pairs`: the headline speed pairs of the docs, re-measured end to end.
//!
//! Each side of a pair is a whole `peridyn record` process (setup, stepping, frames and the
//! recording included), each at the Δt its preset gives it (0.7 of its own stable step unless
//! the docs say otherwise), the two sides alternated (fast, baseline, baseline, fast, …) so a
//! drift of the machine falls on both. Beside the speed-up stands the accuracy the docs quote
//! for it, read from the final scalars the same runs print. The table is Markdown, headed by
//! the date, the CPU, the thread count and the SIMD implementation.

use std::collections::HashMap;
use std::process::{Command, Stdio};
use std::time::Instant;

/// One side of a pair: a variant of the pair's preset and `--set` overrides.
#[derive(Debug, Clone, Copy)]
pub struct Side {
    pub variant: &'static str,
    pub sets: &'static [&'static str],
}

/// An accuracy figure quoted beside a speed-up, from the two runs' final scalars (the names
/// `peridyn record` prints).
#[derive(Debug, Clone, Copy)]
pub enum Accuracy {
    /// Both runs' crack angle of this name (`crack angle <name>`), in degrees.
    Angle(&'static str),
    /// |fast − baseline| / |baseline| of one scalar.
    Relative(&'static str),
    /// Both runs' values of one scalar and their difference.
    Absolute(&'static str),
    /// The docs' figure needs more than the final frame (named here); the table says where
    /// it is.
    Elsewhere(&'static str),
}

/// A headline pair: the run that is meant to be faster, and the run it is measured against.
#[derive(Debug, Clone, Copy)]
pub struct Pair {
    pub what: &'static str,
    pub preset: &'static str,
    pub fast: Side,
    pub baseline: Side,
    /// The same comparison on small variants or a shortened run, seconds each: `--quick`, run
    /// in CI to keep the harness working (its figures are not asserted).
    pub quick: [Side; 2],
    pub accuracy: &'static [Accuracy],
}

const fn side(variant: &'static str) -> Side {
    Side { variant, sets: &[] }
}

const fn with(variant: &'static str, sets: &'static [&'static str]) -> Side {
    Side { variant, sets }
}

/// The large domain S11's layer is measured against (docs/validation.md, S11).
const S11_LARGE: &[&str] = &[
    "geometry.difference.base.sphere.radius=\"670 mm\"",
    "absorbing=false",
];

/// The multi-adaptive pairs' accuracy: the tip-circle energy and both crack angles.
const KW_MULTIGRID_ACCURACY: &[Accuracy] = &[
    Accuracy::Relative("energy/circle/upper_tip"),
    Accuracy::Angle("upper"),
    Accuracy::Angle("lower"),
];

/// `--quick`'s multi-adaptive pair: the small variants to 45 µs (the cracks have started).
const QUICK_KW_MULTIGRID: &[&str] = &["time.end=\"45 us\""];

/// The pairs of the README's headline table and docs/validation.md's speed sections, each side
/// at the Δt its preset gives it.
pub const PAIRS: &[Pair] = &[
    Pair {
        what: "Kalthoff–Winkler paper grid: hybrid against all standard",
        preset: "kalthoff-winkler",
        fast: side("paper-fast"),
        baseline: side("paper-fast-standard"),
        quick: [side("small-fast"), side("small")],
        accuracy: &[Accuracy::Angle("upper"), Accuracy::Angle("lower")],
    },
    Pair {
        what: "corrosion-3d, 1 000 steps: fixed hybrid against all standard",
        preset: "corrosion-3d",
        fast: with("", &["time.end=\"100 s\""]),
        baseline: with("standard", &["time.end=\"100 s\""]),
        quick: [
            with("small", &["time.end=\"50 s\""]),
            with("small-standard", &["time.end=\"50 s\""]),
        ],
        accuracy: &[Accuracy::Absolute("relative volume loss")],
    },
    Pair {
        what: "Multi-adaptive Kalthoff–Winkler against uniform fine",
        preset: "kalthoff-winkler-multigrid",
        fast: side("full-band-hybrid"),
        baseline: side("full-band-fine"),
        quick: [
            with("small-hybrid-fast", QUICK_KW_MULTIGRID),
            with("small-fine", QUICK_KW_MULTIGRID),
        ],
        accuracy: KW_MULTIGRID_ACCURACY,
    },
    Pair {
        what: "Multi-adaptive Kalthoff–Winkler, standard on both levels, against uniform fine",
        preset: "kalthoff-winkler-multigrid",
        fast: side("full-band"),
        baseline: side("full-band-fine"),
        quick: [
            with("small", QUICK_KW_MULTIGRID),
            with("small-fine", QUICK_KW_MULTIGRID),
        ],
        accuracy: KW_MULTIGRID_ACCURACY,
    },
    Pair {
        what: "screw-3d: multi-grid against uniform fine",
        preset: "screw-3d",
        fast: side(""),
        baseline: side("fine"),
        quick: [
            with("small", &["time.end=\"1800 s\""]),
            with("small-fine", &["time.end=\"1800 s\""]),
        ],
        accuracy: &[Accuracy::Absolute("relative volume loss")],
    },
    Pair {
        what: "nnpp-screw: multi-grid against uniform fine",
        preset: "nnpp-screw",
        fast: side(""),
        baseline: side("fine"),
        quick: [
            with("small", &["time.end=\"3 h\""]),
            with("small-fine", &["time.end=\"3 h\""]),
        ],
        accuracy: &[Accuracy::Absolute("relative volume loss")],
    },
    Pair {
        what: "S2 corrosion on an unbounded domain: absorbing layer against the large domain",
        preset: "abc-corrosion-2d",
        fast: side("scaled"),
        baseline: side("scaled-reference"),
        quick: [
            with("small", &["time.end=\"0.02 s\""]),
            with("small-reference", &["time.end=\"0.02 s\""]),
        ],
        accuracy: &[Accuracy::Elsewhere(
            "the node-by-node error of the frames: docs/validation.md, S2",
        )],
    },
    Pair {
        what: "S11 half-space impact: absorbing layer against the large domain",
        preset: "half-space-impact",
        fast: side(""),
        baseline: with("", S11_LARGE),
        quick: [
            with("small", &["time.end=\"30 us\""]),
            with("small-reference", &["time.end=\"30 us\""]),
        ],
        accuracy: &[
            Accuracy::Relative("crack_length/right"),
            Accuracy::Angle("right"),
            Accuracy::Relative("energy/circle/near"),
        ],
    },
    Pair {
        what: "Kalthoff–Winkler, dual horizon: adaptive against fine",
        preset: "kalthoff-winkler-dh",
        fast: with("own-step", &["output.every=100000"]),
        baseline: with("fine-own-step", &["output.every=100000"]),
        quick: [
            with("own-step", &["output.every=100000"]),
            with("fine-own-step", &["output.every=100000"]),
        ],
        accuracy: &[Accuracy::Angle("upper"), Accuracy::Angle("lower")],
    },
];

/// What one process reported.
#[derive(Debug, Clone, Default)]
pub struct Run {
    pub seconds: f64,
    /// Peak resident memory (bytes), where the platform reports it.
    pub peak_bytes: Option<u64>,
    pub scalars: HashMap<String, f64>,
}

/// The final scalars of `peridyn record`'s report: every `name: number [unit]` line (the first
/// number after the first colon). "crack angle upper: 65.3°" becomes `crack angle upper`.
pub fn parse_scalars(report: &str) -> HashMap<String, f64> {
    let mut scalars = HashMap::new();
    for line in report.lines() {
        let Some((name, rest)) = line.split_once(": ") else {
            continue;
        };
        let token: String = rest
            .split_whitespace()
            .next()
            .unwrap_or("")
            .chars()
            .take_while(|c| c.is_ascii_digit() || matches!(c, '.' | '-' | '+' | 'e' | 'E'))
            .collect();
        if let Ok(value) = token.parse::<f64>() {
            scalars.insert(name.trim().to_string(), value);
        }
    }
    scalars
}

/// Runs `peridyn record` for one side as a child process of this executable.
fn run_side(preset: &str, side: &Side, scratch: &std::path::Path) -> Result<Run, String> {
    let exe = std::env::current_exe().map_err(|e| format!("this executable: {e}"))?;
    let mut command = Command::new(exe);
    command.args(["record", preset]);
    if !side.variant.is_empty() {
        command.args(["--variant", side.variant]);
    }
    command.args(["-q", "-o"]).arg(scratch);
    for set in side.sets {
        command.args(["--set", set]);
    }
    command.stdout(Stdio::piped()).stderr(Stdio::piped());
    let started = Instant::now();
    let child = command
        .spawn()
        .map_err(|e| format!("{preset} [{}]: cannot start: {e}", side.variant))?;
    let (output, peak_bytes) =
        wait_with_peak_memory(child).map_err(|e| format!("{preset} [{}]: {e}", side.variant))?;
    let seconds = started.elapsed().as_secs_f64();
    let _ = std::fs::remove_file(scratch);
    let stdout = String::from_utf8_lossy(&output.stdout);
    if !output.status.success() {
        return Err(format!(
            "{preset} [{}] failed ({}): {}",
            side.variant,
            output.status,
            String::from_utf8_lossy(&output.stderr).trim()
        ));
    }
    Ok(Run {
        seconds,
        peak_bytes,
        scalars: parse_scalars(&stdout),
    })
}

/// The child's output and, on Unix, its peak resident memory (its own `getrusage`, read by
/// `wait4`: the children's aggregate of `getrusage(RUSAGE_CHILDREN)` would mix the runs).
#[cfg(unix)]
fn wait_with_peak_memory(
    mut child: std::process::Child,
) -> Result<(std::process::Output, Option<u64>), String> {
    use std::io::Read;
    use std::os::unix::process::ExitStatusExt;
    // Drain both pipes on threads, so a child that fills one does not block.
    let drain = |pipe: Option<Box<dyn Read + Send>>| {
        std::thread::spawn(move || {
            let mut bytes = Vec::new();
            if let Some(mut pipe) = pipe {
                let _ = pipe.read_to_end(&mut bytes);
            }
            bytes
        })
    };
    let stdout = drain(
        child
            .stdout
            .take()
            .map(|p| Box::new(p) as Box<dyn Read + Send>),
    );
    let stderr = drain(
        child
            .stderr
            .take()
            .map(|p| Box::new(p) as Box<dyn Read + Send>),
    );
    let pid = child.id() as libc::pid_t;
    let mut status = 0;
    // SAFETY: a zeroed rusage is a valid value of the plain C struct, and wait4 writes it.
    let mut usage: libc::rusage = unsafe { std::mem::zeroed() };
    // SAFETY: pid is this process's own child, not yet reaped (std waits only when asked).
    let reaped = unsafe { libc::wait4(pid, &mut status, 0, &mut usage) };
    if reaped != pid {
        return Err(format!(
            "waiting for the run: {}",
            std::io::Error::last_os_error()
        ));
    }
    let output = std::process::Output {
        status: std::process::ExitStatus::from_raw(status),
        stdout: stdout.join().unwrap_or_default(),
        stderr: stderr.join().unwrap_or_default(),
    };
    // Linux reports kilobytes, macOS bytes.
    let scale = if cfg!(target_os = "macos") { 1 } else { 1024 };
    Ok((output, Some(usage.ru_maxrss as u64 * scale)))
}

#[cfg(not(unix))]
fn wait_with_peak_memory(
    child: std::process::Child,
) -> Result<(std::process::Output, Option<u64>), String> {
    child
        .wait_with_output()
        .map(|output| (output, None))
        .map_err(|e| e.to_string())
}

/// The accuracy cell of a pair from one fast and one baseline run.
fn accuracy_cell(accuracy: &[Accuracy], fast: &Run, baseline: &Run) -> String {
    let both = |name: &str| {
        let get = |run: &Run| run.scalars.get(name).copied();
        get(fast).zip(get(baseline))
    };
    let missing = |name: &str| format!("{name}: not reported");
    accuracy
        .iter()
        .map(|figure| match *figure {
            Accuracy::Angle(name) => {
                let key = format!("crack angle {name}");
                both(&key).map_or_else(
                    || format!("{name}: no crack found"),
                    |(a, b)| format!("{name} {a:.1}° / {b:.1}°"),
                )
            }
            Accuracy::Relative(name) => match both(name) {
                Some((a, b)) if b != 0.0 => format!(
                    "{name} {a:.4e} / {b:.4e} ({:+.2} %)",
                    100.0 * (a - b) / b.abs()
                ),
                _ => missing(name),
            },
            Accuracy::Absolute(name) => both(name).map_or_else(
                || missing(name),
                |(a, b)| format!("{name} {a:.4} / {b:.4} (Δ {:+.1e})", a - b),
            ),
            Accuracy::Elsewhere(text) => text.to_string(),
        })
        .collect::<Vec<_>>()
        .join("; ")
}

fn median(values: &mut [f64]) -> f64 {
    values.sort_by(f64::total_cmp);
    let n = values.len();
    if n == 0 {
        return f64::NAN;
    }
    if n % 2 == 1 {
        values[n / 2]
    } else {
        0.5 * (values[n / 2 - 1] + values[n / 2])
    }
}

/// Civil date (UTC) of a day count since 1970-01-01 (Hinnant's algorithm): the table's date,
/// without a calendar crate for one line.
fn civil_date(days: i64) -> (i64, u32, u32) {
    let z = days + 719_468;
    let era = z.div_euclid(146_097);
    let doe = z.rem_euclid(146_097);
    let yoe = (doe - doe / 1460 + doe / 36_524 - doe / 146_096) / 365;
    let doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
    let mp = (5 * doy + 2) / 153;
    let day = (doy - (153 * mp + 2) / 5 + 1) as u32;
    let month = if mp < 10 { mp + 3 } else { mp - 9 } as u32;
    let year = yoe + era * 400 + i64::from(month <= 2);
    (year, month, day)
}

fn today() -> String {
    let seconds = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| d.as_secs() as i64);
    let (y, m, d) = civil_date(seconds.div_euclid(86_400));
    format!("{y:04}-{m:02}-{d:02}")
}

fn cpu_model() -> String {
    std::fs::read_to_string("/proc/cpuinfo")
        .ok()
        .and_then(|text| {
            text.lines()
                .find(|l| l.starts_with("model name"))
                .and_then(|l| l.split_once(':'))
                .map(|(_, v)| v.trim().to_string())
        })
        .unwrap_or_else(|| std::env::consts::ARCH.to_string())
}

fn gigabytes(bytes: Option<u64>) -> String {
    bytes.map_or("–".to_string(), |b| format!("{:.2}", b as f64 / 1e9))
}

/// The table `report` writes, and how many pairs failed to run.
pub struct PairsReport {
    pub table: String,
    pub failures: usize,
}

/// Both sides of one pair, `rounds` alternations: fast, baseline, baseline, fast, …, so a
/// steady drift of the machine falls on both sides alike.
fn measure_pair(
    pair: &Pair,
    sides: [Side; 2],
    rounds: usize,
    scratch: &std::path::Path,
    progress: &mut dyn FnMut(&str),
) -> Result<[Vec<Run>; 2], String> {
    let mut runs = [Vec::new(), Vec::new()];
    for round in 0..rounds {
        let order = if round % 2 == 0 { [0, 1] } else { [1, 0] };
        for which in order {
            let side = &sides[which];
            let name = if side.variant.is_empty() {
                "base"
            } else {
                side.variant
            };
            progress(&format!("{} [{name}]", pair.preset));
            runs[which].push(run_side(pair.preset, side, scratch)?);
        }
    }
    Ok(runs)
}

/// A side as the table names it: its variant and overrides.
fn describe(side: &Side) -> String {
    let mut text = if side.variant.is_empty() {
        "the base".to_string()
    } else {
        format!("`{}`", side.variant)
    };
    for set in side.sets {
        text += &format!(" `--set {set}`");
    }
    text
}

/// One row of the table.
fn row(pair: &Pair, sides: &[Side; 2], runs: &[Vec<Run>; 2]) -> String {
    let wall = |runs: &[Run]| median(&mut runs.iter().map(|r| r.seconds).collect::<Vec<_>>());
    let peak = |runs: &[Run]| runs.iter().filter_map(|r| r.peak_bytes).max();
    let [fast, baseline] = runs;
    let (fast_wall, baseline_wall) = (wall(fast), wall(baseline));
    format!(
        "| {} (`{}`) | {} | {} | {:.2} / {:.2} | {:.2}× | {} / {} | {} |\n",
        pair.what,
        pair.preset,
        describe(&sides[0]),
        describe(&sides[1]),
        fast_wall,
        baseline_wall,
        baseline_wall / fast_wall,
        gigabytes(peak(fast)),
        gigabytes(peak(baseline)),
        accuracy_cell(pair.accuracy, &fast[0], &baseline[0]),
    )
}

/// Runs `pairs` (`quick`: the small variants), `rounds` alternations each, and returns the
/// Markdown table; `progress` is told each run as it starts. A pair that fails to run gets a
/// row saying why, and the others still run.
pub fn report(
    pairs: &[&Pair],
    quick: bool,
    rounds: usize,
    progress: &mut dyn FnMut(&str),
) -> PairsReport {
    let scratch = std::env::temp_dir().join(format!("peridyn-pairs-{}.rrd", std::process::id()));
    let threads = std::thread::available_parallelism().map_or(1, |n| n.get());
    let mut table = format!(
        "## Headline pairs{}, end to end\n\n{}, {} ({} threads, {}), {} alternation{} each; \
         wall: the median over the runs of the whole `peridyn record` process, setup and \
         recording included; peak memory: the largest resident set.\n\n\
         | pair | fast run | baseline | wall fast / baseline (s) | speed-up | peak memory fast / baseline (GB) | accuracy, fast / baseline |\n\
         |---|---|---|---:|---:|---:|---|\n",
        if quick {
            " (quick: small variants)"
        } else {
            ""
        },
        today(),
        cpu_model(),
        threads,
        peridyn_core::simd::Simd::selected().name(),
        rounds,
        if rounds == 1 { "" } else { "s" },
    );
    let mut failures = 0;
    for &pair in pairs {
        let sides = if quick {
            pair.quick
        } else {
            [pair.fast, pair.baseline]
        };
        match measure_pair(pair, sides, rounds, &scratch, progress) {
            Ok(runs) => table += &row(pair, &sides, &runs),
            Err(e) => {
                failures += 1;
                table += &format!(
                    "| {} (`{}`) | {} | {} | failed: {} | | | |\n",
                    pair.what,
                    pair.preset,
                    describe(&sides[0]),
                    describe(&sides[1]),
                    e.replace('|', "/").replace('\n', " ")
                );
            }
        }
    }
    PairsReport { table, failures }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn record_report_lines_become_scalars() {
        let report = "steps: 584  frames: 13  wall: 8.68 s\n\
                      broken bonds: 71352\n\
                      energy/circle/near: 1.895071e5 J\n\
                      crack_length/right: 42.148 mm\n\
                      crack angle right: 63.0°\n\
                      recording: /tmp/x.rrd\n";
        let scalars = parse_scalars(report);
        assert_eq!(scalars["steps"], 584.0);
        assert_eq!(scalars["broken bonds"], 71352.0);
        assert_eq!(scalars["energy/circle/near"], 1.895071e5);
        assert_eq!(scalars["crack_length/right"], 42.148);
        assert_eq!(scalars["crack angle right"], 63.0);
        assert!(!scalars.contains_key("recording"));
    }

    #[test]
    fn civil_dates_of_known_days() {
        assert_eq!(civil_date(0), (1970, 1, 1));
        assert_eq!(civil_date(11_016), (2000, 2, 29));
        // 2026-12-07 is day 20 794.
        assert_eq!(civil_date(20_794), (2026, 12, 7));
    }

    #[test]
    fn the_median_of_even_and_odd_counts() {
        assert_eq!(median(&mut [3.0, 1.0, 2.0]), 2.0);
        assert_eq!(median(&mut [4.0, 1.0]), 2.5);
    }

    #[test]
    fn every_pair_names_variants_of_its_preset_and_valid_overrides() {
        for pair in PAIRS {
            for side in [pair.fast, pair.baseline].iter().chain(pair.quick.iter()) {
                let variant = (!side.variant.is_empty()).then_some(side.variant);
                let sets: Vec<String> = side.sets.iter().map(|s| s.to_string()).collect();
                let scene = crate::scene::Scene::load_with(pair.preset, variant, &sets);
                assert!(
                    scene.is_ok(),
                    "{} [{}]: {:?}",
                    pair.preset,
                    side.variant,
                    scene.err()
                );
            }
        }
    }
}
