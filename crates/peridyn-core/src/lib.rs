//! peridyn-core: the numerics of peridyn, with no viewer, user interface or command line.
//!
//! Data flows one way: `scene` (validated preset) → `discretization` (lattice, families,
//! per-node store) → `scheme` operators with `model` laws → `adapt` (changes between steps) →
//! `sim` simulations on the `solver` contract (clock, stages, `Stepper`) → `frame` snapshots,
//! plain data that the application crate (`peridyn`) sends to Rerun, VTU files and reports.
//! `sparse` (linear systems) imports none of it. Papers are cited by the short ids of
//! `REFERENCES.md`.

pub mod absorb;
pub mod adapt;
pub mod discretization;
pub mod frame;
pub mod integrate;
pub mod metrics;
pub mod model;
pub mod runner;
pub mod scene;
pub mod scheme;
pub mod sim;
pub mod simd;
pub mod solver;
pub mod sparse;
