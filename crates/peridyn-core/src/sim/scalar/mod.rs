//! Scalar-field simulations, one per physics, on one body (`body`: the field on a
//! discretization, the assembled operator on the solved rows, held nodes following the
//! reference solution, the relative ℓ² error (3.79)): a static linear solve
//! ([`StaticSimulation`], 1D elasticity, thesis §3.2.5), transient PD diffusion and
//! bi-material corrosion by forward Euler ([`DiffusionSimulation`], thesis §3.2.6, §2.3.3), and
//! the PD scalar wave by damped velocity-Verlet ([`WaveSimulation`], (4.62)). The shared
//! setup: the nodes' roles and the initial field (`layout`), the operator (`operator`), the
//! stable step (`stable`) and the frame (`frame`); the schemes of diffusion (`rates`,
//! `hybrid`) and the plug-ins (`phase`, `grid`, `layer`) each in a file of their own.

mod body;
mod diffusion;
mod frame;
mod grid;
mod hybrid;
mod layer;
mod layout;
mod operator;
mod phase;
mod rates;
mod stable;
mod statics;
mod wave;
mod wave_body;

pub use body::FieldBody;
pub use diffusion::DiffusionSimulation;
pub use operator::assemble;
pub use statics::StaticSimulation;
pub use wave::WaveSimulation;
pub use wave_body::{Wave, WaveBody};
