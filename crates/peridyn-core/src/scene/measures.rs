//! `[metrics]`: what a run measures besides its fields — crack angles and lengths, probes,
//! energy circles and damage counts (the crack-opening metric belongs to the state-based scenes).

use super::checks::{each, point};
use super::error::{ErrorContext, SceneError};
use super::geometry::{Point, Shape, Solid};
use super::schema::Preset;
use super::spec::{CrackAngleSpec, CrackLengthSpec, DamageCountSpec, EnergyCircleSpec};

/// The checked `[metrics]` tables.
pub(super) struct Measures {
    pub crack_angles: Vec<CrackAngleSpec>,
    pub crack_lengths: Vec<CrackLengthSpec>,
    pub energy_circles: Vec<EnergyCircleSpec>,
    /// Scalar-field probes: (name, point).
    pub probes: Vec<(String, Vec<f64>)>,
    pub damage_counts: Vec<DamageCountSpec>,
}

pub(super) fn measures(p: &Preset, ctx: &ErrorContext, dim: usize) -> Result<Measures, SceneError> {
    let m = &p.metrics;
    let crack_angles = each(ctx, "metrics.crack_angle", &m.crack_angle, |c, path| {
        let (tip, threshold, region) = crack_search((&c.tip, c.threshold, &c.region), dim, path)?;
        let direction = point(&c.direction, dim, &format!("{path}.direction"))?;
        if direction.iter().all(|v| *v == 0.0) {
            return Err(format!("{path}.direction: must not be zero"));
        }
        Ok(CrackAngleSpec {
            name: c.name.clone(),
            tip,
            direction,
            threshold,
            region,
        })
    })?;
    let crack_lengths = each(ctx, "metrics.crack_length", &m.crack_length, |c, path| {
        let (tip, threshold, region) = crack_search((&c.tip, c.threshold, &c.region), dim, path)?;
        Ok(CrackLengthSpec {
            name: c.name.clone(),
            tip,
            threshold,
            region,
        })
    })?;
    let probes = each(ctx, "metrics.probe", &m.probe, |q, path| {
        Ok((
            q.name.clone(),
            point(&q.point, dim, &format!("{path}.point"))?,
        ))
    })?;
    let energy_circles = each(ctx, "metrics.energy_circle", &m.energy_circle, |c, path| {
        let radius = c.radius.si();
        if !(radius > 0.0 && radius.is_finite()) {
            return Err(format!("{path}.radius: must be a length > 0, got {radius}"));
        }
        Ok(EnergyCircleSpec {
            name: c.name.clone(),
            center: point(&c.center, dim, &format!("{path}.center"))?,
            radius,
        })
    })?;
    let damage_counts = each(ctx, "metrics.damage_count", &m.damage_count, |c, path| {
        if !(0.0..=1.0).contains(&c.threshold) {
            return Err(format!("{path}.threshold: must be in [0, 1]"));
        }
        Ok(DamageCountSpec {
            name: c.name.clone(),
            region: c.region.to_solid(dim, &format!("{path}.region"))?,
            threshold: c.threshold,
        })
    })?;
    Ok(Measures {
        crack_angles,
        crack_lengths,
        energy_circles,
        probes,
        damage_counts,
    })
}

/// A crack search's tip, damage threshold (in [0, 1]) and region, checked.
fn crack_search(
    (tip, threshold, region): (&Point, f64, &Shape),
    dim: usize,
    path: &str,
) -> Result<(Vec<f64>, f64, Solid), String> {
    let tip = point(tip, dim, &format!("{path}.tip"))?;
    if !(0.0..=1.0).contains(&threshold) {
        return Err(format!(
            "{path}.threshold: must be in [0, 1], got {threshold}"
        ));
    }
    Ok((
        tip,
        threshold,
        region.to_solid(dim, &format!("{path}.region"))?,
    ))
}
