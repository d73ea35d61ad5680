//! `[absorbing]`, the scalar wave's material and the initial pulses → their scene specs, with
//! the defaults of thesis §4.1.3, §4.2.3 per physics (seed-thesis-ch4-5 §1.3).

use super::error::{ErrorContext, SceneError};
use super::schema::{AbsorbingTable, Physics, Preset, PulseDirectionTable};
use super::validate::{length, point, positive};
use super::*;
use crate::model::diffusion::second_moment;

/// The scalar wave: χ, d, and its kernel c_s ω / r^p as a [`DiffusionSpec`] (the operator is the
/// diffusion one with κ = c_s).
pub(super) fn wave(
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

fn in_range(
    ctx: &ErrorContext,
    field: &str,
    v: f64,
    ok: bool,
    range: &str,
) -> Result<f64, SceneError> {
    if ok && v.is_finite() {
        Ok(v)
    } else {
        Err(ctx.error(field, format!("must be in {range}, got {v}")))
    }
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
    if !matches!(solid, Solid::Box { .. } | Solid::Sphere { .. }) {
        return Err(ctx.error(
            "geometry",
            "an absorbing layer needs the truncation to be one box or one sphere (disc)",
        ));
    }
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
    Ok(AbsorbingSpec {
        method,
        damping,
        damping_band,
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
        cutoff,
        tikhonov,
        cone: table.cone.unwrap_or(wave),
        max_norm,
        max_condition,
        thinning: table.thinning,
        filter,
        rest_modes: table.rest_modes,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

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
