//! The reactions of the Mg-screw NNPP model (thesis §3.4.2, (3.98)–(3.103), (3.91)–(3.92);
//! seed-thesis-ch2-3 §8.6, whose reading of the missing text of (3.93)–(3.96) is followed):
//! the metal (C1) and its hydroxide complex (C2) exchange by Me + H₂O ⇌ MeOH + H⁺ (rates
//! k1f, k1b), water dissociates H₂O ⇌ H⁺ + OH⁻ (k2f, k2b), and at the interface hydrogen and
//! hydroxide are produced or consumed with the currents J50, J60 scaled by the overpotential.
//! Each rate is linear in its own species at t^{n+1} (the others at t^n), so it is a
//! [`LinearSource`] R = r0 + r1 C^{n+1} of the semi-implicit step:
//!
//! * R1 = −k1f C1^{n+1} + k1b C2 C5                    (liquid or interface)
//! * R2 =  k1f C1 − k1b C2^{n+1} C5                    (liquid or interface)
//! * R5 =  k1f C1 − k1b C2 C5^{n+1} + k2f − k2b C5^{n+1} C6 [+ J50/(z5 F c_s) e^{α_H F η/RT}]
//! * R6 =  k2f − k2b C5 C6^{n+1}                       [+ J60/(z6 F c_s) e^{α_OH F η/RT}]
//!
//! the bracketed terms at interface nodes (a phase mismatch in the family), every R zero on a
//! solid node whose whole family is solid. The overpotential (3.102)–(3.103):
//! η = φ_applied − φ0 − (RT/(z1 F)) ln(C1/C_sat) − φ. The metal's interface-bond diffusivity
//! may follow the Butler–Volmer form (3.92): D_int(η) = D0 [e^{α_a z1 F η/RT} − e^{−α_c z1 F η/RT}]
//! at the solid end's η (a bond's diffusivity must not depend on its direction, or Σ C V is
//! not conserved).

use super::nernst_planck::FARADAY;

/// R = r0 + r1 C^{n+1} at one node.
pub type LinearSource = [f64; 2];

/// Where a node sits for the reactions.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Site {
    /// Solid, with a solid family: no reaction.
    BulkSolid,
    /// Liquid, with a liquid family.
    BulkLiquid,
    /// Some family node has the other phase.
    Interface,
}

/// Butler–Volmer interface diffusivity of the metal (3.92).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ButlerVolmer {
    /// D0 (m²/s).
    pub exchange: f64,
    /// α_a, α_c.
    pub anodic: f64,
    pub cathodic: f64,
}

/// Which species plays which role, the rates and the interface constants (SI; concentrations
/// in the species' own unit, normalized by C_solid in the screw).
#[derive(Debug, Clone, PartialEq)]
pub struct ReactionLaw {
    pub metal: usize,
    pub complex: usize,
    pub hydrogen: usize,
    pub hydroxide: usize,
    pub forward_1: f64,
    pub backward_1: f64,
    pub forward_2: f64,
    pub backward_2: f64,
    /// J50, J60.
    pub hydrogen_current: f64,
    pub hydroxide_current: f64,
    /// α_H⁺, α_OH⁻.
    pub hydrogen_charge: f64,
    pub hydroxide_charge: f64,
    /// c_solid (mol/m³) in J/(z F c_solid).
    pub solid_concentration: f64,
    /// φ_applied, φ0 (V).
    pub applied_potential: f64,
    pub standard_potential: f64,
    /// C_sat in the metal's unit (the phase change's threshold).
    pub saturation: f64,
    pub butler_volmer: Option<ButlerVolmer>,
}

/// C1/C_sat is floored here in the logarithm of (3.103): a liquid node with no metal would
/// give η = ∞ (the floor caps φ_c at −27.6 RT/(z1 F), −0.32 V for Mg).
const SATURATION_RATIO_FLOOR: f64 = 1e-12;

/// The largest exponent of the interface terms (e^50 ≈ 5·10²¹): a guard against overflow,
/// far above any overpotential of the screw's parameters.
const MAX_EXPONENT: f64 = 50.0;

impl ReactionLaw {
    /// η (3.102)–(3.103) at a node with metal concentration `c1` and potential `phi`;
    /// `thermal` = F/(RT), `z1` the metal's valence.
    pub fn overpotential(&self, c1: f64, phi: f64, thermal: f64, z1: f64) -> f64 {
        let ratio = (c1 / self.saturation).max(SATURATION_RATIO_FLOOR);
        self.applied_potential - self.standard_potential - ratio.ln() / (z1 * thermal) - phi
    }

    /// The metal's interface-bond diffusivity at overpotential η, if it follows (3.92).
    /// Choice: floored at 0. (3.92) turns negative for η < 0 (cathodic), and a negative bond
    /// diffusivity makes the operator anti-diffusive (ill-posed; BiCGSTAB diverges on it);
    /// the thesis's runs stay anodic (η ≥ 138 mV with Table 3.7's potentials).
    pub fn interface_diffusivity(&self, eta: f64, thermal: f64, z1: f64) -> Option<f64> {
        let bv = self.butler_volmer?;
        let x = z1 * thermal * eta;
        let e = |a: f64| (a * x).clamp(-MAX_EXPONENT, MAX_EXPONENT).exp();
        Some((bv.exchange * (e(bv.anodic) - e(-bv.cathodic))).max(0.0))
    }

    /// Writes each species' linearized rate at one node into `out` (zero for species without
    /// a reaction). `c(k)`: C_k^n there; `valence(k)`: z_k; η the node's overpotential.
    pub fn sources(
        &self,
        site: Site,
        c: impl Fn(usize) -> f64,
        valence: impl Fn(usize) -> f64,
        eta: f64,
        thermal: f64,
        out: &mut [LinearSource],
    ) {
        out.iter_mut().for_each(|s| *s = [0.0; 2]);
        if site == Site::BulkSolid {
            return;
        }
        let (c1, c2, c5, c6) = (
            c(self.metal),
            c(self.complex),
            c(self.hydrogen),
            c(self.hydroxide),
        );
        let (k1f, k1b, k2f, k2b) = (
            self.forward_1,
            self.backward_1,
            self.forward_2,
            self.backward_2,
        );
        let interface = |current: f64, charge: f64, k: usize| {
            if site != Site::Interface {
                return 0.0;
            }
            let exponent = (charge * thermal * eta).clamp(-MAX_EXPONENT, MAX_EXPONENT);
            current / (valence(k) * FARADAY * self.solid_concentration) * exponent.exp()
        };
        out[self.metal] = [k1b * c2 * c5, -k1f];
        out[self.complex] = [k1f * c1, -k1b * c5];
        out[self.hydrogen] = [
            k1f * c1 + k2f + interface(self.hydrogen_current, self.hydrogen_charge, self.hydrogen),
            -k1b * c2 - k2b * c6,
        ];
        out[self.hydroxide] = [
            k2f + interface(
                self.hydroxide_current,
                self.hydroxide_charge,
                self.hydroxide,
            ),
            -k2b * c5,
        ];
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn law() -> ReactionLaw {
        ReactionLaw {
            metal: 0,
            complex: 1,
            hydrogen: 2,
            hydroxide: 3,
            forward_1: 5e-9,
            backward_1: 0.0158,
            forward_2: 2.5e-8,
            backward_2: 2.5e-16,
            hydrogen_current: -2e-3,
            hydroxide_current: 8e-10,
            hydrogen_charge: 0.5,
            hydroxide_charge: 0.5,
            solid_concentration: 143.1e3,
            applied_potential: -0.300,
            standard_potential: -0.477,
            saturation: 5.1 / 143.1,
            butler_volmer: Some(ButlerVolmer {
                exchange: 1e-15,
                anodic: 0.5,
                cathodic: 0.5,
            }),
        }
    }

    /// At C1 = C_sat and φ = 0 the overpotential is φ_applied − φ0 = 177 mV; the metal's
    /// Nernst term lowers it by RT/(z1 F) ln(C1/C_sat).
    #[test]
    fn overpotential_follows_3_102() {
        let l = law();
        let thermal = 96485.33212 / (8.314462618 * 298.15);
        assert!((l.overpotential(l.saturation, 0.0, thermal, 2.19) - 0.177).abs() < 1e-12);
        let eta = l.overpotential(1.0, 0.01, thermal, 2.19);
        let expected = 0.177 - (1.0 / l.saturation).ln() / (2.19 * thermal) - 0.01;
        assert!((eta - expected).abs() < 1e-12);
        assert!(l.overpotential(0.0, 0.0, thermal, 2.19).is_finite());
        // Butler–Volmer: zero at η = 0, odd-ish, growing.
        assert_eq!(l.interface_diffusivity(0.0, thermal, 2.19), Some(0.0));
        let d = l.interface_diffusivity(0.1, thermal, 2.19).unwrap();
        let x = 2.19 * thermal * 0.1;
        assert!((d - 1e-15 * ((0.5 * x).exp() - (-0.5 * x).exp())).abs() < 1e-27);
        // Cathodic: no negative diffusivity.
        assert_eq!(l.interface_diffusivity(-0.1, thermal, 2.19), Some(0.0));
    }

    /// The linearized sources: with C^{n+1} = C^n they give the rate laws; the exchange
    /// (3.95) conserves C1 + C2; water dissociation makes H⁺ and OH⁻ at equal rates.
    #[test]
    fn sources_are_the_rate_laws() {
        let l = law();
        let c = [0.8, 0.1, 0.3, 0.2];
        let mut out = [[0.0; 2]; 5];
        let rate = |out: &[LinearSource], k: usize| out[k][0] + out[k][1] * c[k];
        l.sources(Site::BulkLiquid, |k| c[k], |_| 1.0, 0.1, 38.9, &mut out);
        let r1 = -5e-9 * 0.8 + 0.0158 * 0.1 * 0.3;
        assert!((rate(&out, 0) - r1).abs() < 1e-18);
        assert!((rate(&out, 0) + rate(&out, 1)).abs() < 1e-18);
        let r5 = -r1 + 2.5e-8 - 2.5e-16 * 0.3 * 0.2;
        assert!((rate(&out, 2) - r5).abs() < 1e-18);
        assert!((rate(&out, 3) - (2.5e-8 - 2.5e-16 * 0.3 * 0.2)).abs() < 1e-18);
        assert_eq!(out[4], [0.0; 2]);
        // The interface adds the currents; a bulk solid node reacts not at all.
        let mut at = [[0.0; 2]; 5];
        l.sources(Site::Interface, |k| c[k], |_| 1.0, 0.1, 38.9, &mut at);
        let j5 = -2e-3 / (96485.33212 * 143.1e3) * (0.5f64 * 38.9 * 0.1).exp();
        assert!((at[2][0] - out[2][0] - j5).abs() < 1e-20);
        l.sources(Site::BulkSolid, |k| c[k], |_| 1.0, 0.1, 38.9, &mut at);
        assert!(at.iter().all(|s| *s == [0.0; 2]));
    }
}
