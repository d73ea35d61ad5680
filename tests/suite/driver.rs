//! The command driver on a real simulation: refused commands (including a rebuild whose scene
//! cannot be built) leave the run going; saving started mid-run gives a complete recording.

use std::path::PathBuf;

use peridyn::control::runspec::RunSpec;
use peridyn::control::{Command, Driver};
use peridyn::readback;
use peridyn::record::{Outlet, RecordTarget};
use peridyn::scene::Scene;

fn temp(name: &str) -> PathBuf {
    crate::common::temp("driver", name)
}

fn driver(file: &std::path::Path) -> Driver {
    let scene = Scene::load("vibrating-plate", Some("small")).unwrap();
    let outlet = Outlet::open(&RecordTarget::File(file.to_path_buf())).unwrap();
    Driver::start(RunSpec::new(&scene, Some(10), None), outlet, "test").unwrap()
}

fn steps(driver: &mut Driver, n: u64) {
    for _ in 0..n {
        driver.step().unwrap();
    }
}

#[test]
fn refused_commands_leave_the_run_going() {
    let mut d = driver(&temp("refused.rrd"));
    steps(&mut d, 5);
    let id = d.state.recording_id();
    assert!(d.command(Command::SetChi(2.0)).is_err());
    // Validation passes, building fails (the scene would be far too large): refused too.
    let err = d.command(Command::SetSpacing(1e-7)).unwrap_err();
    assert!(err.contains("discretization.spacing"), "{err}");
    assert_eq!(d.state.recording_id(), id, "no restart");
    assert_eq!(d.state.discretization.dx, 5e-4, "choice taken back");
    assert_eq!(d.state.message.as_deref(), Some(err.as_str()));
    assert!(d.state.running && d.wants_step());
    steps(&mut d, 5);
    assert_eq!(d.steps_done(), 10, "the run kept going");
    assert!(d.state.log.is_empty());
    d.finish(false, None).unwrap();
}

#[test]
fn saving_started_mid_run_is_a_complete_recording() {
    let main = temp("main.rrd");
    let saved = temp("saved.rrd");
    let mut d = driver(&main);
    steps(&mut d, 25);
    d.command(Command::StartSaving(saved.clone())).unwrap();
    steps(&mut d, 30);
    d.command(Command::StopSaving).unwrap();
    steps(&mut d, 20);
    d.finish(false, None).unwrap();

    let rec = readback::read(&saved).unwrap();
    assert!(
        rec.entity("/scene/preset")
            .is_some_and(|e| !e.texts.is_empty()),
        "the header (preset) is in the late file"
    );
    let frames: Vec<i64> = rec
        .entity("/nodes/damage")
        .unwrap()
        .points
        .keys()
        .copied()
        .collect();
    assert_eq!(frames, [30, 40, 50], "frames while saving, and only those");
    let run = rec.entity("/control/run").unwrap().texts.last().unwrap();
    assert!(run.contains("save start"), "{run}");
    let all: Vec<i64> = readback::read(&main)
        .unwrap()
        .entity("/nodes/damage")
        .unwrap()
        .points
        .keys()
        .copied()
        .collect();
    assert_eq!(all, (0..=70).step_by(10).collect::<Vec<_>>());
}

/// The panel's simulation thread: commands arrive over a channel, the published state follows.
#[test]
fn the_worker_thread_applies_panel_commands() {
    use std::sync::atomic::AtomicBool;
    use std::sync::{Arc, Mutex};
    use std::time::{Duration, Instant};

    let d = driver(&temp("worker.rrd"));
    let shared = Arc::new(Mutex::new(d.state.clone()));
    let (send, receive) = crossbeam_channel::unbounded();
    let stop = Arc::new(AtomicBool::new(false));
    let worker = peridyn::control::worker::spawn(d, receive, shared.clone(), stop.clone()).unwrap();
    let state = || shared.lock().unwrap().clone();
    let wait_for = |what: &str, ok: &dyn Fn(&peridyn::control::ControlState) -> bool| {
        let start = Instant::now();
        while !ok(&state()) {
            assert!(
                start.elapsed() < Duration::from_secs(60),
                "{what}: {:?}",
                state()
            );
            std::thread::sleep(Duration::from_millis(10));
        }
    };
    send.send(Command::Pause).unwrap();
    wait_for("paused", &|s| !s.running);
    std::thread::sleep(Duration::from_millis(200));
    let at = state().metrics.step;
    std::thread::sleep(Duration::from_millis(200));
    assert_eq!(state().metrics.step, at, "a paused run does not advance");
    send.send(Command::Step(1)).unwrap();
    wait_for("one step", &|s| s.metrics.step == at + 1);
    send.send(Command::SetChi(1.5)).unwrap();
    wait_for("refusal shown", &|s| {
        s.message.as_deref().is_some_and(|m| m.contains("(0, 1]"))
    });
    send.send(Command::Play).unwrap();
    wait_for("ran to the end", &|s| {
        s.metrics.step == s.metrics.total_steps && s.metrics.total_steps > 0
    });
    stop.store(true, std::sync::atomic::Ordering::Relaxed);
    let summary = worker.join().unwrap().unwrap();
    assert_eq!(summary.steps, summary.info.total_steps);
}

#[test]
fn a_replayed_recording_goes_to_the_session_outlet_beside_the_live_run() {
    let old = temp("old.rrd");
    let mut d = driver(&old);
    steps(&mut d, 20);
    d.finish(false, None).unwrap();

    let live = temp("live.rrd");
    let scene = Scene::load("vibrating-plate", Some("small")).unwrap();
    let outlet = Outlet::open(&RecordTarget::File(live.clone())).unwrap();
    let mut d = Driver::start(RunSpec::new(&scene, Some(10), None), outlet, "other").unwrap();
    d.command(Command::Replay(old.clone())).unwrap();
    assert!(d.state.log.is_empty(), "not part of the run's history");
    steps(&mut d, 10);
    d.finish(false, None).unwrap();
    let ids: Vec<String> = readback::read_each(&live)
        .unwrap()
        .into_iter()
        .map(|(id, _)| id)
        .collect();
    assert!(ids.contains(&"other-run1".to_string()), "{ids:?}");
    assert!(ids.contains(&"test-run1".to_string()), "{ids:?}");
}

#[test]
fn loading_another_preset_starts_a_new_session() {
    let file = temp("load.rrd");
    let mut d = driver(&file);
    steps(&mut d, 5);
    d.command(Command::SetChi(0.8)).unwrap();
    let err = d
        .command(Command::Load {
            preset: "kalthoff-winkler".into(),
            variant: Some("huge".into()),
        })
        .unwrap_err();
    assert!(err.contains("small"), "the variants are named: {err}");
    assert_eq!(d.steps_done(), 5, "the current run goes on");
    d.command(Command::Load {
        preset: "kalthoff-winkler".into(),
        variant: Some("small".into()),
    })
    .unwrap();
    assert_eq!(d.state.nodes, 20301);
    assert_eq!(d.state.run, 1);
    assert!(d.state.log.is_empty(), "a new session with its own history");
    assert!(
        d.state
            .recording_id()
            .starts_with("kalthoff-winkler-small-")
    );
    steps(&mut d, 3);
    d.finish(false, None).unwrap();
    let recordings = readback::read_each(&file).unwrap();
    assert_eq!(recordings.len(), 2);
    let doc = recordings[1]
        .1
        .entity("/control/run")
        .unwrap()
        .texts
        .last()
        .unwrap();
    let spec = RunSpec::from_text(doc).unwrap();
    assert_eq!(spec.variant.as_deref(), Some("small"));
    assert!(spec.commands.is_empty(), "{doc}");
    assert!(spec.preset.contains("kalthoff-winkler"));
    let first = recordings[0].1.entity("/control/commands").unwrap();
    assert_eq!(
        first.texts,
        ["run 1 at 5 steps: set chi 0.8"],
        "logged once"
    );
}

/// The grid ratio of a multi-grid scene is a rebuild: the next run has the new fine level
/// (61 refined coarse cells of `corrosion-1d multigrid` split 2 ways instead of 4).
#[test]
fn a_grid_ratio_command_rebuilds_the_fine_level() {
    let scene = Scene::load("corrosion-1d", Some("multigrid")).unwrap();
    let outlet = Outlet::open(&RecordTarget::File(temp("ratio.rrd"))).unwrap();
    let mut d = Driver::start(RunSpec::new(&scene, Some(10), None), outlet, "ratio").unwrap();
    assert_eq!(d.state.discretization.ratio, Some(4));
    steps(&mut d, 3);
    d.command(Command::SetGridRatio(2)).unwrap();
    assert_eq!(d.state.run, 2, "a new run");
    assert_eq!(d.state.discretization.ratio, Some(2));
    assert_eq!(d.info().nodes, 140 + 122 + 2 * (4 + 2));
    let refused = d.command(Command::SetGridRatio(40)).unwrap_err();
    assert!(refused.contains("2..=16"), "{refused}");
    d.finish(false, None).unwrap();
}
