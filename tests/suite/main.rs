//! The integration tests as one binary, each file a module: the dependency graph is linked
//! once instead of once per file, which keeps the CI build within its time.

mod common;

mod architecture;
mod bench_pairs;
mod checkpoint;
mod cli;
mod clock;
mod control_cli;
mod damaged_inputs;
mod diffusion_manufactured;
mod driver;
mod dual_horizon;
mod export;
mod multiadaptive;
mod panel;
mod remote;
mod static_1d_manufactured;
