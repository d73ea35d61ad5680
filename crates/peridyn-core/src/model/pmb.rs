//! Prototype microelastic brittle (PMB / GPBM) bond-based material, thesis (2.24)–(2.36).
//!
//! Micromodulus c and critical stretch s0 follow the tables of seed-thesis-ch2-3 §1.3: the thesis
//! prints plane stress only ((2.31), (2.35)); the plane-strain, 3D and 1D rows are the note's
//! [derived] rows (seed-thesis-ch2-3 erratum 13: KW is plane strain, so both are exposed).

use std::f64::consts::PI;

use serde::Deserialize;

/// Influence function ω of a bond, (2.12)–(2.13).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Influence {
    /// ω0 = 1 (2.12).
    #[default]
    Constant,
    /// ω1 = 1 − r/δ (2.13).
    Linear,
}

/// The 2D reduction of a 3D body.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Plane {
    /// Plane stress, ν = 1/3.
    Stress,
    /// Plane strain, ν = 1/4.
    #[default]
    Strain,
}

/// The bond stiffness as a preset gives it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Stiffness {
    /// Young's modulus E: the micromodulus follows from the tables of seed-thesis-ch2-3 §1.3.
    YoungsModulus(f64),
    /// The micromodulus c itself.
    Micromodulus(f64),
}

/// Bond failure as a preset gives it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Failure {
    /// No bond breaks.
    None,
    /// Fracture energy G0: the critical stretch follows from (2.35) and seed-thesis-ch2-3 §1.3.
    FractureEnergy(f64),
    /// The critical stretch s0 itself.
    CriticalStretch(f64),
}

/// The constants of a PMB material, as given (nothing derived yet).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PmbConstants {
    pub stiffness: Stiffness,
    pub failure: Failure,
    pub influence: Influence,
    pub plane: Plane,
}

/// Micromodulus c from Young's modulus, (2.31) and the derived rows of seed-thesis-ch2-3 §1.3.
pub fn micromodulus(e: f64, horizon: f64, dim: usize, plane: Plane, influence: Influence) -> f64 {
    let d = horizon;
    let omega1 = influence == Influence::Linear;
    match dim {
        1 => (if omega1 { 6.0 } else { 2.0 }) * e / (d * d),
        2 => {
            let base = match plane {
                Plane::Stress => 9.0 * e / (PI * d.powi(3)),
                Plane::Strain => 48.0 * e / (5.0 * PI * d.powi(3)),
            };
            if omega1 { 4.0 * base } else { base }
        }
        _ => (if omega1 { 60.0 } else { 12.0 }) * e / (PI * d.powi(4)),
    }
}

/// Critical stretch s0 from the fracture energy G0, written in terms of c so it also holds when
/// the preset overrides c: (2.35) and the [derived] rows of seed-thesis-ch2-3 §1.3.
pub fn critical_stretch(g0: f64, c: f64, horizon: f64, dim: usize, influence: Influence) -> f64 {
    let d = horizon;
    let omega1 = influence == Influence::Linear;
    let s2 = match dim {
        1 => (if omega1 { 24.0 } else { 6.0 }) * g0 / (c * d.powi(3)),
        2 => (if omega1 { 20.0 } else { 4.0 }) * g0 / (c * d.powi(4)),
        _ => (if omega1 { 60.0 } else { 10.0 }) * g0 / (PI * c * d.powi(5)),
    };
    s2.sqrt()
}

/// Influence function ω(r), (2.12)–(2.13).
#[inline(always)]
pub fn influence(kind: Influence, r: f64, horizon: f64) -> f64 {
    match kind {
        Influence::Constant => 1.0,
        Influence::Linear => (1.0 - r / horizon).max(0.0),
    }
}

/// Poisson ratio implied by bond-based PD.
pub fn poisson_ratio(dim: usize, plane: Plane) -> f64 {
    if dim == 2 && plane == Plane::Stress {
        1.0 / 3.0
    } else {
        0.25
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn kalthoff_winkler_critical_stretch_matches_the_note() {
        // seed-thesis-ch2-3 §8.3: δ = 2 mm, E = 190 GPa, G0 = 22 170 J/m².
        let (e, g0, d) = (190e9, 22170.0, 2e-3);
        let c = micromodulus(e, d, 2, Plane::Strain, Influence::Constant);
        let s0 = critical_stretch(g0, c, d, 2, Influence::Constant);
        assert!((s0 - 8.74e-3).abs() < 0.01e-3, "plane strain s0 = {s0}");
        let c = micromodulus(e, d, 2, Plane::Stress, Influence::Constant);
        let s0 = critical_stretch(g0, c, d, 2, Influence::Constant);
        assert!((s0 - 9.03e-3).abs() < 0.01e-3, "plane stress s0 = {s0}");
        // (2.35) printed form for plane stress.
        let printed = (4.0 * PI * g0 / (9.0 * e * d)).sqrt();
        assert!((s0 - printed).abs() < 1e-15);
    }

    #[test]
    fn three_d_rows_agree_with_bulk_modulus_forms() {
        let (e, g0, d): (f64, f64, f64) = (70e9, 100.0, 1e-3);
        let k = e / (3.0 * (1.0 - 2.0 * 0.25));
        for (inf, printed_c, printed_s0) in [
            (
                Influence::Constant,
                18.0 * k / (PI * d.powi(4)),
                (5.0 * g0 / (9.0 * k * d)).sqrt(),
            ),
            (
                Influence::Linear,
                90.0 * k / (PI * d.powi(4)),
                (2.0 * g0 / (3.0 * k * d)).sqrt(),
            ),
        ] {
            let c = micromodulus(e, d, 3, Plane::Strain, inf);
            assert!((c / printed_c - 1.0).abs() < 1e-12);
            let s0 = critical_stretch(g0, c, d, 3, inf);
            assert!((s0 / printed_s0 - 1.0).abs() < 1e-12);
        }
        let c1 = micromodulus(e, d, 1, Plane::Strain, Influence::Constant);
        let s0 = critical_stretch(g0, c1, d, 1, Influence::Constant);
        assert!((s0 / (3.0 * g0 / (e * d)).sqrt() - 1.0).abs() < 1e-12);
    }
}

/// The bond law evaluated by the schemes: f = μ ω c s e (2.33) with irreversible failure
/// at s ≥ s0 (2.34). `critical_stretch` is +∞ without failure.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PmbLaw {
    pub micromodulus: f64,
    pub critical_stretch: f64,
    pub influence: Influence,
    pub horizon: f64,
}

impl PmbLaw {
    /// The law of a material with horizon δ in `dim` dimensions: c from E by (2.31) and the
    /// rows of seed-thesis-ch2-3 §1.3 (or as given), s0 from G0 by (2.35) (or as given), +∞
    /// without failure.
    pub fn new(constants: &PmbConstants, horizon: f64, dim: usize) -> PmbLaw {
        let c = constants;
        let micromodulus = match c.stiffness {
            Stiffness::Micromodulus(m) => m,
            Stiffness::YoungsModulus(e) => micromodulus(e, horizon, dim, c.plane, c.influence),
        };
        let critical_stretch = match c.failure {
            Failure::None => f64::INFINITY,
            Failure::CriticalStretch(s0) => s0,
            Failure::FractureEnergy(g0) => {
                critical_stretch(g0, micromodulus, horizon, dim, c.influence)
            }
        };
        PmbLaw {
            micromodulus,
            critical_stretch,
            influence: c.influence,
            horizon,
        }
    }

    /// Pairwise energy density w = ω c s² ‖ξ‖ / 2 (2.27).
    #[inline(always)]
    pub fn bond_energy(&self, stretch: f64, length: f64) -> f64 {
        0.5 * influence(self.influence, length, self.horizon)
            * self.micromodulus
            * stretch
            * stretch
            * length
    }
}
