//! The body every scalar-field simulation steps: one value per node on a discretization, the
//! scene's assembled operator on the solved rows with their rate buffer, the held nodes and the
//! reference solution they follow, and the relative ℓ² error (3.79) (seed-004 (66)) against it.

use rayon::prelude::*;

use super::layout::Layout;
use crate::discretization::{Discretization, Field};
use crate::integrate::euler::EulerBody;
use crate::metrics::probes::Probe;
use crate::model::diffusion::DiffusionKernel;
use crate::scene::{Reference, Scene};
use crate::scheme::{MIN_ROWS_PER_TASK, ScalarOperator};
use crate::solver::{SimError, Size, State, Tick};

/// A field this many times larger than its scale has diverged.
const DIVERGENCE_FACTOR: f64 = 1e6;

pub struct FieldBody<const D: usize> {
    pub(super) scene: Scene,
    pub(super) discretization: Discretization<D>,
    /// The node field of the values.
    pub(super) values: Field<f64>,
    /// The kernel of the scalar operator: diffusion's κ ω/‖ξ‖^q, or in 1D static elasticity
    /// the linearized bond force c ω/|ξ| (κ = c, q = 1).
    pub(super) kernel: DiffusionKernel,
    /// Rows: the free nodes (Ω_s's only, in a hybrid), in increasing order.
    pub(super) operator: ScalarOperator,
    pub(super) held: Vec<u32>,
    /// The operator's value on each of its rows, then (forward Euler) the row's new value.
    pub(super) rate: Vec<f64>,
    pub(super) reference: Option<Reference>,
    pub(super) probes: Vec<Probe>,
    /// Each node's volume where it is active (0 on fictitious nodes): Σ C V over these is the
    /// total.
    pub(super) active_volumes: Vec<f64>,
    /// |field| scale for the color range and the divergence check.
    pub(super) amplitude: f64,
}

impl<const D: usize> FieldBody<D> {
    /// The body of `layout` with `operator` (assembled with `kernel` or, in corrosion scenes,
    /// with κ = 1) and the physical `kernel` its sources use.
    pub(super) fn new(
        scene: &Scene,
        layout: Layout<D>,
        kernel: DiffusionKernel,
        operator: ScalarOperator,
    ) -> FieldBody<D> {
        let Layout {
            mut discretization,
            held,
            active_volumes,
            field,
            ..
        } = layout;
        let positions = discretization.nodes.reference();
        let amplitude = scene
            .reference
            .map_or(0.0, |r| r.amplitude(positions.iter().map(|x| x.as_slice())))
            .max(field.iter().fold(0.0, |a: f64, v| a.max(v.abs())));
        let probes = Probe::resolve(&scene.probes, positions, &operator);
        let values = discretization.nodes.fields.add_values("field", field);
        FieldBody {
            scene: scene.clone(),
            discretization,
            values,
            kernel,
            rate: vec![0.0; operator.rows.len()],
            operator,
            held,
            reference: scene.reference,
            probes,
            active_volumes,
            amplitude,
        }
    }

    pub fn scene(&self) -> &Scene {
        &self.scene
    }

    pub fn len(&self) -> usize {
        self.discretization.len()
    }

    pub fn is_empty(&self) -> bool {
        self.discretization.is_empty()
    }

    /// The current field, one value per node.
    pub fn field(&self) -> &[f64] {
        self.discretization.nodes.fields.get(self.values)
    }

    pub(super) fn field_mut(&mut self) -> &mut [f64] {
        self.discretization.nodes.fields.get_mut(self.values)
    }

    pub fn positions(&self) -> &[[f64; D]] {
        self.discretization.nodes.reference()
    }

    pub fn operator(&self) -> &ScalarOperator {
        &self.operator
    }

    /// Relative ℓ² error (3.79) (seed-004 (66)) over all nodes against the reference at time
    /// `t`, if there is one.
    pub fn relative_error_at(&self, t: f64) -> Option<f64> {
        let r = self.reference?;
        let (num, den) =
            self.positions()
                .iter()
                .zip(self.field())
                .fold((0.0, 0.0), |(n, d), (x, v)| {
                    let e = r.value(x, t);
                    (n + (v - e).powi(2), d + e * e)
                });
        Some(if den > 0.0 {
            (num / den).sqrt()
        } else {
            num.sqrt()
        })
    }

    /// L u on the operator's rows, into the rate buffer.
    pub(super) fn rates(&mut self) {
        let field = self.discretization.nodes.fields.get(self.values);
        self.operator.apply_rows(field, &mut self.rate);
    }

    /// Forward Euler (3.10) on the operator's rows: C⁺ = C + Δt (L C + S) from the rate
    /// buffer into it (the update is Jacobi-like: every row reads C^n); returns max |C⁺|.
    pub(super) fn euler_rows(&mut self, tick: Tick) -> f64 {
        // Taken for the call and put back: no allocation.
        let mut rate = std::mem::take(&mut self.rate);
        let updated = self.euler(&self.operator.rows, &mut rate, tick);
        self.rate = rate;
        updated
    }

    /// [`Self::euler_rows`] on other `rows` with their rates (a hybrid's WLS rows).
    pub(super) fn euler(&self, rows: &[u32], rates: &mut [f64], tick: Tick) -> f64 {
        let (t, dt) = (tick.start, tick.dt);
        let (reference, kernel) = (self.reference, &self.kernel);
        let (positions, field) = (self.positions(), self.field());
        rates
            .par_iter_mut()
            .with_min_len(MIN_ROWS_PER_TASK)
            .enumerate()
            .map(|(r, rate)| {
                let i = rows[r] as usize;
                let source = reference.map_or(0.0, |rf| rf.forcing(&positions[i], t, kernel));
                *rate = field[i] + dt * (*rate + source);
                rate.abs()
            })
            .reduce(|| 0.0, f64::max)
    }

    /// Writes the new values of the operator's rows from the rate buffer into the field.
    pub(super) fn write_rows(&mut self) {
        let field = self.discretization.nodes.fields.get_mut(self.values);
        for (r, &i) in self.operator.rows.iter().enumerate() {
            field[i as usize] = self.rate[r];
        }
    }

    /// Writes `values` of `rows` into the field.
    pub(super) fn write(&mut self, rows: &[u32], values: &[f64]) {
        let field = self.field_mut();
        for (r, &i) in rows.iter().enumerate() {
            field[i as usize] = values[r];
        }
    }

    /// The run stops where the largest value `max_value` of step `tick` is not finite or over
    /// 10⁶× the field's scale.
    pub(super) fn diverged(&self, max_value: f64, tick: Tick) -> Option<SimError> {
        let scale = self.amplitude.max(f64::MIN_POSITIVE);
        (!max_value.is_finite() || max_value > DIVERGENCE_FACTOR * scale).then_some(
            SimError::Diverged {
                step: tick.step,
                time: tick.time,
                max_value,
                dt: tick.dt,
                stable_dt: tick.stable_dt,
            },
        )
    }

    /// The size of the operator with `extra` (entries, rows) of WLS rows beside it.
    pub(super) fn size(&self, (wls_entries, wls_rows): (usize, usize)) -> Size {
        let op = &self.operator;
        let entries = op.columns.len() + wls_entries;
        Size {
            dim: D,
            nodes: self.len(),
            bonds: entries,
            bytes_per_bond: 12.0,
            stencil: entries as f64 / (op.rows.len() + wls_rows).max(1) as f64,
        }
    }

    /// The field's part of a checkpoint.
    pub(super) fn save(&self, state: &mut State) {
        state.put_f64("field", self.field().to_vec());
    }

    /// The field of a checkpoint, checked against this body's size.
    pub(super) fn read<'a>(&self, state: &'a State) -> Result<&'a [f64], String> {
        state.f64("field", self.len())
    }
}

impl<const D: usize> EulerBody for FieldBody<D> {
    /// The held nodes follow the reference solution (`hold_value` layers keep their value).
    fn hold(&mut self, time: f64) {
        if let Some(r) = self.reference {
            let nodes = &mut self.discretization.nodes;
            let (positions, field) = (nodes.base.reference(), nodes.fields.get_mut(self.values));
            for &i in &self.held {
                field[i as usize] = r.value(&positions[i as usize], time);
            }
        }
    }

    fn stop(&self, measure: f64, tick: Tick) -> Option<SimError> {
        self.diverged(measure, tick)
    }
}
