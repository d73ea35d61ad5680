//! The PD scalar wave (2.37)–(2.40) by damped velocity-Verlet (4.62) (`integrate::verlet`) on
//! the standard scheme: the wave's body (`wave_body`) with its forces and its plug-in, the
//! absorbing layer of an unbounded domain (`layer`, thesis Chapter 4).

use std::any::Any;
use std::ops::Deref;

use super::body::FieldBody;
use super::frame::Shown;
use super::layer::Layer;
use super::layout::Layout;
use super::operator::{kernel, operator};
use super::stable::stable_step;
use super::wave_body::{Wave, WaveBody, WaveForces};
use crate::absorb::scalar_layer::Absorber;
use crate::discretization::Discretization;
use crate::frame::{Frame, NodeField};
use crate::integrate::verlet;
use crate::metrics::probes;
use crate::scene::{Scene, SceneError};
use crate::solver::adaptation::{notes_of, refuse_foreign_sections, tune_each};
use crate::solver::{
    Adaptation, Clock, Integrator, Param, RunState, SimError, SimInfo, Stages, State, Stepper,
};

/// The wave's own checkpoint sections besides the field.
const SECTIONS: [&str; 3] = ["velocity", "previous_field", "previous_velocity"];

pub struct WaveSimulation<const D: usize> {
    pub body: WaveBody<D>,
    plugins: Vec<Box<dyn Adaptation<WaveBody<D>>>>,
    run: RunState,
}

/// A simulation reads as its field body (field, positions, operator) for measurements.
impl<const D: usize> Deref for WaveSimulation<D> {
    type Target = FieldBody<D>;

    fn deref(&self) -> &FieldBody<D> {
        &self.body.base
    }
}

impl<const D: usize> WaveSimulation<D> {
    pub fn new(scene: &Scene) -> Result<Self, SceneError> {
        let mut layout = Layout::new(scene, Discretization::<D>::of_scene(scene)?, None)?;
        let kernel = kernel(scene, D);
        let operator = operator(scene, &layout.discretization, None, &kernel, &layout.free)?;
        let absorbing = std::mem::take(&mut layout.absorbing);
        let base = FieldBody::new(scene, layout, kernel, operator);
        let n = base.len();
        let stable = stable_step(scene, n, &base.operator, 1.0, None, Integrator::Verlet);
        let run = RunState::new(scene, stable, &[])?;
        let mut plugins: Vec<Box<dyn Adaptation<WaveBody<D>>>> = Vec::new();
        if let Some(spec) = scene.absorbing {
            let a = Absorber::new(scene, spec, absorbing, &kernel, n);
            plugins.push(Box::new(Layer::fitted(a, &base, run.clock.dt())));
        }
        let damping = scene.wave.map_or(0.0, |w| w.damping);
        let wave = Wave::new(damping, base.field(), base.operator.rows.len());
        let mut sim = WaveSimulation {
            body: WaveBody { base, wave },
            plugins,
            run,
        };
        sim.run.stages = Stages::new(&verlet::stage_names(&WaveForces, &sim.plugins));
        Ok(sim)
    }

    /// u̇ per node.
    pub fn velocity(&self) -> &[f64] {
        &self.body.wave.velocity
    }

    /// Sets the field (tests, restarts), `values` per node.
    pub fn set_field(&mut self, values: &mut [f64]) {
        self.body.field_mut().copy_from_slice(values);
        self.body.wave.forces_fresh = false;
    }

    /// The absorbing layer, on an unbounded domain.
    fn layer(&self) -> Option<&Layer<D>> {
        self.plugins
            .iter()
            .find_map(|p| (&**p as &dyn Any).downcast_ref::<Layer<D>>())
    }
}

impl<const D: usize> Stepper for WaveSimulation<D> {
    fn step(&mut self) -> Result<(), SimError> {
        verlet::step(
            &mut self.body,
            &mut WaveForces,
            &mut self.plugins,
            &mut self.run,
        )
    }

    /// The displacement and u̇, the near field's energy (the discrete (4.99); every row without
    /// a layer), then what each plug-in adds.
    fn frame(&mut self) -> Frame {
        let shown = Shown {
            name: "displacement",
            nonnegative: false,
        };
        let (base, velocity) = (&self.body.base, self.body.wave.velocity.as_slice());
        let mut frame = base.frame(&mut self.run, shown, Some(velocity));
        let absorbing = self.layer().map(|l| l.is_absorbing());
        let energy = probes::near_field_energy(
            &base.operator,
            base.field(),
            Some(velocity),
            &base.active_volumes,
            absorbing,
        );
        frame
            .scalars
            .push(("energy/near_field".to_string(), energy));
        let top = velocity.iter().fold(0.0, |a: f64, v| a.max(v.abs()));
        let range = if top > 0.0 { top } else { 1.0 };
        frame.fields.push(NodeField {
            name: "velocity".into(),
            values: velocity.to_vec(),
            range: (-range, range),
        });
        let clock = &self.run.clock;
        for p in &mut self.plugins {
            p.frame(&self.body, clock, &mut frame);
        }
        frame
    }

    fn info(&self) -> SimInfo {
        let mut info = self.run.info(self.body.size((0, 0)));
        info.notes = notes_of(&self.plugins);
        info
    }

    fn run(&self) -> &RunState {
        &self.run
    }

    fn run_mut(&mut self) -> &mut RunState {
        &mut self.run
    }

    fn save_state(&self) -> State {
        let mut state = State::default();
        self.run.clock.save(&mut state);
        self.body.save(&mut state);
        let w = &self.body.wave;
        let saved = [&w.velocity, &w.previous_field, &w.previous_velocity];
        for (name, values) in SECTIONS.iter().zip(saved) {
            state.put_f64(name, values.clone());
        }
        for p in &self.plugins {
            p.save(&self.body, &mut state);
        }
        state
    }

    fn restore_state(&mut self, state: &State) -> Result<(), String> {
        let clock = Clock::restore(state)?;
        let n = self.body.len();
        let field = self.body.read(state)?;
        let plugins = &self.plugins;
        refuse_foreign_sections(state, |s| plugins.iter().any(|p| p.owns_section(s)))?;
        let [velocity, previous_field, previous_velocity] = SECTIONS.map(|s| state.f64(s, n));
        let (velocity, previous_field, previous_velocity) =
            (velocity?, previous_field?, previous_velocity?);
        for p in &mut self.plugins {
            p.restore(&mut self.body, state)?;
        }
        self.body.field_mut().copy_from_slice(field);
        let w = &mut self.body.wave;
        w.velocity.copy_from_slice(velocity);
        w.previous_field.copy_from_slice(previous_field);
        w.previous_velocity.copy_from_slice(previous_velocity);
        w.forces_fresh = false;
        self.run.clock = clock;
        Ok(())
    }

    fn tune(&mut self, param: Param) -> Result<(), String> {
        tune_each(&mut WaveForces, &mut self.plugins, &mut self.body, param)
    }
}
