//! Remote viewing: `peridyn run --serve` on a free port streams frames to a gRPC client (the
//! Rerun SDK's own reader, as a viewer uses it); when the client goes away the simulation
//! keeps running and keeps recording to file. An unreachable viewer gives a clear error.

use std::net::TcpStream;
use std::path::PathBuf;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use re_log_channel::{DataSourceMessage, SmartMessagePayload};
use rerun::log::{Chunk, LogMsg};

fn temp(name: &str) -> PathBuf {
    crate::common::temp("remote", name)
}

fn free_port() -> u16 {
    std::net::TcpListener::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port()
}

/// Reads messages from the served stream until `frames` frames of `/nodes/damage` arrived;
/// returns the steps seen.
fn receive_frames(url: &str, frames: usize, timeout: Duration) -> Vec<i64> {
    let runtime = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(1)
        .enable_all()
        .build()
        .unwrap();
    let handle = re_async::AsyncRuntimeHandle::new_native(runtime.handle().clone());
    let uri: rerun::external::re_uri::ProxyUri = url.parse().unwrap();
    let receiver = rerun::external::re_grpc_client::stream(&handle, uri);
    let step = rerun::TimelineName::from("step");
    let start = Instant::now();
    let mut steps = Vec::new();
    while steps.len() < frames && start.elapsed() < timeout {
        let Ok(msg) = receiver.recv_timeout(Duration::from_millis(500)) else {
            continue;
        };
        match msg.payload {
            SmartMessagePayload::Msg(DataSourceMessage::LogMsg(LogMsg::ArrowMsg(_, arrow))) => {
                let chunk = Chunk::from_arrow_msg(&arrow).unwrap();
                if chunk.entity_path().to_string() == "/nodes/damage"
                    && let Some(times) = chunk.timelines().get(&step)
                {
                    steps.extend(times.times_raw().iter().copied());
                }
            }
            SmartMessagePayload::Quit(e) => panic!("the stream ended: {e:?}"),
            _ => {}
        }
    }
    // Dropping the receiver and the runtime closes the connection: the client goes away.
    drop(receiver);
    runtime.shutdown_timeout(Duration::from_secs(1));
    steps
}

#[test]
fn served_run_streams_frames_and_outlives_its_client() {
    let port = free_port();
    let file = temp("served.rrd");
    let mut child = Command::new(env!("CARGO_BIN_EXE_peridyn"))
        .args([
            "run",
            "kalthoff-winkler",
            "--variant",
            "medium",
            "--serve",
            &format!("127.0.0.1:{port}"),
            "--every",
            "10",
            "-q",
            "-o",
            file.to_str().unwrap(),
        ])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    // The run's messages, line by line, as they come.
    let (lines, stderr_lines) = std::sync::mpsc::channel::<String>();
    let stderr = child.stderr.take().unwrap();
    std::thread::spawn(move || {
        use std::io::BufRead;
        for line in std::io::BufReader::new(stderr)
            .lines()
            .map_while(Result::ok)
        {
            let _ = lines.send(line);
        }
    });
    let mut seen = Vec::new();
    let finished = |seen: &mut Vec<String>| {
        seen.extend(stderr_lines.try_iter());
        seen.iter().any(|l| l.contains("still serving"))
    };
    let start = Instant::now();
    while TcpStream::connect(("127.0.0.1", port)).is_err() {
        assert!(start.elapsed() < Duration::from_secs(60), "never served");
        std::thread::sleep(Duration::from_millis(20));
    }
    let url = format!("rerun+http://127.0.0.1:{port}/proxy");
    let steps = receive_frames(&url, 3, Duration::from_secs(120));
    assert!(steps.len() >= 3, "frames received: {steps:?}");
    assert!(steps.iter().all(|s| s % 10 == 0), "{steps:?}");
    // The client is gone while the run is still going.
    assert!(
        !finished(&mut seen),
        "the run ended before the client left: {seen:?}"
    );

    // The run goes on to its end, then keeps serving.
    let start = Instant::now();
    while !finished(&mut seen) {
        assert!(
            child.try_wait().unwrap().is_none(),
            "the simulation stopped early: {seen:?}"
        );
        assert!(start.elapsed() < Duration::from_secs(300), "never finished");
        std::thread::sleep(Duration::from_millis(100));
    }
    let info = peridyn::sim::build(
        &peridyn::scene::Scene::load("kalthoff-winkler", Some("medium")).unwrap(),
    )
    .unwrap()
    .info();
    let last = info.total_steps as i64;
    let mut expected: Vec<i64> = (0..=last).step_by(10).collect();
    if *expected.last().unwrap() != last {
        expected.push(last);
    }
    // A second client connecting after the run still gets the whole recording.
    let mut late = receive_frames(&url, expected.len(), Duration::from_secs(120));
    late.sort();
    late.dedup();
    assert_eq!(late, expected);
    assert!(child.try_wait().unwrap().is_none(), "still serving");
    Command::new("kill")
        .args(["-INT", &child.id().to_string()])
        .status()
        .unwrap();
    let status = child.wait().unwrap();
    seen.extend(stderr_lines.iter());
    assert_eq!(status.code(), Some(0), "{seen:?}");
    assert!(
        seen.iter()
            .any(|l| l.contains(&format!("127.0.0.1:{port}/proxy"))),
        "address printed: {seen:?}"
    );
    let rec = peridyn::readback::read(&file).unwrap();
    let saved: Vec<i64> = rec
        .entity("/nodes/damage")
        .unwrap()
        .points
        .keys()
        .copied()
        .collect();
    assert_eq!(saved, expected, "the file has every frame");
}

#[test]
fn an_unreachable_viewer_is_a_clear_error() {
    let port = free_port();
    let out = Command::new(env!("CARGO_BIN_EXE_peridyn"))
        .args([
            "run",
            "vibrating-plate",
            "--variant",
            "small",
            "--connect",
            &format!("rerun+http://127.0.0.1:{port}/proxy"),
        ])
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{stderr}");
    assert!(stderr.contains("no Rerun viewer is listening"), "{stderr}");
    assert!(!stderr.contains("panicked"), "{stderr}");
}

/// `--connect` to a viewer (here another peridyn's gRPC server) that dies mid-run: the run
/// goes on to its end and the file it saves is complete.
#[test]
fn a_connected_run_survives_its_viewer_dying() {
    let port = free_port();
    let mut viewer = Command::new(env!("CARGO_BIN_EXE_peridyn"))
        .args([
            "run",
            "vibrating-plate",
            "--variant",
            "small",
            "--serve",
            &format!("127.0.0.1:{port}"),
            "-q",
        ])
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    let start = Instant::now();
    while TcpStream::connect(("127.0.0.1", port)).is_err() {
        assert!(start.elapsed() < Duration::from_secs(60), "never served");
        std::thread::sleep(Duration::from_millis(20));
    }
    let file = temp("connected.rrd");
    let mut run = Command::new(env!("CARGO_BIN_EXE_peridyn"))
        .args([
            "run",
            "kalthoff-winkler",
            "--variant",
            "medium",
            "--connect",
            &format!("rerun+http://127.0.0.1:{port}/proxy"),
            "--every",
            "10",
            "-q",
            "-o",
            file.to_str().unwrap(),
        ])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    // Let some frames go out, then kill the viewer.
    let start = Instant::now();
    while std::fs::metadata(&file).map(|m| m.len()).unwrap_or(0) < 1_000_000 {
        assert!(
            start.elapsed() < Duration::from_secs(120),
            "no frames written"
        );
        std::thread::sleep(Duration::from_millis(20));
    }
    viewer.kill().unwrap();
    viewer.wait().unwrap();
    let start = Instant::now();
    while run.try_wait().unwrap().is_none() {
        assert!(
            start.elapsed() < Duration::from_secs(300),
            "the run hangs after its viewer died"
        );
        std::thread::sleep(Duration::from_millis(100));
    }
    let out = run.wait_with_output().unwrap();
    assert_eq!(
        out.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let info = peridyn::sim::build(
        &peridyn::scene::Scene::load("kalthoff-winkler", Some("medium")).unwrap(),
    )
    .unwrap()
    .info();
    let rec = peridyn::readback::read(&file).unwrap();
    let last = rec
        .entity("/nodes/damage")
        .unwrap()
        .points
        .keys()
        .next_back()
        .copied();
    assert_eq!(
        last,
        Some(info.total_steps as i64),
        "the file has the whole run"
    );
}

/// The listening TCP sockets on `port`, as (local address, hex as the kernel prints it).
fn listeners(port: u16) -> Vec<String> {
    let port_hex = format!(":{port:04X}");
    ["/proc/net/tcp", "/proc/net/tcp6"]
        .iter()
        .filter_map(|t| std::fs::read_to_string(t).ok())
        .flat_map(|text| {
            text.lines()
                .skip(1)
                .filter_map(|l| {
                    let cols: Vec<&str> = l.split_whitespace().collect();
                    let (local, state) = (cols.get(1)?, cols.get(3)?);
                    (local.ends_with(&port_hex) && *state == "0A")
                        .then(|| local.trim_end_matches(&port_hex).to_string())
                })
                .collect::<Vec<_>>()
        })
        .collect()
}

/// `--serve` without an address binds loopback only (read from the kernel's socket table:
/// 127.0.0.1 is `0100007F`), and says so.
#[test]
fn serve_without_an_address_listens_on_loopback_only() {
    let port = 9876;
    assert!(
        listeners(port).is_empty(),
        "port {port} is taken on this machine"
    );
    let child = Command::new(env!("CARGO_BIN_EXE_peridyn"))
        .args([
            "run",
            "vibrating-plate",
            "--variant",
            "small",
            "--steps",
            "5",
            "--serve",
            "-q",
        ])
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let start = Instant::now();
    let bound = loop {
        let found = listeners(port);
        if !found.is_empty() {
            break found;
        }
        assert!(start.elapsed() < Duration::from_secs(60), "never listened");
        std::thread::sleep(Duration::from_millis(20));
    };
    Command::new("kill")
        .args(["-INT", &child.id().to_string()])
        .status()
        .unwrap();
    let out = child.wait_with_output().unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(bound, ["0100007F"], "bound to: {bound:?}; {stderr}");
    assert!(stderr.contains("this machine only"), "{stderr}");
}
