//! The fixed hybrid of a corrosion scene (thesis §3.3.2; seed-003 §5, §8.5): Ω_s — the solid
//! and the liquid within `band` of it, the zone where the phases interact — runs the standard
//! scheme with bond classes; Ω_w — the far liquid — runs WLS-2 diffusion (§3.4) with κ_liq over
//! its collocation nodes, wherever they lie (no ghost layer). With band ≥ δ an Ω_w node has no
//! solid within its horizon, and the solid only shrinks, so every bond it could see is
//! liquid–liquid for the whole run: the invariant "no phase change in Ω_w" holds by
//! construction and is still counted in every frame.

use kiddo::{ImmutableKdTree, SquaredEuclidean};
use rayon::prelude::*;

use crate::adapt::hybrid::{HELD, STANDARD, WLS};
use crate::family::Families;
use crate::model::diffusion::DiffusionKernel;
use crate::scheme::VectorOperator;
use crate::scheme::wls::{self, Basis, FitError};

/// Ω_s of the fixed corrosion hybrid: nodes within `band` of an initially solid node; held
/// nodes are marked [`HELD`], all others Ω_w.
pub fn corrosion_mask<const D: usize>(
    positions: &[[f64; D]],
    solid: &[bool],
    held: &[bool],
    band: f64,
) -> Vec<u8> {
    let solid_positions: Vec<[f64; D]> = positions
        .iter()
        .zip(solid)
        .filter(|(_, s)| **s)
        .map(|(x, _)| *x)
        .collect();
    let near_solid: Vec<bool> = if solid_positions.is_empty() {
        vec![false; positions.len()]
    } else {
        let tree: ImmutableKdTree<f64, D> = ImmutableKdTree::new_from_slice(&solid_positions)
            .expect("a k-d tree over finite lattice coordinates");
        let band2 = band * band * (1.0 + 1e-12);
        positions
            .par_iter()
            .map(|x| {
                tree.query(x)
                    .nearest_one::<SquaredEuclidean<f64>>()
                    .execute()
                    .distance
                    <= band2
            })
            .collect()
    };
    near_solid
        .iter()
        .zip(held)
        .map(|(&near, &h)| match (h, near) {
            (true, _) => HELD,
            (false, true) => STANDARD,
            (false, false) => WLS,
        })
        .collect()
}

/// The WLS-2 diffusion operator with κ_liq on the Ω_w rows, in stencil form (translated rows
/// share weights and are evaluated in runs).
pub fn liquid_operator<const D: usize>(
    mask: &[u8],
    positions: &[[f64; D]],
    families: &Families,
    kernel: &DiffusionKernel,
    k_aux: usize,
) -> Result<VectorOperator<1>, FitError> {
    let rows: Vec<u32> = (0..mask.len() as u32)
        .filter(|&i| mask[i as usize] == WLS)
        .collect();
    let basis = Basis::new(D, 2);
    let l = wls::diffusion_l(
        &basis,
        kernel.diffusivity,
        kernel.exponent,
        kernel.horizon,
        kernel.influence,
    );
    wls::diffusion_stencil_operator(
        &rows,
        positions,
        families,
        &basis,
        &l,
        kernel.horizon,
        k_aux,
    )
}

/// Fraction of nodes in Ω_s.
pub fn standard_fraction(mask: &[u8]) -> f64 {
    mask.iter().filter(|&&m| m == STANDARD).count() as f64 / mask.len().max(1) as f64
}
