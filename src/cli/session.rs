//! The one run loop of the command line: `record`, `run`, scripted runs and
//! `replay --resimulate` all build a `control::Driver` on an outlet and run it headless with
//! their script (possibly empty), a progress bar and Ctrl-C handling.

use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::sync::atomic::Ordering;

use indicatif::{ProgressBar, ProgressStyle};

use super::report::{describe, print_summary};
use super::{Failure, SceneRequest, exit_code, stop_flag, wait_while_serving};
use crate::control::checkpoint::{Checkpoint, Plan};
use crate::control::driver::Outputs;
use crate::control::runspec::{self, RunSpec};
use crate::control::script::{self, Timed};
use crate::control::{Driver, driver};
use crate::record::{Outlet, RecordTarget};
use crate::replay::SendError;
use crate::runner::RunSummary;
use crate::scene::Scene;

/// How a recorded or streamed run goes.
#[derive(Debug, Clone, Default)]
pub struct RunOptions {
    /// A frame every K steps (overrides the preset's `output.every`).
    pub every: Option<u64>,
    /// Stop after this many steps.
    pub steps: Option<u64>,
    /// No progress bar.
    pub quiet: bool,
    /// Timed commands to apply.
    pub script: Option<PathBuf>,
    /// A ParaView series per run into this folder.
    pub vtu: Option<PathBuf>,
    /// Write a checkpoint every N steps or span of simulated time (`500`, `500 steps`, `20 us`).
    pub checkpoint_every: Option<String>,
    /// Where (default: the recording's name with `.ckpt`).
    pub checkpoint: Option<PathBuf>,
}

/// The default recording of a scene: `PRESET[-VARIANT].rrd`.
fn default_output(scene: &Scene) -> PathBuf {
    match &scene.variant {
        Some(v) => PathBuf::from(format!("{}-{v}.rrd", scene.name)),
        None => PathBuf::from(format!("{}.rrd", scene.name)),
    }
}

/// `peridyn record`: runs headless into a file.
pub fn record(
    request: &SceneRequest,
    output: Option<PathBuf>,
    options: &RunOptions,
) -> Result<ExitCode, Failure> {
    let scene = request.load()?;
    let path = output.unwrap_or_else(|| default_output(&scene));
    let summary = simulate(
        &scene,
        RecordTarget::File(path.clone()),
        options,
        path.with_extension("ckpt"),
    )?;
    println!("recording: {}", path.display());
    println!(
        "view it:   pip install 'rerun-sdk==0.36.*' && rerun {}",
        path.display()
    );
    Ok(exit_code(&summary))
}

/// `peridyn run`: streams to a viewer (and a file, if given).
pub fn run(
    request: &SceneRequest,
    target: RecordTarget,
    options: &RunOptions,
) -> Result<ExitCode, Failure> {
    let scene = request.load()?;
    let checkpoint = default_output(&scene).with_extension("ckpt");
    let summary = simulate(&scene, target, options, checkpoint)?;
    Ok(exit_code(&summary))
}

fn simulate(
    scene: &Scene,
    target: RecordTarget,
    options: &RunOptions,
    default_checkpoint: PathBuf,
) -> Result<RunSummary, Failure> {
    if options.every == Some(0) {
        return Err(Failure::BadInput("--every must be ≥ 1".into()));
    }
    let script = match &options.script {
        Some(path) => script::load(path).map_err(|e| Failure::BadInput(e.to_string()))?,
        None => Vec::new(),
    };
    let checkpoints = match &options.checkpoint_every {
        Some(every) => Some(
            Plan::new(
                options.checkpoint.clone().unwrap_or(default_checkpoint),
                every,
            )
            .map_err(Failure::BadInput)?,
        ),
        None if options.checkpoint.is_some() => {
            return Err(Failure::BadInput(
                "--checkpoint needs --checkpoint-every (N steps or a time)".into(),
            ));
        }
        None => None,
    };
    let spec = RunSpec::new(scene, options.every, options.steps);
    let outputs = Outputs {
        vtu: options.vtu.clone(),
    };
    let session = crate::record::recording_id(scene);
    run_session(target, options.quiet, checkpoints, |outlet| {
        let driver =
            Driver::start_with(spec, outlet, &session, outputs).map_err(Failure::BadInput)?;
        Ok((driver, script))
    })
}

/// `peridyn resume`: continues a checkpointed session into `output` (default
/// `CHECKPOINT-resumed.rrd`), writing checkpoints on the same cadence into the same file.
pub fn resume(
    checkpoint: &Path,
    output: Option<PathBuf>,
    options: &RunOptions,
) -> Result<ExitCode, Failure> {
    let saved = Checkpoint::read(checkpoint).map_err(Failure::BadInput)?;
    let output = output.unwrap_or_else(|| {
        let stem = checkpoint
            .file_stem()
            .map(|s| s.to_string_lossy().to_string())
            .unwrap_or_else(|| "run".into());
        checkpoint.with_file_name(format!("{stem}-resumed.rrd"))
    });
    let checkpoints = saved
        .header
        .checkpoint_every
        .as_deref()
        .map(|every| Plan::new(checkpoint.to_path_buf(), every))
        .transpose()
        .map_err(|e| Failure::BadInput(format!("{}: {e}", checkpoint.display())))?;
    let session = format!("resumed-{}", std::process::id());
    let outputs = Outputs {
        vtu: options.vtu.clone(),
    };
    let summary = run_session(
        RecordTarget::File(output.clone()),
        options.quiet,
        checkpoints,
        |outlet| {
            Driver::resume(&saved, outlet, &session, outputs)
                .map_err(|e| Failure::BadInput(format!("{}: {e}", checkpoint.display())))
        },
    )?;
    println!("recording: {}", output.display());
    Ok(exit_code(&summary))
}

/// Runs a session to its end with its script: progress, Ctrl-C (the recording keeps every
/// frame logged before it), checkpoints on their cadence, a served stream kept up afterwards,
/// the summary printed. `start` builds the session's driver on the outlet.
fn run_session(
    target: RecordTarget,
    quiet: bool,
    checkpoints: Option<Plan>,
    start: impl FnOnce(Outlet) -> Result<(Driver, Vec<Timed>), Failure>,
) -> Result<RunSummary, Failure> {
    let serving = matches!(target, RecordTarget::Serve { .. });
    // Ctrl-C is ours before the outlet opens: a served stream's runtime takes SIGINT for its
    // own once it starts, and a signal that arrives in between would be swallowed (the run
    // and then the serving wait would never see it).
    let stop = stop_flag();
    let outlet = Outlet::open(&target).map_err(Failure::Runtime)?;
    // The session's driver closes its recordings at the end; the outlet kept here keeps a
    // served stream (and its replay buffer) up until Ctrl-C.
    let (driver, script) = start(outlet.clone())?;
    eprintln!(
        "{}",
        describe(driver.scene(), &driver.info(), Some(driver.total_steps()))
    );
    if !script.is_empty() {
        eprintln!("{} scripted commands", script.len());
    }
    if let Some(plan) = &checkpoints {
        eprintln!(
            "checkpoints every {} into {}",
            plan.cadence(),
            plan.path.display()
        );
    }
    let bar = if quiet {
        ProgressBar::hidden()
    } else {
        ProgressBar::new(driver.total_steps())
    };
    bar.set_style(
        ProgressStyle::with_template("{bar:40} {pos}/{len} steps  {per_sec}  eta {eta}")
            .unwrap_or_else(|_| ProgressStyle::default_bar()),
    );
    let mut progress = |n: u64, total: u64| {
        if n.is_multiple_of(16) || n == total {
            bar.set_length(total);
            bar.set_position(n);
        }
    };
    let outcome = driver::run_script(driver, &script, checkpoints, &stop, &mut progress)
        .map_err(Failure::Runtime)?;
    bar.finish_and_clear();
    for (line, why) in &outcome.refused {
        eprintln!("warning: script line {line}: {why}");
    }
    if !outcome.unfired.is_empty() {
        eprintln!(
            "warning: script lines {:?} never fired (the run ended first)",
            outcome.unfired
        );
    }
    let summary = outcome.summary;
    if serving && !stop.load(Ordering::Relaxed) {
        wait_while_serving(&stop);
    }
    drop(outlet);
    print_summary(&summary);
    println!("runs: {}", outcome.runs);
    if let Some(e) = &summary.error {
        eprintln!("error: {e}");
    }
    if summary.interrupted {
        eprintln!("interrupted: the recording holds every frame logged before the signal");
    }
    Ok(summary)
}

/// `peridyn replay`: sends a recording to a viewer, or (`resimulate`) re-runs it from the
/// preset and command log it carries into `output` (default `FILE-resim.rrd`). `viewer` gives
/// the viewer target the command line chose, saving to the file it is given, if any.
pub fn replay(
    file: &Path,
    resimulate: bool,
    output: Option<PathBuf>,
    viewer: impl Fn(Option<PathBuf>) -> Option<RecordTarget>,
    quiet: bool,
) -> Result<ExitCode, Failure> {
    if resimulate {
        let rec = crate::readback::read(file).map_err(Failure::BadInput)?;
        if rec.entities.is_empty() {
            return Err(Failure::BadInput(format!(
                "{}: not a Rerun recording (or one without data)",
                file.display()
            )));
        }
        let text = rec
            .entity(&format!("/{}", runspec::ENTITY))
            .and_then(|e| e.texts.last())
            .ok_or_else(|| {
                Failure::BadInput(format!(
                    "{}: no `{}` document; only recordings made by peridyn can be re-run",
                    file.display(),
                    runspec::ENTITY
                ))
            })?;
        let bad = |e: String| Failure::BadInput(format!("{}: {e}", file.display()));
        let spec = RunSpec::from_text(text).map_err(bad)?;
        let script = spec.script().map_err(bad)?;
        let output = output.unwrap_or_else(|| {
            let stem = file
                .file_stem()
                .map(|s| s.to_string_lossy().to_string())
                .unwrap_or_else(|| "replay".into());
            file.with_file_name(format!("{stem}-resim.rrd"))
        });
        let target = viewer(Some(output.clone())).unwrap_or(RecordTarget::File(output.clone()));
        let session = crate::record::recording_id(
            &spec
                .scene()
                .map_err(|e| Failure::BadInput(format!("{}: {e}", file.display())))?,
        );
        let summary = run_session(target, quiet, None, |outlet| {
            let driver = Driver::start(spec, outlet, &session).map_err(Failure::BadInput)?;
            Ok((driver, script))
        })?;
        println!("recording: {}", output.display());
        return Ok(exit_code(&summary));
    }
    let target = viewer(None).unwrap_or(RecordTarget::Connect {
        url: super::DEFAULT_VIEWER.into(),
        file: None,
    });
    let serving = matches!(target, RecordTarget::Serve { .. });
    if !file.is_file() {
        return Err(Failure::BadInput(format!(
            "{}: no such recording",
            file.display()
        )));
    }
    let stop = stop_flag();
    let outlet = Outlet::open(&target).map_err(Failure::Runtime)?;
    let sent = crate::replay::send(file, &outlet).map_err(|e| match e {
        SendError::Recording(e) => Failure::BadInput(e),
        SendError::Viewer(e) => Failure::Runtime(e),
    })?;
    println!("replayed {sent} messages from {}", file.display());
    if serving {
        wait_while_serving(&stop);
    }
    Ok(ExitCode::SUCCESS)
}
