//! Standard meshfree particle scheme (thesis §3.1, (3.1) with the nonlinear bond force (2.33)):
//! a sum over all family nodes weighted by the partial-volume factor β (3.2).
//!
//! The force loop is a per-node gather over CSR rows, parallel over nodes; bond states are
//! written only by the row's owner, so relaxed atomics suffice and compile to plain moves.

use std::sync::atomic::{AtomicU8, Ordering::Relaxed};

use rayon::prelude::*;

use crate::family::{Families, partial_volume};
use crate::model::pmb::{PmbLaw, influence};

/// Quadrature data shared by every bond: β on/off, spacing, horizon.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Quadrature {
    pub spacing: f64,
    pub horizon: f64,
    pub volume_correction: bool,
}

impl Quadrature {
    /// β(‖ξ‖) of (3.2), or 1 when the correction is off.
    #[inline(always)]
    pub fn beta(&self, length: f64) -> f64 {
        if self.volume_correction {
            partial_volume(length, self.horizon, self.spacing)
        } else {
            1.0
        }
    }
}

/// Bond state μ: 1 intact, 0 broken (2.34). One byte per directed bond.
pub fn intact_bonds(count: usize) -> Vec<AtomicU8> {
    (0..count).map(|_| AtomicU8::new(1)).collect()
}

/// Force density on every node (N/m³), breaking bonds whose stretch reaches s0. Returns the
/// number of directed bonds broken in this call.
pub fn pmb_forces<const D: usize>(
    positions: &[[f64; D]],
    volumes: &[f64],
    families: &Families,
    intact: &[AtomicU8],
    law: &PmbLaw,
    quadrature: &Quadrature,
    force: &mut [[f64; D]],
) -> u64 {
    let c = law.micromodulus;
    let s0 = law.critical_stretch;
    force
        .par_iter_mut()
        .enumerate()
        .with_min_len(256)
        .map(|(i, f_i)| {
            let y_i = positions[i];
            let mut acc = [0.0; D];
            let mut broken = 0u64;
            let range = families.range(i);
            let neighbors = &families.neighbors[range.clone()];
            let lengths = &families.lengths[range.clone()];
            let state = &intact[range];
            for ((&j, &length), mu) in neighbors.iter().zip(lengths).zip(state) {
                let j = j as usize;
                let y_j = positions[j];
                let mut d = [0.0; D];
                let mut r2 = 0.0;
                for k in 0..D {
                    d[k] = y_j[k] - y_i[k];
                    r2 += d[k] * d[k];
                }
                let r = r2.sqrt();
                let extension = r - length;
                if mu.load(Relaxed) == 0 {
                    continue;
                }
                if extension >= s0 * length {
                    mu.store(0, Relaxed);
                    broken += 1;
                    continue;
                }
                let weight = c
                    * influence(law.influence, length, law.horizon)
                    * quadrature.beta(length)
                    * volumes[j];
                // ω c s β V_j · (y_j − y_i)/‖y_j − y_i‖ with s = extension / length.
                let scale = weight * extension / (length * r);
                for k in 0..D {
                    acc[k] += scale * d[k];
                }
            }
            *f_i = acc;
            broken
        })
        .sum()
}

/// Σ_j ‖C(ξ)‖ β V_j of the stable-step bound (3.8), with ‖C‖ = ω c/‖ξ‖, per node.
pub fn stiffness_sums(
    volumes: &[f64],
    families: &Families,
    law: &PmbLaw,
    quadrature: &Quadrature,
) -> Vec<f64> {
    (0..families.node_count())
        .into_par_iter()
        .map(|i| {
            families
                .range(i)
                .map(|b| {
                    let l = families.lengths[b];
                    let j = families.neighbors[b] as usize;
                    influence(law.influence, l, law.horizon) * law.micromodulus / l
                        * quadrature.beta(l)
                        * volumes[j]
                })
                .sum()
        })
        .collect()
}

/// Damage φ_i = 1 − Σ μ β V_j / Σ β V_j, (2.36) discretized.
pub fn damage(
    volumes: &[f64],
    families: &Families,
    intact: &[AtomicU8],
    quadrature: &Quadrature,
) -> Vec<f64> {
    (0..families.node_count())
        .into_par_iter()
        .map(|i| {
            let (mut all, mut kept) = (0.0, 0.0);
            for b in families.range(i) {
                let w = quadrature.beta(families.lengths[b]) * volumes[families.neighbors[b] as usize];
                all += w;
                if intact[b].load(Relaxed) != 0 {
                    kept += w;
                }
            }
            if all > 0.0 { 1.0 - kept / all } else { 0.0 }
        })
        .collect()
}

/// Strain-energy density of node i, W_i = ½ Σ_j w_ij β V_j over intact bonds, (2.26)–(2.27).
pub fn energy_density<const D: usize>(
    i: usize,
    positions: &[[f64; D]],
    volumes: &[f64],
    families: &Families,
    intact: &[AtomicU8],
    law: &PmbLaw,
    quadrature: &Quadrature,
) -> f64 {
    let mut w = 0.0;
    for b in families.range(i) {
        if intact[b].load(Relaxed) == 0 {
            continue;
        }
        let j = families.neighbors[b] as usize;
        let l = families.lengths[b];
        let r = (0..D)
            .map(|k| (positions[j][k] - positions[i][k]).powi(2))
            .sum::<f64>()
            .sqrt();
        w += law.bond_energy((r - l) / l, l) * quadrature.beta(l) * volumes[j];
    }
    0.5 * w
}

/// Total strain energy Σ_i W_i V_i.
pub fn strain_energy<const D: usize>(
    positions: &[[f64; D]],
    volumes: &[f64],
    families: &Families,
    intact: &[AtomicU8],
    law: &PmbLaw,
    quadrature: &Quadrature,
) -> f64 {
    (0..families.node_count())
        .into_par_iter()
        .map(|i| {
            energy_density(i, positions, volumes, families, intact, law, quadrature) * volumes[i]
        })
        .sum()
}

/// The linearized operator of (3.1) per unit mass, applied to a displacement field:
/// out_i = (1/ρ) Σ_j ω c (ξ⊗ξ/‖ξ‖³) (u_i − u_j) β V_j over intact bonds (the stiffness the
/// stable-step bound needs; positive semi-definite in the mass inner product).
pub fn apply_linearized<const D: usize>(
    reference: &[[f64; D]],
    volumes: &[f64],
    families: &Families,
    intact: &[AtomicU8],
    law: &PmbLaw,
    quadrature: &Quadrature,
    density: f64,
    u: &[[f64; D]],
    out: &mut [[f64; D]],
) {
    let c = law.micromodulus / density;
    out.par_iter_mut().enumerate().with_min_len(256).for_each(|(i, o)| {
        let mut acc = [0.0; D];
        for b in families.range(i) {
            if intact[b].load(Relaxed) == 0 {
                continue;
            }
            let j = families.neighbors[b] as usize;
            let l = families.lengths[b];
            let mut xi = [0.0; D];
            let mut proj = 0.0;
            for k in 0..D {
                xi[k] = reference[j][k] - reference[i][k];
                proj += xi[k] * (u[i][k] - u[j][k]);
            }
            let scale = c * influence(law.influence, l, law.horizon) * quadrature.beta(l) * volumes[j]
                / (l * l * l)
                * proj;
            for k in 0..D {
                acc[k] += scale * xi[k];
            }
        }
        *o = acc;
    });
}
