//! Preset → Scene: the tables checked in a fixed order (the first problem is the one reported),
//! each by the module of its concern with the shared checks of `checks`, and the checks across
//! tables here (which physics a pre-crack, a layer or a reference needs).

use super::absorbing::{absorbing, pulses};
use super::boundary::{
    boundary_layer, concentrations, extend_for_outside_layers, precrack, velocity_field,
};
use super::checks::{each, positive};
use super::error::{ErrorContext, SceneError};
use super::geometry::{Solid, si};
use super::materials::laws;
use super::measures::measures;
use super::nernst_planck::{NernstPlanckSpec, nernst_planck};
use super::reference::Reference;
use super::schema::{Perturbation, Physics, Preset, SchemeKind};
use super::schemes::{check_scheme_physics, hybrid, multigrid, scheme};
use super::spec::{AbsorbingSpec, Condition, HybridSpec, MultigridSpec};
use super::state_based::{StateBasedSpec, state_based};
use super::time::time;
use super::units::{Measure, Relative};
use super::validated::Scene;

/// Directed bonds a scene may have (≈ 13 bytes each while the families are built: 16 GB).
const MAX_BONDS: f64 = 1.2e9;

/// The lattice a preset asks for, in SI units.
struct Lattice {
    spacing: f64,
    horizon: f64,
    perturbation: [f64; 2],
    origin: Option<Vec<f64>>,
}

/// The models and layers that hang on the scheme: checked together because each needs the
/// others' choices.
struct Models {
    state_based: Option<StateBasedSpec>,
    hybrid: Option<HybridSpec>,
    nernst_planck: Option<NernstPlanckSpec>,
    multigrid: Option<MultigridSpec>,
    absorbing: Option<AbsorbingSpec>,
}

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
    let (solid, lattice) = lattice(p, ctx, dim)?;
    let (spacing, horizon) = (lattice.spacing, lattice.horizon);
    let physics = p.physics;
    let scheme = scheme(p, ctx, dim, spacing)?;
    let boundary = each(ctx, "boundary", &p.boundary, |b, path| {
        boundary_layer(b, dim, spacing, horizon, physics, path)
    })?;
    let solid =
        extend_for_outside_layers(solid, &boundary).map_err(|m| ctx.from_path_message(&m))?;
    size_limits(ctx, &solid, dim, spacing, horizon)?;
    let laws = laws(p, ctx, dim, horizon)?;
    let models = models(p, ctx, &solid, &lattice, scheme.kind, laws.young())?;
    let initial_pulses = pulses(p, ctx, dim, physics)?;
    let reference = p
        .reference
        .as_ref()
        .map(|r| {
            Reference::from_spec(
                r,
                dim,
                physics,
                laws.material.as_ref(),
                laws.diffusion.as_ref(),
            )
        })
        .transpose()
        .map_err(|m| ctx.from_path_message(&m))?;
    let manufactured = models
        .nernst_planck
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
    let precracks = each(ctx, "precracks", &p.precracks, |c, path| {
        precrack(c, dim, path)
    })?;
    let initial_concentration = concentrations(p, ctx, dim)?;
    let initial_velocity = each(ctx, "initial.velocity", &p.initial.velocity, |v, path| {
        velocity_field(v, dim, path)
    })?;
    let time = time(p, ctx)?;
    if p.output.every == Some(0) {
        return Err(ctx.error("output.every", "must be ≥ 1 (steps between frames)"));
    }
    let measures = measures(p, ctx, dim)?;
    let d = &p.discretization;
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
        perturbation: lattice.perturbation,
        origin: lattice.origin,
        physics,
        scheme,
        reference,
        diffusion: laws.diffusion,
        hybrid: models.hybrid,
        multigrid: models.multigrid,
        absorbing: models.absorbing,
        state_based: models.state_based,
        wave: laws.wave,
        nernst_planck: models.nernst_planck,
        initial_pulses,
        seed: d.seed,
        family_radius: d.family_radius,
        volume_correction: d.volume_correction,
        material: laws.material,
        precracks,
        boundary,
        initial_velocity,
        initial_concentration,
        time,
        output_every: p.output.every,
        crack_angles: measures.crack_angles,
        crack_lengths: measures.crack_lengths,
        energy_circles: measures.energy_circles,
        probes: measures.probes,
        damage_counts: measures.damage_counts,
    })
}

/// The body and the lattice: `geometry` and `[discretization]`'s spacing, horizon,
/// perturbation and origin.
fn lattice(p: &Preset, ctx: &ErrorContext, dim: usize) -> Result<(Solid, Lattice), SceneError> {
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
    let lattice = Lattice {
        spacing,
        horizon,
        perturbation,
        origin,
    };
    Ok((solid, lattice))
}

/// The lattice's nodes and bonds, estimated from the body's bounds, within what a run can hold.
fn size_limits(
    ctx: &ErrorContext,
    solid: &Solid,
    dim: usize,
    spacing: f64,
    horizon: f64,
) -> Result<(), SceneError> {
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
    Ok(())
}

/// The state-based material, the hybrid, the NNPP system, the two grid levels and the
/// absorbing layer, each checked against the scheme and physics.
fn models(
    p: &Preset,
    ctx: &ErrorContext,
    solid: &Solid,
    lattice: &Lattice,
    kind: SchemeKind,
    young: Option<f64>,
) -> Result<Models, SceneError> {
    let (dim, physics) = (p.dimension, p.physics);
    let (spacing, horizon) = (lattice.spacing, lattice.horizon);
    let state_based = state_based(p, ctx, dim, young)?;
    if state_based.is_some() && kind != SchemeKind::Standard {
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
    let hybrid = hybrid(p, ctx, kind, spacing, horizon)?;
    let nernst_planck = nernst_planck(p, ctx, dim, horizon)?;
    check_scheme_physics(p, ctx, kind, hybrid.as_ref(), horizon)?;
    let multigrid = multigrid(
        p,
        ctx,
        dim,
        physics,
        kind,
        lattice.perturbation,
        [spacing, horizon],
    )?;
    if physics == Physics::ScalarWave && (kind != SchemeKind::Standard || multigrid.is_some()) {
        return Err(ctx.error(
            "discretization.scheme",
            "a scalar wave runs on the standard scheme, on one grid",
        ));
    }
    let absorbing = p
        .absorbing
        .as_ref()
        .map(|t| absorbing(t, ctx, (dim, physics, solid), spacing, horizon))
        .transpose()?;
    if absorbing.is_some() && (multigrid.is_some() || kind != SchemeKind::Standard) {
        return Err(ctx.error(
            "absorbing",
            "an absorbing layer runs with the standard scheme on one grid (no multigrid, hybrid \
             or WLS)",
        ));
    }
    Ok(Models {
        state_based,
        hybrid,
        nernst_planck,
        multigrid,
        absorbing,
    })
}
