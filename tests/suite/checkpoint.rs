//! Restarts: a run continued from a checkpoint ends with final fields bit-identical to the
//! uninterrupted run (dynamics with damage, the adaptive hybrid with a script that changes Δt
//! and χ, corrosion on one grid and on two); damaged, foreign or truncated files are refused with exit code 2; a run
//! killed while writing checkpoints leaves one that resumes.

use std::collections::BTreeMap;
use std::path::PathBuf;
use std::process::{Command, Output, Stdio};
use std::time::{Duration, Instant};

use peridyn::readback;

use crate::common::peridyn;

fn temp(name: &str) -> PathBuf {
    crate::common::temp("checkpoint", name)
}

fn ok(out: Output) -> String {
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{stderr}");
    String::from_utf8_lossy(&out.stdout).into()
}

/// The `final time: … field hashes: …` line of a run's summary.
fn final_hashes(stdout: &str) -> String {
    stdout
        .lines()
        .find(|l| l.starts_with("final time: "))
        .unwrap_or_else(|| panic!("no final hashes in: {stdout}"))
        .to_string()
}

/// Records `preset`/`variant` whole, then again writing checkpoints every `every` steps, and
/// resumes from the last checkpoint: the resumed run ends on the same fields, bit for bit.
/// Returns the node counts per frame of the whole recording and of the resumed one.
fn resumes_bit_for_bit(
    preset: &str,
    variant: &str,
    every: u64,
    script: Option<&str>,
) -> (BTreeMap<i64, usize>, BTreeMap<i64, usize>) {
    let name = format!("{preset}-{variant}");
    let mut common = vec!["record", preset, "--variant", variant, "-q"];
    let script_path = temp(&format!("{name}.script"));
    if let Some(text) = script {
        std::fs::write(&script_path, text).unwrap();
        common.extend(["--script", script_path.to_str().unwrap()]);
    }
    let whole = temp(&format!("{name}-whole.rrd"));
    let mut args = common.clone();
    args.extend(["-o", whole.to_str().unwrap()]);
    let expected = final_hashes(&ok(peridyn(&args)));

    let first = temp(&format!("{name}-first.rrd"));
    let checkpoint = temp(&format!("{name}.ckpt"));
    let every = every.to_string();
    let mut args = common.clone();
    args.extend([
        "-o",
        first.to_str().unwrap(),
        "--checkpoint-every",
        &every,
        "--checkpoint",
        checkpoint.to_str().unwrap(),
    ]);
    assert_eq!(
        final_hashes(&ok(peridyn(&args))),
        expected,
        "checkpointing changes nothing"
    );

    let resumed = temp(&format!("{name}-resumed.rrd"));
    let stdout = ok(peridyn(&[
        "resume",
        checkpoint.to_str().unwrap(),
        "-o",
        resumed.to_str().unwrap(),
        "-q",
    ]));
    assert_eq!(
        final_hashes(&stdout),
        expected,
        "{name}: resumed ≠ uninterrupted"
    );
    // The resumed recording starts at the checkpoint's step, not at 0.
    let counts = node_counts(&resumed);
    let start = *counts.keys().next().unwrap();
    assert!(start > 0, "{name}: resumed at step {start}");
    (node_counts(&whole), counts)
}

/// Points per frame of the first `/nodes/` entity with points, in the recording's first run.
fn node_counts(path: &std::path::Path) -> BTreeMap<i64, usize> {
    let recordings = readback::read_each(path).unwrap();
    let (_, first_run) = &recordings[0];
    first_run
        .entities
        .iter()
        .filter(|(n, _)| n.starts_with("/nodes/"))
        .map(|(_, e)| e.points.clone())
        .find(|points| !points.is_empty())
        .unwrap()
}

#[test]
fn a_fracture_run_resumes_bit_for_bit() {
    resumes_bit_for_bit("kalthoff-winkler", "small", 100, None);
}

#[test]
fn an_adaptive_hybrid_run_with_a_script_resumes_bit_for_bit() {
    resumes_bit_for_bit(
        "kalthoff-winkler",
        "small-hybrid",
        100,
        // Fired before the last checkpoint (step 1200 of 1252): in its command log; fired
        // after it: in its script lines (a Δt change the resumed run must still make).
        Some(
            "at 60 steps set dt 0.35 stable\nat 150 steps set chi 0.9\nat 200 steps set every 7\n\
             at 1210 steps set dt 0.3 stable\n",
        ),
    );
}

/// Issue 17: a dual-horizon run whose particles split before its last checkpoint (and after
/// it) resumes bit for bit: the checkpoint replays its splits on the fresh scene.
#[test]
fn a_splitting_dual_horizon_run_resumes_bit_for_bit() {
    // Checkpoints at steps 1 100 and 2 200 of 3 000.
    let (whole, resumed) = resumes_bit_for_bit("branching", "small", 1100, None);
    let (initial, at_checkpoint, last) = (
        *whole.values().next().unwrap(),
        *resumed.values().next().unwrap(),
        *resumed.values().last().unwrap(),
    );
    assert!(
        initial < at_checkpoint && at_checkpoint < last,
        "splits before and after the checkpoint: {initial} → {at_checkpoint} → {last}"
    );
}

/// A multi-adaptive run whose switch refined cells before its last checkpoint (and after it)
/// resumes bit for bit: the checkpoint replays the refinements on the fresh levels.
#[test]
fn a_multi_adaptive_run_resumes_bit_for_bit() {
    resumes_bit_for_bit("kalthoff-winkler-multigrid", "small", 150, None);
}

#[test]
fn a_corrosion_run_resumes_bit_for_bit() {
    resumes_bit_for_bit("corrosion-1d", "small", 150, None);
}

#[test]
fn a_multigrid_corrosion_run_resumes_bit_for_bit() {
    resumes_bit_for_bit("corrosion-1d", "multigrid", 150, None);
}

#[test]
fn damaged_foreign_and_truncated_checkpoints_are_refused() {
    let checkpoint = temp("plate.ckpt");
    ok(peridyn(&[
        "record",
        "vibrating-plate",
        "--variant",
        "small",
        "--steps",
        "20",
        "--checkpoint-every",
        "10",
        "--checkpoint",
        checkpoint.to_str().unwrap(),
        "-o",
        temp("plate.rrd").to_str().unwrap(),
        "-q",
    ]));
    let bytes = std::fs::read(&checkpoint).unwrap();
    let mut flipped = bytes.clone();
    let k = flipped.len() / 3;
    flipped[k] ^= 1;
    let mut other_version = bytes.clone();
    other_version[19] = 7;
    let cases: [(&str, Vec<u8>, &str); 4] = [
        ("truncated", bytes[..bytes.len() / 2].to_vec(), "truncated"),
        ("corrupt", flipped, "corrupt"),
        ("other-version", other_version, "format 7"),
        (
            "random",
            (0..4096u32)
                .map(|i| i.wrapping_mul(2654435761) as u8)
                .collect(),
            "not a peridyn checkpoint",
        ),
    ];
    for (name, content, needle) in cases {
        let path = temp(&format!("{name}.ckpt"));
        std::fs::write(&path, content).unwrap();
        let out = peridyn(&["resume", path.to_str().unwrap(), "-q"]);
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{name}: {stderr}");
        assert!(stderr.contains(needle), "{name}: {stderr}");
        assert!(
            stderr.contains(path.to_str().unwrap()),
            "names the file: {stderr}"
        );
        assert!(!stderr.contains("panicked"), "{stderr}");
    }
}

/// A checkpoint after every step, and the process killed (SIGKILL) while running: the file is
/// always a complete checkpoint (written aside, renamed into place), and the run resumes.
#[test]
fn a_run_killed_while_checkpointing_resumes() {
    let checkpoint = temp("killed.ckpt");
    let mut child = Command::new(env!("CARGO_BIN_EXE_peridyn"))
        .args([
            "record",
            "kalthoff-winkler",
            "--variant",
            "small",
            "--checkpoint-every",
            "1",
            "--checkpoint",
            checkpoint.to_str().unwrap(),
            "-o",
            temp("killed.rrd").to_str().unwrap(),
            "-q",
        ])
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    let start = Instant::now();
    while !checkpoint.exists() {
        assert!(
            start.elapsed() < Duration::from_secs(60),
            "no checkpoint written"
        );
        std::thread::sleep(Duration::from_millis(10));
    }
    std::thread::sleep(Duration::from_millis(300));
    child.kill().unwrap();
    child.wait().unwrap();
    let out = peridyn(&[
        "resume",
        checkpoint.to_str().unwrap(),
        "-o",
        temp("killed-resumed.rrd").to_str().unwrap(),
        "-q",
    ]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{stderr}");
    assert!(final_hashes(&String::from_utf8_lossy(&out.stdout)).contains("damage"));
}
