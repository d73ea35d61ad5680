//! Where a scene holds, cuts and starts its fields: `[[boundary]]` layers (and the box they
//! grow outside the body), `[[precracks]]`, and `[initial]` velocities and concentrations.

use super::checks::{axis_index, each, fixed, point};
use super::error::{ErrorContext, SceneError};
use super::geometry::Solid;
use super::schema::{BoundaryLayer, Physics, Precrack, Preset, VelocityField};
use super::spec::{BoundarySpec, Condition, CrackGeometry, InitialVelocity};
use super::units::{Measure, Relative};

/// Boxes grow by the thickness of their `outside` layers.
pub(super) fn extend_for_outside_layers(
    solid: Solid,
    layers: &[BoundarySpec],
) -> Result<Solid, String> {
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

pub(super) fn precrack(c: &Precrack, dim: usize, path: &str) -> Result<CrackGeometry, String> {
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

pub(super) fn boundary_layer(
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

pub(super) fn velocity_field(
    v: &VelocityField,
    dim: usize,
    path: &str,
) -> Result<InitialVelocity, String> {
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

/// `[[initial.concentration]]`: regions and their values (diffusion and corrosion scenes).
pub(super) fn concentrations(
    p: &Preset,
    ctx: &ErrorContext,
    dim: usize,
) -> Result<Vec<(Solid, f64)>, SceneError> {
    let initial_concentration = each(
        ctx,
        "initial.concentration",
        &p.initial.concentration,
        |c, path| {
            let value = c.value.si();
            if !value.is_finite() {
                return Err(format!("{path}.value: must be finite, got {value}"));
            }
            Ok((c.region.to_solid(dim, &format!("{path}.region"))?, value))
        },
    )?;
    if matches!(p.physics, Physics::Dynamics | Physics::NernstPlanck)
        && !initial_concentration.is_empty()
    {
        return Err(ctx.error(
            "initial.concentration",
            "concentrations need physics = \"diffusion\" or \"corrosion\" (NNPP species \
             take theirs from [[nernst_planck.species]])",
        ));
    }
    Ok(initial_concentration)
}
