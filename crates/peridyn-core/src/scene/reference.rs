//! Manufactured solutions (seed-004 Examples 1–2, thesis §3.2.5–3.2.6): the exact field, and the
//! body force or source that makes it a solution of the PD problem (or of its local limit).

use std::f64::consts::PI;

use super::schema::{Physics, ReferenceOperator, ReferenceSpec};
use super::spec::{DiffusionSpec, MaterialSpec};
use crate::model::diffusion::DiffusionKernel;
use crate::model::pmb::Influence;

#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Reference {
    /// 1D static elasticity, u = sin(x / length); 0 = L[u] + b, L the nonlocal operator or
    /// its local limit.
    Sine1d {
        length: f64,
        operator: ReferenceOperator,
    },
    /// 2D diffusion, C = sin(ω t) P(x, y) with the quartic P of (3.77); Ċ = L[C] + S.
    Quartic2d { frequency: f64 },
}

impl Reference {
    pub fn from_spec(
        spec: &ReferenceSpec,
        dim: usize,
        physics: Physics,
        material: Option<&MaterialSpec>,
        diffusion: Option<&DiffusionSpec>,
    ) -> Result<Reference, String> {
        match *spec {
            ReferenceSpec::Sine1d { length, operator } => {
                let (Some(m), 1, Physics::Static) = (material, dim, physics) else {
                    return Err("reference.solution: \"sine-1d\" is a 1D static solution \
                                (physics = \"static\", dimension = 1)"
                        .into());
                };
                let length = length.si();
                if length.is_nan() || length <= 0.0 {
                    return Err(format!("reference.length: must be > 0, got {length}"));
                }
                if m.constants.influence != Influence::Constant {
                    return Err(
                        "material.influence: \"sine-1d\" is derived for ω = 1 (\"constant\")"
                            .into(),
                    );
                }
                Ok(Reference::Sine1d { length, operator })
            }
            ReferenceSpec::Quartic2d { frequency } => {
                let (Some(d), 2, Physics::Diffusion) = (diffusion, dim, physics) else {
                    return Err(
                        "reference.solution: \"quartic-2d\" is a 2D diffusion solution \
                                (physics = \"diffusion\", dimension = 2)"
                            .into(),
                    );
                };
                if d.exponent != 2.0 || d.influence != Influence::Constant {
                    return Err(
                        "material.kernel_exponent: \"quartic-2d\" is derived for q = 2 \
                                and influence = \"constant\" (3.78)"
                            .into(),
                    );
                }
                if !frequency.is_finite() {
                    return Err(format!(
                        "reference.frequency: must be finite, got {frequency}"
                    ));
                }
                Ok(Reference::Quartic2d { frequency })
            }
        }
    }

    /// The exact field at `x`, time `t`.
    pub fn value(&self, x: &[f64], t: f64) -> f64 {
        match *self {
            Reference::Sine1d { length, .. } => (x[0] / length).sin(),
            Reference::Quartic2d { frequency, .. } => (frequency * t).sin() * quartic(x),
        }
    }

    /// The body force b (static) or source S (diffusion) at `x`, time `t`, for the scalar
    /// operator of `kernel` (its coefficient is c for 1D static elasticity, κ for diffusion).
    pub fn forcing(&self, x: &[f64], t: f64, kernel: &DiffusionKernel) -> f64 {
        let (coefficient, horizon) = (kernel.diffusivity, kernel.horizon);
        match *self {
            Reference::Sine1d { length, operator } => {
                let c = coefficient;
                // b / sin(x / ℓ):
                let factor = match operator {
                    // ∫_{-δ}^{δ} c/|ξ| (sin((x+ξ)/ℓ) − sin(x/ℓ)) dξ = −2c Cin(δ/ℓ) sin(x/ℓ),
                    // (3.74) with γ (seed-thesis-ch2-3 erratum 4: not e):
                    // Cin(a) = γ − Ci(a) + ln a.
                    ReferenceOperator::Nonlocal => 2.0 * c * cin(horizon / length),
                    // Local limit (3.75)–(3.76): 0 = E u'' + b, E = c δ²/2 in 1D.
                    ReferenceOperator::Local => c * horizon * horizon / 2.0 / (length * length),
                };
                factor * (x[0] / length).sin()
            }
            // (3.78): S = ω cos(ω t) P − sin(ω t) L[P].
            Reference::Quartic2d { frequency } => {
                frequency * (frequency * t).cos() * quartic(x)
                    - (frequency * t).sin() * coefficient * pd_of_quartic(x, horizon)
            }
        }
    }

    /// The largest |value| over the given positions and all times: a fixed color range.
    pub fn amplitude<'a>(&self, positions: impl Iterator<Item = &'a [f64]>) -> f64 {
        match self {
            Reference::Sine1d { .. } => 1.0,
            Reference::Quartic2d { .. } => positions.fold(0.0, |a: f64, x| a.max(quartic(x).abs())),
        }
    }
}

/// P(x, y) = x²y² + x³y + x⁴ + xy³ + y⁴ (3.77).
pub fn quartic(p: &[f64]) -> f64 {
    let (x, y) = (p[0], p[1]);
    x * x * y * y + x.powi(3) * y + x.powi(4) + x * y.powi(3) + y.powi(4)
}

/// L[P] for κ = 1, q = 2, ω = 1 over a full disc of radius δ: the second term of (3.78).
pub fn pd_of_quartic(p: &[f64], horizon: f64) -> f64 {
    let (x, y, d) = (p[0], p[1], horizon);
    PI * d * d / 16.0 * (7.0 * d * d + 56.0 * x * x + 48.0 * x * y + 56.0 * y * y)
}

/// Cin(a) = ∫_0^a (1 − cos t)/t dt = γ − Ci(a) + ln a, by its power series (a ≲ 10).
pub fn cin(a: f64) -> f64 {
    let (mut sum, mut factorial, mut k) = (0.0, 1.0, 1u32);
    loop {
        factorial *= f64::from((2 * k - 1) * (2 * k)); // (2k)!
        let term = a.powi(2 * k as i32) / (2.0 * f64::from(k) * factorial);
        sum += if k % 2 == 1 { term } else { -term };
        if term < 1e-18 * sum.abs().max(1e-300) || k > 200 {
            return sum;
        }
        k += 1;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Cin against γ − Ci(a) + ln a with tabulated Ci(1) = 0.337403922900968.
    #[test]
    fn cin_matches_the_cosine_integral() {
        let gamma = 0.577_215_664_901_532_9;
        let expected = gamma - 0.337_403_922_900_968 + 0.0;
        assert!((cin(1.0) - expected).abs() < 1e-14, "{}", cin(1.0));
    }

    #[test]
    fn body_force_of_the_m_convergence_problem() {
        // δ = 6, c = 2/δ²: b = 2c Cin(0.6) sin(x/10) ≈ 0.00985 sin(x/10).
        assert!((2.0 * (2.0 / 36.0) * cin(0.6) - 0.00985).abs() < 1e-5);
    }
}
