//! Scripted runs from the command line: a bad script is refused with its file, line and the
//! allowed values (exit code 2); a scripted recording carries its command log and preset, and
//! `peridyn replay --resimulate` reproduces its final damage field bit for bit.

use std::path::PathBuf;

use peridyn::readback;

use crate::common::peridyn;

fn temp(name: &str) -> PathBuf {
    crate::common::temp("control", name)
}

fn stdout_line<'a>(out: &'a str, prefix: &str) -> &'a str {
    out.lines()
        .find_map(|l| l.strip_prefix(prefix))
        .unwrap_or_else(|| panic!("no `{prefix}` in: {out}"))
}

#[test]
fn a_bad_script_names_its_file_line_and_the_allowed_values() {
    let cases = [
        (
            "at 10 steps set colour red\n",
            "chi, dt, m, dx, scheme, every",
        ),
        ("\nat 10 parsecs set chi 0.9\n", "allowed: steps, s"),
        ("at 10 steps pause\n", "a script may give"),
    ];
    for (i, (text, needle)) in cases.iter().enumerate() {
        let script = temp(&format!("bad{i}.txt"));
        std::fs::write(&script, text).unwrap();
        let out = peridyn(&[
            "record",
            "vibrating-plate",
            "--variant",
            "small",
            "--script",
            script.to_str().unwrap(),
            "-o",
            temp("never.rrd").to_str().unwrap(),
        ]);
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{stderr}");
        let line = text.lines().position(|l| !l.is_empty()).unwrap() + 1;
        assert!(
            stderr.contains(&format!("{}:{line}:", script.display())),
            "file and line: {stderr}"
        );
        assert!(stderr.contains(needle), "{stderr}");
        assert!(!stderr.contains("panicked"), "{stderr}");
    }
    let out = peridyn(&[
        "record",
        "vibrating-plate",
        "--script",
        "/no/such/script.txt",
    ]);
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("/no/such/script.txt"));
}

/// The final damage values of the last recording of a file.
fn final_damage(path: &std::path::Path) -> (usize, i64, Vec<f32>) {
    let recordings = readback::read_each(path).unwrap();
    let (_, last) = recordings.last().unwrap();
    let values = &last.entity("/nodes/damage").unwrap().values;
    let (step, damage) = values.iter().next_back().unwrap();
    (recordings.len(), *step, damage.clone())
}

#[test]
fn a_scripted_recording_carries_its_commands_and_resimulates_exactly() {
    let script = temp("script.txt");
    std::fs::write(
        &script,
        "# halve the step, record a χ, then coarsen the horizon and restart\n\
         at 10 steps set dt 0.5 stable\n\
         at 5 us set chi 0.9\n\
         at 100 steps set m 3 restart\n\
         at 40 steps set every 7\n\
         at 1 s set chi 0.5\n",
    )
    .unwrap();
    let original = temp("scripted.rrd");
    let out = peridyn(&[
        "record",
        "kalthoff-winkler",
        "--variant",
        "small",
        "--steps",
        "200",
        "--every",
        "25",
        "--script",
        script.to_str().unwrap(),
        "-o",
        original.to_str().unwrap(),
        "-q",
    ]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    let stdout = String::from_utf8_lossy(&out.stdout).to_string();
    assert!(out.status.success(), "{stderr}");
    assert_eq!(stdout_line(&stdout, "runs: "), "2");
    assert!(stderr.contains("lines [6] never fired"), "{stderr}");
    let hash = stdout_line(&stdout, "final damage hash: ").to_string();
    let broken: f64 = stdout_line(&stdout, "broken bonds: ").parse().unwrap();
    assert!(broken > 0.0, "the test needs a damage field: {stdout}");

    // Two recordings (one per run); each carries its commands and the whole log so far.
    let recordings = readback::read_each(&original).unwrap();
    assert_eq!(recordings.len(), 2);
    assert_ne!(
        recordings[0].0, recordings[1].0,
        "a restart is a new recording"
    );
    let commands = |i: usize| {
        recordings[i]
            .1
            .entity("/control/commands")
            .unwrap()
            .texts
            .clone()
    };
    assert_eq!(
        commands(0),
        [
            "run 1 at 10 steps: set dt 0.5 stable",
            "run 1 at 16 steps: set chi 0.9",
            "run 1 at 100 steps: set m 3.0 restart",
        ],
        // Δt = 0.7 × 5.0494e-7 s for 10 steps (3.53 µs), then 0.5 × 5.0494e-7 s: 5.05 µs at 16.
        "χ fires at the first step at or after 5 µs"
    );
    assert_eq!(commands(1), ["run 2 at 40 steps: set every 7"]);
    let run_doc = recordings[1]
        .1
        .entity("/control/run")
        .unwrap()
        .texts
        .last()
        .unwrap()
        .clone();
    assert!(
        run_doc.contains("run 1 at 100 steps: set m 3.0 restart"),
        "{run_doc}"
    );
    assert!(
        run_doc.contains("run 2 at 40 steps: set every 7"),
        "{run_doc}"
    );
    let scene = peridyn::scene::Scene::load("kalthoff-winkler", Some("small")).unwrap();
    assert!(
        recordings[1].1.entity("/scene/preset").unwrap().texts[0].contains(&scene.preset_text),
        "the preset is stored whole in every run"
    );
    // Frames: every 25 steps until the cadence changed at step 40 of run 2, then every 7.
    let steps: Vec<i64> = recordings[1]
        .1
        .entity("/nodes/damage")
        .unwrap()
        .points
        .keys()
        .copied()
        .collect();
    assert_eq!(&steps[..3], &[0, 25, 42]);
    let last_steps: i64 = stdout_line(&stdout, "steps: ")
        .split_whitespace()
        .next()
        .unwrap()
        .parse()
        .unwrap();
    assert_eq!(*steps.last().unwrap(), last_steps);

    let again = temp("scripted-again.rrd");
    let out = peridyn(&[
        "replay",
        "--resimulate",
        original.to_str().unwrap(),
        "-o",
        again.to_str().unwrap(),
        "-q",
    ]);
    let stdout2 = String::from_utf8_lossy(&out.stdout).to_string();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert_eq!(stdout_line(&stdout2, "final damage hash: "), hash);
    assert_eq!(stdout_line(&stdout2, "runs: "), "2");
    let (n1, step1, damage1) = final_damage(&original);
    let (n2, step2, damage2) = final_damage(&again);
    assert_eq!((n1, step1), (n2, step2));
    assert!(damage1.iter().any(|&d| d > 0.0));
    assert!(
        damage1
            .iter()
            .zip(&damage2)
            .all(|(a, b)| a.to_bits() == b.to_bits()),
        "the recorded damage fields are identical"
    );
}

#[test]
fn replay_refuses_what_it_cannot_replay() {
    let out = peridyn(&["replay", "--resimulate", "/no/such.rrd"]);
    assert_eq!(out.status.code(), Some(2));
    let text = temp("not-a-recording.rrd");
    std::fs::write(&text, "hello").unwrap();
    let out = peridyn(&["replay", "--resimulate", text.to_str().unwrap()]);
    assert_eq!(out.status.code(), Some(2));
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(stderr.contains("not a Rerun recording"), "{stderr}");
}
