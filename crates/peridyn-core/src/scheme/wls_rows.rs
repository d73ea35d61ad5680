//! WLS-2 elasticity rows over a subset of the nodes: the precomputed blocks K_ij = L̄ Q̄_i of the
//! linearized bond-based operator (thesis (3.54)–(3.56), seed-004 §2), their translation runs,
//! and the forces K u per row. Shared by the hybrid configuration (its Ω_w rows) and the
//! multi-adaptive scheme's coarse level in its "adaptive, hybrid" variant (thesis §3.5).

use super::VectorOperator;
use super::runs::RowRuns;
use super::wls::{self, Basis, FitError};
use crate::discretization::Families;
use crate::model::pmb::PmbLaw;
use crate::scheme::wls::Collocation;
use rayon::prelude::*;

pub struct WlsRows<const D: usize> {
    /// One row per listed node; its columns are the node's collocation set.
    pub op: VectorOperator<D>,
    /// Node → its row (u32::MAX for nodes without one).
    row_of: Vec<u32>,
    /// The translation runs of `op` (the fast path of its product).
    runs: RowRuns,
    force: Vec<[f64; D]>,
    /// u = y − x by components (the runs' loads are contiguous).
    displacement: [Vec<f64>; D],
}

impl<const D: usize> WlsRows<D> {
    /// The rows of `rows` (node indices, ascending) among `reference.len()` nodes, collocated
    /// over each node's family with the collocation rule.
    pub fn elasticity(
        rows: &[u32],
        reference: &[[f64; D]],
        families: &Families,
        law: &PmbLaw,
        rule: impl Into<Collocation>,
    ) -> Result<Self, FitError> {
        let basis = Basis::new(D, 2);
        let l = wls::bond_l(&basis, law.micromodulus, law.horizon, law.influence);
        let op =
            wls::elasticity_operator(rows, reference, families, &basis, &l, law.horizon, rule)?;
        let mut row_of = vec![u32::MAX; reference.len()];
        for (r, &i) in rows.iter().enumerate() {
            row_of[i as usize] = r as u32;
        }
        Ok(WlsRows {
            runs: RowRuns::new(&op),
            force: vec![[0.0; D]; rows.len()],
            displacement: std::array::from_fn(|_| vec![0.0; reference.len()]),
            op,
            row_of,
        })
    }

    /// Node i's row, if it has one.
    #[inline]
    pub fn row(&self, i: usize) -> Option<usize> {
        let r = self.row_of[i];
        (r != u32::MAX).then_some(r as usize)
    }

    /// Node i's collocation set (its row's columns, the node itself included).
    pub fn columns(&self, i: usize) -> &[u32] {
        let r = self.row_of[i] as usize;
        &self.op.columns[self.op.offsets[r]..self.op.offsets[r + 1]]
    }

    /// Mean collocation nodes per row.
    pub fn collocation_size(&self) -> f64 {
        self.op.columns.len() as f64 / self.op.rows.len().max(1) as f64
    }

    /// Forces K u on the rows whose node is `live` (u = positions − reference), kept per row
    /// for [`Self::force_of`]; the other rows keep their last value.
    pub fn forces(
        &mut self,
        reference: &[[f64; D]],
        positions: &[[f64; D]],
        live: impl Fn(usize) -> bool + Sync,
    ) {
        displacement_components(
            self.displacement.each_mut().map(|u| u.as_mut_slice()),
            reference,
            positions,
        );
        let op = &self.op;
        let u: [&[f64]; D] = std::array::from_fn(|k| self.displacement[k].as_slice());
        self.runs
            .apply(op, u, |r| live(op.rows[r] as usize), &mut self.force);
    }

    /// The last force of node i, which must have a row.
    #[inline]
    pub fn force_of(&self, i: usize) -> [f64; D] {
        self.force[self.row_of[i] as usize]
    }

    /// The linearized operator per unit mass on the `live` rows, −K u / ρ (the sign of the
    /// standard scheme's `apply_linearized`), other rows untouched; for stable-step estimates.
    /// The product runs on the translation runs as the forces do, on component copies of u
    /// made per call (a setup path: allocation is fine here).
    pub fn apply_linearized(
        &self,
        u: &[[f64; D]],
        density: f64,
        out: &mut [[f64; D]],
        live: impl Fn(usize) -> bool + Sync,
    ) {
        let (op, row_of) = (&self.op, &self.row_of);
        let components: [Vec<f64>; D] =
            std::array::from_fn(|k| u.par_iter().with_min_len(4096).map(|v| v[k]).collect());
        let mut product = vec![[0.0; D]; op.rows.len()];
        self.runs.apply(
            op,
            std::array::from_fn(|k| components[k].as_slice()),
            |r| live(op.rows[r] as usize),
            &mut product,
        );
        out.par_iter_mut()
            .enumerate()
            .with_min_len(4096)
            .for_each(|(i, o)| {
                let r = row_of[i];
                if r != u32::MAX && live(i) {
                    *o = product[r as usize].map(|f| -f / density);
                }
            });
    }
}

/// u[k][i] = y_i[k] − x_i[k] for every component in one parallel pass over the nodes (the
/// component slices are split together, so each node's positions are read once).
fn displacement_components<const D: usize>(
    u: [&mut [f64]; D],
    reference: &[[f64; D]],
    positions: &[[f64; D]],
) {
    const LEAF: usize = 4096;
    if reference.len() <= LEAF {
        for (i, (y, x)) in positions.iter().zip(reference).enumerate() {
            for k in 0..D {
                u[k][i] = y[k] - x[k];
            }
        }
        return;
    }
    let mid = reference.len() / 2;
    let mut low: [&mut [f64]; D] = std::array::from_fn(|_| &mut [][..]);
    let mut high: [&mut [f64]; D] = std::array::from_fn(|_| &mut [][..]);
    for (k, component) in u.into_iter().enumerate() {
        let (a, b) = component.split_at_mut(mid);
        (low[k], high[k]) = (a, b);
    }
    let ((x_low, x_high), (y_low, y_high)) = (reference.split_at(mid), positions.split_at(mid));
    rayon::join(
        || displacement_components(low, x_low, y_low),
        || displacement_components(high, x_high, y_high),
    );
}
