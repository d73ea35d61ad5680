//! `material.model = "osb"`, `[refinement]`, `time.integrator = "adr"` and `[[metrics.opening]]`
//! → the scene's [`StateBasedSpec`] (zeng2024; defaults are the paper's: φ_c = 0.4, α = 0.5,
//! one refinement level).

use super::checks::{check_split_damage, check_split_strain, each, point, positive};
use super::error::{ErrorContext, SceneError};
use super::geometry::Solid;
use super::schema::{BondWeights, IntegratorKind, ModelKind, Physics, Preset};
use crate::model::osb::OsbMaterial;

/// ADR's residual tolerance where a preset gives none.
pub const DEFAULT_TOLERANCE: f64 = 1e-6;

/// When a particle splits, and how deep.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SplitRule {
    /// φ_c of (15).
    pub damage: f64,
    /// α of (16), in (0, 1).
    pub strain_factor: f64,
    /// Refinement levels (1: parents split once).
    pub levels: u8,
    /// δ_child / δ_parent (zeng2024 Table 3 compares 0.5, the default and the paper's choice for
    /// every other example, with 1.0, which keeps one horizon across a size change).
    pub horizon_ratio: f64,
}

/// An OSB scene on a dual-horizon discretization.
#[derive(Debug, Clone, PartialEq)]
pub struct StateBasedSpec {
    pub material: OsbMaterial,
    pub weights: BondWeights,
    /// `None`: no particle splits.
    pub refinement: Option<SplitRule>,
    /// Particles split before the run (to every level), whatever the criteria say.
    pub refined_region: Option<Solid>,
    /// ADR's tolerance; `None`: velocity-Verlet.
    pub relaxation: Option<f64>,
    pub openings: Vec<OpeningSpec>,
}

#[derive(Debug, Clone, PartialEq)]
pub struct OpeningSpec {
    pub name: String,
    pub mouth: Vec<f64>,
    pub axis: usize,
}

fn refuse(ctx: &ErrorContext, field: &str, what: &str) -> SceneError {
    ctx.error(field, format!("{what} needs material.model = \"osb\""))
}

pub(super) fn state_based(
    p: &Preset,
    ctx: &ErrorContext,
    dim: usize,
    young: Option<f64>,
) -> Result<Option<StateBasedSpec>, SceneError> {
    let m = &p.material;
    let adr = p
        .time
        .as_ref()
        .is_some_and(|t| t.integrator == Some(IntegratorKind::Adr));
    if m.model != ModelKind::Osb {
        if p.refinement.is_some() {
            return Err(refuse(ctx, "refinement", "particle splitting"));
        }
        if adr {
            return Err(refuse(ctx, "time.integrator", "dynamic relaxation"));
        }
        if !p.metrics.opening.is_empty() {
            return Err(refuse(ctx, "metrics.opening", "the crack-opening metric"));
        }
        for (field, given) in [
            ("material.poisson_ratio", m.poisson_ratio.is_some()),
            ("material.thickness", m.thickness.is_some()),
            (
                "discretization.bond_weights",
                p.discretization.bond_weights.is_some(),
            ),
        ] {
            if given {
                return Err(refuse(ctx, field, "this field"));
            }
        }
        return Ok(None);
    }
    if dim != 2 || p.physics != Physics::Dynamics {
        return Err(ctx.error(
            "material.model",
            format!(
                "\"osb\" runs 2D dynamics; this scene is {dim}D {:?}",
                p.physics
            ),
        ));
    }
    for (field, given) in [
        ("material.micromodulus", m.micromodulus.is_some()),
        ("material.critical_stretch", m.critical_stretch.is_some()),
        ("multigrid", p.multigrid.is_some()),
        ("absorbing", p.absorbing.is_some()),
    ] {
        if given {
            return Err(ctx.error(
                field,
                "is not available with material.model = \"osb\" (E, ν and G_c give its constants)",
            ));
        }
    }
    let Some(youngs_modulus) = young else {
        return Err(ctx.error("material.youngs_modulus", "\"osb\" needs E"));
    };
    let poisson_ratio = match m.poisson_ratio {
        Some(nu) if nu > -1.0 && nu < 0.5 => nu,
        Some(nu) => {
            return Err(ctx.error(
                "material.poisson_ratio",
                format!("must lie in (-1, 0.5), got {nu}"),
            ));
        }
        None => return Err(ctx.error("material.poisson_ratio", "\"osb\" needs ν")),
    };
    let thickness = match m.thickness {
        Some(h) => positive(ctx, "material.thickness", h.si())?,
        None => 1.0,
    };
    let fracture_energy = match m.fracture_energy {
        Some(g) => Some(positive(ctx, "material.fracture_energy", g.si())?),
        None => None,
    };
    let refinement = split_rule(p, ctx)?;
    let relaxation = relaxation(p, ctx, adr)?;
    let openings = each(ctx, "metrics.opening", &p.metrics.opening, |o, path| {
        if o.axis >= dim {
            return Err(format!("{path}.axis: must be 0 or 1, got {}", o.axis));
        }
        Ok(OpeningSpec {
            name: o.name.clone(),
            mouth: point(&o.mouth, dim, &format!("{path}.mouth"))?,
            axis: o.axis,
        })
    })?;
    Ok(Some(StateBasedSpec {
        material: OsbMaterial {
            youngs_modulus,
            poisson_ratio,
            plane: m.plane,
            thickness,
            fracture_energy,
        },
        weights: p.discretization.bond_weights.unwrap_or_default(),
        refinement: refinement.as_ref().map(|r| r.0),
        refined_region: refinement.and_then(|r| r.1),
        relaxation,
        openings,
    }))
}

/// `[refinement]`: when a particle splits (φ_c, α), how deep, and the region split before the
/// run; `None` where splitting is off.
fn split_rule(
    p: &Preset,
    ctx: &ErrorContext,
) -> Result<Option<(SplitRule, Option<Solid>)>, SceneError> {
    Ok(match &p.refinement {
        Some(r) if r.enabled => {
            let damage = check_split_damage(r.damage.unwrap_or(0.4))
                .map_err(|m| ctx.error("refinement.damage", m))?;
            let strain_factor = check_split_strain(r.strain_factor.unwrap_or(0.5))
                .map_err(|m| ctx.error("refinement.strain_factor", m))?;
            let levels = r.levels.unwrap_or(1);
            if !(1..=3).contains(&levels) {
                return Err(ctx.error(
                    "refinement.levels",
                    format!("must be 1, 2 or 3, got {levels}"),
                ));
            }
            let horizon_ratio = r.horizon_ratio.unwrap_or(0.5);
            if !(0.5..=1.0).contains(&horizon_ratio) {
                return Err(ctx.error(
                    "refinement.horizon_ratio",
                    format!("must lie in [0.5, 1] (δ_child / δ_parent), got {horizon_ratio}"),
                ));
            }
            let region = r
                .region
                .as_ref()
                .map(|shape| shape.to_solid(2, "refinement.region"))
                .transpose()
                .map_err(|m| ctx.error("refinement.region", m))?;
            Some((
                SplitRule {
                    damage,
                    strain_factor,
                    levels,
                    horizon_ratio,
                },
                region,
            ))
        }
        _ => None,
    })
}

/// ADR's tolerance (`None`: velocity-Verlet); `time.tolerance` belongs to ADR only.
fn relaxation(p: &Preset, ctx: &ErrorContext, adr: bool) -> Result<Option<f64>, SceneError> {
    Ok(match (adr, p.time.as_ref().and_then(|t| t.tolerance)) {
        (true, Some(t)) if t > 0.0 && t < 1.0 => Some(t),
        (true, Some(t)) => {
            return Err(ctx.error(
                "time.tolerance",
                format!("the relative residual must lie in (0, 1), got {t}"),
            ));
        }
        (true, None) => Some(DEFAULT_TOLERANCE),
        (false, Some(_)) => {
            return Err(ctx.error(
                "time.tolerance",
                "is read by time.integrator = \"adr\" only",
            ));
        }
        (false, None) => None,
    })
}
