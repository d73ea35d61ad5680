//! The eframe window: the panel beside a Rerun viewer (spawned, or remote). Commands go to
//! the simulation thread over a channel; the thread publishes the state the panel shows.

use std::sync::{Arc, Mutex};
use std::time::Duration;

use crossbeam_channel::Sender;
use eframe::egui;

use super::view::{self, PanelInputs};
use crate::control::{Command, ControlState};

pub struct PanelApp {
    shared: Arc<Mutex<ControlState>>,
    commands: Sender<Command>,
    inputs: PanelInputs,
}

impl PanelApp {
    pub fn new(shared: Arc<Mutex<ControlState>>, commands: Sender<Command>) -> Self {
        PanelApp {
            shared,
            commands,
            inputs: PanelInputs::default(),
        }
    }
}

impl eframe::App for PanelApp {
    fn ui(&mut self, ui: &mut egui::Ui, _frame: &mut eframe::Frame) {
        let state = self
            .shared
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .clone();
        egui::ScrollArea::vertical().show(ui, |ui| {
            for command in view::show(ui, &state, &mut self.inputs) {
                // The thread is gone only when the window is closing.
                let _ = self.commands.send(command);
            }
        });
        ui.ctx().request_repaint_after(Duration::from_millis(100));
    }
}

/// Opens the panel window; returns when it is closed.
pub fn run(shared: Arc<Mutex<ControlState>>, commands: Sender<Command>) -> Result<(), String> {
    let options = eframe::NativeOptions {
        viewport: egui::ViewportBuilder::default()
            .with_title("peridyn control")
            .with_inner_size([420.0, 720.0]),
        ..Default::default()
    };
    eframe::run_native(
        "peridyn control",
        options,
        Box::new(move |_cc| Ok(Box::new(PanelApp::new(shared, commands)))),
    )
    .map_err(|e| {
        format!("cannot open the panel window: {e} (it needs a display; headless runs use `peridyn record --script`)")
    })
}
