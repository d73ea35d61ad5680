//! `[material]` by physics: the elastic material of dynamics and static scenes, the diffusion
//! kernel of diffusion and corrosion scenes, and the scalar wave's speed, damping and kernel.

use super::checks::positive;
use super::error::{ErrorContext, SceneError};
use super::schema::{Physics, Preset};
use super::spec::{CorrosionSpec, DiffusionSpec, MaterialSpec, WaveSpec};
use crate::model::diffusion::second_moment;
use crate::model::pmb::{Failure, PmbConstants, Stiffness};

/// The constitutive laws of a scene, by physics (NNPP's are in its own table).
pub(super) struct Laws {
    /// The elastic material (dynamics and static scenes).
    pub material: Option<MaterialSpec>,
    /// The diffusion kernel (diffusion, corrosion; the scalar wave's operator).
    pub diffusion: Option<DiffusionSpec>,
    pub wave: Option<WaveSpec>,
}

impl Laws {
    /// E where the material gives it (the state-based material derives its constants from it).
    pub fn young(&self) -> Option<f64> {
        self.material
            .as_ref()
            .and_then(|m| match m.constants.stiffness {
                Stiffness::YoungsModulus(e) => Some(e),
                Stiffness::Micromodulus(_) => None,
            })
    }
}

/// `[material]` read as its physics needs it.
pub(super) fn laws(
    p: &Preset,
    ctx: &ErrorContext,
    dim: usize,
    horizon: f64,
) -> Result<Laws, SceneError> {
    let physics = p.physics;
    let mut wave = None;
    let (material, diffusion) = match physics {
        Physics::Diffusion | Physics::Corrosion => (None, Some(diffusion(p, ctx, physics)?)),
        Physics::ScalarWave => {
            let (w, kernel) = scalar_wave(p, ctx, dim, horizon)?;
            wave = Some(w);
            (None, Some(kernel))
        }
        Physics::NernstPlanck => (None, None),
        Physics::Static if dim != 1 => {
            return Err(ctx.error(
                "physics",
                format!("\"static\" is available in 1D; this scene is {dim}D"),
            ));
        }
        _ => (Some(material(p, ctx, physics)?), None),
    };
    Ok(Laws {
        material,
        diffusion,
        wave,
    })
}

fn material(p: &Preset, ctx: &ErrorContext, physics: Physics) -> Result<MaterialSpec, SceneError> {
    let m = &p.material;
    let density = match (m.density, physics) {
        (Some(rho), _) => positive(ctx, "material.density", rho.si())?,
        (None, Physics::Dynamics) => {
            return Err(ctx.error("material.density", "dynamics needs a mass density ρ"));
        }
        (None, _) => 1.0,
    };
    let stiffness = match (m.micromodulus, m.youngs_modulus) {
        (Some(c), _) => Stiffness::Micromodulus(positive(ctx, "material.micromodulus", c.si())?),
        (None, Some(e)) => {
            Stiffness::YoungsModulus(positive(ctx, "material.youngs_modulus", e.si())?)
        }
        (None, None) => {
            return Err(ctx.error(
                "material.youngs_modulus",
                "give `youngs_modulus` (E) or `micromodulus` (c)",
            ));
        }
    };
    let failure = match (m.critical_stretch, m.fracture_energy) {
        (Some(s0), _) => Failure::CriticalStretch(positive(ctx, "material.critical_stretch", s0)?),
        (None, Some(g0)) => {
            Failure::FractureEnergy(positive(ctx, "material.fracture_energy", g0.si())?)
        }
        (None, None) => Failure::None,
    };
    Ok(MaterialSpec {
        density,
        constants: PmbConstants {
            stiffness,
            failure,
            influence: m.influence,
            plane: m.plane,
        },
    })
}

fn diffusion(
    p: &Preset,
    ctx: &ErrorContext,
    physics: Physics,
) -> Result<DiffusionSpec, SceneError> {
    let m = &p.material;
    let diffusivity = match m.diffusivity {
        Some(k) => positive(ctx, "material.diffusivity", k.si())?,
        None => return Err(ctx.error("material.diffusivity", "diffusion needs κ (`diffusivity`)")),
    };
    let exponent = m.kernel_exponent.unwrap_or(2.0);
    if !(0.0..3.0).contains(&exponent) {
        return Err(ctx.error(
            "material.kernel_exponent",
            format!("q must be in [0, 3) so the kernel stays integrable in 1D–3D, got {exponent}"),
        ));
    }
    let corrosion = match physics {
        Physics::Corrosion => {
            let interface = m.interface_diffusivity.ok_or_else(|| {
                ctx.error(
                    "material.interface_diffusivity",
                    "corrosion needs κ_int of solid–liquid bonds (`interface_diffusivity`)",
                )
            })?;
            let interface = positive(ctx, "material.interface_diffusivity", interface.si())?;
            let saturation = m.saturation.ok_or_else(|| {
                ctx.error(
                    "material.saturation",
                    "corrosion needs the saturation concentration C_sat (`saturation`)",
                )
            })?;
            let saturation = positive(ctx, "material.saturation", saturation.si())?;
            Some(CorrosionSpec {
                interface_diffusivity: interface,
                saturation,
            })
        }
        _ => None,
    };
    Ok(DiffusionSpec {
        diffusivity,
        exponent,
        influence: m.influence,
        corrosion,
    })
}

/// The scalar wave: χ, d, and its kernel c_s ω / r^p as a [`DiffusionSpec`] (the operator is the
/// diffusion one with κ = c_s).
fn scalar_wave(
    p: &Preset,
    ctx: &ErrorContext,
    dim: usize,
    horizon: f64,
) -> Result<(WaveSpec, DiffusionSpec), SceneError> {
    let m = &p.material;
    let speed = match m.wave_speed {
        Some(v) => positive(ctx, "material.wave_speed", v.si())?,
        None => {
            return Err(ctx.error(
                "material.wave_speed",
                "a scalar wave needs χ (`wave_speed`, m/s)",
            ));
        }
    };
    let damping = m.damping.map_or(0.0, |d| d.si());
    if !(damping >= 0.0 && damping.is_finite()) {
        return Err(ctx.error(
            "material.damping",
            format!("d must be a finite number ≥ 0 (1/s), got {damping}"),
        ));
    }
    let exponent = m.kernel_exponent.unwrap_or(2.0);
    if !(0.0..dim as f64 + 1.0).contains(&exponent) {
        return Err(ctx.error(
            "material.kernel_exponent",
            format!(
                "p must be in [0, {}) so the {dim}D kernel's second moment is finite, got {exponent}",
                dim + 1
            ),
        ));
    }
    let moment = second_moment(dim, exponent, m.influence, horizon);
    Ok((
        WaveSpec { speed, damping },
        DiffusionSpec {
            diffusivity: speed * speed / moment,
            exponent,
            influence: m.influence,
            corrosion: None,
        },
    ))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::pmb::Influence;

    /// Table 4.1 of the thesis (κ0, κ1 per D) and the wave constants (4.47), (4.51), (4.87).
    #[test]
    fn second_moments_give_the_papers_constants() {
        use std::f64::consts::PI;
        let d: f64 = 0.7;
        let cases = [
            (1, 0.0, Influence::Constant, 3.0 / d.powi(3)),
            (1, 1.0, Influence::Constant, 2.0 / d.powi(2)),
            (1, 0.0, Influence::Linear, 12.0 / d.powi(3)),
            (1, 1.0, Influence::Linear, 6.0 / d.powi(2)),
            (2, 0.0, Influence::Constant, 8.0 / (PI * d.powi(4))),
            (2, 1.0, Influence::Constant, 6.0 / (PI * d.powi(3))),
            (3, 1.0, Influence::Constant, 6.0 / (PI * d.powi(4))),
            (3, 1.0, Influence::Linear, 30.0 / (PI * d.powi(4))),
            (2, 1.0, Influence::Linear, 24.0 / (PI * d.powi(3))),
            (2, 2.0, Influence::Constant, 4.0 / (PI * d * d)),
            (2, 2.0, Influence::Linear, 12.0 / (PI * d * d)),
            (3, 2.0, Influence::Constant, 9.0 / (2.0 * PI * d.powi(3))),
            (3, 2.0, Influence::Linear, 18.0 / (PI * d.powi(3))),
        ];
        for (dim, p, w, kappa) in cases {
            let got = 1.0 / second_moment(dim, p, w, d);
            assert!(
                (got / kappa - 1.0).abs() < 1e-12,
                "{dim}D p = {p} {w:?}: {got} vs {kappa}"
            );
        }
    }
}
