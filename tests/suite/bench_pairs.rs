//! `peridyn bench --pairs --quick`: the harness that re-measures the docs' headline pairs runs
//! every pair on its small variants, end to end, and reports a speed-up, the peak memory and
//! the accuracy figure of each. Its figures are not asserted (speed goals live in the
//! benchmark's reports); that every pair runs and reads its accuracy scalars is.

use peridyn::bench::pairs::PAIRS;

use crate::common::peridyn;

/// What a successful `peridyn` run with `args` printed.
fn table(args: &[&str]) -> String {
    let out = peridyn(args);
    let stdout = String::from_utf8_lossy(&out.stdout).into_owned();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{stderr}\n{stdout}");
    stdout
}

/// The table's rows of pairs (each names its preset as "(`preset`)").
fn pair_rows(stdout: &str) -> Vec<&str> {
    stdout
        .lines()
        .filter(|l| l.starts_with("| ") && l.contains("`)"))
        .collect()
}

#[test]
fn quick_pairs_run_end_to_end_and_report_every_figure() {
    let stdout = table(&["bench", "--pairs", "--quick"]);
    let rows = pair_rows(&stdout);
    assert_eq!(rows.len(), PAIRS.len(), "one row per pair:\n{stdout}");
    for (row, pair) in rows.iter().zip(PAIRS) {
        assert!(row.contains(pair.preset), "{row}");
        let cells: Vec<&str> = row.split(" | ").collect();
        let speed_up: f64 = cells[4].trim_end_matches('×').parse().unwrap_or(f64::NAN);
        assert!(speed_up.is_finite() && speed_up > 0.0, "speed-up: {row}");
        if cfg!(unix) {
            assert!(!cells[5].contains('–'), "peak memory: {row}");
        }
        assert!(
            !row.contains("not reported") && !row.contains("no crack found"),
            "accuracy scalar missing: {row}"
        );
    }
}

/// `--only PRESET` runs that preset's pairs alone; a preset with no pair is refused with the
/// list of the pairs' presets.
#[test]
fn only_runs_one_presets_pairs_and_refuses_an_unknown_preset() {
    let stdout = table(&[
        "bench",
        "--pairs",
        "--quick",
        "--only",
        "kalthoff-winkler-dh",
    ]);
    let rows = pair_rows(&stdout);
    assert_eq!(rows.len(), 1, "{stdout}");
    assert!(rows[0].contains("(`kalthoff-winkler-dh`)"), "{stdout}");

    let out = peridyn(&["bench", "--pairs", "--only", "no-such-preset"]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success());
    assert!(
        stderr.contains("--only")
            && stderr.contains("no-such-preset")
            && stderr.contains("screw-3d"),
        "{stderr}"
    );
}
