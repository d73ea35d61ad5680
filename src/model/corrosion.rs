//! Bi-material PD corrosion (thesis (2.48)–(2.49), phase variable (2.79); seed-003 §1.6):
//! diffusion whose bond micro-diffusivity depends on the phases of its two ends — κ_liq for
//! liquid–liquid, κ_int for solid–liquid, no flux for solid–solid — and an irreversible
//! solid → liquid change when a solid node's concentration drops below C_sat (the errata's
//! reading of (2.79): nothing turns back into solid).

use rayon::prelude::*;

use crate::scene::CorrosionSpec;
use crate::scheme::ScalarOperator;

/// Phase values.
pub const LIQUID: u8 = 0;
pub const SOLID: u8 = 1;

pub struct Corrosion {
    pub kappa_liquid: f64,
    pub kappa_interface: f64,
    pub saturation: f64,
    /// Per node.
    pub phase: Vec<u8>,
    solid_volume0: f64,
}

impl Corrosion {
    /// Phases from the initial field: solid where C ≥ C_sat.
    pub fn new(kappa_liquid: f64, spec: CorrosionSpec, field: &[f64], volumes: &[f64]) -> Self {
        let phase: Vec<u8> = field
            .iter()
            .map(|&c| if c >= spec.saturation { SOLID } else { LIQUID })
            .collect();
        let solid_volume0 = phase
            .iter()
            .zip(volumes)
            .filter(|(p, _)| **p == SOLID)
            .map(|(_, v)| v)
            .sum();
        Corrosion {
            kappa_liquid,
            kappa_interface: spec.interface_diffusivity,
            saturation: spec.saturation,
            phase,
            solid_volume0,
        }
    }

    /// κ of a bond between phases a and b.
    #[inline(always)]
    fn kappa(&self, a: u8, b: u8) -> f64 {
        match (a, b) {
            (LIQUID, LIQUID) => self.kappa_liquid,
            (SOLID, SOLID) => 0.0,
            _ => self.kappa_interface,
        }
    }

    /// Ċ_i = Σ_j κ(φ_i, φ_j) w_ij (C_j − C_i) on the rows of `unit`, an operator assembled with
    /// κ = 1 (its first entry per row is the node itself, (3.4)); out is per row.
    pub fn rates(&self, unit: &ScalarOperator, field: &[f64], out: &mut [f64]) {
        out.par_iter_mut().enumerate().for_each(|(r, o)| {
            let i = unit.rows[r] as usize;
            let (c_i, p_i) = (field[i], self.phase[i]);
            let range = unit.offsets[r] + 1..unit.offsets[r + 1];
            *o = unit.columns[range.clone()]
                .iter()
                .zip(&unit.weights[range])
                .map(|(&j, w)| {
                    let j = j as usize;
                    self.kappa(p_i, self.phase[j]) * w * (field[j] - c_i)
                })
                .sum();
        });
    }

    /// (2.79), irreversible: solid nodes below C_sat turn liquid. Returns how many changed.
    pub fn update_phases(&mut self, field: &[f64]) -> usize {
        let saturation = self.saturation;
        self.phase
            .par_iter_mut()
            .zip(field)
            .map(|(p, &c)| {
                if *p == SOLID && c < saturation {
                    *p = LIQUID;
                    1
                } else {
                    0
                }
            })
            .sum()
    }

    /// Relative volume loss V_L = 1 − V_solid(t)/V_solid(0).
    pub fn volume_loss(&self, volumes: &[f64]) -> f64 {
        let solid: f64 = self
            .phase
            .iter()
            .zip(volumes)
            .filter(|(p, _)| **p == SOLID)
            .map(|(_, v)| v)
            .sum();
        if self.solid_volume0 > 0.0 {
            1.0 - solid / self.solid_volume0
        } else {
            0.0
        }
    }

    /// The largest bond κ: operators built with it bound the spectral radius from above.
    pub fn kappa_max(&self) -> f64 {
        self.kappa_liquid.max(self.kappa_interface)
    }
}
