//! Hybrid against all-standard (issues 5 and 14). Kalthoff–Winkler end to end: each
//! configuration at 0.7 of *its own* stable step, setup included, with crack angles, the Ω_s
//! fraction and the share of nodes whose damage differs from the standard run's beside the wall
//! times; the same configurations at one common Δt (the smallest own step) as a detail. And
//! `corrosion-3d`'s fixed hybrid against all-standard, with the relative volume loss beside them.

use std::fmt::Write as _;
use std::time::Instant;

use crate::runner::{self, NullSink};
use crate::scene::Scene;
use crate::sim;

struct Run {
    label: String,
    /// Setup: families, operators, the stable-step estimate.
    setup: f64,
    /// Stepping, without I/O.
    wall: f64,
    steps: u64,
    dt: f64,
    angles: Vec<(String, Option<f64>)>,
    omega_s: Option<(f64, f64)>,
    volume_loss: Option<f64>,
    damage: Vec<f64>,
}

impl Run {
    fn total(&self) -> f64 {
        self.setup + self.wall
    }
}

fn run(
    preset: &str,
    variant: Option<&str>,
    set: &[String],
    label: &str,
    steps: Option<u64>,
) -> Result<Run, String> {
    let mut scene = Scene::load_with(preset, variant, set).map_err(|e| e.to_string())?;
    scene.output_every = Some(u64::MAX / 2);
    let started = Instant::now();
    let mut stepper = sim::build(&scene).map_err(|e| e.to_string())?;
    let setup = started.elapsed().as_secs_f64();
    let initial = stepper.frame().scalar("hybrid/omega_s_fraction");
    let summary = runner::run(
        stepper.as_mut(),
        &mut NullSink,
        &Default::default(),
        steps,
        &mut |_, _| {},
    );
    let frame = stepper.frame();
    let last = frame.scalar("hybrid/omega_s_fraction");
    let damage = frame
        .fields
        .iter()
        .find(|f| f.name == "damage")
        .map(|f| f.values.clone())
        .unwrap_or_default();
    Ok(Run {
        label: label.to_string(),
        setup,
        wall: summary.wall_seconds,
        steps: summary.steps,
        dt: summary.info.dt,
        angles: summary.crack_angles,
        omega_s: initial.zip(last),
        volume_loss: frame.scalar("corrosion/volume_loss"),
        damage,
    })
}

/// The Kalthoff–Winkler configurations of `variant` (`small`, `medium` or `paper`): all
/// standard, the hybrid with the papers' collocation set (δ/3, 29 nodes) and the hybrid with
/// the wide orbit stencil of issue 14 (`<variant>-fast`).
fn configurations(variant: &str) -> Vec<(String, Option<&'static str>, String)> {
    let hybrid = if variant == "paper" {
        "hybrid".to_string()
    } else {
        format!("{variant}-hybrid")
    };
    vec![
        (variant.to_string(), None, "standard".to_string()),
        (
            hybrid.clone(),
            Some("all"),
            "hybrid, papers' stencil, check all".into(),
        ),
        (
            hybrid,
            Some("near"),
            "hybrid, papers' stencil, check near".into(),
        ),
        (
            format!("{variant}-fast"),
            Some("all"),
            "hybrid, wide stencil, check all".into(),
        ),
        (
            format!("{variant}-fast"),
            Some("near"),
            "hybrid, wide stencil, check near".into(),
        ),
    ]
}

/// Runs the comparison on `variant` of kalthoff-winkler and returns Markdown.
pub fn report(variant: &str) -> Result<String, String> {
    let configurations = configurations(variant);
    let runs = |dt: &str| -> Result<Vec<Run>, String> {
        configurations
            .iter()
            .map(|(v, check, label)| {
                let mut set = vec![format!("time.dt={dt}")];
                set.extend(check.map(|c| format!("hybrid.check=\"{c}\"")));
                eprintln!("[bench] kalthoff-winkler {v} ({label}), Δt {dt}");
                run("kalthoff-winkler", Some(v), &set, label, None)
            })
            .collect()
    };
    let own = runs("\"0.7 stable\"")?;
    let common = own.iter().map(|r| r.dt).fold(f64::INFINITY, f64::min);
    let equal = runs(&format!("{common:e}"))?;
    let mut out = format!(
        "## Hybrid against standard, end to end: kalthoff-winkler `{variant}` ({} threads)\n\n\
         Each configuration at 0.7 of its own stable step to the preset's end time, setup \
         (families, operators, stable-step estimate) included; one pass each, this machine's \
         wall times drift by up to 30 % over minutes (compare ratios across runs with \
         farm-bench). Damage differs: share of nodes whose final damage differs from the \
         standard run's by more than 0.3.\n\n",
        rayon::current_num_threads(),
    );
    table(&mut out, &own, true);
    let _ = write!(
        out,
        "\nThe same configurations at one common Δt = {common:.4e} s (the smallest own step; a \
         detail, not the result):\n\n"
    );
    table(&mut out, &equal, false);
    out.push_str(&corrosion_report(variant)?);
    Ok(out)
}

/// The `corrosion-3d` pair: `medium` times 1000 steps of the full scaled scene (Δt = 0.1 s;
/// the dissolution starts later), `small` runs the coarse scene to its end (3000 s).
fn corrosion_report(variant: &str) -> Result<String, String> {
    let (hybrid_variant, standard_variant, steps) = match variant {
        "small" => (Some("small"), "small-standard", None),
        _ => (None, "standard", Some(1000)),
    };
    let mut rows = Vec::new();
    for (v, label) in [
        (Some(standard_variant), "standard"),
        (hybrid_variant, "hybrid-fixed"),
    ] {
        rows.push(run("corrosion-3d", v, &[], label, steps)?);
    }
    let mut out = format!(
        "\n## Hybrid against standard: corrosion-3d `{}` ({} threads)\n\n\
         Same grid and Δt, {} steps; wall time of the steps (setup: standard {:.1} s, hybrid \
         {:.1} s, families and operator assembly).\n\n\
         | scheme | wall (s) | speed-up | Ω_s | relative volume loss |\n|---|---:|---:|---|---:|\n",
        if variant == "small" { "small" } else { "base" },
        rayon::current_num_threads(),
        rows[0].steps,
        rows[0].setup,
        rows[1].setup
    );
    let base = rows[0].wall;
    for r in &rows {
        let _ = writeln!(
            out,
            "| {} | {:.2} | {:.2}× | {} | {:.4} |",
            r.label,
            r.wall,
            base / r.wall,
            r.omega_s
                .map_or("100 %".into(), |(a, _)| format!("{:.2} %", 100.0 * a)),
            r.volume_loss.unwrap_or(f64::NAN)
        );
    }
    Ok(out)
}

fn table(out: &mut String, rows: &[Run], with_setup: bool) {
    let _ = write!(
        out,
        "| configuration | Δt (s) | steps | setup (s) | stepping (s) | total (s) | speed-up ({}) | \
         Ω_s initial → final | crack angles (°) | damage differs |\n\
         |---|---:|---:|---:|---:|---:|---:|---|---|---:|\n",
        if with_setup { "total" } else { "stepping" }
    );
    let reference = &rows[0];
    let time = |r: &Run| if with_setup { r.total() } else { r.wall };
    for r in rows {
        let angles: Vec<String> = r
            .angles
            .iter()
            .map(|(n, a)| match a {
                Some(a) => format!("{n} {a:.1}"),
                None => format!("{n} —"),
            })
            .collect();
        let differs = if r.damage.len() == reference.damage.len() && !r.damage.is_empty() {
            let n = r
                .damage
                .iter()
                .zip(&reference.damage)
                .filter(|(a, b)| (*a - *b).abs() > 0.3)
                .count();
            format!("{:.2} %", 100.0 * n as f64 / r.damage.len() as f64)
        } else {
            "—".into()
        };
        let _ = writeln!(
            out,
            "| {} | {:.3e} | {} | {:.2} | {:.2} | {:.2} | {:.2}× | {} | {} | {} |",
            r.label,
            r.dt,
            r.steps,
            r.setup,
            r.wall,
            r.total(),
            time(reference) / time(r),
            r.omega_s.map_or("100 %".into(), |(a, b)| format!(
                "{:.2} % → {:.2} %",
                100.0 * a,
                100.0 * b
            )),
            angles.join(", "),
            differs
        );
    }
}
