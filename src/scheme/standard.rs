//! Standard meshfree particle scheme (thesis §3.1, (3.1) with the nonlinear bond force (2.33)):
//! a sum over all family nodes weighted by the partial-volume factor β (3.2).
//!
//! The force loop is a per-node gather over CSR rows, parallel over blocks of nodes; each
//! task owns its rows of the force array and of the bond states.

use rayon::prelude::*;

use crate::family::{Families, partial_volume};
use crate::model::pmb::{PmbLaw, influence};
use crate::scene::Influence;

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
pub fn intact_bonds(count: usize) -> Vec<u8> {
    vec![1; count]
}

/// Force density on every node (N/m³), breaking bonds whose stretch reaches s0, and each
/// node's strain-energy density W_i over the bonds still intact. Returns the number of
/// directed bonds broken in this call. `uniform_volume` (all V_j equal) saves a
/// gather per bond.
#[allow(clippy::too_many_arguments)]
pub fn pmb_forces<const D: usize>(
    positions: &[[f64; D]],
    volumes: &[f64],
    uniform_volume: Option<f64>,
    families: &Families,
    intact: &mut [u8],
    law: &PmbLaw,
    quadrature: &Quadrature,
    force: &mut [[f64; D]],
    energy_density: &mut [f64],
) -> u64 {
    assert_eq!(positions.len(), families.node_count());
    assert_eq!(intact.len(), families.bond_count());
    let c = law.micromodulus;
    let (h, reach, inv_dx) = (
        law.horizon,
        quadrature.horizon + 0.5 * quadrature.spacing,
        1.0 / quadrature.spacing,
    );
    let beta = move |l: f64| ((reach - l) * inv_dx).clamp(0.0, 1.0);
    // One monomorphized loop per (influence, β, volume) combination: no branches inside.
    macro_rules! with_volume {
        ($weight:expr) => {
            match uniform_volume {
                Some(v) => pmb_rows(
                    positions,
                    families,
                    intact,
                    law,
                    force,
                    energy_density,
                    |l| $weight(l) * v,
                    |_| 1.0,
                ),
                None => pmb_rows(
                    positions,
                    families,
                    intact,
                    law,
                    force,
                    energy_density,
                    $weight,
                    |j| volumes[j],
                ),
            }
        };
    }
    match (law.influence, quadrature.volume_correction) {
        (Influence::Constant, true) => with_volume!(|l: f64| c * beta(l)),
        (Influence::Constant, false) => with_volume!(|_l: f64| c),
        (Influence::Linear, true) => with_volume!(|l: f64| c * (1.0 - l / h).max(0.0) * beta(l)),
        (Influence::Linear, false) => with_volume!(|l: f64| c * (1.0 - l / h).max(0.0)),
    }
}

/// Nodes per task of the force loop.
const ROWS_PER_TASK: usize = 512;

/// The gather loop of `pmb_forces`: f_i = Σ_j μ ω c s β V_j e_ij, (2.33) in the sum (3.1).
/// Node ranges are split recursively (no allocation) so each task owns its rows of `force`
/// and of the bond states.
#[inline(always)]
#[allow(clippy::too_many_arguments)]
fn pmb_rows<const D: usize>(
    positions: &[[f64; D]],
    families: &Families,
    intact: &mut [u8],
    law: &PmbLaw,
    force: &mut [[f64; D]],
    energy_density: &mut [f64],
    weight: impl Fn(f64) -> f64 + Sync,
    volume: impl Fn(usize) -> f64 + Sync,
) -> u64 {
    let kernel =
        |first: usize, force: &mut [[f64; D]], energy: &mut [f64], state: &mut [u8]| -> u64 {
            let s0 = law.critical_stretch;
            let base = families.offsets[first];
            let mut broken = 0u64;
            for (row, (f_i, w_i)) in force.iter_mut().zip(energy.iter_mut()).enumerate() {
                let i = first + row;
                let y_i = positions[i];
                let range = families.range(i);
                let neighbors = &families.neighbors[range.clone()];
                let lengths = &families.lengths[range.clone()];
                let state = &mut state[range.start - base..range.end - base];
                let mut acc = [0.0; D];
                let mut w = 0.0;
                for ((&j, &length), mu) in neighbors.iter().zip(lengths).zip(state.iter_mut()) {
                    if *mu == 0 {
                        continue;
                    }
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
                    if extension >= s0 * length {
                        *mu = 0;
                        broken += 1;
                        continue;
                    }
                    // ω c β V_j · s · (y_j − y_i)/‖y_j − y_i‖ with s = extension / length.
                    let scale = weight(length) * volume(j) * extension / (length * r);
                    // Strain energy w β V_j = ½ ω c s² ‖ξ‖ β V_j (2.27), with the force.
                    w += scale * extension * r;
                    for k in 0..D {
                        acc[k] += scale * d[k];
                    }
                }
                *f_i = acc;
                *w_i = 0.25 * w;
            }
            broken
        };
    split_rows(families, 0, force, energy_density, intact, &kernel)
}

fn split_rows<const D: usize, K>(
    families: &Families,
    first: usize,
    force: &mut [[f64; D]],
    energy: &mut [f64],
    state: &mut [u8],
    kernel: &K,
) -> u64
where
    K: Fn(usize, &mut [[f64; D]], &mut [f64], &mut [u8]) -> u64 + Sync,
{
    if force.len() <= ROWS_PER_TASK {
        return kernel(first, force, energy, state);
    }
    let mid = force.len() / 2;
    let (force_a, force_b) = force.split_at_mut(mid);
    let (energy_a, energy_b) = energy.split_at_mut(mid);
    let cut = families.offsets[first + mid] - families.offsets[first];
    let (state_a, state_b) = state.split_at_mut(cut);
    let (a, b) = rayon::join(
        || split_rows(families, first, force_a, energy_a, state_a, kernel),
        || split_rows(families, first + mid, force_b, energy_b, state_b, kernel),
    );
    a + b
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
    intact: &[u8],
    quadrature: &Quadrature,
) -> Vec<f64> {
    (0..families.node_count())
        .into_par_iter()
        .map(|i| {
            let (mut all, mut kept) = (0.0, 0.0);
            for b in families.range(i) {
                let w =
                    quadrature.beta(families.lengths[b]) * volumes[families.neighbors[b] as usize];
                all += w;
                if intact[b] != 0 {
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
    intact: &[u8],
    law: &PmbLaw,
    quadrature: &Quadrature,
) -> f64 {
    let mut w = 0.0;
    for b in families.range(i) {
        if intact[b] == 0 {
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
    intact: &[u8],
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
#[allow(clippy::too_many_arguments)]
pub fn apply_linearized<const D: usize>(
    reference: &[[f64; D]],
    volumes: &[f64],
    families: &Families,
    intact: &[u8],
    law: &PmbLaw,
    quadrature: &Quadrature,
    density: f64,
    u: &[[f64; D]],
    out: &mut [[f64; D]],
) {
    let c = law.micromodulus / density;
    out.par_iter_mut()
        .enumerate()
        .with_min_len(256)
        .for_each(|(i, o)| {
            let mut acc = [0.0; D];
            for b in families.range(i) {
                if intact[b] == 0 {
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
                let scale =
                    c * influence(law.influence, l, law.horizon) * quadrature.beta(l) * volumes[j]
                        / (l * l * l)
                        * proj;
                for k in 0..D {
                    acc[k] += scale * xi[k];
                }
            }
            *o = acc;
        });
}
