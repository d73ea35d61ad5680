//! Rerun sink: maps `Frame`s to archetypes under a stable entity layout, on its own thread
//! behind a bounded channel so logging never runs inside the solver's step.
//!
//! Layout: `scene/preset` (the preset text), `nodes/<field>` (points at current positions,
//! colored by the field over a fixed range, carrying the raw per-node values as `<field>`),
//! `metrics/<name>` (scalar series), `log/events` (warnings, the reason a run stopped).
//! Time lines: `step` (sequence) and `sim_time` (duration).

use std::path::PathBuf;
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;
use std::time::Duration;

use crossbeam_channel::{Receiver, Sender, bounded};
use rerun::external::arrow::array::{ArrayRef, Float32Array};
use rerun::log::LogMsg;
use rerun::sink::{FileSink, LogSink};
use rerun::{AsComponents, ComponentIdentifier, RecordingStream, RecordingStreamBuilder};

use crate::frame::Frame;
use crate::runner::FrameSink;
use crate::scene::Scene;
use crate::sim::SimInfo;

/// Where a recording goes.
#[derive(Debug, Clone)]
pub enum RecordTarget {
    File(PathBuf),
    /// Stream to a running viewer; optionally also save to a file.
    Connect {
        url: String,
        file: Option<PathBuf>,
    },
    /// Host a gRPC server viewers connect to, at `addr` = "IP:PORT".
    Serve {
        addr: String,
        file: Option<PathBuf>,
    },
    /// Start a local viewer (needs `rerun` on PATH).
    Spawn {
        file: Option<PathBuf>,
    },
}

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
        log_scene(&stream, scene, info)
            .map_err(|e| format!("cannot write to the recording: {e}"))?;
        let (sender, receiver) = bounded(CHANNEL_CAPACITY);
        let radius = (0.5 * scene.spacing) as f32;
        let save = outlet.save.clone();
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

/// The destinations of a session's recordings, opened once and shared by every recording
/// (every run) of the session: one file holds them all, one viewer connection or one served
/// stream carries them all. Saving to a file can also start and stop while running.
#[derive(Clone)]
pub struct Outlet {
    /// The destinations given at the start (file, viewer, server).
    sinks: Vec<Arc<dyn LogSink>>,
    /// A file started and stopped while running.
    save: Arc<SaveSlot>,
}

impl Outlet {
    pub fn open(target: &RecordTarget) -> Result<Outlet, String> {
        use rerun::sink::GrpcSink;
        let file_sink = |path: &PathBuf| -> Result<Arc<dyn LogSink>, String> {
            Ok(Arc::new(FileSink::new(path.clone()).map_err(|e| {
                format!("cannot write {}: {e}", path.display())
            })?))
        };
        let connect = |url: &str| -> Result<Arc<dyn LogSink>, String> {
            check_reachable(url)?;
            let uri = url
                .parse::<rerun::external::re_uri::ProxyUri>()
                .map_err(|e| {
                    format!("bad viewer URL `{url}`: {e} (expected rerun+http://HOST:PORT/proxy)")
                })?;
            Ok(Arc::new(GrpcSink::new(uri)))
        };
        let (mut sinks, file) = match target {
            RecordTarget::File(path) => (vec![], Some(path)),
            RecordTarget::Connect { url, file } => (vec![connect(url)?], file.as_ref()),
            RecordTarget::Serve { addr, file } => {
                let (ip, port) = split_addr(addr)?;
                let server: Arc<dyn LogSink> = Arc::new(
                    rerun::grpc_server::GrpcServerSink::new(
                        &ip,
                        port,
                        rerun::ServerOptions::default(),
                    )
                    .map_err(|e| format!("cannot serve on `{addr}`: {e}"))?,
                );
                eprintln!(
                    "serving: connect a viewer with `rerun --connect rerun+http://127.0.0.1:{port}/proxy` (or this machine's address)"
                );
                (vec![server], file.as_ref())
            }
            RecordTarget::Spawn { file } => {
                let spawned = rerun::spawn(&rerun::SpawnOptions {
                    wait_for_bind: true,
                    ..Default::default()
                })
                .map_err(|e| {
                    format!(
                        "cannot start a viewer: {e} (install it with `pip install 'rerun-sdk==0.36.*'`)"
                    )
                })?;
                let url = format!("rerun+http://127.0.0.1:{}/proxy", spawned.port);
                (vec![connect(&url)?], file.as_ref())
            }
        };
        if let Some(path) = file {
            sinks.insert(0, file_sink(path)?);
        }
        Ok(Outlet {
            sinks,
            save: Arc::new(SaveSlot::default()),
        })
    }

    /// A new recording stream on every destination.
    pub fn stream(&self, recording_id: &str, scene: &Scene) -> Result<RecordingStream, String> {
        let save: Arc<dyn LogSink> = self.save.clone();
        let sinks: Vec<Box<dyn LogSink>> = self
            .sinks
            .iter()
            .chain([&save])
            .map(|s| Box::new(Shared(s.clone())) as Box<dyn LogSink>)
            .collect();
        RecordingStreamBuilder::new("peridyn")
            .recording_id(recording_id)
            .recording_name(scene.name.clone())
            .send_properties(true)
            .enabled(true)
            .set_sinks(sinks)
            .map_err(|e| format!("cannot open the recording: {e}"))
    }

    /// Sends an already-encoded message (a replayed recording) to every destination but a
    /// file started by `save start`.
    pub fn send_raw(&self, msg: LogMsg) {
        for sink in &self.sinks {
            sink.send(msg.clone());
        }
    }

    /// Waits until every destination has taken what was sent.
    pub fn flush(&self, timeout: Duration) -> Result<(), String> {
        for sink in &self.sinks {
            sink.flush_blocking(timeout)
                .map_err(|e| format!("cannot deliver the recording: {e}"))?;
        }
        Ok(())
    }

    /// Stops saving and completes the file (footer written).
    pub fn stop_saving(&self) {
        self.save.stop();
    }
}

/// One sink shared by several recording streams.
struct Shared(Arc<dyn LogSink>);

impl LogSink for Shared {
    fn send(&self, msg: LogMsg) {
        self.0.send(msg);
    }

    fn flush_blocking(&self, timeout: Duration) -> Result<(), rerun::sink::SinkFlushError> {
        self.0.flush_blocking(timeout)
    }
}

/// A file that can be opened and closed while running. It keeps the current recording's
/// header (store info and static chunks) so a file started mid-run is a complete recording.
#[derive(Default)]
struct SaveSlot {
    file: Mutex<Option<FileSink>>,
    header: Mutex<Vec<LogMsg>>,
}

/// Static chunks above this size are not kept for late files (they are not headers).
const HEADER_CHUNK_LIMIT: usize = 1 << 20;

impl SaveSlot {
    fn start(&self, file: FileSink) {
        for msg in self.header.lock().unwrap_or_else(|e| e.into_inner()).iter() {
            file.send(msg.clone());
        }
        *self.file.lock().unwrap_or_else(|e| e.into_inner()) = Some(file);
    }

    fn stop(&self) {
        let file = self.file.lock().unwrap_or_else(|e| e.into_inner()).take();
        if let Some(file) = file {
            let _ = file.flush_blocking(Duration::from_secs(30));
        }
    }

    fn is_header(msg: &LogMsg) -> bool {
        match msg {
            LogMsg::SetStoreInfo(_) => true,
            LogMsg::ArrowMsg(_, arrow) => {
                arrow.batch.get_array_memory_size() < HEADER_CHUNK_LIMIT
                    && rerun::log::Chunk::from_arrow_msg(arrow).is_ok_and(|c| c.is_static())
            }
            _ => false,
        }
    }
}

impl LogSink for SaveSlot {
    fn send(&self, msg: LogMsg) {
        if Self::is_header(&msg) {
            let mut header = self.header.lock().unwrap_or_else(|e| e.into_inner());
            // Runs are sequential: a new recording's header replaces the previous one.
            if matches!(msg, LogMsg::SetStoreInfo(_)) {
                header.clear();
            }
            header.push(msg.clone());
        }
        if let Some(file) = self.file.lock().unwrap_or_else(|e| e.into_inner()).as_ref() {
            file.send(msg);
        }
    }

    fn flush_blocking(&self, timeout: Duration) -> Result<(), rerun::sink::SinkFlushError> {
        match self.file.lock().unwrap_or_else(|e| e.into_inner()).as_ref() {
            Some(file) => file.flush_blocking(timeout).map_err(|e| match e {
                rerun::external::re_log_encoding::FileFlushError::Failed { message } => {
                    rerun::sink::SinkFlushError::Failed { message }
                }
                rerun::external::re_log_encoding::FileFlushError::Timeout => {
                    rerun::sink::SinkFlushError::Timeout
                }
            }),
            None => Ok(()),
        }
    }
}

fn split_addr(addr: &str) -> Result<(String, u16), String> {
    let (ip, port) = addr
        .rsplit_once(':')
        .ok_or_else(|| format!("bad address `{addr}`: expected IP:PORT, e.g. 0.0.0.0:9876"))?;
    let port = port
        .parse()
        .map_err(|_| format!("bad port in `{addr}`: expected a number 1–65535"))?;
    Ok((ip.to_string(), port))
}

/// The SDK does not fail on an unreachable viewer (it retries and eventually blocks), so test
/// the address first and give a clear error.
fn check_reachable(url: &str) -> Result<(), String> {
    use std::net::ToSocketAddrs;
    let host_port = url
        .split("://")
        .nth(1)
        .and_then(|rest| rest.split('/').next())
        .ok_or_else(|| format!("bad viewer URL `{url}` (expected rerun+http://HOST:PORT/proxy)"))?;
    let addrs: Vec<_> = host_port
        .to_socket_addrs()
        .map_err(|e| format!("cannot resolve viewer address `{host_port}`: {e}"))?
        .collect();
    for addr in &addrs {
        if std::net::TcpStream::connect_timeout(addr, Duration::from_millis(1500)).is_ok() {
            return Ok(());
        }
    }
    Err(format!(
        "no Rerun viewer is listening at {url}; start one with `rerun` (pip install 'rerun-sdk==0.36.*'), or use --spawn, --serve or `peridyn record`"
    ))
}

fn log_scene(
    stream: &RecordingStream,
    scene: &Scene,
    info: &SimInfo,
) -> rerun::RecordingStreamResult<()> {
    let header = format!(
        "# {}{}\n\nsource: `{}`; {}D, {} nodes, {} directed bonds, Δt = {:.4e} s (stable bound {:.4e} s), {} steps.\n\n```toml\n{}\n```\n",
        scene.name,
        scene
            .variant
            .as_deref()
            .map(|v| format!(" — variant `{v}`"))
            .unwrap_or_default(),
        scene.source,
        info.dim,
        info.nodes,
        info.bonds,
        info.dt,
        info.stable_dt,
        info.total_steps,
        scene.preset_text
    );
    stream.log_static("scene/preset", &rerun::TextDocument::from_markdown(header))
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
                log_frame(&stream, &frame, radius, &mut annotated)
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

fn log_frame(
    stream: &RecordingStream,
    frame: &Frame,
    radius: f32,
    annotated: &mut Vec<&'static str>,
) -> rerun::RecordingStreamResult<()> {
    stream.set_time_sequence("step", frame.step as i64);
    stream.set_duration_secs("sim_time", frame.time);
    let dim = frame.dim;
    // Positions converted once, shared by every field's entity.
    let positions: Vec<[f32; 3]> = frame
        .positions
        .chunks_exact(dim)
        .map(|p| std::array::from_fn(|k| p.get(k).map_or(0.0, |&v| v as f32)))
        .collect();
    let palette = palette();
    for field in &frame.fields {
        let scale = 255.0 / (field.range.1 - field.range.0);
        let colors: Vec<rerun::Color> = field
            .values
            .iter()
            .map(|&v| {
                let t = ((v - field.range.0) * scale).clamp(0.0, 255.0);
                palette[if t.is_finite() { t as usize } else { 0 }]
            })
            .collect();
        let raw: ArrayRef = Arc::new(Float32Array::from_iter_values(
            field.values.iter().map(|&v| v as f32),
        ));
        let values = rerun::AnyValues::default().with_component_from_data(
            ComponentIdentifier::try_new(field.name).unwrap_or("value".into()),
            raw,
        );
        let path = format!("nodes/{}", field.name);
        let points: Box<dyn AsComponents> = if dim == 3 {
            Box::new(
                rerun::Points3D::new(positions.iter().copied())
                    .with_colors(colors)
                    .with_radii([radius]),
            )
        } else {
            Box::new(
                rerun::Points2D::new(positions.iter().map(|p| [p[0], p[1]]))
                    .with_colors(colors)
                    .with_radii([radius]),
            )
        };
        stream.log(path, &[points.as_ref(), &values as &dyn AsComponents])?;
    }
    for class in &frame.classes {
        let path = format!("nodes/{}", class.name);
        if !annotated.contains(&class.name) {
            let context =
                rerun::AnnotationContext::new(class.classes.iter().map(|&(id, label, rgb)| {
                    (id, label, rerun::Rgba32::from_rgb(rgb[0], rgb[1], rgb[2]))
                }));
            stream.log_static(path.as_str(), &context)?;
            annotated.push(class.name);
        }
        let ids = class
            .ids
            .iter()
            .map(|&c| rerun::components::ClassId::from(c));
        if dim == 3 {
            stream.log(
                path,
                &rerun::Points3D::new(positions.iter().copied())
                    .with_class_ids(ids)
                    .with_radii([radius]),
            )?;
        } else {
            stream.log(
                path,
                &rerun::Points2D::new(positions.iter().map(|p| [p[0], p[1]]))
                    .with_class_ids(ids)
                    .with_radii([radius]),
            )?;
        }
    }
    for event in &frame.events {
        stream.log(
            "log/events",
            &rerun::TextLog::new(event.as_str()).with_level(rerun::TextLogLevel::INFO),
        )?;
    }
    for (name, value) in &frame.scalars {
        stream.log(format!("metrics/{name}"), &rerun::Scalars::single(*value))?;
    }
    Ok(())
}

/// The colormap sampled at 256 levels.
fn palette() -> &'static [rerun::Color; 256] {
    static PALETTE: std::sync::OnceLock<[rerun::Color; 256]> = std::sync::OnceLock::new();
    PALETTE.get_or_init(|| std::array::from_fn(|i| colormap(i as f64 / 255.0)))
}

/// Viridis, sampled at nine points and interpolated linearly; t is clamped to [0, 1].
pub fn colormap(t: f64) -> rerun::Color {
    const VIRIDIS: [[f64; 3]; 9] = [
        [68.0, 1.0, 84.0],
        [71.0, 44.0, 122.0],
        [59.0, 81.0, 139.0],
        [44.0, 113.0, 142.0],
        [33.0, 144.0, 141.0],
        [39.0, 173.0, 129.0],
        [92.0, 200.0, 99.0],
        [170.0, 220.0, 50.0],
        [253.0, 231.0, 37.0],
    ];
    let t = if t.is_finite() {
        t.clamp(0.0, 1.0)
    } else {
        0.0
    };
    let x = t * 8.0;
    let i = (x.floor() as usize).min(7);
    let f = x - i as f64;
    let channel = |k: usize| (VIRIDIS[i][k] * (1.0 - f) + VIRIDIS[i + 1][k] * f).round() as u8;
    rerun::Color::from_rgb(channel(0), channel(1), channel(2))
}
