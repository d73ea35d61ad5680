//! Constitutive laws, each independent of the discretization and the time integrator.

pub mod pmb;
