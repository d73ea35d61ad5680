//! peridyn: adaptive peridynamic simulations, watched and measured live.
//!
//! Data flows one way: `scene` (validated preset) → `discretization` (lattice, families,
//! per-node store) → `scheme` operators with `model` laws → `adapt` (changes between steps) →
//! `sim` simulations on the `solver` contract (clock, stages, `Stepper`) → `frame` snapshots →
//! sinks (`record` for Rerun) → `control`, `panel`, the CLI. The solver core knows nothing of
//! Rerun or user interfaces; `sparse` (linear systems) imports none of it. Papers are cited by
//! the short ids of `REFERENCES.md`.

pub mod absorb;
pub mod adapt;
pub mod bench;
pub mod cli;
pub mod control;
pub mod discretization;
pub mod export;
pub mod frame;
pub mod integrate;
pub mod metrics;
pub mod model;
pub mod panel;
pub mod readback;
pub mod record;
pub mod replay;
pub mod report;
pub mod runner;
pub mod scene;
pub mod scheme;
pub mod sim;
pub mod simd;
pub mod solver;
pub mod sparse;
