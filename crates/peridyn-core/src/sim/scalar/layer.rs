//! The absorbing layer of a scalar field on an unbounded domain (`absorb::scalar_layer`,
//! thesis Chapter 4) as a plug-in: before each step its rows are refitted if Δt changed and
//! its new values (a wave's rates too) computed from t^n (and t^{n−1}); they overwrite the
//! field once it is advanced, and a wave's velocities after its second kick. Frames carry the
//! layer's classes (and, for diffusion, the near field's energy); `check` its conditioning.

use super::body::FieldBody;
use super::wave_body::WaveBody;
use crate::absorb::scalar_layer::Absorber;
use crate::frame::Frame;
use crate::metrics::probes;
use crate::solver::{Adaptation, Clock, Tick};

pub struct Layer<const D: usize>(pub Absorber<D>);

impl<const D: usize> Layer<D> {
    /// The layer fitted for the run's first Δt (its conditioning is reported before a step).
    pub fn fitted(absorber: Absorber<D>, body: &FieldBody<D>, dt: f64) -> Layer<D> {
        let mut layer = Layer(absorber);
        layer.fit(body, dt);
        layer
    }

    /// Refits the rows if `dt` is not the one they were fitted for.
    fn fit(&mut self, body: &FieldBody<D>, dt: f64) {
        let families = &body.discretization.families;
        self.0.ensure_fitted(dt, body.positions(), families);
    }

    /// Which nodes are the layer's (the near field is the rest).
    pub fn is_absorbing(&self) -> &[bool] {
        &self.0.is_absorbing
    }

    fn classes(&self, frame: &mut Frame) {
        frame.classes.push(self.0.class_field(&[]));
    }
}

/// Diffusion and corrosion: the layer's values from C^n alone.
impl<const D: usize> Adaptation<FieldBody<D>> for Layer<D> {
    fn before_step(&mut self, body: &mut FieldBody<D>, tick: Tick) {
        self.fit(body, tick.dt);
        let a = &mut self.0;
        let field = body.field();
        a.layer.values(field, field, &mut a.values);
    }

    fn after_move(&mut self, body: &mut FieldBody<D>, _tick: Tick) {
        self.0.overwrite(body.field_mut());
    }

    /// The near field's Π = ½ Σ C² V (seed-thesis-ch4-5 erratum 13) and the layer's classes.
    fn frame(&mut self, body: &FieldBody<D>, _clock: &Clock, frame: &mut Frame) {
        let energy = probes::near_field_energy(
            &body.operator,
            body.field(),
            None,
            &body.active_volumes,
            Some(self.is_absorbing()),
        );
        frame
            .scalars
            .push(("energy/near_field".to_string(), energy));
        self.classes(frame);
    }

    fn notes(&self) -> Vec<String> {
        self.0.report()
    }
}

/// A scalar wave: values and rates from the two levels t^n, t^{n−1} (4.62).
impl<const D: usize> Adaptation<WaveBody<D>> for Layer<D> {
    fn before_step(&mut self, body: &mut WaveBody<D>, tick: Tick) {
        self.fit(body, tick.dt);
        let (a, w) = (&mut self.0, &body.wave);
        let field = body.base.field();
        a.layer.values(field, &w.previous_field, &mut a.values);
        a.layer.rates(
            [field, &w.previous_field],
            [&w.velocity, &w.previous_velocity],
            &mut a.rates,
        );
    }

    fn after_move(&mut self, body: &mut WaveBody<D>, _tick: Tick) {
        self.0.overwrite(body.field_mut());
    }

    fn after_constraints(&mut self, body: &mut WaveBody<D>, _tick: Tick) {
        self.0.overwrite_rates(&mut body.wave.velocity);
    }

    fn frame(&mut self, _body: &WaveBody<D>, _clock: &Clock, frame: &mut Frame) {
        self.classes(frame);
    }

    fn notes(&self) -> Vec<String> {
        self.0.report()
    }
}
