//! Preset → Scene: range checks with the field's name, units to SI, derived material constants.

use super::collocation::Collocation;
use super::error::{ErrorContext, SceneError};
use super::geometry::{Point, si};
use super::reference;
use super::schema::{
    BoundaryLayer, CoarseKind, Perturbation, Physics, Precrack, Preset, SchemeKind, VelocityField,
};
use super::units::{Measure, Relative};
use super::*;
use crate::model::pmb::{Failure, PmbConstants, Stiffness};

/// Directed bonds a scene may have (≈ 13 bytes each while the families are built: 16 GB).
const MAX_BONDS: f64 = 1.2e9;

pub(super) fn validate(
    p: &Preset,
    ctx: &ErrorContext,
    text: &str,
    variant: Option<&str>,
) -> Result<Scene, SceneError> {
    let dim = p.dimension;
    if !(1..=3).contains(&dim) {
        return Err(ctx.error("dimension", format!("must be 1, 2 or 3, got {dim}")));
    }
    let solid = p
        .geometry
        .to_solid(dim, "geometry")
        .map_err(|m| ctx.from_path_message(&m))?;
    let (lo, hi) = solid.bounds();
    if lo.iter().chain(&hi).any(|v| !v.is_finite()) {
        return Err(ctx.error(
            "geometry",
            format!("every coordinate and size must be a finite number; bounds {lo:?} to {hi:?}"),
        ));
    }

    let d = &p.discretization;
    let spacing = positive(ctx, "discretization.spacing", d.spacing.si())?;
    let horizon = match d.horizon {
        Measure::Si(h) => positive(ctx, "discretization.horizon", h)?,
        Measure::Relative(m, Relative::Spacing) => {
            positive(ctx, "discretization.horizon", m)? * spacing
        }
        Measure::Relative(_, r) => {
            return Err(ctx.error(
                "discretization.horizon",
                format!(
                    "`{}` is not a length: give e.g. \"2 mm\" or \"4 dx\"",
                    r.unit()
                ),
            ));
        }
    };
    let perturbation = match d.perturbation {
        Perturbation::Symmetric(p) => [-p, p],
        Perturbation::Range(r) => r,
    };
    let valid = match d.perturbation {
        Perturbation::Symmetric(p) => (0.0..0.5).contains(&p),
        Perturbation::Range([lo, hi]) => -0.5 < lo && lo <= hi && hi < 0.5,
    };
    if !valid {
        return Err(ctx.error(
            "discretization.perturbation",
            format!(
                "must be a fraction of the spacing p in [0, 0.5) (offsets in ±p Δx), or a range \
                 [lo, hi] with -0.5 < lo ≤ hi < 0.5; got {:?}",
                d.perturbation
            ),
        ));
    }
    let origin = match &d.origin {
        None => None,
        Some(o) if o.len() == dim => Some(si(o)),
        Some(o) => {
            return Err(ctx.error(
                "discretization.origin",
                format!("has {} components, the scene is {dim}-dimensional", o.len()),
            ));
        }
    };
    let physics = p.physics;
    let scheme = scheme(p, ctx, dim, spacing)?;
    let boundary = p
        .boundary
        .iter()
        .enumerate()
        .map(|(i, b)| boundary_layer(b, dim, spacing, horizon, physics, &format!("boundary[{i}]")))
        .collect::<Result<Vec<_>, _>>()
        .map_err(|m| ctx.from_path_message(&m))?;
    let solid =
        extend_for_outside_layers(solid, &boundary).map_err(|m| ctx.from_path_message(&m))?;
    let (lo, hi) = solid.bounds();
    let nodes_estimate: f64 = lo
        .iter()
        .zip(&hi)
        .map(|(a, b)| (b - a) / spacing + 1.0)
        .product();
    if nodes_estimate > 5e7 {
        return Err(ctx.error(
            "discretization.spacing",
            format!("gives about {nodes_estimate:.3e} lattice nodes; the limit is 5e7"),
        ));
    }
    // Family size ≈ volume of the ball in cells; 13 bytes per directed bond.
    let m = horizon / spacing;
    let family = match dim {
        1 => 2.0 * m,
        2 => std::f64::consts::PI * m * m,
        _ => 4.0 / 3.0 * std::f64::consts::PI * m.powi(3),
    };
    let bonds_estimate = nodes_estimate * family;
    if bonds_estimate > MAX_BONDS {
        return Err(ctx.error(
            "discretization.horizon",
            format!(
                "gives about {bonds_estimate:.3e} directed bonds ({:.0} GB); the limit is {MAX_BONDS:.1e} \
                 ({:.0} GB): lower the horizon factor or coarsen the spacing",
                bonds_estimate * 13.0 / 1e9,
                MAX_BONDS * 13.0 / 1e9
            ),
        ));
    }

    let mut wave = None;
    let (material, diffusion) = match physics {
        Physics::Diffusion | Physics::Corrosion => (None, Some(diffusion(p, ctx, physics)?)),
        Physics::ScalarWave => {
            let (w, kernel) = super::absorbing::wave(p, ctx, dim, horizon)?;
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
    let young = material.as_ref().and_then(|m| match m.constants.stiffness {
        crate::model::pmb::Stiffness::YoungsModulus(e) => Some(e),
        crate::model::pmb::Stiffness::Micromodulus(_) => None,
    });
    let state_based = super::state_based::state_based(p, ctx, dim, young)?;
    if state_based.is_some() && scheme.kind != SchemeKind::Standard {
        return Err(ctx.error(
            "discretization.scheme",
            "material.model = \"osb\" runs its dual-horizon standard scheme only",
        ));
    }
    let cuts_bonds = matches!(
        physics,
        Physics::Dynamics | Physics::ScalarWave | Physics::Diffusion
    );
    if !cuts_bonds && !p.precracks.is_empty() {
        return Err(ctx.error(
            "precracks",
            "pre-cracks need physics = \"dynamics\", \"scalar-wave\" or \"diffusion\"",
        ));
    }
    let hybrid = hybrid(p, ctx, scheme.kind, spacing, horizon)?;
    let nernst_planck = super::nernst_planck::nernst_planck(p, ctx, dim, horizon)?;
    if physics == Physics::NernstPlanck
        && (scheme.kind != SchemeKind::Standard || p.absorbing.is_some())
    {
        return Err(ctx.error(
            "discretization.scheme",
            "physics = \"nernst-planck\" runs the standard scheme (on one grid or a \
             multi-grid with a predefined fine region), without an absorbing layer",
        ));
    }
    if physics == Physics::Corrosion
        && !matches!(scheme.kind, SchemeKind::Standard | SchemeKind::HybridFixed)
    {
        return Err(ctx.error(
            "discretization.scheme",
            format!(
                "\"{}\": corrosion's bond classes need the standard scheme (or \"hybrid-fixed\", standard where the phases meet)",
                scheme.kind.name()
            ),
        ));
    }
    let fixed_corrosion = physics == Physics::Corrosion && scheme.kind == SchemeKind::HybridFixed;
    if physics != Physics::Dynamics && scheme.kind.is_hybrid() && !fixed_corrosion {
        return Err(ctx.error(
            "discretization.scheme",
            format!(
                "\"{}\" is available for dynamics (and \"hybrid-fixed\" for corrosion)",
                scheme.kind.name()
            ),
        ));
    }
    if let Some(h) = hybrid.as_ref().filter(|_| fixed_corrosion)
        && h.band < horizon * (1.0 - 1e-9)
    {
        return Err(ctx.error(
            "hybrid.band",
            format!(
                "{:.4e} m is below the horizon {horizon:.4e} m: a corrosion hybrid needs Ω_s to \
                 reach at least δ beyond the solid, so that no Ω_w node has a solid neighbour; \
                 use e.g. band = \"1.2 horizon\"",
                h.band
            ),
        ));
    }
    if physics == Physics::Dynamics && scheme.kind.wls_order().is_some() {
        return Err(ctx.error(
            "discretization.scheme",
            format!(
                "\"{}\" is available for physics = \"static\" and \"diffusion\"; dynamics uses \
                 \"standard\", \"hybrid-fixed\" or \"hybrid-adaptive\"",
                scheme.kind.name()
            ),
        ));
    }
    let multigrid = multigrid(
        p,
        ctx,
        dim,
        physics,
        scheme.kind,
        perturbation,
        [spacing, horizon],
    )?;
    if physics == Physics::ScalarWave
        && (scheme.kind != SchemeKind::Standard || multigrid.is_some())
    {
        return Err(ctx.error(
            "discretization.scheme",
            "a scalar wave runs on the standard scheme, on one grid",
        ));
    }
    let absorbing = p
        .absorbing
        .as_ref()
        .map(|t| super::absorbing::absorbing(t, ctx, (dim, physics, &solid), spacing, horizon))
        .transpose()?;
    if absorbing.is_some() && (multigrid.is_some() || scheme.kind != SchemeKind::Standard) {
        return Err(ctx.error(
            "absorbing",
            "an absorbing layer runs with the standard scheme on one grid (no multigrid, hybrid \
             or WLS)",
        ));
    }
    let initial_pulses = super::absorbing::pulses(p, ctx, dim, physics)?;
    let reference = p
        .reference
        .as_ref()
        .map(|r| {
            reference::Reference::from_spec(r, dim, physics, material.as_ref(), diffusion.as_ref())
        })
        .transpose()
        .map_err(|m| ctx.from_path_message(&m))?;
    let manufactured = nernst_planck
        .as_ref()
        .is_some_and(|n| n.manufactured.is_some());
    if reference.is_none()
        && !manufactured
        && boundary.iter().any(|b| b.condition == Condition::Reference)
    {
        return Err(ctx.error(
            "reference",
            "a `hold_reference` boundary layer needs a [reference] table",
        ));
    }
    let precracks = p
        .precracks
        .iter()
        .enumerate()
        .map(|(i, c)| precrack(c, dim, &format!("precracks[{i}]")))
        .collect::<Result<Vec<_>, _>>()
        .map_err(|m| ctx.from_path_message(&m))?;
    let initial_concentration = p
        .initial
        .concentration
        .iter()
        .enumerate()
        .map(|(i, c)| {
            let path = format!("initial.concentration[{i}]");
            let value = c.value.si();
            if !value.is_finite() {
                return Err(format!("{path}.value: must be finite, got {value}"));
            }
            Ok((c.region.to_solid(dim, &format!("{path}.region"))?, value))
        })
        .collect::<Result<Vec<_>, String>>()
        .map_err(|m| ctx.from_path_message(&m))?;
    if matches!(physics, Physics::Dynamics | Physics::NernstPlanck)
        && !initial_concentration.is_empty()
    {
        return Err(ctx.error(
            "initial.concentration",
            "concentrations need physics = \"diffusion\" or \"corrosion\" (NNPP species \
             take theirs from [[nernst_planck.species]])",
        ));
    }
    let initial_velocity = p
        .initial
        .velocity
        .iter()
        .enumerate()
        .map(|(i, v)| velocity_field(v, dim, &format!("initial.velocity[{i}]")))
        .collect::<Result<Vec<_>, _>>()
        .map_err(|m| ctx.from_path_message(&m))?;
    let time = match (&p.time, physics) {
        (Some(t), _) => time_spec(t, ctx)?,
        // A static scene is one global solve.
        (None, Physics::Static) => TimeSpec {
            step: StepSize::Absolute(1.0),
            duration: Duration::Steps(1),
            allow_unstable: false,
        },
        (None, _) => return Err(ctx.error("time", "give a [time] table with `dt` and `end`")),
    };
    if p.output.every == Some(0) {
        return Err(ctx.error("output.every", "must be ≥ 1 (steps between frames)"));
    }
    let crack_angles = p
        .metrics
        .crack_angle
        .iter()
        .enumerate()
        .map(|(i, c)| {
            let path = format!("metrics.crack_angle[{i}]");
            let tip = point(&c.tip, dim, &format!("{path}.tip"))?;
            let direction = point(&c.direction, dim, &format!("{path}.direction"))?;
            if direction.iter().all(|v| *v == 0.0) {
                return Err(format!("{path}.direction: must not be zero"));
            }
            if !(0.0..=1.0).contains(&c.threshold) {
                return Err(format!("{path}.threshold: must be in [0, 1]"));
            }
            Ok(CrackAngleSpec {
                name: c.name.clone(),
                tip,
                direction,
                threshold: c.threshold,
                region: c.region.to_solid(dim, &format!("{path}.region"))?,
            })
        })
        .collect::<Result<Vec<_>, _>>()
        .map_err(|m| ctx.from_path_message(&m))?;
    let probes = p
        .metrics
        .probe
        .iter()
        .enumerate()
        .map(|(i, q)| {
            Ok((
                q.name.clone(),
                point(&q.point, dim, &format!("metrics.probe[{i}].point"))?,
            ))
        })
        .collect::<Result<Vec<_>, String>>()
        .map_err(|m| ctx.from_path_message(&m))?;
    let energy_circles = p
        .metrics
        .energy_circle
        .iter()
        .enumerate()
        .map(|(i, c)| {
            let path = format!("metrics.energy_circle[{i}]");
            let radius = c.radius.si();
            if !(radius > 0.0 && radius.is_finite()) {
                return Err(format!("{path}.radius: must be a length > 0, got {radius}"));
            }
            Ok(EnergyCircleSpec {
                name: c.name.clone(),
                center: point(&c.center, dim, &format!("{path}.center"))?,
                radius,
            })
        })
        .collect::<Result<Vec<_>, _>>()
        .map_err(|m| ctx.from_path_message(&m))?;
    let damage_counts = p
        .metrics
        .damage_count
        .iter()
        .enumerate()
        .map(|(i, c)| {
            let path = format!("metrics.damage_count[{i}]");
            if !(0.0..=1.0).contains(&c.threshold) {
                return Err(format!("{path}.threshold: must be in [0, 1]"));
            }
            Ok(DamageCountSpec {
                name: c.name.clone(),
                region: c.region.to_solid(dim, &format!("{path}.region"))?,
                threshold: c.threshold,
            })
        })
        .collect::<Result<Vec<_>, _>>()
        .map_err(|m| ctx.from_path_message(&m))?;

    Ok(Scene {
        name: p.name.clone(),
        description: p.description.clone(),
        variant: variant.map(str::to_string),
        source: ctx.file.to_string(),
        preset_text: text.to_string(),
        overrides: Vec::new(),
        dim,
        solid,
        spacing,
        horizon,
        perturbation,
        origin,
        physics,
        scheme,
        reference,
        diffusion,
        hybrid,
        multigrid,
        absorbing,
        state_based,
        wave,
        nernst_planck,
        initial_pulses,
        seed: d.seed,
        family_radius: d.family_radius,
        volume_correction: d.volume_correction,
        material,
        precracks,
        boundary,
        initial_velocity,
        initial_concentration,
        time,
        output_every: p.output.every,
        crack_angles,
        energy_circles,
        probes,
        damage_counts,
    })
}

/// The two levels of a multi-grid scene: a whole grid ratio in 2..=16, the standard scheme on
/// both levels, an unperturbed lattice (the fine cells split the coarse ones). Diffusion and
/// corrosion take a predefined `region`; dynamics the multi-adaptive switch from a `band`.
fn multigrid(
    p: &Preset,
    ctx: &ErrorContext,
    dim: usize,
    physics: Physics,
    kind: SchemeKind,
    perturbation: [f64; 2],
    [spacing, horizon]: [f64; 2],
) -> Result<Option<MultigridSpec>, SceneError> {
    let Some(m) = &p.multigrid else {
        return Ok(None);
    };
    if !(2..=16).contains(&m.ratio) {
        return Err(ctx.error(
            "multigrid.ratio",
            format!(
                "the grid ratio Δx⁺/Δx⁻ must be a whole number in 2..=16, got {}",
                m.ratio
            ),
        ));
    }
    if kind != SchemeKind::Standard {
        return Err(ctx.error(
            "discretization.scheme",
            format!(
                "\"{}\": a multi-grid scene runs the standard scheme on both levels",
                kind.name()
            ),
        ));
    }
    if perturbation != [0.0, 0.0] {
        return Err(ctx.error(
            "discretization.perturbation",
            "a multi-grid scene needs an unperturbed lattice (fine cells split the coarse ones)",
        ));
    }
    // The fields of a WLS coarse level.
    let wls_fields = [
        (m.collocation_factor.is_some(), "collocation_factor"),
        (m.collocation_orbits.is_some(), "collocation_orbits"),
        (m.fit_weight.is_some(), "fit_weight"),
    ];
    let refinement = match physics {
        Physics::Diffusion | Physics::Corrosion | Physics::NernstPlanck => {
            let switch_fields = [
                (m.band.is_some(), "band"),
                (m.chi.is_some(), "chi"),
                (m.transfer.is_some(), "transfer"),
            ];
            for &(given, field) in &switch_fields {
                if given {
                    return Err(ctx.error(
                        &format!("multigrid.{field}"),
                        "belongs to the multi-adaptive switch of dynamics; diffusion, \
                         corrosion and nernst-planck refine the predefined `region`",
                    ));
                }
            }
            let Some(region) = &m.region else {
                return Err(ctx.error(
                    "multigrid.region",
                    "is missing: diffusion, corrosion and nernst-planck refine a predefined \
                     region",
                ));
            };
            let region = region
                .to_solid(dim, "multigrid.region")
                .map_err(|e| ctx.from_path_message(&e))?;
            Refinement::Region(region)
        }
        Physics::Dynamics => {
            if m.region.is_some() {
                return Err(ctx.error(
                    "multigrid.region",
                    "dynamics refines adaptively: give the initial `band` around boundaries \
                     and pre-cracks instead",
                ));
            }
            let band = match m.band {
                None => horizon,
                Some(b) => length(ctx, "multigrid.band", b, spacing, horizon)?,
            };
            if band.is_nan() || band < horizon * (1.0 - 1e-9) || !band.is_finite() {
                return Err(ctx.error(
                    "multigrid.band",
                    format!(
                        "{band:.4e} m is narrower than the horizon {horizon:.4e} m: nodes whose \
                         neighbourhood a boundary or pre-crack cuts must start on the fine level"
                    ),
                ));
            }
            let chi = check_chi(m.chi.unwrap_or(DEFAULT_CHI))
                .map_err(|e| ctx.error("multigrid.chi", e))?;
            Refinement::Adaptive {
                band,
                chi,
                transfer: m.transfer.unwrap_or_default(),
            }
        }
        Physics::Static | Physics::ScalarWave => {
            return Err(ctx.error(
                "multigrid",
                "two grid levels are available for dynamics, diffusion, corrosion and \
                 nernst-planck",
            ));
        }
    };
    let coarse = match m.coarse.unwrap_or(CoarseKind::Standard) {
        CoarseKind::Standard => {
            if let Some((_, field)) = wls_fields.iter().find(|(given, _)| *given) {
                return Err(ctx.error(
                    &format!("multigrid.{field}"),
                    "belongs to a WLS coarse level: set multigrid.coarse = \"wls\" or remove it",
                ));
            }
            CoarseScheme::Standard
        }
        CoarseKind::Wls => CoarseScheme::Wls(collocation_rule(
            ctx,
            RuleFields {
                table: "multigrid",
                factor: m.collocation_factor,
                default_factor: if dim == 3 { 3 } else { 4 },
                orbits: m.collocation_orbits.as_deref(),
                weight: m.fit_weight,
            },
            dim,
            spacing,
        )?),
    };
    let coupling = m.coupling.unwrap_or_default();
    if coupling == Coupling::Conservative && physics != Physics::NernstPlanck {
        return Err(ctx.error(
            "multigrid.coupling",
            "\"conservative\" is built for the implicit nernst-planck systems; diffusion, \
             corrosion and dynamics use \"interpolated\" (the default)",
        ));
    }
    Ok(Some(MultigridSpec {
        ratio: m.ratio,
        refinement,
        coarse,
        coupling,
    }))
}

/// A length given in SI units or relative to the horizon or spacing.
pub(super) fn length(
    ctx: &ErrorContext,
    field: &str,
    m: Measure,
    spacing: f64,
    horizon: f64,
) -> Result<f64, SceneError> {
    match m {
        Measure::Si(b) => Ok(b),
        Measure::Relative(f, Relative::Horizon) => Ok(f * horizon),
        Measure::Relative(f, Relative::Spacing) => Ok(f * spacing),
        Measure::Relative(_, r) => Err(ctx.error(
            field,
            format!(
                "`{}` is not a length: give \"1.2 horizon\", \"5 dx\" or \"3 mm\"",
                r.unit()
            ),
        )),
    }
}

/// The WLS auxiliary-grid factor k_aux (spacing δ/k_aux), within 1..=64.
fn collocation_factor(ctx: &ErrorContext, field: &str, k: usize) -> Result<usize, SceneError> {
    if (1..=64).contains(&k) {
        Ok(k)
    } else {
        Err(ctx.error(field, format!("k_aux must be in 1..=64, got {k}")))
    }
}

pub(super) fn positive(ctx: &ErrorContext, field: &str, v: f64) -> Result<f64, SceneError> {
    if v > 0.0 && v.is_finite() {
        Ok(v)
    } else {
        Err(ctx.error(field, format!("must be a finite number > 0, got {v}")))
    }
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

/// The scheme and, for WLS, the auxiliary-grid factor k_aux (defaults from the papers' tables:
/// 1D C²/C⁴/C⁶ → 2/5/6 (5/11/13 nodes), 2D C²/C⁴ → 3/4 (29/49), 3D C² → 3 (123)).
fn scheme(
    p: &Preset,
    ctx: &ErrorContext,
    dim: usize,
    spacing: f64,
) -> Result<SchemeSpec, SceneError> {
    let d = &p.discretization;
    let kind = d.scheme;
    let order = match kind.wls_order() {
        Some(order) => order,
        // Ω_w of a hybrid runs WLS-2: 29 collocation nodes in 2D, 123 in 3D (δ/3).
        None if kind.is_hybrid() => {
            return Ok(SchemeSpec {
                kind,
                collocation: collocation_rule(
                    ctx,
                    RuleFields {
                        table: "hybrid",
                        factor: p.hybrid.collocation_factor,
                        default_factor: 3,
                        orbits: p.hybrid.collocation_orbits.as_deref(),
                        weight: p.hybrid.fit_weight,
                    },
                    dim,
                    spacing,
                )?,
            });
        }
        None => {
            return Ok(SchemeSpec {
                kind,
                collocation: Collocation::grid(0),
            });
        }
    };
    let default = match (dim, order) {
        (1, 2) => Some(2),
        (1, 4) => Some(5),
        (1, _) => Some(6),
        (2, 2) => Some(3),
        (2, 4) => Some(4),
        (3, 2) => Some(3),
        _ => None,
    };
    let collocation_factor = match (d.collocation_factor, default) {
        (Some(k), _) => collocation_factor(ctx, "discretization.collocation_factor", k)?,
        (None, Some(k)) => k,
        (None, None) => {
            return Err(ctx.error(
                "discretization.scheme",
                format!(
                    "\"{}\" in {dim}D has no default collocation set; give \
                     discretization.collocation_factor (k_aux), or use a lower order",
                    kind.name()
                ),
            ));
        }
    };
    Ok(SchemeSpec {
        kind,
        collocation: Collocation::grid(collocation_factor),
    })
}

fn hybrid(
    p: &Preset,
    ctx: &ErrorContext,
    kind: SchemeKind,
    spacing: f64,
    horizon: f64,
) -> Result<Option<HybridSpec>, SceneError> {
    if !kind.is_hybrid() {
        return Ok(None);
    }
    let h = &p.hybrid;
    let band = length(ctx, "hybrid.band", h.band, spacing, horizon)?;
    if band.is_nan() || band < horizon * (1.0 - 1e-9) || !band.is_finite() {
        return Err(ctx.error(
            "hybrid.band",
            format!(
                "{band:.4e} m is narrower than the horizon {horizon:.4e} m: nodes whose \
                 neighbourhood is cut by a boundary or pre-crack must use the standard scheme \
                 (give at least \"1 horizon\")"
            ),
        ));
    }
    let chi = check_chi(h.chi).map_err(|m| ctx.error("hybrid.chi", m))?;
    if h.check_every == 0 {
        return Err(ctx.error("hybrid.check_every", "must be ≥ 1 (steps between checks)"));
    }
    if let Some(k) = h.collocation_factor {
        collocation_factor(ctx, "hybrid.collocation_factor", k)?;
    }
    let interface_damping = h.interface_damping.unwrap_or(DEFAULT_INTERFACE_DAMPING);
    if !(0.0..=0.02).contains(&interface_damping) {
        return Err(ctx.error(
            "hybrid.interface_damping",
            format!("must be in [0, 0.02], got {interface_damping}"),
        ));
    }
    let interface_band = length(
        ctx,
        "hybrid.interface_band",
        h.interface_band,
        spacing,
        horizon,
    )?;
    if !(interface_band >= spacing * (1.0 - 1e-9) && interface_band <= 2.0 * horizon) {
        return Err(ctx.error(
            "hybrid.interface_band",
            format!(
                "{interface_band:.4e} m must be between one spacing ({spacing:.4e} m) and two \
                 horizons ({:.4e} m)",
                2.0 * horizon
            ),
        ));
    }
    Ok(Some(HybridSpec {
        adaptive: kind == SchemeKind::HybridAdaptive,
        band,
        chi,
        check: h.check,
        check_every: h.check_every,
        interface_damping,
        interface_band,
    }))
}

/// κ of the hybrid's interface damping (`adapt::interface`; docs/results.md, issue 14).
const DEFAULT_INTERFACE_DAMPING: f64 = 0.02;

/// The collocation fields of one preset table (`hybrid` for Ω_w, `multigrid` for a WLS coarse
/// level).
struct RuleFields<'a> {
    table: &'static str,
    factor: Option<usize>,
    default_factor: usize,
    orbits: Option<&'a [Vec<u32>]>,
    weight: Option<f64>,
}

/// A WLS collocation rule: the papers' auxiliary grid δ/k_aux (`<table>.collocation_factor`,
/// default k_aux = 3 for Ω_w: 29 collocation nodes in 2D, 123 in 3D), or with
/// `<table>.collocation_orbits` (2D only) whole orbits of lattice offsets, and the weight exponent
/// `<table>.fit_weight` (default the papers' 16).
fn collocation_rule(
    ctx: &ErrorContext,
    f: RuleFields,
    dim: usize,
    spacing: f64,
) -> Result<Collocation, SceneError> {
    let field = |name: &str| format!("{}.{name}", f.table);
    let exponent = f
        .weight
        .unwrap_or(super::collocation::PAPERS_WEIGHT_EXPONENT);
    let Some(orbits) = f.orbits else {
        let k = collocation_factor(
            ctx,
            &field("collocation_factor"),
            f.factor.unwrap_or(f.default_factor),
        )?;
        return Collocation::grid(k)
            .with_weight(exponent)
            .map_err(|m| ctx.error(&field("fit_weight"), m));
    };
    let orbits_field = field("collocation_orbits");
    if f.factor.is_some() {
        return Err(ctx.error(
            &orbits_field,
            format!(
                "give either {} (the auxiliary grid) or {orbits_field}, not both",
                field("collocation_factor")
            ),
        ));
    }
    if dim != 2 {
        return Err(ctx.error(
            &orbits_field,
            format!("orbits of lattice offsets are defined in 2D only; this scene is {dim}D"),
        ));
    }
    let fixed: Vec<[u8; 2]> = orbits
        .iter()
        .map(|o| match o.as_slice() {
            [a, b] if *a <= 64 && *b <= 64 => Ok([*a as u8, *b as u8]),
            _ => Err(ctx.error(
                &orbits_field,
                format!("each orbit is [a, b] with 0 ≤ a, b ≤ 64 (in lattice spacings), got {o:?}"),
            )),
        })
        .collect::<Result<_, _>>()?;
    // Each check names its own field: the orbits first, then the weight.
    Collocation::orbits(spacing, &fixed, super::collocation::PAPERS_WEIGHT_EXPONENT)
        .map_err(|m| ctx.error(&orbits_field, m))?
        .with_weight(exponent)
        .map_err(|m| ctx.error(&field("fit_weight"), m))
}

/// Boxes grow by the thickness of their `outside` layers.
fn extend_for_outside_layers(solid: Solid, layers: &[BoundarySpec]) -> Result<Solid, String> {
    if !layers.iter().any(|l| l.outside) {
        return Ok(solid);
    }
    let Solid::Box { mut min, mut max } = solid else {
        return Err("geometry: layers with `outside = true` need a box geometry".into());
    };
    for l in layers.iter().filter(|l| l.outside) {
        if let Some((axis, upper, t)) = l.face {
            if upper {
                max[axis] += t;
            } else {
                min[axis] -= t;
            }
        }
    }
    Ok(Solid::Box { min, max })
}

pub(super) fn point(p: &Point, dim: usize, path: &str) -> Result<Vec<f64>, String> {
    if p.len() != dim {
        return Err(format!(
            "{path}: has {} components, the scene is {dim}-dimensional",
            p.len()
        ));
    }
    Ok(si(p))
}

fn fixed<const N: usize>(p: &Point, dim: usize, path: &str) -> Result<[f64; N], String> {
    let v = point(p, dim, path)?;
    let mut out = [0.0; N];
    out.copy_from_slice(&v);
    Ok(out)
}

fn precrack(c: &Precrack, dim: usize, path: &str) -> Result<CrackGeometry, String> {
    let wrong = |kind: &str, needs: usize| {
        Err(format!(
            "{path}: a `{kind}` pre-crack needs a {needs}D scene, this one is {dim}D"
        ))
    };
    match c {
        Precrack::Point { at } if dim == 1 => Ok(CrackGeometry::Point(at.si())),
        Precrack::Point { .. } => wrong("point", 1),
        Precrack::Segment { from, to, ends } if dim == 2 => Ok(CrackGeometry::Segment(
            fixed(from, dim, &format!("{path}.segment.from"))?,
            fixed(to, dim, &format!("{path}.segment.to"))?,
            *ends,
        )),
        Precrack::Segment { .. } => wrong("segment", 2),
        Precrack::Patch {
            origin,
            edge_a,
            edge_b,
        } if dim == 3 => Ok(CrackGeometry::Patch {
            origin: fixed(origin, dim, &format!("{path}.patch.origin"))?,
            edge_a: fixed(edge_a, dim, &format!("{path}.patch.edge_a"))?,
            edge_b: fixed(edge_b, dim, &format!("{path}.patch.edge_b"))?,
        }),
        Precrack::Patch { .. } => wrong("patch", 3),
    }
}

pub(crate) fn axis_index(name: &str, dim: usize, path: &str) -> Result<usize, String> {
    let i = match name {
        "x" => 0,
        "y" => 1,
        "z" => 2,
        _ => {
            return Err(format!(
                "{path}: must be \"x\", \"y\" or \"z\", got \"{name}\""
            ));
        }
    };
    if i >= dim {
        return Err(format!("{path}: axis \"{name}\" does not exist in {dim}D"));
    }
    Ok(i)
}

fn boundary_layer(
    b: &BoundaryLayer,
    dim: usize,
    spacing: f64,
    horizon: f64,
    physics: Physics,
    path: &str,
) -> Result<BoundarySpec, String> {
    let mechanical = b.velocity.is_some() || b.displacement.is_some() || b.body_force.is_some();
    if b.hold_reference && mechanical {
        return Err(format!(
            "{path}.hold_reference: a layer holds the reference solution or a velocity, \
             displacement or body force, not both"
        ));
    }
    if b.hold_reference && physics == Physics::Dynamics {
        return Err(format!(
            "{path}.hold_reference: only static and diffusion scenes hold a reference field"
        ));
    }
    if physics != Physics::Dynamics && mechanical {
        return Err(format!(
            "{path}.velocity: physics = \"{physics:?}\" holds fields with `hold_reference = true`"
        ));
    }
    if let Some(v) = b.hold_value {
        if b.hold_reference || mechanical {
            return Err(format!(
                "{path}.hold_value: a layer holds one thing: a value, the reference solution, \
                 or a velocity, displacement or body force"
            ));
        }
        if !matches!(
            physics,
            Physics::Diffusion | Physics::Corrosion | Physics::ScalarWave | Physics::NernstPlanck
        ) {
            return Err(format!(
                "{path}.hold_value: only diffusion, corrosion and scalar-wave scenes hold a \
                 field value"
            ));
        }
        if !v.si().is_finite() {
            return Err(format!("{path}.hold_value: must be finite, got {}", v.si()));
        }
    }
    let (condition, value) = match (&b.velocity, &b.displacement, &b.body_force) {
        _ if b.hold_reference => (Condition::Reference, vec![0.0; dim]),
        _ if b.hold_value.is_some() => {
            (Condition::Value, vec![b.hold_value.map_or(0.0, |v| v.si())])
        }
        (Some(v), None, None) => (
            Condition::Velocity,
            point(v, dim, &format!("{path}.velocity"))?,
        ),
        (None, Some(u), None) => (
            Condition::Displacement,
            point(u, dim, &format!("{path}.displacement"))?,
        ),
        (None, None, Some(f)) => (
            Condition::BodyForce,
            point(f, dim, &format!("{path}.body_force"))?,
        ),
        _ => {
            return Err(format!(
                "{path}.velocity: give exactly one of `velocity`, `displacement`, `body_force`, \
                 `hold_reference`"
            ));
        }
    };
    let axes = match &b.axes {
        None => (0..dim).collect(),
        Some(s) => s
            .chars()
            .map(|c| axis_index(&c.to_string(), dim, &format!("{path}.axes")))
            .collect::<Result<Vec<_>, _>>()?,
    };
    let face = match (&b.face, b.thickness) {
        (Some(f), Some(t)) => {
            let (axis, side) = f.split_at(1.min(f.len()));
            let upper = match side {
                "+" => true,
                "-" => false,
                _ => {
                    return Err(format!(
                        "{path}.face: must be like \"x-\" or \"y+\", got \"{f}\""
                    ));
                }
            };
            let t = match t {
                Measure::Si(t) => t,
                Measure::Relative(f, Relative::Spacing) => f * spacing,
                Measure::Relative(f, Relative::Horizon) => f * horizon,
                Measure::Relative(_, r) => {
                    return Err(format!(
                        "{path}.thickness: `{}` is not a length: give \"2 mm\", \"3 dx\" or \"1 horizon\"",
                        r.unit()
                    ));
                }
            };
            if !(t > 0.0 && t.is_finite()) {
                return Err(format!("{path}.thickness: must be > 0, got {t}"));
            }
            Some((axis_index(axis, dim, &format!("{path}.face"))?, upper, t))
        }
        (None, None) => None,
        (Some(_), None) => return Err(format!("{path}.thickness: a `face` needs a `thickness`")),
        (None, Some(_)) => return Err(format!("{path}.face: a `thickness` needs a `face`")),
    };
    let region = b
        .region
        .as_ref()
        .map(|r| r.to_solid(dim, &format!("{path}.region")))
        .transpose()?;
    if b.outside && face.is_none() {
        return Err(format!("{path}.outside: needs a `face` and a `thickness`"));
    }
    if region.is_none() && face.is_none() {
        return Err(format!(
            "{path}.region: give a `region`, a `face` + `thickness`, or both"
        ));
    }
    Ok(BoundarySpec {
        name: if b.name.is_empty() {
            path.to_string()
        } else {
            b.name.clone()
        },
        region,
        face,
        condition,
        value,
        axes,
        outside: b.outside,
    })
}

fn velocity_field(v: &VelocityField, dim: usize, path: &str) -> Result<InitialVelocity, String> {
    Ok(match v {
        VelocityField::Uniform { value } => {
            InitialVelocity::Uniform(point(value, dim, &format!("{path}.uniform.value"))?)
        }
        VelocityField::Ramp {
            component,
            axis,
            from,
            to,
        } => InitialVelocity::Ramp {
            component: axis_index(component, dim, &format!("{path}.ramp.component"))?,
            axis: axis_index(axis, dim, &format!("{path}.ramp.axis"))?,
            from: from.si(),
            to: to.si(),
        },
        VelocityField::Sine {
            component,
            axis,
            amplitude,
            modes,
        } => InitialVelocity::Sine {
            component: axis_index(component, dim, &format!("{path}.sine.component"))?,
            axis: axis_index(axis, dim, &format!("{path}.sine.axis"))?,
            amplitude: amplitude.si(),
            modes: *modes,
        },
    })
}

fn time_spec(t: &super::schema::TimeSpec, ctx: &ErrorContext) -> Result<TimeSpec, SceneError> {
    let adr = t.integrator == Some(super::schema::IntegratorKind::Adr);
    let dt = match (t.dt, adr) {
        (Some(dt), _) => dt,
        // Dynamic relaxation iterates with a unit pseudo step.
        (None, true) => Measure::Si(1.0),
        (None, false) => {
            return Err(ctx.error(
                "time.dt",
                "give the time step, e.g. \"2 ns\" or \"0.7 stable\"",
            ));
        }
    };
    let step = match dt {
        Measure::Si(dt) => StepSize::Absolute(positive(ctx, "time.dt", dt)?),
        Measure::Relative(f, Relative::StableStep) => {
            StepSize::FractionOfStable(positive(ctx, "time.dt", f)?)
        }
        Measure::Relative(_, r) => {
            return Err(ctx.error(
                "time.dt",
                format!(
                    "`{}` is not a time step: give e.g. \"2 ns\" or \"0.5 stable\"",
                    r.unit()
                ),
            ));
        }
    };
    if let StepSize::FractionOfStable(f) = step
        && f > 1.0
        && !t.allow_unstable
    {
        return Err(ctx.error(
            "time.dt",
            format!(
                "{f} stable is above the stable bound (3.8); use a value ≤ 1 or set time.allow_unstable = true"
            ),
        ));
    }
    let duration = match t.end {
        Measure::Si(end) => Duration::End(positive(ctx, "time.end", end)?),
        Measure::Relative(n, Relative::Steps) if n >= 1.0 && n.fract() == 0.0 => {
            Duration::Steps(n as u64)
        }
        Measure::Relative(n, Relative::Steps) => {
            return Err(ctx.error("time.end", format!("{n} steps: must be a whole number ≥ 1")));
        }
        Measure::Relative(_, r) => {
            return Err(ctx.error(
                "time.end",
                format!(
                    "`{}` is not a duration: give e.g. \"87 us\" or \"2000 steps\"",
                    r.unit()
                ),
            ));
        }
    };
    Ok(TimeSpec {
        step,
        duration,
        allow_unstable: t.allow_unstable,
    })
}
