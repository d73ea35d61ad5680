//! Peridynamic diffusion kernel κ ω(‖ξ‖) / ‖ξ‖^q (thesis (2.41)–(2.43), (3.4)).

use super::pmb::{Influence, influence};

#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DiffusionKernel {
    pub diffusivity: f64,
    /// Kernel exponent q (seed-thesis-ch2-3 erratum 7: the p, q and s of (2.49), (2.72),
    /// (2.77) are all q).
    pub exponent: f64,
    pub influence: Influence,
    pub horizon: f64,
}

impl DiffusionKernel {
    /// κ ω(r) / r^q.
    #[inline(always)]
    pub fn weight(&self, r: f64) -> f64 {
        self.diffusivity * influence(self.influence, r, self.horizon) / r.powf(self.exponent)
    }
}
