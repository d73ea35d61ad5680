//! What every scalar simulation's frame holds: the field (and its pointwise error against the
//! reference, if any), Σ C V over the active nodes, timings, the relative ℓ² error (3.79) and
//! the probes. Each simulation and its plug-ins add their own.

use super::body::FieldBody;
use crate::frame::{Frame, NodeField};
use crate::solver::RunState;

/// How the field is shown: its name, and whether it is never negative (a concentration of a
/// corrosion scene: the colormap spans [0, max]).
pub struct Shown {
    pub name: &'static str,
    pub nonnegative: bool,
}

impl<const D: usize> FieldBody<D> {
    /// The frame of the field at the run's time; `velocity` is a wave's u̇ (the probes'
    /// energy densities include it).
    pub(super) fn frame(
        &self,
        run: &mut RunState,
        shown: Shown,
        velocity: Option<&[f64]>,
    ) -> Frame {
        let t = run.clock.time();
        let (positions, field) = (self.positions(), self.field());
        // The pointwise error exists only against a reference (none in corrosion scenes).
        let error: Option<Vec<f64>> = self.reference.map(|r| {
            positions
                .iter()
                .zip(field)
                .map(|(x, v)| v - r.value(x, t))
                .collect()
        });
        let integral: f64 = field
            .iter()
            .zip(&self.active_volumes)
            .map(|(c, v)| c * v)
            .sum();
        let mut scalars = vec![("field/integral".to_string(), integral)];
        scalars.extend(run.timing_scalars());
        let amplitude = if self.amplitude > 0.0 {
            self.amplitude
        } else {
            1.0
        };
        let lowest = if shown.nonnegative { 0.0 } else { -amplitude };
        let mut fields = vec![NodeField {
            name: shown.name.into(),
            values: field.to_vec(),
            range: (lowest, amplitude),
        }];
        if let Some(error) = error {
            let max_error = error.iter().fold(0.0, |a: f64, v| a.max(v.abs()));
            scalars.push(("error/max_abs".to_string(), max_error));
            if let Some(e) = self.relative_error_at(t) {
                scalars.push(("error/relative_l2".to_string(), e));
            }
            let range = if max_error > 0.0 { max_error } else { 1.0 };
            fields.push(NodeField {
                name: "error".into(),
                values: error,
                range: (-range, range),
            });
        }
        for p in &self.probes {
            scalars.extend(p.scalars(&self.operator, field, velocity));
        }
        Frame {
            step: run.clock.step(),
            time: t,
            dim: D,
            positions: positions.as_flattened().to_vec(),
            fields,
            classes: Vec::new(),
            events: Vec::new(),
            scalars,
            radii: Vec::new(),
        }
    }
}
