//! The phase change of corrosion scenes, run between steps (thesis (2.79), irreversible per
//! seed-thesis-ch2-3 erratum 18): solid nodes whose concentration dropped below C_sat turn liquid;
//! nothing turns back into solid.

use rayon::prelude::*;

use super::masks::Phase;
use crate::model::corrosion::CorrosionLaw;

#[derive(Debug, Clone)]
pub struct PhaseChange {
    saturation: f64,
    /// The initial solid volume, for the relative volume loss.
    solid_volume0: f64,
}

impl PhaseChange {
    /// The initial phases of `field` (solid where C ≥ C_sat) and the change that follows them.
    pub fn initial(
        law: &CorrosionLaw,
        field: &[f64],
        volumes: &[f64],
    ) -> (PhaseChange, Vec<Phase>) {
        let phase: Vec<Phase> = field
            .iter()
            .map(|&c| {
                if law.solid_at(c) {
                    Phase::Solid
                } else {
                    Phase::Liquid
                }
            })
            .collect();
        let change = PhaseChange {
            saturation: law.saturation,
            solid_volume0: solid_volume(&phase, volumes),
        };
        (change, phase)
    }

    /// Solid nodes below C_sat turn liquid; returns how many changed.
    pub fn update(&self, phase: &mut [Phase], field: &[f64]) -> usize {
        let saturation = self.saturation;
        phase
            .par_iter_mut()
            .zip(field)
            .map(|(p, &c)| {
                if *p == Phase::Solid && c < saturation {
                    *p = Phase::Liquid;
                    1
                } else {
                    0
                }
            })
            .sum()
    }

    /// Relative volume loss V_L = 1 − V_solid(t)/V_solid(0).
    pub fn volume_loss(&self, phase: &[Phase], volumes: &[f64]) -> f64 {
        if self.solid_volume0 > 0.0 {
            1.0 - solid_volume(phase, volumes) / self.solid_volume0
        } else {
            0.0
        }
    }
}

/// Σ ΔV over the solid nodes (`volumes`: 0 where a node does not count).
pub fn solid_volume(phase: &[Phase], volumes: &[f64]) -> f64 {
    phase
        .iter()
        .zip(volumes)
        .filter(|(p, _)| p.is_solid())
        .map(|(_, v)| v)
        .sum()
}
