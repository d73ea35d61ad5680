//! The `peridyn` command line: argument parsing only; what each command does is in
//! `peridyn::cli`.

use std::path::PathBuf;
use std::process::ExitCode;

use clap::{Args, Parser, Subcommand};

use peridyn::cli::{self, BenchOptions, Failure, RunOptions, SceneRequest};
use peridyn::record::RecordTarget;
use peridyn::scene::builtin;

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
    /// Continue a run from a checkpoint (`record --checkpoint-every`).
    Resume {
        /// A checkpoint written by peridyn.
        checkpoint: PathBuf,
        /// The recording of the continued run (default: CHECKPOINT-resumed.rrd).
        #[arg(short, long)]
        output: Option<PathBuf>,
        /// No progress bar.
        #[arg(long, short)]
        quiet: bool,
        /// Also write a ParaView series into this folder.
        #[arg(long, value_name = "DIR")]
        vtu: Option<PathBuf>,
    },
    /// Write a recording as a ParaView time series: one .vtu per frame and a .pvd.
    Export {
        /// A recording made by peridyn.
        file: PathBuf,
        /// Which recording of the file (0 = the first; a session that restarted holds one per
        /// run).
        #[arg(long, default_value_t = 0)]
        recording: usize,
        /// Output folder.
        #[arg(short, long)]
        output: PathBuf,
    },
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
        /// The docs' headline speed pairs, end to end: each side a whole `record` process,
        /// alternated, with the accuracy figure beside each; prints a Markdown table.
        #[arg(long)]
        pairs: bool,
        /// With --pairs: the same comparisons on small variants (seconds each).
        #[arg(long)]
        quick: bool,
        /// With --pairs: alternations per pair (default 2, or 1 with --quick).
        #[arg(long)]
        rounds: Option<usize>,
        /// With --pairs: only the pairs of this preset (re-measure what a change touched).
        #[arg(long, value_name = "PRESET")]
        only: Option<String>,
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

#[derive(Args, Default)]
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
    /// Also write a ParaView series (one .vtu per frame and a .pvd) into this folder, off the
    /// solver thread.
    #[arg(long, value_name = "DIR")]
    vtu: Option<PathBuf>,
    /// Write a restart file every N steps or span of simulated time (`500`, `500 steps`,
    /// `20 us`); `peridyn resume FILE` continues from the last one.
    #[arg(long, value_name = "WHEN")]
    checkpoint_every: Option<String>,
    /// The restart file (default: the recording's name with `.ckpt`).
    #[arg(long, value_name = "FILE")]
    checkpoint: Option<PathBuf>,
    /// Timed commands to apply, one per line: `at 20 us set chi 0.9`,
    /// `at 2000 steps set m 3 restart` (see README).
    #[arg(long)]
    script: Option<PathBuf>,
}

/// Exit codes: 0 success, 1 runtime failure (I/O, viewer), 2 bad input, 3 unstable run,
/// 130 interrupted.
fn main() -> ExitCode {
    let cli = Cli::parse();
    // Before any kernel runs: a bad value is the user's to fix, not silently replaced.
    if let Err(message) = peridyn::simd::Simd::from_env() {
        return Failure::BadInput(message).report();
    }
    let command = cli.command.unwrap_or_else(|| {
        let (preset, variant) = builtin::DEFAULT;
        Command::Record {
            scene: SceneArgs {
                preset: preset.into(),
                variant: Some(variant.into()),
                set: Vec::new(),
            },
            output: None,
            run: RunArgs::default(),
        }
    });
    execute(command).unwrap_or_else(Failure::report)
}

impl SceneArgs {
    fn request(&self) -> SceneRequest {
        SceneRequest {
            preset: self.preset.clone(),
            variant: self.variant.clone(),
            set: self.set.clone(),
        }
    }
}

impl RunArgs {
    fn options(&self) -> RunOptions {
        RunOptions {
            every: self.every,
            steps: self.steps,
            quiet: self.quiet,
            script: self.script.clone(),
            vtu: self.vtu.clone(),
            checkpoint_every: self.checkpoint_every.clone(),
            checkpoint: self.checkpoint.clone(),
        }
    }
}

fn execute(command: Command) -> Result<ExitCode, Failure> {
    match command {
        Command::List => cli::list(),
        Command::Check(args) => cli::check(&args.request()),
        Command::Record { scene, output, run } => {
            cli::record(&scene.request(), output, &run.options())
        }
        Command::Run {
            scene,
            viewer,
            output,
            run,
        } => {
            let target = viewer
                .target(output.clone())
                .unwrap_or(RecordTarget::Connect {
                    url: cli::DEFAULT_VIEWER.into(),
                    file: output,
                });
            cli::run(&scene.request(), target, &run.options())
        }
        Command::Sweep {
            preset,
            variant,
            vary,
            schemes,
            set,
            out,
        } => cli::sweep(
            &SceneRequest {
                preset,
                variant,
                set,
            },
            &vary,
            &schemes,
            &out,
        ),
        Command::Replay(args) => {
            let viewer = |file| args.viewer.target(file);
            cli::replay(
                &args.file,
                args.resimulate,
                args.output.clone(),
                viewer,
                args.quiet,
            )
        }
        Command::Resume {
            checkpoint,
            output,
            quiet,
            vtu,
        } => cli::resume(
            &checkpoint,
            output,
            &RunOptions {
                quiet,
                vtu,
                ..RunOptions::default()
            },
        ),
        Command::Export {
            file,
            recording,
            output,
        } => cli::export(&file, recording, &output),
        Command::Gui(args) => {
            let (preset, variant) = match args.preset {
                Some(p) => (p, args.variant),
                None => {
                    let (p, v) = builtin::DEFAULT;
                    (p.to_string(), args.variant.or(Some(v.to_string())))
                }
            };
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
            let request = SceneRequest {
                preset,
                variant,
                set: Vec::new(),
            };
            cli::gui(&request, target)
        }
        Command::Bench {
            steps,
            variant,
            schemes_only,
            hybrid_only,
            pairs,
            quick,
            rounds,
            only,
        } => cli::bench(&BenchOptions {
            steps,
            variant,
            schemes_only,
            hybrid_only,
            pairs,
            quick,
            rounds,
            only,
        }),
    }
}

/// Where a stream goes: a running viewer, a served gRPC stream, or a spawned viewer.
#[derive(Args)]
struct ViewerArgs {
    /// Stream to a running viewer (default URL rerun+http://127.0.0.1:9876/proxy).
    #[arg(long, num_args = 0..=1, default_missing_value = "rerun+http://127.0.0.1:9876/proxy", conflicts_with_all = ["serve", "spawn"])]
    connect: Option<String>,
    /// Host a gRPC stream that viewers connect to (default 127.0.0.1:9876, this machine only;
    /// give e.g. 0.0.0.0:9876 to serve other machines: the stream is unauthenticated); it keeps
    /// serving after the run until Ctrl-C.
    #[arg(long, num_args = 0..=1, default_missing_value = "127.0.0.1:9876", conflicts_with = "spawn")]
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
    /// Host a gRPC stream that viewers connect to (IP:PORT; a non-loopback address is reachable
    /// from other machines, unauthenticated), instead of spawning a viewer.
    #[arg(long)]
    serve: Option<String>,
    /// Also save everything to this file.
    #[arg(short, long)]
    output: Option<PathBuf>,
}
