//! The fixed hybrid of a corrosion scene (thesis §3.3.2; seed-thesis-ch2-3 §5, §8.5): Ω_s — the
//! solid and the liquid within `band` of it, the zone where the phases interact — runs the standard
//! scheme with bond classes; Ω_w — the far liquid — runs WLS-2 diffusion (seed-thesis-ch2-3 §3.4)
//! with κ_liq over its collocation nodes, wherever they lie (no ghost layer). With band ≥ δ an Ω_w
//! node has no solid within its horizon, and the solid only shrinks, so every bond it could see is
//! liquid–liquid for the whole run: the invariant "no phase change in Ω_w" holds by
//! construction and is still counted in every frame.

use crate::scheme::wls::Collocation;
use kiddo::{ImmutableKdTree, SquaredEuclidean};
use rayon::prelude::*;

use super::masks::{Phase, SchemeClass};
use crate::discretization::Families;
use crate::model::diffusion::DiffusionKernel;
use crate::scheme::VectorOperator;
use crate::scheme::runs::RowRuns;
use crate::scheme::wls::{self, Basis, FitError};

/// The fixed hybrid of a scalar scene: the per-node scheme mask and Ω_w's WLS rows (in
/// stencil form, evaluated over translation runs) with their rates; the scene's own operator
/// then holds the Ω_s rows only.
pub struct FixedHybrid {
    pub mask: Vec<SchemeClass>,
    pub wls: VectorOperator<1>,
    runs: RowRuns,
    /// L C on each Ω_w row, then (forward Euler) the row's new value.
    pub rate: Vec<f64>,
}

impl FixedHybrid {
    /// WLS-2 diffusion with the liquid's `kernel` on the Ω_w nodes of `mask`.
    pub fn new<const D: usize>(
        mask: Vec<SchemeClass>,
        positions: &[[f64; D]],
        families: &Families,
        kernel: &DiffusionKernel,
        rule: impl Into<Collocation>,
    ) -> Result<FixedHybrid, FitError> {
        let wls = liquid_operator(&mask, positions, families, kernel, rule)?;
        Ok(FixedHybrid {
            mask,
            runs: RowRuns::new(&wls),
            rate: vec![0.0; wls.rows.len()],
            wls,
        })
    }

    /// L C on the Ω_w rows into `rate`.
    pub fn rates(&mut self, field: &[f64]) {
        let (rates, _) = self.rate.as_chunks_mut::<1>();
        self.runs.apply(&self.wls, [field], |_| true, rates);
    }

    /// Solid nodes in Ω_w: a phase change where the WLS rows cannot see one. Counted in every
    /// frame, never expected (see the module notes).
    pub fn violations(&self, phase: &[Phase]) -> usize {
        self.mask
            .iter()
            .zip(phase)
            .filter(|(m, p)| **m == SchemeClass::Wls && p.is_solid())
            .count()
    }
}

/// Ω_s of the fixed corrosion hybrid: nodes within `band` of an initially solid node; held
/// nodes are marked [`SchemeClass::Held`], all others Ω_w.
pub fn corrosion_mask<const D: usize>(
    positions: &[[f64; D]],
    solid: &[bool],
    held: &[bool],
    band: f64,
) -> Vec<SchemeClass> {
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
            (true, _) => SchemeClass::Held,
            (false, true) => SchemeClass::Standard,
            (false, false) => SchemeClass::Wls,
        })
        .collect()
}

/// The WLS-2 diffusion operator with κ_liq on the Ω_w rows, in stencil form (translated rows
/// share weights and are evaluated in runs).
pub fn liquid_operator<const D: usize>(
    mask: &[SchemeClass],
    positions: &[[f64; D]],
    families: &Families,
    kernel: &DiffusionKernel,
    rule: impl Into<Collocation>,
) -> Result<VectorOperator<1>, FitError> {
    let rows: Vec<u32> = (0..mask.len() as u32)
        .filter(|&i| mask[i as usize] == SchemeClass::Wls)
        .collect();
    let basis = Basis::new(D, 2);
    let l = wls::diffusion_l(
        &basis,
        kernel.diffusivity,
        kernel.exponent,
        kernel.horizon,
        kernel.influence,
    );
    wls::diffusion_stencil_operator(&rows, positions, families, &basis, &l, kernel.horizon, rule)
}
