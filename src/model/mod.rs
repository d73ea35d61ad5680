//! Constitutive laws, each independent of the discretization and the time integrator.

pub mod diffusion;
pub mod pmb;
