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

/// ½ ∫_H ω(r) ξ₁² / r^p dV: the second moment that calibrates a scalar PD kernel to its local
/// limit (c_s = χ² / moment; thesis (4.47), (4.51), (4.87); Table 4.1 for diffusion).
pub fn second_moment(dim: usize, exponent: f64, influence: Influence, horizon: f64) -> f64 {
    let n = dim as f64;
    let sphere = match dim {
        1 => 2.0,
        2 => std::f64::consts::TAU,
        _ => 4.0 * std::f64::consts::PI,
    };
    // ∫_0^δ ω(r) r^a dr with a = n + 1 − p.
    let a = n + 1.0 - exponent;
    let radial = match influence {
        Influence::Constant => horizon.powf(a + 1.0) / (a + 1.0),
        Influence::Linear => horizon.powf(a + 1.0) * (1.0 / (a + 1.0) - 1.0 / (a + 2.0)),
    };
    sphere / (2.0 * n) * radial
}
