//! The integration tests as one binary, each file a module: the dependency graph is linked
//! once instead of once per file, which keeps the CI build within its time.

mod common;

mod absorbing;
mod absorbing_bond;
mod architecture;
mod checkpoint;
mod cli;
mod clock;
mod control_cli;
mod corrosion;
mod diffusion_manufactured;
mod driver;
mod dual_horizon;
mod dynamics;
mod export;
mod hybrid;
mod kalthoff_winkler;
mod multiadaptive;
mod multigrid;
mod nnpp;
mod nnpp_scene;
mod nnpp_screw;
mod nnpp_step;
mod operators;
mod panel;
mod remote;
mod screw;
mod static_1d_manufactured;
mod wls_elasticity;
