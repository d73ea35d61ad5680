//! The command line end to end: bad input gives one clear error and exit code 2, a recording
//! reads back with the expected layout, and an interrupted recording stays readable.

use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::{Duration, Instant};

use peridyn::adapt::masks::{Phase, SchemeClass};
use peridyn::readback;

use crate::common::peridyn;

/// Runs peridyn, asserts success and returns its stdout.
fn run_ok(args: &[&str]) -> String {
    let out = peridyn(args);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8_lossy(&out.stdout).to_string()
}

fn temp(name: &str) -> PathBuf {
    crate::common::temp("test", name)
}

const GOOD: &str = r#"
name = "plate"
dimension = 2
[geometry]
box = { min = [0.0, 0.0], max = ["20 mm", "10 mm"] }
[discretization]
spacing = "1 mm"
horizon = "3 dx"
[material]
density = "8000 kg/m^3"
youngs_modulus = "190 GPa"
fracture_energy = "22170 J/m^2"
[[precracks]]
segment = { from = ["0 mm", "5 mm"], to = ["5 mm", "5 mm"] }
[time]
dt = "0.5 stable"
end = "10 steps"
"#;

/// Writes a preset, runs `peridyn check` on it and returns (exit code, stderr).
fn check(name: &str, text: &str) -> (i32, String) {
    let path = temp(name);
    std::fs::write(&path, text).unwrap();
    let out = peridyn(&["check", path.to_str().unwrap()]);
    (
        out.status.code().unwrap_or(-1),
        String::from_utf8_lossy(&out.stderr).to_string(),
    )
}

fn assert_clear_error(name: &str, text: &str, must_contain: &[&str]) {
    let (code, stderr) = check(name, text);
    assert_eq!(code, 2, "{name}: exit code {code}, stderr: {stderr}");
    assert!(!stderr.contains("panicked"), "{stderr}");
    assert_eq!(
        stderr
            .trim()
            .lines()
            .filter(|l| l.starts_with("error"))
            .count(),
        1,
        "{stderr}"
    );
    assert!(stderr.contains(name), "error must name the file: {stderr}");
    for s in must_contain {
        assert!(stderr.contains(s), "{name}: `{s}` missing from: {stderr}");
    }
}

#[test]
fn good_preset_checks() {
    let (code, stderr) = check("good.toml", GOOD);
    assert_eq!(code, 0, "{stderr}");
}

#[test]
fn unknown_field_is_named_with_its_line() {
    let text = GOOD.replace(
        "density = \"8000 kg/m^3\"",
        "density = \"8000 kg/m^3\"\ncolour = \"red\"",
    );
    assert_clear_error("unknown.toml", &text, &["colour", ":11"]);
}

#[test]
fn negative_horizon_is_refused() {
    let text = GOOD.replace("horizon = \"3 dx\"", "horizon = \"-3 dx\"");
    assert_clear_error(
        "negative.toml",
        &text,
        &["discretization.horizon", ":8", "> 0"],
    );
}

#[test]
fn time_step_above_the_bound_is_refused() {
    let text = GOOD.replace("dt = \"0.5 stable\"", "dt = \"1 us\"");
    assert_clear_error(
        "dt.toml",
        &text,
        &["time.dt", "stable bound", "allow_unstable"],
    );
}

#[test]
fn precrack_outside_the_body_is_refused() {
    let text = GOOD.replace(
        "segment = { from = [\"0 mm\", \"5 mm\"], to = [\"5 mm\", \"5 mm\"] }",
        "segment = { from = [\"30 mm\", \"5 mm\"], to = [\"40 mm\", \"5 mm\"] }",
    );
    assert_clear_error("crack.toml", &text, &["precracks[0]", "outside the body"]);
}

#[test]
fn malformed_toml_gives_the_line() {
    let text = GOOD.replace("horizon = \"3 dx\"", "horizon = = 3");
    assert_clear_error("broken.toml", &text, &[":8"]);
}

/// Variants extend each other: a chain overlays outermost first; an unknown parent or a cycle
/// is an error naming the `extends` field.
#[test]
fn variants_extend_each_other() {
    let text = format!(
        "{GOOD}\n[variants.fine]\ndiscretization = {{ spacing = \"0.5 mm\" }}\n\
         [variants.fine-long]\nextends = \"fine\"\ntime = {{ end = \"20 steps\" }}\n\
         [variants.loop-a]\nextends = \"loop-b\"\n[variants.loop-b]\nextends = \"loop-a\"\n\
         [variants.orphan]\nextends = \"nothing\"\n"
    );
    let s = peridyn::scene::Scene::from_text("v.toml", &text, Some("fine-long")).unwrap();
    assert!((s.spacing - 0.5e-3).abs() < 1e-15 && (s.horizon - 1.5e-3).abs() < 1e-15);
    let cycle = peridyn::scene::Scene::from_text("v.toml", &text, Some("loop-a"))
        .unwrap_err()
        .to_string();
    assert!(
        cycle.contains("variants.loop-a.extends") && cycle.contains("loop-a → loop-b → loop-a"),
        "{cycle}"
    );
    let orphan = peridyn::scene::Scene::from_text("v.toml", &text, Some("orphan"))
        .unwrap_err()
        .to_string();
    assert!(
        orphan.contains("variants.orphan.extends") && orphan.contains("no variant `nothing`"),
        "{orphan}"
    );
}

#[test]
fn unknown_preset_and_variant() {
    let out = peridyn(&["check", "no-such-preset"]);
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("kalthoff-winkler"));
    let out = peridyn(&["check", "kalthoff-winkler", "--variant", "huge"]);
    assert_eq!(out.status.code(), Some(2));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("small") && err.contains("medium"), "{err}");
}

#[test]
fn every_builtin_preset_and_variant_checks() {
    let out = peridyn(&["list"]);
    assert!(out.status.success());
    let list = String::from_utf8_lossy(&out.stdout).to_string();
    for name in peridyn::scene::builtin::names() {
        assert!(list.contains(name));
        let preset: peridyn::scene::Preset =
            toml::from_str(peridyn::scene::builtin::text(name).unwrap()).unwrap();
        assert!(
            preset.variants.contains_key("small"),
            "{name} has no `small` variant"
        );
        for variant in preset.variants.keys() {
            // Validation only (no discretization): the paper variants are large.
            peridyn::scene::Scene::load(name, Some(variant)).unwrap_or_else(|e| panic!("{e}"));
        }
    }
}

fn steps_of(rec: &readback::Recording, entity: &str) -> Vec<i64> {
    rec.entity(entity)
        .unwrap_or_else(|| {
            panic!(
                "no entity {entity}; have {:?}",
                rec.entities.keys().collect::<Vec<_>>()
            )
        })
        .points
        .keys()
        .copied()
        .collect()
}

#[test]
fn kalthoff_winkler_small_recording_reads_back() {
    let path = temp("kw-small.rrd");
    let stdout = run_ok(&[
        "record",
        "kalthoff-winkler",
        "--variant",
        "small",
        "-o",
        path.to_str().unwrap(),
        "-q",
    ]);
    assert!(stdout.contains("bond evaluations/s"), "{stdout}");

    let scene = peridyn::scene::Scene::load("kalthoff-winkler", Some("small")).unwrap();
    let sim = peridyn::sim::build(&scene).unwrap();
    let info = sim.info();
    let rec = readback::read(&path).unwrap();
    let mut expected: Vec<i64> = (0..=info.total_steps)
        .step_by(info.frame_every as usize)
        .map(|s| s as i64)
        .collect();
    if *expected.last().unwrap() != info.total_steps as i64 {
        expected.push(info.total_steps as i64);
    }
    for entity in ["/nodes/damage", "/nodes/velocity"] {
        assert_eq!(
            steps_of(&rec, entity),
            expected,
            "{entity}: one frame per output step"
        );
        let content = rec.entity(entity).unwrap();
        assert!(
            content.points.values().all(|&n| n == info.nodes),
            "one point per node"
        );
        assert_eq!(
            content.values.len(),
            expected.len(),
            "{entity}: raw values every frame"
        );
        assert!(content.values.values().all(|v| v.len() == info.nodes));
    }
    let damage = &rec.entity("/nodes/damage").unwrap().values;
    let last = damage.values().last().unwrap();
    assert!(last.iter().all(|v| (0.0..=1.0).contains(v)));
    assert!(
        last.iter().filter(|&&v| v > 0.35).count() > 100,
        "cracks grew"
    );
    for metric in [
        "/metrics/energy/kinetic",
        "/metrics/energy/strain",
        "/metrics/energy/total",
        "/metrics/momentum/x",
        "/metrics/bonds/broken",
        "/metrics/timing/step_wall_s",
    ] {
        let series = &rec
            .entity(metric)
            .unwrap_or_else(|| panic!("no {metric}"))
            .scalars;
        assert_eq!(series.len(), expected.len(), "{metric}");
    }
    let preset = rec.entity("/scene/preset").expect("preset document");
    assert!(
        preset.texts.iter().any(|t| t.contains(&scene.preset_text)),
        "preset text stored whole"
    );
}

fn wait_for(path: &Path, min_bytes: u64, timeout: Duration) {
    let start = Instant::now();
    while start.elapsed() < timeout {
        if std::fs::metadata(path)
            .map(|m| m.len() >= min_bytes)
            .unwrap_or(false)
        {
            return;
        }
        std::thread::sleep(Duration::from_millis(50));
    }
    panic!("{} did not grow to {min_bytes} bytes", path.display());
}

#[test]
fn interrupted_recording_is_readable_and_complete_up_to_the_signal() {
    let path = temp("kw-interrupted.rrd");
    let child = Command::new(env!("CARGO_BIN_EXE_peridyn"))
        .args([
            "record",
            "kalthoff-winkler",
            "--variant",
            "medium",
            "--every",
            "5",
            "-q",
            "-o",
            path.to_str().unwrap(),
        ])
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    wait_for(&path, 2_000_000, Duration::from_secs(120));
    let status = Command::new("kill")
        .args(["-INT", &child.id().to_string()])
        .status()
        .unwrap();
    assert!(status.success());
    let out = child.wait_with_output().unwrap();
    assert_eq!(
        out.status.code(),
        Some(130),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let rec = readback::read(&path).unwrap();
    let events = &rec
        .entity("/log/events")
        .expect("the interruption is logged")
        .texts;
    let step: i64 = events
        .iter()
        .find_map(|t| t.strip_prefix("interrupted at step "))
        .and_then(|s| s.trim().parse().ok())
        .unwrap_or_else(|| panic!("{events:?}"));
    let steps = steps_of(&rec, "/nodes/damage");
    let expected: Vec<i64> = (0..=step).step_by(5).collect();
    assert_eq!(
        steps, expected,
        "every frame logged before the signal is in the file"
    );
}

#[test]
fn a_scene_too_large_for_memory_is_refused_before_building() {
    let text = GOOD
        .replace(
            "box = { min = [0.0, 0.0], max = [\"20 mm\", \"10 mm\"] }",
            "box = { min = [0.0, 0.0], max = [\"2 m\", \"1 m\"] }",
        )
        .replace("horizon = \"3 dx\"", "horizon = \"24 dx\"");
    assert_clear_error(
        "huge.toml",
        &text,
        &["discretization.horizon", "directed bonds", "GB"],
    );
}

#[test]
fn diffusion_recording_holds_concentration_error_and_error_norm() {
    let path = temp("diffusion-small.rrd");
    let stdout = run_ok(&[
        "record",
        "diffusion-2d-manufactured",
        "--variant",
        "small",
        "--set",
        "discretization.scheme=wls-4",
        "-o",
        path.to_str().unwrap(),
        "-q",
    ]);
    let printed: f64 = stdout
        .lines()
        .find_map(|l| l.strip_prefix("relative l2 error (3.79): "))
        .unwrap_or_else(|| panic!("{stdout}"))
        .parse()
        .unwrap();
    let rec = readback::read(&path).unwrap();
    for entity in ["/nodes/concentration", "/nodes/error"] {
        let content = rec.entity(entity).unwrap_or_else(|| panic!("no {entity}"));
        assert_eq!(
            content.values.len(),
            11,
            "{entity}: frames at 0, 100, …, 1000"
        );
        assert!(content.values.values().all(|v| v.len() == 1600));
    }
    let errors = &rec.entity("/metrics/error/relative_l2").unwrap().scalars;
    let (&last_step, &last) = errors.iter().last().unwrap();
    assert_eq!(last_step, 1000);
    assert!(
        (last - printed).abs() <= 1e-6 * printed,
        "{last} vs {printed}"
    );
    // The logged pointwise error is the field minus the reference.
    let field = &rec.entity("/nodes/concentration").unwrap().values[&1000];
    let error = &rec.entity("/nodes/error").unwrap().values[&1000];
    let max_error = error.iter().fold(0.0f32, |a, v| a.max(v.abs()));
    assert!(max_error > 0.0 && max_error < 1e-3 * field.iter().fold(0.0f32, |a, v| a.max(v.abs())));
}

#[test]
fn ill_conditioned_collocation_set_names_the_node_and_the_fix() {
    let text = peridyn::scene::builtin::text("diffusion-2d-manufactured")
        .unwrap()
        .replace(
            "scheme = \"wls-2\"",
            "scheme = \"wls-4\"\ncollocation_factor = 2",
        );
    assert_clear_error(
        "ill-conditioned.toml",
        &text,
        &[
            "discretization.collocation_factor",
            "WLS fit at node",
            "larger k_aux",
            "lower order",
        ],
    );
}

#[test]
fn sweep_writes_csv_markdown_and_plots() {
    let dir = temp("sweep-static");
    run_ok(&[
        "sweep",
        "static-1d-manufactured",
        "--vary",
        "discretization.spacing=1,0.5",
        "--schemes",
        "standard,wls-2",
        "--out",
        dir.to_str().unwrap(),
    ]);
    let csv = std::fs::read_to_string(dir.join("sweep.csv")).unwrap();
    let lines: Vec<&str> = csv.lines().collect();
    assert_eq!(
        lines[0],
        "scheme,discretization.spacing,nodes,stencil,steps,setup_s,run_s,error,failure"
    );
    assert_eq!(lines.len(), 5);
    assert!(
        lines[1].starts_with("standard,1,213,13.00,1,"),
        "{}",
        lines[1]
    );
    assert!(lines[2].starts_with("wls-2,1,213,5.00,1,"), "{}", lines[2]);
    let md = std::fs::read_to_string(dir.join("sweep.md")).unwrap();
    assert!(
        md.starts_with("| scheme | discretization.spacing |"),
        "{md}"
    );
    for png in ["error-vs-nodes.png", "error-vs-wall.png"] {
        let bytes = std::fs::read(dir.join(png)).unwrap();
        assert_eq!(&bytes[..8], b"\x89PNG\r\n\x1a\n", "{png}");
        assert!(bytes.len() > 10_000, "{png} has content");
    }
    let bad = peridyn(&[
        "sweep",
        "static-1d-manufactured",
        "--vary",
        "discretization.spacing=1",
        "--schemes",
        "wls-9",
    ]);
    assert_eq!(bad.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&bad.stderr).contains("unknown scheme `wls-9`"));
}

/// New scene fields of scalar-field scenes: each mistake names its field and what is allowed.
#[test]
fn scalar_scene_mistakes_are_named() {
    let diffusion = peridyn::scene::builtin::text("diffusion-2d-manufactured").unwrap();
    let cases = [
        (
            "bad-perturbation.toml",
            diffusion.replace("seed = 2024", "seed = 2024\nperturbation = [0.3, 0.1]"),
            vec!["discretization.perturbation", "lo ≤ hi"],
        ),
        (
            "bad-exponent.toml",
            diffusion.replace("kernel_exponent = 2.0", "kernel_exponent = 3.5"),
            vec!["material.kernel_exponent", "[0, 3)"],
        ),
        (
            "bad-reference.toml",
            diffusion.replace("kernel_exponent = 2.0", "kernel_exponent = 1.0"),
            vec!["material.kernel_exponent", "q = 2"],
        ),
        (
            "bad-thickness.toml",
            diffusion.replacen("thickness = \"1 horizon\"", "thickness = \"1 steps\"", 1),
            vec!["boundary[0].thickness", "not a length"],
        ),
        (
            "no-time.toml",
            diffusion.replace("[time]\ndt = 1e-5\nend = \"10000 steps\"", ""),
            vec!["time", "dt"],
        ),
        (
            "dynamic-wls.toml",
            GOOD.replace(
                "horizon = \"3 dx\"",
                "horizon = \"3 dx\"\nscheme = \"wls-2\"",
            ),
            vec!["discretization.scheme", "dynamics uses \"standard\""],
        ),
        (
            "nan-geometry.toml",
            GOOD.replace("max = [\"20 mm\", \"10 mm\"]", "max = [nan, \"10 mm\"]"),
            vec!["geometry", "finite"],
        ),
        (
            "static-2d.toml",
            GOOD.replace("dimension = 2", "dimension = 2\nphysics = \"static\""),
            vec!["physics", "1D"],
        ),
    ];
    for (name, text, needles) in cases {
        assert_clear_error(name, &text, &needles);
    }
}

#[test]
fn hybrid_recording_holds_the_scheme_mask_and_omega_s_fraction() {
    let path = temp("kw-small-hybrid.rrd");
    run_ok(&[
        "record",
        "kalthoff-winkler",
        "--variant",
        "small-hybrid",
        "--steps",
        "200",
        "-o",
        path.to_str().unwrap(),
        "-q",
    ]);
    let rec = readback::read(&path).unwrap();
    let scheme = rec.entity("/nodes/scheme").expect("scheme mask entity");
    assert!(scheme.points.len() >= 2, "mask logged every frame");
    let fractions = &rec
        .entity("/metrics/hybrid/omega_s_fraction")
        .unwrap()
        .scalars;
    let values: Vec<f64> = fractions.values().copied().collect();
    assert!(values.windows(2).all(|w| w[1] >= w[0]), "{values:?}");
    assert!(values[0] > 0.0 && values[0] < 0.5);
    let violations = &rec.entity("/metrics/hybrid/violations").unwrap().scalars;
    assert!(violations.values().all(|&v| v == 0.0));
    assert!(rec.entity("/metrics/hybrid/chi").is_some());
    // The mask's class ids agree with the logged Ω_s fraction, frame by frame.
    for (step, ids) in &scheme.classes {
        let standard = ids
            .iter()
            .filter(|&&c| c == SchemeClass::Standard.id())
            .count();
        let fraction = standard as f64 / ids.len() as f64;
        assert!((fraction - fractions[step]).abs() < 1e-12, "step {step}");
    }
    assert_eq!(scheme.classes.len(), scheme.points.len());
    assert!(
        rec.entity("/log/events")
            .unwrap()
            .texts
            .iter()
            .any(|t| t.contains("nodes switched to the standard scheme")),
        "switching events logged"
    );
    assert_first_view(
        &rec,
        &[
            "/nodes/damage",
            "/nodes/scheme",
            "/metrics/hybrid/omega_s_fraction",
        ],
    );
}

/// The recording carries its default blueprint: views of the scene's main field and masks,
/// and of its figures of merit (the viewer opens on these, not on an automatic grid).
fn assert_first_view(rec: &readback::Recording, entities: &[&str]) {
    assert!(!rec.blueprint.is_empty(), "no blueprint in the recording");
    for entity in entities {
        assert!(
            rec.blueprint.iter().any(|t| t == entity),
            "no view of {entity} in the blueprint: {:?}",
            rec.blueprint
        );
    }
    assert!(
        rec.blueprint.iter().any(|t| t == "/metrics/timing/**"),
        "timing grouped in its own view"
    );
}

/// A corrosion recording holds what a viewer needs to watch the specimen dissolve: the
/// concentration, the phase and scheme masks (class ids) every frame, the volume loss and the
/// Ω_s fraction; no pointwise error field (there is no reference solution to compare with).
#[test]
fn corrosion_recording_holds_concentration_phase_and_scheme_masks() {
    let path = temp("corrosion-3d-small.rrd");
    run_ok(&[
        "record",
        "corrosion-3d",
        "--variant",
        "small",
        // A high saturation makes the specimen dissolve within 300 steps.
        "--set",
        "material.saturation=\"60000 mol/m^3\"",
        "--steps",
        "300",
        "--every",
        "100",
        "-o",
        path.to_str().unwrap(),
        "-q",
    ]);
    let rec = readback::read(&path).unwrap();
    let frames = [0, 100, 200, 300];
    assert_eq!(steps_of(&rec, "/nodes/concentration"), frames);
    assert!(rec.entity("/nodes/error").is_none());
    assert!(rec.entity("/metrics/error/max_abs").is_none());
    let phase = &rec.entity("/nodes/phase").unwrap().classes;
    let scheme = &rec.entity("/nodes/scheme").unwrap().classes;
    let solid_nodes = &rec
        .entity("/metrics/corrosion/solid_nodes")
        .unwrap()
        .scalars;
    let loss = &rec
        .entity("/metrics/corrosion/volume_loss")
        .unwrap()
        .scalars;
    let omega_s = &rec
        .entity("/metrics/hybrid/omega_s_fraction")
        .unwrap()
        .scalars;
    let mut solid_before = usize::MAX;
    for step in frames {
        let (phase, scheme) = (&phase[&step], &scheme[&step]);
        let solid = phase.iter().filter(|&&p| p == Phase::Solid.id()).count();
        assert_eq!(solid as f64, solid_nodes[&step], "step {step}");
        assert!(solid <= solid_before, "the solid only shrinks");
        solid_before = solid;
        // No solid node in Ω_w, and the mask's share is the logged Ω_s fraction.
        assert!(
            phase
                .iter()
                .zip(scheme)
                .all(|(&p, &m)| !(p == Phase::Solid.id() && m == SchemeClass::Wls.id()))
        );
        let standard = scheme
            .iter()
            .filter(|&&m| m == SchemeClass::Standard.id())
            .count();
        assert!((standard as f64 / scheme.len() as f64 - omega_s[&step]).abs() < 1e-12);
    }
    assert_eq!(loss[&0], 0.0);
    assert!(loss[&300] > 0.05, "the specimen dissolved: {}", loss[&300]);
    assert_first_view(
        &rec,
        &[
            "/nodes/concentration",
            "/nodes/phase",
            "/nodes/scheme",
            "/metrics/corrosion/volume_loss",
        ],
    );
}

/// `PERIDYN_SIMD` picks the bond loops' lanes: a value that is none of the four names, or
/// one this CPU cannot run, is bad input (exit code 2, the variable and the choices named);
/// implementations of one width end a run on the same fields bit for bit (AVX2 on the
/// portable loop's, AVX-512 on the 8-lane portable loop's), and the two widths do not
/// (their partial sums are added in other orders).
#[test]
fn the_simd_choice_is_checked_and_one_width_gives_one_result() {
    use peridyn::simd::Simd;
    let output = temp("simd.rrd");
    let run = |simd: &str| {
        Command::new(env!("CARGO_BIN_EXE_peridyn"))
            .env("PERIDYN_SIMD", simd)
            .args(["record", "pmb-block-3d", "--variant", "small", "-q", "-o"])
            .arg(&output)
            .output()
            .expect("run peridyn")
    };
    let bad = run("sse9");
    assert_eq!(bad.status.code(), Some(2));
    let err = String::from_utf8_lossy(&bad.stderr);
    assert!(
        err.contains("PERIDYN_SIMD") && err.contains("portable8"),
        "{err}"
    );
    let hashes = |simd: Simd| {
        let out = run(simd.name());
        if !simd.runs_here() {
            assert_eq!(out.status.code(), Some(2), "{simd:?}");
            return None;
        }
        let stdout = String::from_utf8_lossy(&out.stdout).to_string();
        assert!(out.status.success(), "{stdout}");
        stdout
            .lines()
            .find(|l| l.contains("field hashes"))
            .map(String::from)
    };
    let (four, eight) = (hashes(Simd::Portable), hashes(Simd::Portable8));
    assert!(four.is_some() && four != eight);
    for (vector, portable) in [(Simd::Avx2, &four), (Simd::Avx512, &eight)] {
        if let Some(h) = hashes(vector) {
            assert_eq!(&Some(h), portable, "{vector:?}");
        }
    }
}
