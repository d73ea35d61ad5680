//! `peridyn bench`: directed-bond evaluation throughput on the pmb-block-3d preset, single-
//! thread and all threads, the share of wall time spent logging, and memory per bond.

pub mod hybrid;
pub mod pairs;
pub mod schemes;

use std::sync::Arc;
use std::sync::atomic::AtomicBool;

use crate::record::{RecordTarget, RerunSink};
use crate::runner::{self, NullSink, RunSummary};
use crate::scene::Scene;
use crate::sim;

const PRESET: &str = "pmb-block-3d";

struct Measurement {
    label: String,
    threads: usize,
    summary: RunSummary,
    force_seconds: f64,
    logging_thread_seconds: f64,
}

fn measure(
    scene: &Scene,
    threads: usize,
    steps: Option<u64>,
    record: bool,
    label: &str,
) -> Result<Measurement, String> {
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .map_err(|e| e.to_string())?;
    pool.install(|| {
        let mut sim = sim::build(scene).map_err(|e| e.to_string())?;
        let stop = Arc::new(AtomicBool::new(false));
        let mut no_progress = |_: u64, _: u64| {};
        let path = std::env::temp_dir().join(format!("peridyn-bench-{}.rrd", std::process::id()));
        let mut logging_thread_seconds = 0.0;
        let mut summary = if record {
            let mut sink = RerunSink::start(RecordTarget::File(path.clone()), scene, &sim.info())?;
            let mut summary = runner::run(sim.as_mut(), &mut sink, &stop, steps, &mut no_progress);
            let started = std::time::Instant::now();
            logging_thread_seconds = sink.finish()?.busy_seconds;
            summary.wall_seconds += started.elapsed().as_secs_f64();
            let _ = std::fs::remove_file(&path);
            summary
        } else {
            runner::run(sim.as_mut(), &mut NullSink, &stop, steps, &mut no_progress)
        };
        summary.steps = sim.steps_done();
        Ok(Measurement {
            label: label.to_string(),
            threads,
            force_seconds: sim.stages().get("forces").map_or(0.0, |d| d.as_secs_f64()),
            logging_thread_seconds,
            summary,
        })
    })
}

/// Runs the benchmark and returns a Markdown report.
pub fn run(variant: Option<&str>, steps: Option<u64>) -> Result<String, String> {
    let all = std::thread::available_parallelism().map_or(1, |n| n.get());
    let damaging = Scene::load(PRESET, variant).map_err(|e| e.to_string())?;
    let elastic_variant = if variant.is_none() {
        Some("elastic")
    } else {
        variant
    };
    let elastic = Scene::load(PRESET, elastic_variant).map_err(|e| e.to_string())?;
    let mut quiet = damaging.clone();
    quiet.output_every = Some(u64::MAX / 2);
    let mut quiet_elastic = elastic.clone();
    quiet_elastic.output_every = Some(u64::MAX / 2);

    let mut rows = Vec::new();
    for threads in [1, all] {
        rows.push(measure(
            &quiet_elastic,
            threads,
            steps,
            false,
            "elastic (V = 0.01 m/s)",
        )?);
        rows.push(measure(
            &quiet,
            threads,
            steps,
            false,
            "damaging (V = 10 m/s)",
        )?);
    }
    let logged = measure(&damaging, all, steps, true, "damaging, recording to .rrd")?;
    // The last row is the same damaging run with all threads, without a recording.
    let unlogged_wall = rows
        .last()
        .map_or(logged.summary.wall_seconds, |m| m.summary.wall_seconds);

    let info = &logged.summary.info;
    let bytes_per_bond = info.bytes_per_bond;
    let mut out = format!(
        "## peridyn bench: {PRESET}{}\n\n{} nodes, {} directed bonds, {} steps, Δt = {:.2e} s, {} hardware threads\n\n\
         | case | threads | wall [s] | bond evaluations/s (whole step) | bond evaluations/s (force stage) | broken bonds |\n\
         |---|---|---|---|---|---|\n",
        variant.map(|v| format!(" [{v}]")).unwrap_or_default(),
        info.nodes,
        info.bonds,
        logged.summary.steps,
        info.dt,
        all
    );
    for m in rows.iter().chain(std::iter::once(&logged)) {
        let evaluations = m.summary.steps as f64 * m.summary.info.bonds as f64;
        out += &format!(
            "| {} | {} | {:.3} | {:.3e} | {:.3e} | {} |\n",
            m.label,
            m.threads,
            m.summary.wall_seconds,
            evaluations / m.summary.wall_seconds,
            evaluations / m.force_seconds.max(1e-12),
            m.summary.broken_bonds
        );
    }
    let wall = logged.summary.wall_seconds;
    let share = 1.0 - unlogged_wall / wall;
    out += &format!(
        "\nlogging at the default cadence (a frame every {} steps): {:.1} % of wall time \
         ({:.1} % building frames on the solver thread, {:.1} % busy on the logging thread); \
         the recorded run took {:+.1} % wall time against the same run without a recording\n\
         memory: {:.2} bytes per directed bond (4 index + 1 state, the rows' bond lengths \
         stored once per distinct row, and all per-node arrays, amortized)\n",
        info.frame_every,
        100.0 * (logged.summary.frame_seconds + logged.logging_thread_seconds) / wall,
        100.0 * logged.summary.frame_seconds / wall,
        100.0 * logged.logging_thread_seconds / wall,
        100.0 * share,
        bytes_per_bond
    );
    Ok(out)
}
