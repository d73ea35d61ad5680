//! The core's integration tests as one binary, each file a module: analytic solutions,
//! conservation laws and the papers' numbers for every scheme and physics, with no viewer.

mod common;

mod absorbing;
mod absorbing_bond;
mod corrosion;
mod dynamics;
mod half_space;
mod hybrid;
mod kalthoff_winkler;
mod multigrid;
mod nnpp;
mod nnpp_scene;
mod nnpp_screw;
mod nnpp_step;
mod operators;
mod screw;
mod wls_elasticity;
