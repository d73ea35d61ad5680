//! The simulation thread behind a live panel: takes commands from a channel, steps while
//! playing, and publishes the `ControlState` for the panel to show. A run that blows up is
//! paused with its reason shown, so the user can lower Δt or reset.

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use crossbeam_channel::{Receiver, RecvTimeoutError};

use super::command::Command;
use super::driver::Driver;
use super::state::ControlState;
use crate::runner::RunSummary;

/// How long the thread steps before looking at commands and publishing the state.
const SLICE: Duration = Duration::from_millis(30);

/// Runs `driver` on its own thread until `stop` is raised or the command channel closes.
pub fn spawn(
    driver: Driver,
    commands: Receiver<Command>,
    shared: Arc<Mutex<ControlState>>,
    stop: Arc<AtomicBool>,
) -> std::io::Result<JoinHandle<Result<RunSummary, String>>> {
    std::thread::Builder::new()
        .name("simulation".into())
        .spawn(move || run(driver, &commands, &shared, &stop))
}

fn publish(shared: &Mutex<ControlState>, state: &ControlState) {
    *shared.lock().unwrap_or_else(|e| e.into_inner()) = state.clone();
}

fn run(
    mut driver: Driver,
    commands: &Receiver<Command>,
    shared: &Mutex<ControlState>,
    stop: &AtomicBool,
) -> Result<RunSummary, String> {
    publish(shared, &driver.state);
    let mut error = None;
    loop {
        if stop.load(Ordering::Relaxed) {
            break;
        }
        if driver.wants_step() {
            let start = Instant::now();
            while driver.wants_step() && start.elapsed() < SLICE {
                if let Err(e) = driver.step() {
                    driver.state.running = false;
                    driver.state.message = Some(format!("paused: {e}"));
                    error = Some(e);
                    break;
                }
            }
            loop {
                match commands.try_recv() {
                    Ok(c) => {
                        let _ = driver.command(c);
                    }
                    Err(crossbeam_channel::TryRecvError::Empty) => break,
                    Err(crossbeam_channel::TryRecvError::Disconnected) => {
                        return driver.finish(false, error);
                    }
                }
            }
        } else {
            match commands.recv_timeout(Duration::from_millis(50)) {
                Ok(c) => {
                    let _ = driver.command(c);
                }
                Err(RecvTimeoutError::Timeout) => {}
                Err(RecvTimeoutError::Disconnected) => break,
            }
        }
        publish(shared, &driver.state);
    }
    driver.finish(false, error)
}
