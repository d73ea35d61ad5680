//! Rerun sink: maps `Frame`s to archetypes under a stable entity layout (`layout`), on its own
//! thread behind a bounded channel so logging never runs inside the solver's step, into the
//! destinations of an `Outlet` (`transport`: file, viewer connection, served stream).
//!
//! Layout: `scene/preset` (the preset text), `nodes/<field>` (points at current positions,
//! colored by the field over a fixed range, carrying the raw per-node values as `<field>`),
//! `nodes/<mask>` (class ids with an annotation context), `metrics/<name>` (scalar series),
//! `log/events` (switching and phase events, warnings, the reason a run stopped),
//! `control/run` and `control/commands`. Time lines: `step` (sequence) and `sim_time`
//! (duration).

pub mod blueprint;
mod layout;
mod transport;

pub use layout::colormap;
pub use transport::{Outlet, RecordTarget};

use std::thread::JoinHandle;
use std::time::Duration;

use crossbeam_channel::{Receiver, Sender, bounded};
use rerun::RecordingStream;
use rerun::sink::FileSink;

use crate::frame::Frame;
use crate::runner::FrameSink;
use crate::scene::Scene;
use crate::solver::SimInfo;
use transport::SaveSlot;

enum Message {
    Frame(Box<Frame>),
    Text(String, String),
    /// A command applied at a step: logged to `control/commands` on the `step` time line.
    Command(u64, String),
    /// A static text document (replaces the previous one at that entity).
    Document(String, String),
    /// Start (a file) or stop saving, after everything logged before is delivered.
    Save(Option<FileSink>),
}

/// Frames in flight between the solver and the logging thread: the solver waits (instead of
/// buffering without bound) when the sink falls behind.
const CHANNEL_CAPACITY: usize = 4;

/// What the logging thread did.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct SinkReport {
    pub frames: u64,
    /// Wall time the logging thread spent converting, logging and flushing.
    pub busy_seconds: f64,
}

pub struct RerunSink {
    sender: Option<Sender<Message>>,
    worker: Option<JoinHandle<Result<SinkReport, String>>>,
}

impl RerunSink {
    pub fn start(target: RecordTarget, scene: &Scene, info: &SimInfo) -> Result<Self, String> {
        let outlet = Outlet::open(&target)?;
        Self::start_in(&outlet, &recording_id(scene), scene, info)
    }

    /// Starts a recording with this id in an outlet shared by several recordings (runs that
    /// restart with new settings sit side by side in one viewer or one file).
    pub fn start_in(
        outlet: &Outlet,
        recording_id: &str,
        scene: &Scene,
        info: &SimInfo,
    ) -> Result<Self, String> {
        let stream = outlet.stream(recording_id, scene)?;
        layout::log_scene(&stream, scene, info)
            .map_err(|e| format!("cannot write to the recording: {e}"))?;
        let (sender, receiver) = bounded(CHANNEL_CAPACITY);
        let radius = (0.5 * scene.spacing) as f32;
        let save = outlet.save_slot();
        let worker = std::thread::Builder::new()
            .name("rerun-sink".into())
            .spawn(move || log_loop(stream, receiver, radius, &save))
            .map_err(|e| format!("cannot start the logging thread: {e}"))?;
        Ok(RerunSink {
            sender: Some(sender),
            worker: Some(worker),
        })
    }

    /// Logs a command applied at `step` to `control/commands`.
    pub fn command(&mut self, step: u64, text: &str) {
        if let Some(s) = &self.sender {
            let _ = s.send(Message::Command(step, text.into()));
        }
    }

    /// Starts saving to `path` (in order: everything logged before goes out first, and the
    /// file begins with the recording's header), or stops with `None`.
    pub fn save(&mut self, path: Option<&std::path::Path>) -> Result<(), String> {
        let file = match path {
            Some(p) => Some(
                FileSink::new(p.to_path_buf())
                    .map_err(|e| format!("cannot write {}: {e}", p.display()))?,
            ),
            None => None,
        };
        if let Some(s) = &self.sender {
            s.send(Message::Save(file))
                .map_err(|_| "the logging thread has stopped".to_string())?;
        }
        Ok(())
    }

    /// Logs a static text document (e.g. `control/run`), replacing the previous one.
    pub fn document(&mut self, entity: &str, text: &str) {
        if let Some(s) = &self.sender {
            let _ = s.send(Message::Document(entity.into(), text.into()));
        }
    }

    /// Logs everything still queued, closes the recording (writing the file's footer) and
    /// reports the frames written and the logging thread's busy time.
    pub fn finish(mut self) -> Result<SinkReport, String> {
        self.close()
    }

    fn close(&mut self) -> Result<SinkReport, String> {
        drop(self.sender.take());
        match self.worker.take() {
            Some(handle) => handle
                .join()
                .map_err(|_| "the logging thread panicked".to_string())?,
            None => Ok(SinkReport::default()),
        }
    }
}

impl Drop for RerunSink {
    fn drop(&mut self) {
        let _ = self.close();
    }
}

impl FrameSink for RerunSink {
    fn send(&mut self, frame: Frame) {
        if let Some(s) = &self.sender {
            let _ = s.send(Message::Frame(Box::new(frame)));
        }
    }

    fn message(&mut self, level: &str, text: &str) {
        if let Some(s) = &self.sender {
            let _ = s.send(Message::Text(level.into(), text.into()));
        }
    }
}

pub fn recording_id(scene: &Scene) -> String {
    let nanos = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map(|d| d.as_nanos())
        .unwrap_or(0);
    format!(
        "{}-{}-{nanos:x}",
        scene.name,
        scene.variant.as_deref().unwrap_or("base")
    )
}

fn log_loop(
    stream: RecordingStream,
    receiver: Receiver<Message>,
    radius: f32,
    save: &SaveSlot,
) -> Result<SinkReport, String> {
    let mut report = SinkReport::default();
    let mut result = Ok(());
    // Class fields whose annotation context (static) is already logged.
    let mut annotated: Vec<&'static str> = Vec::new();
    for message in receiver {
        let started = std::time::Instant::now();
        let logged = match message {
            Message::Frame(frame) => {
                report.frames += 1;
                layout::log_frame(&stream, &frame, radius, &mut annotated)
            }
            Message::Command(step, text) => {
                stream.set_time_sequence("step", step as i64);
                stream.log("control/commands", &rerun::TextLog::new(text))
            }
            Message::Document(entity, text) => {
                stream.log_static(entity, &rerun::TextDocument::new(text))
            }
            Message::Save(file) => {
                let _ = stream.flush_with_timeout(Duration::from_secs(30));
                match file {
                    Some(file) => save.start(file),
                    None => save.stop(),
                }
                Ok(())
            }
            Message::Text(level, text) => stream.log(
                "log/events",
                &rerun::TextLog::new(text).with_level(match level.as_str() {
                    "error" => rerun::TextLogLevel::ERROR,
                    "warn" => rerun::TextLogLevel::WARN,
                    _ => rerun::TextLogLevel::INFO,
                }),
            ),
        };
        if let Err(e) = logged {
            result = Err(format!("logging failed: {e}"));
        }
        report.busy_seconds += started.elapsed().as_secs_f64();
    }
    let started = std::time::Instant::now();
    let _ = stream.flush_with_timeout(Duration::from_secs(30));
    drop(stream);
    report.busy_seconds += started.elapsed().as_secs_f64();
    result.map(|_| report)
}
