//! The scheme of a scene and what it needs: `discretization.scheme` (and WLS collocation
//! rules), `[hybrid]`, `[multigrid]`, and which physics each scheme runs.

use super::checks::{DEFAULT_CHI, check_chi, length};
use super::collocation::{Collocation, PAPERS_WEIGHT_EXPONENT};
use super::error::{ErrorContext, SceneError};
use super::schema::{CoarseKind, Coupling, Physics, Preset, SchemeKind};
use super::spec::{CoarseScheme, HybridSpec, MultigridSpec, Refinement, SchemeSpec};

/// The scheme and, for WLS, the auxiliary-grid factor k_aux (defaults from the papers' tables:
/// 1D C²/C⁴/C⁶ → 2/5/6 (5/11/13 nodes), 2D C²/C⁴ → 3/4 (29/49), 3D C² → 3 (123)).
pub(super) fn scheme(
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

pub(super) fn hybrid(
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

/// κ of the hybrid's interface damping (`adapt::interface`; docs/validation.md).
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
    let exponent = f.weight.unwrap_or(PAPERS_WEIGHT_EXPONENT);
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
    Collocation::orbits(spacing, &fixed, PAPERS_WEIGHT_EXPONENT)
        .map_err(|m| ctx.error(&orbits_field, m))?
        .with_weight(exponent)
        .map_err(|m| ctx.error(&field("fit_weight"), m))
}

/// Which physics each scheme runs: nernst-planck the standard scheme without a layer,
/// corrosion the standard scheme or "hybrid-fixed" (with Ω_s a horizon beyond the solid), the
/// hybrids dynamics (and corrosion), WLS static and diffusion scenes.
pub(super) fn check_scheme_physics(
    p: &Preset,
    ctx: &ErrorContext,
    kind: SchemeKind,
    hybrid: Option<&HybridSpec>,
    horizon: f64,
) -> Result<(), SceneError> {
    let physics = p.physics;
    if physics == Physics::NernstPlanck && (kind != SchemeKind::Standard || p.absorbing.is_some()) {
        return Err(ctx.error(
            "discretization.scheme",
            "physics = \"nernst-planck\" runs the standard scheme (on one grid or a \
             multi-grid with a predefined fine region), without an absorbing layer",
        ));
    }
    if physics == Physics::Corrosion
        && !matches!(kind, SchemeKind::Standard | SchemeKind::HybridFixed)
    {
        return Err(ctx.error(
            "discretization.scheme",
            format!(
                "\"{}\": corrosion's bond classes need the standard scheme (or \"hybrid-fixed\", standard where the phases meet)",
                kind.name()
            ),
        ));
    }
    let fixed_corrosion = physics == Physics::Corrosion && kind == SchemeKind::HybridFixed;
    if physics != Physics::Dynamics && kind.is_hybrid() && !fixed_corrosion {
        return Err(ctx.error(
            "discretization.scheme",
            format!(
                "\"{}\" is available for dynamics (and \"hybrid-fixed\" for corrosion)",
                kind.name()
            ),
        ));
    }
    if let Some(h) = hybrid.filter(|_| fixed_corrosion)
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
    if physics == Physics::Dynamics && kind.wls_order().is_some() {
        return Err(ctx.error(
            "discretization.scheme",
            format!(
                "\"{}\" is available for physics = \"static\" and \"diffusion\"; dynamics uses \
                 \"standard\", \"hybrid-fixed\" or \"hybrid-adaptive\"",
                kind.name()
            ),
        ));
    }
    Ok(())
}

/// The two levels of a multi-grid scene: a whole grid ratio in 2..=16, the standard scheme on
/// both levels, an unperturbed lattice (the fine cells split the coarse ones). Diffusion and
/// corrosion take a predefined `region`; dynamics the multi-adaptive switch from a `band`.
pub(super) fn multigrid(
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

/// The WLS auxiliary-grid factor k_aux (spacing δ/k_aux), within 1..=64.
fn collocation_factor(ctx: &ErrorContext, field: &str, k: usize) -> Result<usize, SceneError> {
    if (1..=64).contains(&k) {
        Ok(k)
    } else {
        Err(ctx.error(field, format!("k_aux must be in 1..=64, got {k}")))
    }
}
