//! Where recordings go: a file, a running viewer, a served gRPC stream or a spawned viewer,
//! shared by every recording of a session (`Outlet`), and a file that starts and stops while
//! running (`SaveSlot`).

use std::path::PathBuf;
use std::sync::{Arc, Mutex};
use std::time::Duration;

use rerun::log::LogMsg;
use rerun::sink::{FileSink, LogSink};
use rerun::{RecordingStream, RecordingStreamBuilder};

use crate::scene::Scene;

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
                let loopback = ip
                    .parse::<std::net::IpAddr>()
                    .is_ok_and(|a| a.is_loopback())
                    || ip == "localhost";
                if loopback {
                    eprintln!(
                        "serving on {ip}:{port} (this machine only): connect a viewer with \
                         `rerun --connect rerun+http://{ip}:{port}/proxy`"
                    );
                } else {
                    eprintln!(
                        "warning: serving on {ip}:{port}, reachable from other machines; the \
                         stream is unauthenticated: anyone who reaches this address can watch \
                         it. Connect with `rerun --connect rerun+http://HOST:{port}/proxy`"
                    );
                }
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
            .with_default_blueprint(super::blueprint::of_scene(scene))
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

    /// The file slot a recording's logging thread starts and stops.
    pub(super) fn save_slot(&self) -> Arc<SaveSlot> {
        self.save.clone()
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
pub(super) struct SaveSlot {
    file: Mutex<Option<FileSink>>,
    header: Mutex<Vec<LogMsg>>,
}

/// Static chunks above this size are not kept for late files (they are not headers).
const HEADER_CHUNK_LIMIT: usize = 1 << 20;

impl SaveSlot {
    pub(super) fn start(&self, file: FileSink) {
        for msg in self.header.lock().unwrap_or_else(|e| e.into_inner()).iter() {
            file.send(msg.clone());
        }
        *self.file.lock().unwrap_or_else(|e| e.into_inner()) = Some(file);
    }

    pub(super) fn stop(&self) {
        let file = self.file.lock().unwrap_or_else(|e| e.into_inner()).take();
        if let Some(file) = file {
            let _ = file.flush_blocking(Duration::from_secs(30));
        }
    }

    /// Store infos, static chunks and everything of the default blueprint.
    fn is_header(msg: &LogMsg) -> bool {
        match msg {
            LogMsg::SetStoreInfo(_) | LogMsg::BlueprintActivationCommand(_) => true,
            LogMsg::ArrowMsg(store, _) if store.kind() == rerun::StoreKind::Blueprint => true,
            LogMsg::ArrowMsg(_, arrow) => {
                arrow.batch.get_array_memory_size() < HEADER_CHUNK_LIMIT
                    && rerun::log::Chunk::from_arrow_msg(arrow).is_ok_and(|c| c.is_static())
            }
        }
    }

    /// The store info of a recording (not of its blueprint): a new run's first message.
    fn starts_run(msg: &LogMsg) -> bool {
        matches!(msg, LogMsg::SetStoreInfo(info)
            if info.info.store_id.kind() == rerun::StoreKind::Recording)
    }
}

impl LogSink for SaveSlot {
    fn send(&self, msg: LogMsg) {
        if Self::is_header(&msg) {
            let mut header = self.header.lock().unwrap_or_else(|e| e.into_inner());
            // Runs are sequential: a new recording's header replaces the previous one.
            if Self::starts_run(&msg) {
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
