//! peridyn: adaptive peridynamic simulations, watched and measured live.
//!
//! The numerics live in the `peridyn-core` crate (re-exported here under the same module
//! names): a scene becomes a `solver::Stepper` that emits plain-data `frame::Frame`s. This
//! crate puts them to use: `record` (Rerun sinks), `replay`, `export` (ParaView), `control`
//! (live commands, scripts, checkpoints), `panel` (egui), `report` and `bench`, and the CLI.

pub use peridyn_core::{
    absorb, adapt, discretization, frame, integrate, metrics, model, runner, scene, scheme, sim,
    simd, solver, sparse,
};

pub mod bench;
pub mod cli;
pub mod control;
pub mod export;
pub mod panel;
pub mod readback;
pub mod record;
pub mod replay;
pub mod report;
pub mod rrd;
