//! Constitutive laws, each independent of the discretization and the time integrator.

pub mod corrosion;
pub mod diffusion;
pub mod osb;
pub mod pmb;
