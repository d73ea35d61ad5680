//! The absorbing layer of an unbounded elastic body (`absorb::bond_layer`) as a plug-in of
//! its velocity-Verlet steps (thesis §4.3, (4.166)): the layer's new state is fitted from t^n
//! and t^{n−1} before the step, its displacements overwrite the drift's, its damped band acts
//! after the kick, and its velocities overwrite the kick's.

use super::body::ElasticBody;
use crate::absorb::bond_layer::BondLayer;
use crate::frame::Frame;
use crate::solver::{Adaptation, Clock, State, Tick};

pub struct Layer<const D: usize>(pub BondLayer<D>);

impl<const D: usize> Layer<D> {
    /// The layer fitted for the run's first Δt, at rest before t = 0.
    pub fn start(mut layer: BondLayer<D>, body: &ElasticBody<D>, dt: f64) -> Layer<D> {
        layer.start(dt, body.reference(), body.families(), body.positions());
        Layer(layer)
    }
}

impl<const D: usize> Adaptation<ElasticBody<D>> for Layer<D> {
    fn stage(&self) -> Option<&'static str> {
        Some("absorbing")
    }

    fn before_step(&mut self, body: &mut ElasticBody<D>, tick: Tick) {
        let (reference, families) = (body.reference(), body.families());
        let (positions, velocities) = (body.positions(), body.velocities());
        self.0
            .prepare(tick.dt, reference, families, positions, velocities);
    }

    fn after_move(&mut self, body: &mut ElasticBody<D>, _tick: Tick) {
        let (reference, _, positions, _) = body.motion_mut();
        self.0.overwrite_positions(reference, positions);
    }

    fn damp(&mut self, body: &mut ElasticBody<D>, tick: Tick) {
        self.0.damp(body.velocities_mut(), tick.dt, tick.stable_dt);
    }

    fn after_constraints(&mut self, body: &mut ElasticBody<D>, _tick: Tick) {
        self.0.overwrite_velocities(body.velocities_mut());
    }

    /// The near field's energy (4.169) and the layer's classes.
    fn frame(&mut self, body: &ElasticBody<D>, _clock: &Clock, frame: &mut Frame) {
        let near = self.0.near_field(&body.node_energy);
        frame.scalars.push(("energy/near_field".to_string(), near));
        frame
            .classes
            .push(self.0.absorber.class_field(self.0.damped()));
    }

    fn save(&self, _body: &ElasticBody<D>, state: &mut State) {
        self.0.save(state);
    }

    fn restore(&mut self, _body: &mut ElasticBody<D>, state: &State) -> Result<(), String> {
        self.0.restore(state)
    }

    fn owns_section(&self, section: &str) -> bool {
        section.starts_with("absorbing/")
    }

    fn notes(&self) -> Vec<String> {
        self.0.report()
    }
}
