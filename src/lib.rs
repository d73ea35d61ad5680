//! peridyn: adaptive peridynamic simulations, watched and measured live.
//!
//! Data flows one way: `scene` (validated preset) → `grid` + `family` (discretization) →
//! `scheme` operators with `model` laws → `sim` (stepping) → `frame` snapshots → sinks
//! (`record` for Rerun). The solver core knows nothing of Rerun or user interfaces.

pub mod adapt;
pub mod bench;
pub mod control;
pub mod family;
pub mod frame;
pub mod grid;
pub mod integrate;
pub mod metrics;
pub mod model;
pub mod panel;
pub mod readback;
pub mod record;
pub mod replay;
pub mod report;
pub mod runner;
pub mod scalar;
pub mod scene;
pub mod scheme;
pub mod sim;
