//! The `peridyn` command line: list, check, record, run, bench.

use std::path::PathBuf;
use std::process::ExitCode;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};

use clap::{Args, Parser, Subcommand};
use indicatif::{ProgressBar, ProgressStyle};

use peridyn::record::{RecordTarget, RerunSink};
use peridyn::runner::{self, RunSummary};
use peridyn::scene::{Physics, Scene, SchemeKind, builtin};
use peridyn::{bench, control, report, sim};

#[derive(Parser)]
#[command(
    name = "peridyn",
    version,
    about = "Watch and measure adaptive peridynamic simulations live",
    long_about = "Watch and measure adaptive peridynamic simulations live.\n\n\
                  With no arguments, records the default scene (kalthoff-winkler, variant small) \
                  to kalthoff-winkler-small.rrd."
)]
struct Cli {
    #[command(subcommand)]
    command: Option<Command>,
}

#[derive(Subcommand)]
enum Command {
    /// List the built-in presets and their variants.
    List,
    /// Validate a preset and print its discretization (nodes, bonds, time step).
    Check(SceneArgs),
    /// Run a scene headless and save it as a Rerun recording (.rrd).
    Record {
        #[command(flatten)]
        scene: SceneArgs,
        /// Output file (default: PRESET[-VARIANT].rrd).
        #[arg(short, long)]
        output: Option<PathBuf>,
        #[command(flatten)]
        run: RunArgs,
    },
    /// Run a scene and stream it live to a Rerun viewer.
    Run {
        #[command(flatten)]
        scene: SceneArgs,
        #[command(flatten)]
        viewer: ViewerArgs,
        /// Also save the stream to this .rrd file.
        #[arg(short, long)]
        output: Option<PathBuf>,
        #[command(flatten)]
        run: RunArgs,
    },
    /// Speed against error: run a preset over values and schemes; write CSV, Markdown and PNG
    /// plots (error vs nodes, error vs wall time) into a folder.
    Sweep {
        /// A built-in preset name or a path to a preset .toml file.
        preset: String,
        /// Preset variant, e.g. `perturbed`.
        #[arg(long)]
        variant: Option<String>,
        /// A preset key and its values, e.g. `discretization.spacing=1,0.5,0.25` (repeatable:
        /// every combination runs).
        #[arg(long, value_name = "KEY=V1,V2,…", required = true)]
        vary: Vec<String>,
        /// Schemes to compare, e.g. `standard,wls-2,wls-4`.
        #[arg(long, value_delimiter = ',', default_value = "standard,wls-2,wls-4")]
        schemes: Vec<String>,
        /// Fixed overrides for every run, as with `record --set`.
        #[arg(long = "set", value_name = "KEY=VALUE")]
        set: Vec<String>,
        /// Output folder.
        #[arg(short, long, default_value = "sweep")]
        out: PathBuf,
    },
    /// Open the live control panel beside a Rerun viewer (spawned, or remote with --connect).
    Gui(GuiArgs),
    /// Send a saved recording to a viewer, or re-run it from its stored preset and commands.
    Replay(ReplayArgs),
    /// Throughput benchmark on the pmb-block-3d preset (single- and all-thread).
    Bench {
        /// Steps per measurement (default: the preset's 100).
        #[arg(long)]
        steps: Option<u64>,
        /// Preset variant to measure, e.g. `small` for a quick look.
        #[arg(long)]
        variant: Option<String>,
        /// Only the WLS-against-standard cost per node-step (2D m = 12, 3D m = 6).
        #[arg(long)]
        schemes_only: bool,
        /// Only the hybrid-against-standard pairs: kalthoff-winkler `medium` (or `small`) and
        /// corrosion-3d (1000 steps of the base scene, or `small` to its end).
        #[arg(long, value_name = "VARIANT", num_args = 0..=1, default_missing_value = "medium")]
        hybrid_only: Option<String>,
    },
}

#[derive(Args)]
struct SceneArgs {
    /// A built-in preset name (see `peridyn list`) or a path to a preset .toml file.
    preset: String,
    /// Preset variant, e.g. `small`.
    #[arg(long)]
    variant: Option<String>,
    /// Override a preset value after the variant, e.g. `--set discretization.scheme=wls-4`
    /// (repeatable; values in TOML syntax, bare words are strings).
    #[arg(long = "set", value_name = "KEY=VALUE")]
    set: Vec<String>,
}

#[derive(Args)]
struct RunArgs {
    /// Log a frame every K steps (overrides the preset's output.every).
    #[arg(long)]
    every: Option<u64>,
    /// Stop after this many steps.
    #[arg(long)]
    steps: Option<u64>,
    /// No progress bar.
    #[arg(long, short)]
    quiet: bool,
    /// Timed commands to apply, one per line: `at 20 us set chi 0.9`,
    /// `at 2000 steps set m 3 restart` (see README).
    #[arg(long)]
    script: Option<PathBuf>,
}

/// Exit codes: 0 success, 1 runtime failure (I/O, viewer), 2 bad input, 3 unstable run,
/// 130 interrupted.
fn main() -> ExitCode {
    let cli = Cli::parse();
    let command = cli.command.unwrap_or_else(|| {
        let (preset, variant) = builtin::DEFAULT;
        Command::Record {
            scene: SceneArgs {
                preset: preset.into(),
                variant: Some(variant.into()),
                set: Vec::new(),
            },
            output: None,
            run: RunArgs {
                every: None,
                steps: None,
                quiet: false,
                script: None,
            },
        }
    });
    match execute(command) {
        Ok(code) => code,
        Err(Failure::BadInput(msg)) => {
            eprintln!("error: {msg}");
            ExitCode::from(2)
        }
        Err(Failure::Runtime(msg)) => {
            eprintln!("error: {msg}");
            ExitCode::from(1)
        }
    }
}

enum Failure {
    BadInput(String),
    Runtime(String),
}

fn load(args: &SceneArgs) -> Result<Scene, Failure> {
    Scene::load_with(&args.preset, args.variant.as_deref(), &args.set)
        .map_err(|e| Failure::BadInput(e.to_string()))
}

fn execute(command: Command) -> Result<ExitCode, Failure> {
    match command {
        Command::List => {
            for name in builtin::names() {
                let scene = Scene::load(name, None).map_err(|e| Failure::Runtime(e.to_string()))?;
                let preset: peridyn::scene::Preset = toml::from_str(&scene.preset_text)
                    .map_err(|e| Failure::Runtime(e.to_string()))?;
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
        Command::Check(args) => {
            let scene = load(&args)?;
            let sim = sim::build(&scene).map_err(|e| Failure::BadInput(e.to_string()))?;
            println!("{}", describe(&scene, &sim.info(), None));
            Ok(ExitCode::SUCCESS)
        }
        Command::Record { scene, output, run } => {
            let loaded = load(&scene)?;
            let path = output.unwrap_or_else(|| default_output(&loaded));
            let summary = simulate(&loaded, RecordTarget::File(path.clone()), &run)?;
            println!("recording: {}", path.display());
            println!(
                "view it:   pip install 'rerun-sdk==0.36.*' && rerun {}",
                path.display()
            );
            Ok(exit_code(&summary))
        }
        Command::Run {
            scene,
            viewer,
            output,
            run,
        } => {
            let loaded = load(&scene)?;
            let target = viewer
                .target(output.clone())
                .unwrap_or(RecordTarget::Connect {
                    url: "rerun+http://127.0.0.1:9876/proxy".into(),
                    file: output,
                });
            let summary = simulate(&loaded, target, &run)?;
            Ok(exit_code(&summary))
        }
        Command::Sweep {
            preset,
            variant,
            vary,
            schemes,
            set,
            out,
        } => {
            let axes = vary
                .iter()
                .map(|v| report::Axis::parse(v))
                .collect::<Result<Vec<_>, _>>()
                .map_err(Failure::BadInput)?;
            let schemes = schemes
                .iter()
                .map(|name| {
                    SchemeKind::ALL
                        .into_iter()
                        .find(|k| k.name() == name.trim())
                        .ok_or_else(|| {
                            let known: Vec<&str> =
                                SchemeKind::ALL.iter().map(|k| k.name()).collect();
                            Failure::BadInput(format!(
                                "--schemes: unknown scheme `{name}` (known: {})",
                                known.join(", ")
                            ))
                        })
                })
                .collect::<Result<Vec<_>, _>>()?;
            let spec = report::SweepSpec {
                preset,
                variant,
                set,
                axes,
                schemes,
            };
            let total =
                spec.schemes.len() * spec.axes.iter().map(|a| a.values.len()).product::<usize>();
            let mut done = 0;
            let rows = report::run(&spec, &mut |label| {
                done += 1;
                eprintln!("[{done}/{total}] {label}");
            })
            .map_err(Failure::BadInput)?;
            print!("{}", report::markdown(&spec, &rows));
            for path in report::write(&out, &spec, &rows).map_err(Failure::Runtime)? {
                println!("wrote {path}");
            }
            Ok(ExitCode::SUCCESS)
        }
        Command::Replay(args) => replay(args),
        Command::Gui(args) => gui(args),
        Command::Bench {
            steps,
            variant,
            schemes_only,
            hybrid_only,
        } => {
            if let Some(v) = hybrid_only {
                println!("{}", bench::hybrid::report(&v).map_err(Failure::Runtime)?);
                return Ok(ExitCode::SUCCESS);
            }
            if !schemes_only {
                let report = bench::run(variant.as_deref(), steps).map_err(Failure::Runtime)?;
                println!("{report}");
            }
            println!("{}", bench::schemes::report(0.5).map_err(Failure::Runtime)?);
            if !schemes_only {
                println!(
                    "{}",
                    bench::hybrid::report("medium").map_err(Failure::Runtime)?
                );
            }
            Ok(ExitCode::SUCCESS)
        }
    }
}

fn default_output(scene: &Scene) -> PathBuf {
    match &scene.variant {
        Some(v) => PathBuf::from(format!("{}-{v}.rrd", scene.name)),
        None => PathBuf::from(format!("{}.rrd", scene.name)),
    }
}

fn exit_code(summary: &RunSummary) -> ExitCode {
    if summary.error.is_some() {
        ExitCode::from(3)
    } else if summary.interrupted {
        ExitCode::from(130)
    } else {
        ExitCode::SUCCESS
    }
}

fn simulate(scene: &Scene, target: RecordTarget, args: &RunArgs) -> Result<RunSummary, Failure> {
    if args.script.is_some() {
        return simulate_scripted(scene, target, args);
    }
    let serving = matches!(target, RecordTarget::Serve { .. });
    let mut scene = scene.clone();
    if let Some(k) = args.every {
        if k == 0 {
            return Err(Failure::BadInput("--every must be ≥ 1".into()));
        }
        scene.output_every = Some(k);
    }
    let mut sim = sim::build(&scene).map_err(|e| Failure::BadInput(e.to_string()))?;
    let info = sim.info();
    eprintln!("{}", describe(&scene, &info, args.steps));
    let mut sink = RerunSink::start(target, &scene, &info).map_err(Failure::Runtime)?;
    sink.document(
        control::runspec::ENTITY,
        &control::runspec::RunSpec::new(&scene, args.every, args.steps).to_text(),
    );
    let stop = Arc::new(AtomicBool::new(false));
    {
        let stop = stop.clone();
        // A second Ctrl-C while finishing exits at once.
        let _ = ctrlc::set_handler(move || {
            if stop.swap(true, Ordering::Relaxed) {
                std::process::exit(130);
            }
        });
    }
    let total = args.steps.unwrap_or(info.total_steps).min(info.total_steps);
    let bar = if args.quiet {
        ProgressBar::hidden()
    } else {
        ProgressBar::new(total)
    };
    bar.set_style(
        ProgressStyle::with_template("{bar:40} {pos}/{len} steps  {per_sec}  eta {eta}")
            .unwrap_or_else(|_| ProgressStyle::default_bar()),
    );
    let mut progress = |n: u64, _total: u64| {
        if n.is_multiple_of(16) || n == total {
            bar.set_position(n);
        }
    };
    let summary = runner::run(sim.as_mut(), &mut sink, &stop, Some(total), &mut progress);
    bar.finish_and_clear();
    if serving && !stop.load(Ordering::Relaxed) {
        // Viewers may connect after the run: keep the stream (and its replay buffer) alive.
        eprintln!("run finished; still serving the recording — press Ctrl-C to stop");
        while !stop.load(Ordering::Relaxed) {
            std::thread::sleep(std::time::Duration::from_millis(100));
        }
    }
    let written = sink.finish().map_err(Failure::Runtime)?;
    print_summary(&summary, written.frames);
    if let Some(e) = &summary.error {
        eprintln!("error: {e}");
    }
    if summary.interrupted {
        eprintln!("interrupted: the recording holds every frame logged before the signal");
    }
    Ok(summary)
}

/// A ratio to a bound, readable from 10⁻⁶ to 10.
fn ratio(r: f64) -> String {
    if r >= 0.01 {
        format!("{r:.3}")
    } else {
        format!("{r:.2e}")
    }
}

/// One line on a built scene: size, scheme, time step against its bound, steps.
fn describe(scene: &Scene, info: &sim::SimInfo, steps: Option<u64>) -> String {
    let name = match &scene.variant {
        Some(v) => format!("{} [{v}]", scene.name),
        None => scene.name.clone(),
    };
    let steps = steps.unwrap_or(info.total_steps).min(info.total_steps);
    let stencil = format!(
        "{} scheme, {:.1} nodes per stencil",
        scene.scheme.kind.name(),
        info.stencil
    );
    match scene.physics {
        Physics::Static => format!(
            "{name}: {}D static, {} nodes, {stencil}, {} operator entries, one global solve",
            info.dim, info.nodes, info.bonds
        ),
        Physics::Diffusion | Physics::Corrosion => format!(
            "{name}: {}D {}, {} nodes, {stencil}, Δt = {:.4e} s ({} × forward Euler's \
             bound {:.4e} s from {}), {steps} steps, a frame every {}",
            info.dim,
            if scene.physics == Physics::Corrosion {
                "corrosion"
            } else {
                "diffusion"
            },
            info.nodes,
            info.dt,
            ratio(info.dt / info.stable_dt),
            info.stable_dt,
            if info.stable_dt == info.gershgorin_dt {
                "Gershgorin discs; the step is below it, no power iteration needed"
            } else {
                "the operator's spectral radius"
            },
            info.frame_every
        ),
        Physics::Dynamics => format!(
            "{name}: {}D, {} nodes, {} directed bonds, Δt = {:.4e} s ({:.2}× the stable bound \
             {:.4e} s; (3.8) estimate {:.4e} s), {steps} steps, a frame every {}",
            info.dim,
            info.nodes,
            info.bonds,
            info.dt,
            info.dt / info.stable_dt,
            info.stable_dt,
            info.gershgorin_dt,
            info.frame_every
        ),
    }
}

fn print_summary(s: &RunSummary, frames_written: u64) {
    println!(
        "steps: {}  frames: {} ({} written)  wall: {:.2} s  steps/s: {:.1}  bond evaluations/s: {:.3e}  frame share: {:.1} %",
        s.steps,
        s.frames,
        frames_written,
        s.wall_seconds,
        s.steps_per_second(),
        s.bond_evaluations_per_second(),
        100.0 * s.frame_seconds / s.wall_seconds.max(1e-12)
    );
    let stages: Vec<String> = s
        .stages
        .iter()
        .filter(|(_, t)| *t > 0.0)
        .map(|(n, t)| format!("{n} {t:.2} s"))
        .collect();
    println!("stages: {}", stages.join(", "));
    let last = |key: &str| s.last_frame.as_ref().and_then(|f| f.scalar(key));
    if let Some(e) = s.relative_error {
        println!("relative l2 error (3.79): {e:.6e}");
    } else if let Some(loss) = last("corrosion/volume_loss") {
        println!(
            "relative volume loss: {loss:.4}  solid nodes: {}  mass Σ C V: {:.10e}",
            last("corrosion/solid_nodes").unwrap_or(0.0),
            last("field/integral").unwrap_or(0.0)
        );
    } else {
        println!("broken bonds: {}", s.broken_bonds);
    }
    if let Some(f) = &s.last_frame {
        for key in ["energy/kinetic", "energy/strain", "energy/total"] {
            if let Some(v) = f.scalar(key) {
                println!("{key}: {v:.6e} J");
            }
        }
    }
    if let Some(f) = &s.last_frame {
        let hash = |values: &[f64]| control::driver::field_hash(values.iter().map(|v| v.to_bits()));
        let mut hashes = vec![format!("positions {:016x}", hash(&f.positions))];
        hashes.extend(f.fields.iter().map(|n| format!("{} {:016x}", n.name, hash(&n.values))));
        hashes.extend(f.classes.iter().map(|c| {
            let ids = control::driver::field_hash(c.ids.iter().map(|&v| v as u64));
            format!("{} {ids:016x}", c.name)
        }));
        println!("final time: {:e} s  field hashes: {}", f.time, hashes.join(", "));
    }
    for (name, angle) in &s.crack_angles {
        match angle {
            Some(a) => println!("crack angle {name}: {a:.1}°"),
            None => println!("crack angle {name}: no crack found"),
        }
    }
}

/// Where a stream goes: a running viewer, a served gRPC stream, or a spawned viewer.
#[derive(Args)]
struct ViewerArgs {
    /// Stream to a running viewer (default URL rerun+http://127.0.0.1:9876/proxy).
    #[arg(long, num_args = 0..=1, default_missing_value = "rerun+http://127.0.0.1:9876/proxy", conflicts_with_all = ["serve", "spawn"])]
    connect: Option<String>,
    /// Host a gRPC stream that viewers connect to (default 0.0.0.0:9876); it keeps serving
    /// after the run until Ctrl-C.
    #[arg(long, num_args = 0..=1, default_missing_value = "0.0.0.0:9876", conflicts_with = "spawn")]
    serve: Option<String>,
    /// Start a local `rerun` viewer (needs `rerun` on PATH).
    #[arg(long)]
    spawn: bool,
}

impl ViewerArgs {
    /// The chosen target, also saving to `file` if given; None if no flag was given.
    fn target(&self, file: Option<PathBuf>) -> Option<RecordTarget> {
        if let Some(url) = self.connect.clone() {
            Some(RecordTarget::Connect { url, file })
        } else if let Some(addr) = self.serve.clone() {
            Some(RecordTarget::Serve { addr, file })
        } else if self.spawn {
            Some(RecordTarget::Spawn { file })
        } else {
            None
        }
    }
}

#[derive(Args)]
struct ReplayArgs {
    /// A recording made by peridyn.
    file: PathBuf,
    /// Re-run the simulation from the preset and command log stored in the recording.
    #[arg(long)]
    resimulate: bool,
    /// With --resimulate: save the new recording here (default: FILE-resim.rrd).
    #[arg(short, long, requires = "resimulate")]
    output: Option<PathBuf>,
    #[command(flatten)]
    viewer: ViewerArgs,
    /// No progress bar (with --resimulate).
    #[arg(long, short)]
    quiet: bool,
}

/// Ctrl-C raises the flag; a second Ctrl-C exits at once.
fn stop_flag() -> Arc<AtomicBool> {
    let stop = Arc::new(AtomicBool::new(false));
    let flag = stop.clone();
    let _ = ctrlc::set_handler(move || {
        if flag.swap(true, Ordering::Relaxed) {
            std::process::exit(130);
        }
    });
    stop
}

fn wait_while_serving(stop: &AtomicBool) {
    eprintln!("still serving the recording — press Ctrl-C to stop");
    while !stop.load(Ordering::Relaxed) {
        std::thread::sleep(std::time::Duration::from_millis(100));
    }
}

/// A run driven by a command script: commands at their time, restarts as new recordings.
fn simulate_scripted(
    scene: &Scene,
    target: RecordTarget,
    args: &RunArgs,
) -> Result<RunSummary, Failure> {
    let script = match &args.script {
        Some(path) => control::script::load(path).map_err(|e| Failure::BadInput(e.to_string()))?,
        None => Vec::new(),
    };
    if args.every == Some(0) {
        return Err(Failure::BadInput("--every must be ≥ 1".into()));
    }
    let spec = control::runspec::RunSpec::new(scene, args.every, args.steps);
    run_spec(spec, &script, target, args.quiet)
}

fn run_spec(
    spec: control::runspec::RunSpec,
    script: &[control::script::Timed],
    target: RecordTarget,
    quiet: bool,
) -> Result<RunSummary, Failure> {
    let serving = matches!(target, RecordTarget::Serve { .. });
    let scene = spec.scene().map_err(|e| Failure::BadInput(e.to_string()))?;
    let outlet = peridyn::record::Outlet::open(&target).map_err(Failure::Runtime)?;
    let session = peridyn::record::recording_id(&scene);
    let driver = control::Driver::start(spec, outlet, &session).map_err(Failure::BadInput)?;
    eprintln!(
        "{}: {} nodes, {} bonds, Δt = {:.3e} s (stable bound {:.3e} s), {} steps, {} scripted commands",
        scene.name,
        driver.state.nodes,
        driver.state.bonds,
        driver.state.dt,
        driver.state.stable_dt,
        driver.total_steps(),
        script.len()
    );
    let stop = stop_flag();
    let bar = if quiet {
        ProgressBar::hidden()
    } else {
        ProgressBar::new(driver.total_steps())
    };
    bar.set_style(
        ProgressStyle::with_template("{bar:40} {pos}/{len} steps  {per_sec}  {msg}")
            .unwrap_or_else(|_| ProgressStyle::default_bar()),
    );
    let mut progress = |n: u64, total: u64| {
        if n.is_multiple_of(16) || n == total {
            bar.set_length(total);
            bar.set_position(n);
        }
    };
    let outcome = control::driver::run_script(driver, script, &stop, &mut progress)
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
    print_summary(&summary, summary.frames);
    println!("runs: {}", outcome.runs);
    if let Some(f) = &summary.last_frame
        && let Some(d) = f.fields.iter().find(|f| f.name == "damage")
    {
        let hash = control::driver::field_hash(d.values.iter().map(|v| v.to_bits()));
        println!("final damage hash: {hash:016x}");
    }
    if let Some(e) = &summary.error {
        eprintln!("error: {e}");
    }
    if summary.interrupted {
        eprintln!("interrupted: the recording holds every frame logged before the signal");
    }
    Ok(summary)
}

fn replay(args: ReplayArgs) -> Result<ExitCode, Failure> {
    let viewer = |file: Option<PathBuf>| args.viewer.target(file);
    if args.resimulate {
        let rec = peridyn::readback::read(&args.file).map_err(Failure::BadInput)?;
        if rec.entities.is_empty() {
            return Err(Failure::BadInput(format!(
                "{}: not a Rerun recording (or one without data)",
                args.file.display()
            )));
        }
        let text = rec
            .entity(&format!("/{}", control::runspec::ENTITY))
            .and_then(|e| e.texts.last())
            .ok_or_else(|| {
                Failure::BadInput(format!(
                    "{}: no `{}` document; only recordings made by peridyn can be re-run",
                    args.file.display(),
                    control::runspec::ENTITY
                ))
            })?;
        let spec = control::runspec::RunSpec::from_text(text)
            .map_err(|e| Failure::BadInput(format!("{}: {e}", args.file.display())))?;
        let script = spec
            .script()
            .map_err(|e| Failure::BadInput(format!("{}: {e}", args.file.display())))?;
        let output = args.output.clone().unwrap_or_else(|| {
            let stem = args
                .file
                .file_stem()
                .map(|s| s.to_string_lossy().to_string())
                .unwrap_or_else(|| "replay".into());
            args.file.with_file_name(format!("{stem}-resim.rrd"))
        });
        let target = viewer(Some(output.clone())).unwrap_or(RecordTarget::File(output.clone()));
        let summary = run_spec(spec, &script, target, args.quiet)?;
        println!("recording: {}", output.display());
        return Ok(exit_code(&summary));
    }
    let target = viewer(None).unwrap_or(RecordTarget::Connect {
        url: "rerun+http://127.0.0.1:9876/proxy".into(),
        file: None,
    });
    let serving = matches!(target, RecordTarget::Serve { .. });
    if !args.file.is_file() {
        return Err(Failure::BadInput(format!(
            "{}: no such recording",
            args.file.display()
        )));
    }
    let outlet = peridyn::record::Outlet::open(&target).map_err(Failure::Runtime)?;
    let sent = peridyn::replay::send(&args.file, &outlet).map_err(Failure::Runtime)?;
    println!("replayed {sent} messages from {}", args.file.display());
    if serving {
        wait_while_serving(&stop_flag());
    }
    Ok(ExitCode::SUCCESS)
}

#[derive(Args)]
struct GuiArgs {
    /// A built-in preset name or a preset file (default: kalthoff-winkler).
    preset: Option<String>,
    /// Preset variant (default with the default preset: small).
    #[arg(long)]
    variant: Option<String>,
    /// Stream to a running (possibly remote) viewer instead of spawning one.
    #[arg(long, conflicts_with = "serve")]
    connect: Option<String>,
    /// Host a gRPC stream that remote viewers connect to, instead of spawning a viewer.
    #[arg(long)]
    serve: Option<String>,
    /// Also save everything to this file.
    #[arg(short, long)]
    output: Option<PathBuf>,
}

fn gui(args: GuiArgs) -> Result<ExitCode, Failure> {
    let (preset, variant) = match args.preset {
        Some(p) => (p, args.variant),
        None => {
            let (p, v) = builtin::DEFAULT;
            (p.to_string(), args.variant.or(Some(v.to_string())))
        }
    };
    let scene = load(&SceneArgs {
        preset,
        variant,
        set: Vec::new(),
    })?;
    let target = if let Some(url) = args.connect {
        RecordTarget::Connect {
            url,
            file: args.output,
        }
    } else if let Some(addr) = args.serve {
        RecordTarget::Serve {
            addr,
            file: args.output,
        }
    } else {
        RecordTarget::Spawn { file: args.output }
    };
    let outlet = peridyn::record::Outlet::open(&target).map_err(Failure::Runtime)?;
    let spec = control::runspec::RunSpec::new(&scene, None, None);
    let session = peridyn::record::recording_id(&scene);
    let driver = control::Driver::start(spec, outlet, &session).map_err(Failure::BadInput)?;
    let shared = Arc::new(std::sync::Mutex::new(driver.state.clone()));
    let (sender, receiver) = crossbeam_channel::unbounded();
    let stop = Arc::new(AtomicBool::new(false));
    let worker = control::worker::spawn(driver, receiver, shared.clone(), stop.clone())
        .map_err(|e| Failure::Runtime(format!("cannot start the simulation thread: {e}")))?;
    let shown = peridyn::panel::app::run(shared, sender);
    stop.store(true, Ordering::Relaxed);
    let summary = worker
        .join()
        .map_err(|_| Failure::Runtime("the simulation thread panicked".into()))?
        .map_err(Failure::Runtime)?;
    shown.map_err(Failure::Runtime)?;
    print_summary(&summary, summary.frames);
    Ok(ExitCode::SUCCESS)
}
