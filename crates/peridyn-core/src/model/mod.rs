//! Constitutive laws, each independent of the discretization and the time integrator.

pub mod corrosion;
pub mod diffusion;
pub mod nernst_planck;
pub mod nnpp_reactions;
pub mod osb;
pub mod pmb;
