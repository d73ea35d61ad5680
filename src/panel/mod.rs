//! The live control panel: `view` draws a `ControlState` with egui and returns the user's
//! `Command`s; `app` is the eframe window that sends them to the simulation thread.

pub mod app;
pub mod view;
