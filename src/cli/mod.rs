//! What the `peridyn` commands do, behind the argument parsing of `main.rs`: every recorded
//! or streamed run (`record`, `run`, scripts, `replay --resimulate`) goes through one run loop
//! (`session`), and the plain commands (`list`, `check`, `sweep`, `bench`, `gui`, `replay`)
//! have a function each.

mod report;
mod session;

pub use report::describe;
pub use session::{RunOptions, record, replay, resume, run};

use std::process::ExitCode;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};

use crate::record::{Outlet, RecordTarget};
use crate::runner::RunSummary;
use crate::scene::{Scene, SchemeKind, builtin};
use crate::{bench, control, sim};

/// Where `run` and `replay` stream without a viewer flag: a viewer on this machine.
pub const DEFAULT_VIEWER: &str = "rerun+http://127.0.0.1:9876/proxy";

/// Why a command failed: bad input (exit code 2) or a runtime failure (1).
pub enum Failure {
    BadInput(String),
    Runtime(String),
}

impl Failure {
    /// Prints the error and gives the exit code.
    pub fn report(self) -> ExitCode {
        let (message, code) = match self {
            Failure::BadInput(m) => (m, 2),
            Failure::Runtime(m) => (m, 1),
        };
        eprintln!("error: {message}");
        ExitCode::from(code)
    }
}

/// A preset as the command line names it.
#[derive(Debug, Clone)]
pub struct SceneRequest {
    /// A built-in name or a path to a preset file.
    pub preset: String,
    pub variant: Option<String>,
    /// `--set KEY=VALUE` overrides, in order.
    pub set: Vec<String>,
}

impl SceneRequest {
    pub fn load(&self) -> Result<Scene, Failure> {
        Scene::load_with(&self.preset, self.variant.as_deref(), &self.set)
            .map_err(|e| Failure::BadInput(e.to_string()))
    }
}

/// Exit codes: 0 done, 3 the run became unstable, 130 interrupted.
pub fn exit_code(summary: &RunSummary) -> ExitCode {
    if summary.error.is_some() {
        ExitCode::from(3)
    } else if summary.interrupted {
        ExitCode::from(130)
    } else {
        ExitCode::SUCCESS
    }
}

/// Ctrl-C raises the flag; a second Ctrl-C exits at once.
pub fn stop_flag() -> Arc<AtomicBool> {
    let stop = Arc::new(AtomicBool::new(false));
    let flag = stop.clone();
    let _ = ctrlc::set_handler(move || {
        if flag.swap(true, Ordering::Relaxed) {
            std::process::exit(130);
        }
    });
    stop
}

/// A served stream stays up after the run, for viewers that connect late, until Ctrl-C.
fn wait_while_serving(stop: &AtomicBool) {
    eprintln!("still serving the recording — press Ctrl-C to stop");
    while !stop.load(Ordering::Relaxed) {
        std::thread::sleep(std::time::Duration::from_millis(100));
    }
}

/// `peridyn list`: the built-in presets and their variants.
pub fn list() -> Result<ExitCode, Failure> {
    for name in builtin::names() {
        let scene = Scene::load(name, None).map_err(|e| Failure::Runtime(e.to_string()))?;
        let preset: crate::scene::Preset =
            toml::from_str(&scene.preset_text).map_err(|e| Failure::Runtime(e.to_string()))?;
        let variants: Vec<&str> = preset.variants.keys().map(String::as_str).collect();
        println!(
            "{name:<20} {}\n{:<20} variants: {}",
            scene.description,
            "",
            variants.join(", ")
        );
    }
    Ok(ExitCode::SUCCESS)
}

/// `peridyn check`: builds the scene and prints its discretization and time step.
pub fn check(request: &SceneRequest) -> Result<ExitCode, Failure> {
    let scene = request.load()?;
    let sim = sim::build(&scene).map_err(|e| Failure::BadInput(e.to_string()))?;
    println!("{}", describe(&scene, &sim.info(), None));
    for line in &sim.info().notes {
        println!("{line}");
    }
    Ok(ExitCode::SUCCESS)
}

/// `peridyn sweep`: every combination of the axes' values and the schemes.
pub fn sweep(
    request: &SceneRequest,
    vary: &[String],
    schemes: &[String],
    out: &std::path::Path,
) -> Result<ExitCode, Failure> {
    let axes = vary
        .iter()
        .map(|v| crate::report::Axis::parse(v))
        .collect::<Result<Vec<_>, _>>()
        .map_err(Failure::BadInput)?;
    let schemes = schemes
        .iter()
        .map(|name| {
            SchemeKind::ALL
                .into_iter()
                .find(|k| k.name() == name.trim())
                .ok_or_else(|| {
                    let known: Vec<&str> = SchemeKind::ALL.iter().map(|k| k.name()).collect();
                    Failure::BadInput(format!(
                        "--schemes: unknown scheme `{name}` (known: {})",
                        known.join(", ")
                    ))
                })
        })
        .collect::<Result<Vec<_>, _>>()?;
    let spec = crate::report::SweepSpec {
        preset: request.preset.clone(),
        variant: request.variant.clone(),
        set: request.set.clone(),
        axes,
        schemes,
    };
    let total = spec.schemes.len() * spec.axes.iter().map(|a| a.values.len()).product::<usize>();
    let mut done = 0;
    let rows = crate::report::run(&spec, &mut |label| {
        done += 1;
        eprintln!("[{done}/{total}] {label}");
    })
    .map_err(Failure::BadInput)?;
    print!("{}", crate::report::markdown(&spec, &rows));
    for path in crate::report::write(out, &spec, &rows).map_err(Failure::Runtime)? {
        println!("wrote {path}");
    }
    Ok(ExitCode::SUCCESS)
}

/// What `peridyn bench` measures.
pub struct BenchOptions {
    pub steps: Option<u64>,
    pub variant: Option<String>,
    pub schemes_only: bool,
    /// Only the hybrid pairs, on this Kalthoff–Winkler variant.
    pub hybrid_only: Option<String>,
    /// The docs' headline pairs, end to end (`bench::pairs`); small variants when `quick`.
    pub pairs: bool,
    pub quick: bool,
    /// Alternations per pair (default 2; 1 with `quick`).
    pub rounds: Option<usize>,
    /// Only the pairs of this preset.
    pub only: Option<String>,
}

/// `peridyn bench`: throughput, WLS against standard, hybrid against standard.
pub fn bench(options: &BenchOptions) -> Result<ExitCode, Failure> {
    if options.pairs || options.quick {
        let rounds = options.rounds.unwrap_or(if options.quick { 1 } else { 2 });
        if rounds == 0 {
            return Err(Failure::BadInput(
                "--rounds: give at least 1 alternation per pair".to_string(),
            ));
        }
        let pairs: Vec<_> = bench::pairs::PAIRS
            .iter()
            .filter(|p| options.only.as_ref().is_none_or(|only| p.preset == only))
            .collect();
        if pairs.is_empty() {
            let mut presets: Vec<_> = bench::pairs::PAIRS.iter().map(|p| p.preset).collect();
            presets.sort_unstable();
            presets.dedup();
            return Err(Failure::BadInput(format!(
                "--only: no speed pair runs preset {:?}; the pairs' presets are {}",
                options.only.as_deref().unwrap_or_default(),
                presets.join(", ")
            )));
        }
        let mut progress = |label: &str| eprintln!("running {label}");
        let report = bench::pairs::report(&pairs, options.quick, rounds, &mut progress);
        println!("{}", report.table);
        if report.failures > 0 {
            return Err(Failure::Runtime(format!(
                "{} of {} pairs failed to run (their rows say why)",
                report.failures,
                pairs.len()
            )));
        }
        return Ok(ExitCode::SUCCESS);
    }
    if let Some(v) = &options.hybrid_only {
        println!("{}", bench::hybrid::report(v).map_err(Failure::Runtime)?);
        return Ok(ExitCode::SUCCESS);
    }
    if !options.schemes_only {
        let report =
            bench::run(options.variant.as_deref(), options.steps).map_err(Failure::Runtime)?;
        println!("{report}");
    }
    println!("{}", bench::schemes::report(0.5).map_err(Failure::Runtime)?);
    if !options.schemes_only {
        println!(
            "{}",
            bench::hybrid::report("medium").map_err(Failure::Runtime)?
        );
    }
    Ok(ExitCode::SUCCESS)
}

/// `peridyn export`: a recording as a ParaView series.
pub fn export(
    file: &std::path::Path,
    recording: usize,
    dir: &std::path::Path,
) -> Result<ExitCode, Failure> {
    if !file.is_file() {
        return Err(Failure::BadInput(format!(
            "{}: no such recording",
            file.display()
        )));
    }
    let exported =
        crate::export::from_recording(file, recording, dir).map_err(Failure::BadInput)?;
    println!(
        "wrote {} frames ({} to {} points) and {}",
        exported.frames,
        exported.points.iter().min().unwrap_or(&0),
        exported.points.iter().max().unwrap_or(&0),
        exported.collection.display()
    );
    println!("open it: paraview {}", exported.collection.display());
    Ok(ExitCode::SUCCESS)
}

/// `peridyn gui`: the control panel beside a viewer (spawned unless a target is given).
pub fn gui(request: &SceneRequest, target: RecordTarget) -> Result<ExitCode, Failure> {
    let scene = request.load()?;
    let outlet = Outlet::open(&target).map_err(Failure::Runtime)?;
    let spec = control::runspec::RunSpec::new(&scene, None, None);
    let session = crate::record::recording_id(&scene);
    let driver = control::Driver::start(spec, outlet, &session).map_err(Failure::BadInput)?;
    let shared = Arc::new(std::sync::Mutex::new(driver.state.clone()));
    let (sender, receiver) = crossbeam_channel::unbounded();
    let stop = Arc::new(AtomicBool::new(false));
    let worker = control::worker::spawn(driver, receiver, shared.clone(), stop.clone())
        .map_err(|e| Failure::Runtime(format!("cannot start the simulation thread: {e}")))?;
    let shown = crate::panel::app::run(shared, sender);
    stop.store(true, Ordering::Relaxed);
    let summary = worker
        .join()
        .map_err(|_| Failure::Runtime("the simulation thread panicked".into()))?
        .map_err(Failure::Runtime)?;
    shown.map_err(Failure::Runtime)?;
    report::print_summary(&summary);
    Ok(ExitCode::SUCCESS)
}
