//! Drives a simulation to its end: steps, decimated frames to a sink, progress, interruption.

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Instant;

use crate::frame::Frame;
use crate::solver::{SimError, SimInfo, Stepper};

/// Where frames go. Implementations must not slow the solver: `send` should only hand the
/// frame to another thread.
pub trait FrameSink {
    fn send(&mut self, frame: Frame);
    /// A one-off message (warnings, the reason a run stopped).
    fn message(&mut self, level: &str, text: &str);
}

/// A sink that drops everything (benchmarks, tests of the solver alone).
pub struct NullSink;

impl FrameSink for NullSink {
    fn send(&mut self, _frame: Frame) {}
    fn message(&mut self, _level: &str, _text: &str) {}
}

/// Called after each step with (steps done, total steps).
pub type Progress<'a> = &'a mut dyn FnMut(u64, u64);

#[derive(Debug, Clone)]
pub struct RunSummary {
    pub info: SimInfo,
    pub steps: u64,
    pub frames: u64,
    pub wall_seconds: f64,
    /// Wall time spent building and handing over frames, on the solver thread.
    pub frame_seconds: f64,
    pub interrupted: bool,
    pub error: Option<SimError>,
    pub crack_angles: Vec<(String, Option<f64>)>,
    pub broken_bonds: u64,
    /// Relative ℓ² error (3.79) at the end, for scenes with a reference solution.
    pub relative_error: Option<f64>,
    /// Wall time per stage of `step()`, in seconds.
    pub stages: Vec<(&'static str, f64)>,
    /// The run's final frame (the summary's figures are read from it).
    pub last_frame: Option<Frame>,
}

impl RunSummary {
    /// The summary of `sim` as it stands after a run, its figures read from the run's final
    /// frame (`last_frame`, or one built now if the run sent none at its end).
    pub fn of(
        sim: &mut dyn Stepper,
        frames: u64,
        wall_seconds: f64,
        frame_seconds: f64,
        interrupted: bool,
        error: Option<SimError>,
        last_frame: Option<Frame>,
    ) -> Self {
        let info = sim.info();
        let frame = last_frame.unwrap_or_else(|| sim.frame());
        RunSummary {
            crack_angles: info
                .crack_angles
                .iter()
                .map(|name| {
                    let angle = frame.scalar(&format!("crack_angle_deg/{name}"));
                    (name.clone(), angle)
                })
                .collect(),
            broken_bonds: frame.scalar("bonds/broken").unwrap_or(0.0) as u64,
            relative_error: frame.scalar("error/relative_l2"),
            stages: sim
                .stages()
                .named()
                .map(|(n, d)| (n, d.as_secs_f64()))
                .collect(),
            steps: sim.steps_done(),
            info,
            frames,
            wall_seconds,
            frame_seconds,
            interrupted,
            error,
            last_frame: Some(frame),
        }
    }

    pub fn steps_per_second(&self) -> f64 {
        self.steps as f64 / self.wall_seconds.max(1e-12)
    }

    pub fn bond_evaluations_per_second(&self) -> f64 {
        self.steps_per_second() * self.info.bonds as f64
    }
}

/// Runs `max_steps` (default: the scene's) steps, sending a frame at step 0, every
/// `info.frame_every` steps and at the end. Stops early, keeping every frame sent, when
/// `stop` is raised or the state blows up.
pub fn run(
    sim: &mut dyn Stepper,
    sink: &mut dyn FrameSink,
    stop: &Arc<AtomicBool>,
    max_steps: Option<u64>,
    progress: Progress,
) -> RunSummary {
    let info = sim.info();
    let total = max_steps.unwrap_or(info.total_steps);
    let start = Instant::now();
    let mut frame_seconds = 0.0;
    let mut frames = 0;
    let mut last_frame = None;
    let mut emit = |sim: &mut dyn Stepper, sink: &mut dyn FrameSink, keep: bool| {
        let t = Instant::now();
        let frame = sim.frame();
        if keep {
            last_frame = Some(frame.clone());
        }
        sink.send(frame);
        frames += 1;
        frame_seconds += t.elapsed().as_secs_f64();
    };
    emit(sim, sink, false);
    let mut error = None;
    let mut interrupted = false;
    while sim.steps_done() < total {
        if stop.load(Ordering::Relaxed) {
            interrupted = true;
            sink.message("warn", &format!("interrupted at step {}", sim.steps_done()));
            break;
        }
        if let Err(e) = sim.step() {
            sink.message("error", &e.to_string());
            error = Some(e);
            break;
        }
        let n = sim.steps_done();
        let converged = sim.converged();
        if n.is_multiple_of(info.frame_every) || n == total || converged {
            emit(sim, sink, n == total || converged);
        }
        if converged {
            sink.message("info", &format!("converged after {n} iterations"));
            progress(n, total);
            break;
        }
        progress(n, total);
    }
    RunSummary::of(
        sim,
        frames,
        start.elapsed().as_secs_f64(),
        frame_seconds,
        interrupted,
        error,
        last_frame,
    )
}
