//! Ordinary state-based PD in the Madenci–Oterkus form, 2D (zeng2024 (3)–(11); extraction
//! `seed-002-dual-horizon` §1). Every constant belongs to one horizon δ: dual-horizon bodies
//! ask for the constants of each particle's own horizon (zeng2024 (13)).
//!
//! Choices the paper leaves open (seed-002 §7):
//! - ambiguity 1: the dilatation (5) carries V_j (the printed (5) omits it; θ must be
//!   dimensionless);
//! - ambiguity 8: κ follows the Madenci–Oterkus 2D convention, plane stress
//!   κ = E / (2(1 − ν)) or plane strain κ = E / (2(1 + ν)(1 − 2ν)), μ = E / (2(1 + ν)); the
//!   preset says which.

use std::f64::consts::PI;

use super::pmb::Plane;
use crate::simd::Lanes;

/// An isotropic elastic, brittle OSB material in 2D, as a preset gives it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct OsbMaterial {
    pub youngs_modulus: f64,
    pub poisson_ratio: f64,
    pub plane: Plane,
    /// The out-of-plane thickness h (volumes are Δ²·h).
    pub thickness: f64,
    /// G_c; `None`: no bond breaks.
    pub fracture_energy: Option<f64>,
}

/// The constants of one horizon: zeng2024 (6)–(8) (2D column) and the critical stretch (11).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct OsbHorizon {
    pub horizon: f64,
    /// a = ½(κ − 2μ).
    pub a: f64,
    /// b = 6μ / (π δ⁴ h).
    pub b: f64,
    /// d = 2 / (π h δ³).
    pub d: f64,
    /// s_c of (11); `f64::INFINITY` without failure.
    pub critical_stretch: f64,
}

impl OsbMaterial {
    /// The 2D bulk modulus κ (ambiguity 8, the Madenci–Oterkus convention).
    pub fn bulk_modulus(&self) -> f64 {
        let (e, nu) = (self.youngs_modulus, self.poisson_ratio);
        match self.plane {
            Plane::Stress => e / (2.0 * (1.0 - nu)),
            Plane::Strain => e / (2.0 * (1.0 + nu) * (1.0 - 2.0 * nu)),
        }
    }

    pub fn shear_modulus(&self) -> f64 {
        self.youngs_modulus / (2.0 * (1.0 + self.poisson_ratio))
    }

    /// The classical strain energy density of a homogeneous small strain ε (2D):
    /// W = μ ε:ε + ½ (κ − μ) (tr ε)², and its stress σ = 2μ ε + (κ − μ) tr ε I.
    pub fn classical(&self, strain: [[f64; 2]; 2]) -> (f64, [[f64; 2]; 2]) {
        let (kappa, mu) = (self.bulk_modulus(), self.shear_modulus());
        let trace = strain[0][0] + strain[1][1];
        let mut contraction = 0.0;
        let mut stress = [[0.0; 2]; 2];
        for i in 0..2 {
            for j in 0..2 {
                contraction += strain[i][j] * strain[i][j];
                stress[i][j] = 2.0 * mu * strain[i][j];
            }
            stress[i][i] += (kappa - mu) * trace;
        }
        let energy = mu * contraction + 0.5 * (kappa - mu) * trace * trace;
        (energy, stress)
    }

    /// The constants of horizon δ.
    pub fn at(&self, horizon: f64) -> OsbHorizon {
        let (kappa, mu, h) = (self.bulk_modulus(), self.shear_modulus(), self.thickness);
        let critical_stretch = match self.fracture_energy {
            // (11), 2D row: s_c = sqrt(G_c / ((6μ/π + 16/(9π²)(κ − 2μ)) δ)).
            Some(g) => {
                let denominator = 6.0 * mu / PI + 16.0 / (9.0 * PI * PI) * (kappa - 2.0 * mu);
                (g / (denominator * horizon)).sqrt()
            }
            None => f64::INFINITY,
        };
        OsbHorizon {
            horizon,
            a: 0.5 * (kappa - 2.0 * mu),
            b: 6.0 * mu / (PI * horizon.powi(4) * h),
            d: 2.0 / (PI * h * horizon.powi(3)),
            critical_stretch,
        }
    }
}

impl OsbHorizon {
    /// The scalar of the bond force (zeng2024 (3)–(5), seed-002 §1 "explicit bond force"):
    /// t_kj = 2δ (a d Λ θ ω_θ / |ξ| + b s ω_b) per unit of V_k, along the deformed bond, for
    /// the bonds in `L`'s lanes (the constants' products first, then left to right: one lane
    /// gives the scalar expression's bits). `weight_theta`, `weight_distortion` are the bond's
    /// quadrature weights (V_j, or the moment-matched weights of `scheme::dual_horizon`);
    /// `inverse_length` is 1/|ξ|.
    #[inline(always)]
    pub fn bond_scalar<L: Lanes>(
        &self,
        dilatation: L,
        cosine: L,
        stretch: L,
        inverse_length: L,
        weight_theta: L,
        weight_distortion: L,
    ) -> L {
        L::splat(2.0 * self.horizon)
            * (L::splat(self.a * self.d) * cosine * dilatation * weight_theta * inverse_length
                + L::splat(self.b) * stretch * weight_distortion)
    }

    /// The bonds' contributions to θ_k (5): d δ Λ s ω_θ.
    #[inline(always)]
    pub fn dilatation_term<L: Lanes>(&self, cosine: L, stretch: L, weight_theta: L) -> L {
        L::splat(self.d * self.horizon) * cosine * stretch * weight_theta
    }

    /// The bonds' distortional energies (4): b δ s² |ξ| ω_b.
    #[inline(always)]
    pub fn distortion_energy<L: Lanes>(&self, stretch: L, length: L, weight_distortion: L) -> L {
        L::splat(self.b * self.horizon) * stretch * stretch * length * weight_distortion
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn steel(plane: Plane, nu: f64) -> OsbMaterial {
        OsbMaterial {
            youngs_modulus: 200e9,
            poisson_ratio: nu,
            plane,
            thickness: 1e-3,
            fracture_energy: Some(1000.0),
        }
    }

    #[test]
    fn continuum_integrals_of_the_constants_give_the_classical_energy() {
        // Uniaxial strain ε_xx = e in the continuum: θ = e (d δ ∫ ξ̂ₓ² dV = 1), the distortion
        // b δ ∫ s² |ξ| dV = b δ h (δ³/3)(3π/4) e², so W = a e² + (3/2) μ e² = ½(κ + μ) e²,
        // the classical μ e² + ½(κ − μ) e².
        for (plane, nu) in [(Plane::Stress, 1.0 / 3.0), (Plane::Strain, 0.2)] {
            let m = steel(plane, nu);
            let delta = 3.015e-3;
            let c = m.at(delta);
            let e = 1e-4;
            let theta = c.d * delta * m.thickness * delta * delta / 2.0 * PI * e;
            assert!((theta - e).abs() < 1e-15, "θ = {theta}");
            let distortion = c.b * delta * m.thickness * delta.powi(3) / 3.0 * 0.75 * PI * e * e;
            let w = c.a * theta * theta + distortion;
            let (classical, stress) = m.classical([[e, 0.0], [0.0, 0.0]]);
            assert!((w / classical - 1.0).abs() < 1e-12, "{w} vs {classical}");
            let young_2d = stress[0][0] - stress[1][1] * stress[1][1] / stress[0][0];
            assert!(young_2d > 0.0);
        }
    }

    #[test]
    fn critical_stretch_scales_with_the_inverse_root_of_the_horizon() {
        let m = steel(Plane::Stress, 1.0 / 3.0);
        let (parent, child) = (m.at(3.015e-3), m.at(1.5075e-3));
        let ratio = child.critical_stretch / parent.critical_stretch;
        assert!((ratio - 2f64.sqrt()).abs() < 1e-12, "ratio {ratio}");
        // (11) by hand: κ = 150 GPa, μ = 75 GPa, κ − 2μ = 0 at ν = 1/3 in plane stress.
        let expected = (1000.0 / (6.0 * 75e9 / PI * 3.015e-3)).sqrt();
        assert!((parent.critical_stretch / expected - 1.0).abs() < 1e-12);
        let unbreakable = OsbMaterial {
            fracture_energy: None,
            ..m
        };
        assert!(unbreakable.at(1e-3).critical_stretch.is_infinite());
    }
}
