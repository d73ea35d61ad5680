//! The force pass of the dual bonds (zeng2024 (9)–(13)) and what is read off the bond states:
//! stress, damage (14), the stiffness row sums, the normal strains of the split criterion (16).

use rayon::prelude::*;

use super::kernel::{ROWS_PER_TASK, RowPass};
use super::*;
use crate::simd::Simd;

impl DualBonds {
    /// The force pass (zeng2024 (9)–(13)), in two particle-parallel passes. First, per
    /// particle k over its row H_k (`kernel`, on the lanes `Simd::selected` gives): break
    /// every intact bond whose stretch reaches k's s_c (irreversible), sum θ_k (5) over the
    /// intact ones, then (the row still in cache) each bond's force F_kj, which depends on k's
    /// state only, stored for the reactions; Σ_{H_k} F_kj and W_k (4). Second, per particle, the
    /// reactions −Σ_{H'_k} F_jk and the split criteria. Every lane count gives the same bits.
    /// Returns the bonds broken now. Allocation-free.
    pub fn evaluate(
        &mut self,
        body: &Body,
        positions: &[[f64; 2]],
        out: &mut [ParticleTerms],
    ) -> u64 {
        let simd = Simd::selected();
        self.evaluate_with(body, positions, out, |rows| simd.run(rows))
    }

    /// `evaluate` with `direct` running each task's rows of the first pass.
    pub(super) fn evaluate_with(
        &mut self,
        body: &Body,
        positions: &[[f64; 2]],
        out: &mut [ParticleTerms],
        direct: impl Fn(RowPass) -> u64 + Sync,
    ) -> u64 {
        assert_eq!(out.len(), self.particle_count());
        assert_eq!(positions.len(), body.reference.len());
        let intact = RowSlots::new(&mut self.intact);
        // SAFETY of its writes: each live slot's entry belongs to that slot alone.
        let reactions = RowSlots::new(&mut self.reactions);
        let broken: u64 = out
            .par_chunks_mut(ROWS_PER_TASK)
            .enumerate()
            .map(|(task, terms)| {
                direct(RowPass {
                    first: task * ROWS_PER_TASK,
                    terms,
                    body,
                    positions: positions.as_flattened(),
                    starts: &self.starts,
                    ends: &self.ends,
                    neighbors: &self.neighbors,
                    lengths: &self.lengths,
                    weight_theta: &self.weight_theta,
                    weight_distortion: &self.weight_distortion,
                    reaction_slot: &self.reaction_slot,
                    criteria: &self.criteria,
                    intact: &intact,
                    reactions: &reactions,
                })
            })
            .sum();
        let (reactions, intact, owner) = (&self.reactions, &self.intact, &self.owner);
        let (dual_starts, dual_ends, dual) = (&self.dual_starts, &self.dual_ends, &self.dual);
        out.par_iter_mut().enumerate().for_each(|(k, t)| {
            let gate = self.criteria.get(k).copied().unwrap_or(f64::INFINITY);
            let list = dual_starts[k]..dual_ends[k];
            for f in &reactions[list.clone()] {
                t.force[0] -= f[0];
                t.force[1] -= f[1];
            }
            let mut lost = t.damage;
            if gate.is_finite() {
                for &b in &dual[list] {
                    if intact[b as usize] == 0 {
                        lost += body.volumes[owner[b as usize] as usize];
                    }
                }
            }
            if !gate.is_finite() {
                t.damage = 0.0;
                return;
            }
            // The splitting criteria's inputs.
            t.damage = if self.row_volume[k] > 0.0 {
                lost / self.row_volume[k]
            } else {
                0.0
            };
            t.strains = if lost > 0.0 || t.energy_density >= gate {
                self.normal_strains(k, body, positions)
            } else {
                [0.0; 2]
            };
        });
        broken
    }

    /// Σ_{H_k} F_kj ⊗ ξ_kj / V_k, the particle's stress from its own bonds after `evaluate`
    /// (for a homogeneous deformation, ∂W_k/∂ε).
    pub fn stress(&self, k: usize, body: &Body) -> [[f64; 2]; 2] {
        let x = body.reference;
        let mut sigma = [[0.0; 2]; 2];
        for b in self.range(k) {
            let j = self.neighbors[b] as usize;
            let xi = [x[j][0] - x[k][0], x[j][1] - x[k][1]];
            for (p, row) in sigma.iter_mut().enumerate() {
                for (q, s) in row.iter_mut().enumerate() {
                    let force = self.reactions[self.reaction_slot[b] as usize];
                    *s += force[p] * xi[q] / body.volumes[k];
                }
            }
        }
        sigma
    }

    /// Damage (14) of every particle.
    pub fn damage(&self, volumes: &[f64]) -> Vec<f64> {
        (0..self.particle_count())
            .into_par_iter()
            .map(|k| self.damage_of(k, volumes))
            .collect()
    }

    /// Damage (14) of particle k:
    /// 1 − (Σ_{H_k} μ V_j + Σ_{H'_k} μ V_j) / (Σ_{H_k} V_j + Σ_{H'_k} V_j). The force pass's
    /// split check reads the same quantity as `lost_volume / row_volume` (equal to rounding);
    /// frames keep this form, whose values the crack-angle and branch estimators threshold
    /// (a damage of exactly 0.5 on the lattice must stay on the same side of 0.5).
    pub fn damage_of(&self, k: usize, volumes: &[f64]) -> f64 {
        let (mut intact, mut all) = (0.0, 0.0);
        for b in self.range(k) {
            let v = volumes[self.neighbors[b] as usize];
            all += v;
            intact += v * f64::from(self.intact[b]);
        }
        for &b in self.dual_bonds(k) {
            let v = volumes[self.owner[b as usize] as usize];
            all += v;
            intact += v * f64::from(self.intact[b as usize]);
        }
        if all > 0.0 { 1.0 - intact / all } else { 0.0 }
    }

    /// Per particle, a Gershgorin-type row sum of the linearized stiffness (N/m): each intact
    /// bond's distortional stiffness 2 δ b ω_b V_k / |ξ| counted twice in the rows of both ends,
    /// and the dilatation coupling 2 |2 a d² δ²| V_k (Σ ω_θ / |ξ|)² in its owner's row. The
    /// shape of ADR's fictitious density (Kilic & Madenci's ¼ Σ_j |K_ij|, scaled by the caller)
    /// and of the stable-step estimate.
    pub fn stiffness_rows(&self, body: &Body) -> Vec<f64> {
        let n = self.particle_count();
        let bond_stiffness = |b: usize| -> f64 {
            let k = self.owner[b] as usize;
            let c = &body.constants[k];
            f64::from(self.intact[b])
                * 2.0
                * c.horizon
                * c.b
                * self.weight_distortion[b]
                * body.volumes[k]
                / self.lengths[b]
        };
        (0..n)
            .into_par_iter()
            .map(|k| {
                let c = &body.constants[k];
                let mut row = 0.0;
                let mut theta = 0.0;
                for b in self.range(k) {
                    row += 2.0 * bond_stiffness(b);
                    theta += f64::from(self.intact[b]) * self.weight_theta[b] / self.lengths[b];
                }
                for &b in self.dual_bonds(k) {
                    row += 2.0 * bond_stiffness(b as usize);
                }
                let coupling =
                    2.0 * (2.0 * c.a * c.d * c.d * c.horizon * c.horizon).abs() * body.volumes[k];
                row + coupling * theta * theta
            })
            .collect()
    }

    /// The accumulated normal strains ε_xx, ε_yy of (17) over the intact bonds of H_k, in the
    /// regression form of seed-002 §3.1 ambiguity 1 (Σ μ (Δu·n_i)(ξ·n_i) V / Σ μ (ξ·n_i)² V:
    /// the printed division by (x_j − x_k)·n_i is singular for bonds across the axis).
    pub fn normal_strains(&self, k: usize, body: &Body, positions: &[[f64; 2]]) -> [f64; 2] {
        let (x, y) = (body.reference, positions);
        let mut num = [0.0; 2];
        let mut den = [0.0; 2];
        for b in self.range(k) {
            if self.intact[b] == 0 {
                continue;
            }
            let j = self.neighbors[b] as usize;
            let v = body.volumes[j];
            for i in 0..2 {
                let xi = x[j][i] - x[k][i];
                let du = (y[j][i] - x[j][i]) - (y[k][i] - x[k][i]);
                num[i] += du * xi * v;
                den[i] += xi * xi * v;
            }
        }
        [0, 1].map(|i| if den[i] > 0.0 { num[i] / den[i] } else { 0.0 })
    }
}
