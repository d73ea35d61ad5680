//! `[absorbing]` and the initial pulses → their scene specs, with the defaults of thesis
//! §4.1.3, §4.2.3 per physics (seed-thesis-ch4-5 §1.3).

use super::checks::{in_range, length, point, positive};
use super::error::{ErrorContext, SceneError};
use super::geometry::Solid;
use super::schema::{
    AbsorbingMethod, AbsorbingTable, Dispersion, Physics, Preset, PulseDirectionTable,
};
use super::spec::{AbsorbingSpec, Pulse, PulseDirection};

/// `[[initial.pulse]]`: Gaussians of a scalar field, or of the displacement (dynamics, with a
/// `direction`).
pub(super) fn pulses(
    p: &Preset,
    ctx: &ErrorContext,
    dim: usize,
    physics: Physics,
) -> Result<Vec<Pulse>, SceneError> {
    let scalar = match physics {
        Physics::Diffusion | Physics::Corrosion | Physics::ScalarWave => true,
        Physics::Dynamics => false,
        Physics::Static | Physics::NernstPlanck if p.initial.pulse.is_empty() => true,
        Physics::Static | Physics::NernstPlanck => {
            return Err(ctx.error(
                "initial.pulse",
                "pulses set an initial field: physics = \"diffusion\", \"corrosion\", \
                 \"scalar-wave\" or \"dynamics\"",
            ));
        }
    };
    p.initial
        .pulse
        .iter()
        .enumerate()
        .map(|(i, q)| {
            let path = format!("initial.pulse[{i}]");
            let center = point(&q.center, dim, &format!("{path}.center"))
                .map_err(|m| ctx.from_path_message(&m))?;
            let amplitude = q.amplitude.si();
            if !amplitude.is_finite() {
                return Err(ctx.error(
                    &format!("{path}.amplitude"),
                    format!("must be finite, got {amplitude}"),
                ));
            }
            let decay = positive(ctx, &format!("{path}.decay"), q.decay.si())?;
            let radius = match q.radius {
                Some(r) => positive(ctx, &format!("{path}.radius"), r.si())?,
                None => f64::INFINITY,
            };
            let field = format!("{path}.direction");
            let direction = match (&q.direction, scalar) {
                (None, true) => None,
                (Some(_), true) => {
                    return Err(ctx.error(
                        &field,
                        "a scalar field's pulse has no direction (only dynamics displaces)",
                    ));
                }
                (None, false) => {
                    return Err(ctx.error(
                        &field,
                        "a displacement pulse needs a direction: \"radial\" or a vector",
                    ));
                }
                (Some(PulseDirectionTable::Named(n)), false) if n == "radial" => {
                    Some(PulseDirection::Radial)
                }
                (Some(PulseDirectionTable::Named(n)), false) => {
                    return Err(ctx.error(
                        &field,
                        format!("must be \"radial\" or a vector of {dim} numbers, got \"{n}\""),
                    ));
                }
                (Some(PulseDirectionTable::Vector(v)), false) => {
                    let v = point(v, dim, &field).map_err(|m| ctx.from_path_message(&m))?;
                    let norm = v.iter().map(|x| x * x).sum::<f64>().sqrt();
                    if !(norm > 0.0 && norm.is_finite()) {
                        return Err(ctx.error(&field, "must be a non-zero finite vector"));
                    }
                    Some(PulseDirection::Fixed(v.iter().map(|x| x / norm).collect()))
                }
            };
            Ok(Pulse {
                center,
                amplitude,
                decay,
                radius,
                direction,
            })
        })
        .collect()
}

/// `[absorbing]` with the defaults of its physics: diffusion fits real local modes on one
/// level with a cloud of radius δ/2 all around the node; waves fit outgoing modes of the
/// discrete dispersion relation on two levels, with a cloud of radius δ behind the node.
pub(super) fn absorbing(
    table: &AbsorbingTable,
    ctx: &ErrorContext,
    scene: (usize, Physics, &Solid),
    spacing: f64,
    horizon: f64,
) -> Result<AbsorbingSpec, SceneError> {
    let (dim, physics, solid) = scene;
    let (method, wave, bond) = layer_kind(table, ctx, dim, physics, solid)?;
    let width = match table.width {
        Some(m) => positive(
            ctx,
            "absorbing.width",
            length(ctx, "absorbing.width", m, spacing, horizon)?,
        )?,
        None => horizon,
    };
    let cloud_radius = match table.cloud_radius {
        Some(m) => positive(
            ctx,
            "absorbing.cloud_radius",
            length(ctx, "absorbing.cloud_radius", m, spacing, horizon)?,
        )?,
        None if wave => horizon,
        None => 0.5 * horizon,
    };
    if cloud_radius > horizon * (1.0 + 1e-9) {
        return Err(ctx.error(
            "absorbing.cloud_radius",
            format!(
                "d∞ = {cloud_radius:.4e} m must be within the horizon {horizon:.4e} m (clouds are \
                 taken from the families)"
            ),
        ));
    }
    let count = |field: &str, v: Option<usize>, default: usize, max: usize| {
        let v = v.unwrap_or(default);
        if (1..=max).contains(&v) {
            Ok(v)
        } else {
            Err(ctx.error(field, format!("must be in 1..={max}, got {v}")))
        }
    };
    // 2D diffusion: n_b = 55 = 5 × 11 (thesis §4.1.5 [inferred]); waves: ≥ 10 subdivisions.
    let wave_numbers = count(
        "absorbing.wave_numbers",
        table.wave_numbers,
        if dim == 1 || wave { 20 } else { 5 },
        200,
    )?;
    let directions = count(
        "absorbing.directions",
        table.directions,
        if dim == 1 { 1 } else { 11 },
        90,
    )?;
    if dim == 1 && directions != 1 {
        return Err(ctx.error(
            "absorbing.directions",
            format!("a 1D layer has one direction (the normal), got {directions}"),
        ));
    }
    // Δk = 1 (thesis §4.1.4 [note's check], §4.2.4–4.2.6).
    let max_wave_number = match table.max_wave_number {
        Some(k) => positive(ctx, "absorbing.max_wave_number", k)?,
        None => 1.0,
    };
    let nyquist = std::f64::consts::PI / spacing;
    if wave && max_wave_number > nyquist * (1.0 + 1e-12) {
        return Err(ctx.error(
            "absorbing.max_wave_number",
            format!(
                "Δk must be in (0, π/Δx] = (0, {nyquist:.4e}] 1/m (4.83), got {max_wave_number}"
            ),
        ));
    }
    // Bond-based: Δφ ≤ π/8 (thesis §4.3.4, after [95]).
    let spread_degrees = table.spread_degrees.unwrap_or(match (dim, bond) {
        (1, _) => 0.0,
        (_, true) => 22.5,
        _ => 45.0,
    });
    let spread = in_range(
        ctx,
        "absorbing.spread_degrees",
        spread_degrees,
        (0.0..90.0).contains(&spread_degrees),
        "[0, 90) degrees",
    )?
    .to_radians();
    let knobs = knobs(table, ctx, bond, spacing, horizon)?;
    Ok(AbsorbingSpec {
        method,
        damping: knobs.damping,
        damping_band: knobs.damping_band,
        width,
        cloud_radius,
        wave_numbers,
        directions,
        max_wave_number,
        spread,
        wave_number_set: table.wave_number_set,
        dispersion: table.dispersion.unwrap_or(if wave {
            Dispersion::Discrete
        } else {
            Dispersion::Local
        }),
        cutoff: knobs.cutoff,
        tikhonov: knobs.tikhonov,
        cone: table.cone.unwrap_or(wave),
        max_norm: knobs.max_norm,
        max_condition: knobs.max_condition,
        thinning: table.thinning,
        filter: knobs.filter,
        rest_modes: table.rest_modes,
    })
}

/// Which layer the physics takes, `(method, wave, bond)`: waves fit outgoing modes (bond-based
/// PD in 2D), diffusion real local modes; the truncation is one box or one sphere (or the base
/// of a difference).
fn layer_kind(
    table: &AbsorbingTable,
    ctx: &ErrorContext,
    dim: usize,
    physics: Physics,
    solid: &Solid,
) -> Result<(AbsorbingMethod, bool, bool), SceneError> {
    let (wave, bond) = match physics {
        Physics::ScalarWave => (true, false),
        Physics::Dynamics if dim == 2 => (true, true),
        Physics::Diffusion | Physics::Corrosion | Physics::NernstPlanck => (false, false),
        Physics::Dynamics => {
            return Err(ctx.error(
                "absorbing",
                format!("bond-based absorbing layers are implemented in 2D; this scene is {dim}D"),
            ));
        }
        Physics::Static => {
            return Err(ctx.error(
                "absorbing",
                "absorbing layers are available for physics = \"diffusion\", \"corrosion\", \
                 \"scalar-wave\" and \"dynamics\" (2D)",
            ));
        }
    };
    let method = table.method.unwrap_or_default();
    if method == AbsorbingMethod::FirstOrder && !wave {
        return Err(ctx.error(
            "absorbing.method",
            "the first-order boundary (4.75) is a wave condition: physics = \"scalar-wave\" or \
             \"dynamics\"",
        ));
    }
    if dim > 2 {
        return Err(ctx.error(
            "absorbing",
            format!("absorbing layers are implemented in 1D and 2D; this scene is {dim}D"),
        ));
    }
    if solid.truncation_surface().is_none() {
        return Err(ctx.error(
            "geometry",
            "an absorbing layer needs the truncation to be one box or one sphere (disc), or a \
             difference whose base is one (what it cuts away stays a free surface)",
        ));
    }
    Ok((method, wave, bond))
}

/// The pseudo-inverse's and the layer's damping knobs.
struct Knobs {
    cutoff: f64,
    tikhonov: f64,
    max_norm: f64,
    max_condition: f64,
    filter: f64,
    damping: f64,
    damping_band: f64,
}

fn knobs(
    table: &AbsorbingTable,
    ctx: &ErrorContext,
    bond: bool,
    spacing: f64,
    horizon: f64,
) -> Result<Knobs, SceneError> {
    let cutoff = table.cutoff.unwrap_or(1e-10);
    let cutoff = in_range(
        ctx,
        "absorbing.cutoff",
        cutoff,
        (0.0..1.0).contains(&cutoff),
        "[0, 1)",
    )?;
    let tikhonov = table.tikhonov.unwrap_or(0.0);
    let tikhonov = in_range(
        ctx,
        "absorbing.tikhonov",
        tikhonov,
        (0.0..1.0).contains(&tikhonov),
        "[0, 1)",
    )?;
    // ‖V‖ ≤ 2 for scalar waves, ≤ 1 for bond-based PD (§4.2.3, §4.3.4; erratum 8: a setting).
    let max_norm = positive(
        ctx,
        "absorbing.max_norm",
        table.max_norm.unwrap_or(if bond { 1.0 } else { 2.0 }),
    )?;
    let max_condition = table.max_condition.unwrap_or(1e12);
    let max_condition = in_range(
        ctx,
        "absorbing.max_condition",
        max_condition,
        max_condition > 1.0,
        "(1, ∞)",
    )?;
    let filter = table.filter.unwrap_or(0.0);
    let filter = in_range(
        ctx,
        "absorbing.filter",
        filter,
        (0.0..=0.5).contains(&filter),
        "[0, 0.5]",
    )?;
    // κ ≤ 0.02: the explicit damping update's rate is clamped at 90 % of its limit beyond
    // (`adapt::interface`).
    let damping = table.damping.unwrap_or(0.0);
    let damping = in_range(
        ctx,
        "absorbing.damping",
        damping,
        (0.0..=0.02).contains(&damping),
        "[0, 0.02]",
    )?;
    let damping_band = match table.damping_band {
        Some(m) => positive(
            ctx,
            "absorbing.damping_band",
            length(ctx, "absorbing.damping_band", m, spacing, horizon)?,
        )?,
        None => horizon,
    };
    Ok(Knobs {
        cutoff,
        tikhonov,
        max_norm,
        max_condition,
        filter,
        damping,
        damping_band,
    })
}
