//! The nonlocal Nernst–Planck–Poisson bond law (thesis (2.63)–(2.64), (2.69), (2.75);
//! seed-thesis-ch2-3 §1.7 and its erratum on (2.77)): per species k,
//!
//! ∂C_k/∂t = ∫_H [ K1 ω D_k (C_k' − C_k) / ‖ξ‖^{n+2q1}
//!               + K2 ω D_k (z_k F/RT) (φ' − φ) (C_k' + C_k) / ‖ξ‖^{n+2q2} ] dV' + R_k,
//! −∫_H K3 ω σ (φ' − φ) / ‖ξ‖^{n+2q3} dV' = F Σ_i z_i C_i,
//!
//! n the dimension. The constants K1, K2, K3 make the local limits the classical operators:
//! D_k ∇²C_k + D_k (z_k F/RT)(C_k ∇²φ + ∇C_k·∇φ) and −σ∇²φ. With the kernel's second moment
//! M(q) = ∫_H ω(‖ξ‖) ξ₁² / ‖ξ‖^{n+2q} dV = (S_n/n) ∫_0^δ ω(r) r^{1−2q} dr (S_n the unit
//! sphere's area: 2, 2π, 4π), a Taylor expansion gives K1 = 2/M(q1), K2 = 1/M(q2) (no factor 2:
//! C' + C ≈ 2C; (2.75), not the thesis's (2.77), see the erratum) and K3 = 2/M(q3)
//! ([derived] in the note: the thesis calls K3 "analogous" and omits it). In 3D with ω ≡ 1 this
//! is K1 = 3(1 − q1)/(π δ^{2−2q1}), the note's closed form.

use super::corrosion::Phase;
use super::diffusion;
use super::pmb::{Influence, influence};

/// One species: its name, valence z_k and bond diffusivities by class (m²/s).
#[derive(Debug, Clone, PartialEq)]
pub struct SpeciesLaw {
    pub name: String,
    pub valence: f64,
    /// D_{k,l} of liquid–liquid bonds.
    pub liquid: f64,
    /// D_{k,int} of interface bonds.
    pub interface: f64,
    /// D_{k,s} of solid–solid bonds.
    pub solid: f64,
}

impl SpeciesLaw {
    /// D_{k,ij} of (2.78).
    #[inline(always)]
    pub fn diffusivity(&self, a: Phase, b: Phase) -> f64 {
        match (a.is_solid(), b.is_solid()) {
            (false, false) => self.liquid,
            (true, true) => self.solid,
            _ => self.interface,
        }
    }
}

/// Faraday's constant F, C/mol (CODATA 2018, exact).
pub const FARADAY: f64 = 96_485.332_12;
/// The molar gas constant R, J/(mol K) (CODATA 2018, exact).
pub const GAS_CONSTANT: f64 = 8.314_462_618;

/// The kernel's second moment M(q) = ∫_H ω ξ₁² / ‖ξ‖^{n+2q} dV in dimension `dim` (1, 2, 3):
/// twice the calibration moment of a scalar kernel ω/r^p at p = n + 2q.
pub fn second_moment(dim: usize, influence: Influence, q: f64, horizon: f64) -> f64 {
    2.0 * diffusion::second_moment(dim, dim as f64 + 2.0 * q, influence, horizon)
}

/// The kernel exponents q1, q2, q3 of (2.63)–(2.64) (each < 1) and the influence function.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NnppKernel {
    pub dim: usize,
    pub influence: Influence,
    pub horizon: f64,
    pub exponents: [f64; 3],
}

/// K1, K2, K3 of (2.69), (2.75) and the Poisson analogue.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NnppConstants {
    pub k1: f64,
    pub k2: f64,
    pub k3: f64,
}

impl NnppKernel {
    /// The exponents must lie below 1 (the moments diverge at q = 1).
    pub fn new(
        dim: usize,
        influence: Influence,
        horizon: f64,
        exponents: [f64; 3],
    ) -> Result<Self, String> {
        if !(1..=3).contains(&dim) {
            return Err(format!("the dimension must be 1, 2 or 3, got {dim}"));
        }
        if !(horizon.is_finite() && horizon > 0.0) {
            return Err(format!("the horizon must be positive, got {horizon:e}"));
        }
        if let Some(q) = exponents.iter().find(|q| !(q.is_finite() && **q < 1.0)) {
            return Err(format!(
                "a kernel exponent q must be below 1 (the local limit diverges at 1), got {q}"
            ));
        }
        Ok(NnppKernel {
            dim,
            influence,
            horizon,
            exponents,
        })
    }

    pub fn constants(&self) -> NnppConstants {
        let m = |q| second_moment(self.dim, self.influence, q, self.horizon);
        let [q1, q2, q3] = self.exponents;
        NnppConstants {
            k1: 2.0 / m(q1),
            k2: 1.0 / m(q2),
            k3: 2.0 / m(q3),
        }
    }

    /// ω(r) / r^{n+2q}.
    #[inline(always)]
    fn weight(&self, r: f64, q: f64) -> f64 {
        influence(self.influence, r, self.horizon) / r.powf(self.dim as f64 + 2.0 * q)
    }
}

/// One species' physical constants: diffusivity D_k (m²/s), valence z_k, temperature T (K).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Species {
    pub diffusivity: f64,
    pub valence: f64,
    pub temperature: f64,
}

impl Species {
    /// z_k F / (R T), 1/V.
    pub fn mobility_factor(&self) -> f64 {
        self.valence * FARADAY / (GAS_CONSTANT * self.temperature)
    }
}

/// The integrand of (2.63) for one bond of length `r` (per unit volume of the far end):
/// diffusion K1 ω D (C' − C)/r^{n+2q1} plus electromigration
/// K2 ω D (zF/RT)(φ' − φ)(C' + C)/r^{n+2q2}. Antisymmetric in the bond's ends (swap C, C' and
/// φ, φ': the sign flips), so Σ C V is conserved by any symmetric quadrature.
#[inline(always)]
pub fn species_bond_rate(
    kernel: &NnppKernel,
    constants: &NnppConstants,
    species: &Species,
    r: f64,
    [c, c_far]: [f64; 2],
    [phi, phi_far]: [f64; 2],
) -> f64 {
    let [q1, q2, _] = kernel.exponents;
    species.diffusivity
        * (constants.k1 * kernel.weight(r, q1) * (c_far - c)
            + constants.k2
                * kernel.weight(r, q2)
                * species.mobility_factor()
                * (phi_far - phi)
                * (c_far + c))
}

/// The integrand of the left side of (2.64) for one bond: −K3 ω σ (φ' − φ)/r^{n+2q3}.
#[inline(always)]
pub fn poisson_bond_term(
    kernel: &NnppKernel,
    constants: &NnppConstants,
    conductivity: f64,
    r: f64,
    [phi, phi_far]: [f64; 2],
) -> f64 {
    -constants.k3 * kernel.weight(r, kernel.exponents[2]) * conductivity * (phi_far - phi)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The note's 3D closed forms: K1 = 3(1 − q)/(π δ^{2−2q}), K2 half of it; q = −1/2 gives
    /// K1 = 9/(2π δ³) (Table 4.1's J2 κ0/D).
    #[test]
    fn three_dimensional_constants_match_the_closed_forms() {
        let delta = 0.45e-3;
        for q in [-0.5, 0.0, 0.5] {
            let k = NnppKernel::new(3, Influence::Constant, delta, [q; 3])
                .unwrap()
                .constants();
            let closed = 3.0 * (1.0 - q) / (std::f64::consts::PI * delta.powf(2.0 - 2.0 * q));
            assert!((k.k1 / closed - 1.0).abs() < 1e-14, "q = {q}");
            assert!((k.k2 / (0.5 * closed) - 1.0).abs() < 1e-14, "q = {q}");
            assert_eq!(k.k3, k.k1);
        }
        let k = NnppKernel::new(3, Influence::Constant, delta, [-0.5; 3])
            .unwrap()
            .constants();
        let table = 9.0 / (2.0 * std::f64::consts::PI * delta.powi(3));
        assert!((k.k1 / table - 1.0).abs() < 1e-14);
    }

    #[test]
    fn exponents_at_or_above_one_are_refused() {
        let e = NnppKernel::new(2, Influence::Constant, 1.0, [0.0, 1.0, 0.0]).unwrap_err();
        assert!(e.contains("below 1"), "{e}");
        assert!(NnppKernel::new(4, Influence::Constant, 1.0, [0.0; 3]).is_err());
    }
}
