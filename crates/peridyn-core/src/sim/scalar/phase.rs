//! The phase change of a corrosion scene (`adapt::phase`, thesis (2.79)) as a plug-in of its
//! forward-Euler steps: after each step solid nodes below C_sat turn liquid, logged as an
//! event; frames carry the relative volume loss, the solid count and the phases; checkpoints
//! the phases.

use super::body::FieldBody;
use crate::adapt::masks::Phase;
use crate::adapt::phase::PhaseChange;
use crate::discretization::Field;
use crate::frame::Frame;
use crate::solver::{Adaptation, Clock, State, Tick};

pub struct Phases {
    pub change: PhaseChange,
    pub phase: Field<Phase>,
    /// Events since the last frame.
    events: Vec<String>,
}

impl Phases {
    pub fn new(change: PhaseChange, phase: Field<Phase>) -> Phases {
        Phases {
            change,
            phase,
            events: Vec::new(),
        }
    }
}

impl<const D: usize> Adaptation<FieldBody<D>> for Phases {
    fn after_step(&mut self, body: &mut FieldBody<D>, tick: Tick) {
        let fields = &mut body.discretization.nodes.fields;
        let (phase, field) = fields.pair_mut(self.phase, body.values);
        let changed = self.change.update(phase, field);
        if changed > 0 {
            self.events.push(format!(
                "t = {:.4e} s (step {}): {changed} nodes turned liquid",
                tick.time, tick.step
            ));
        }
    }

    fn frame(&mut self, body: &FieldBody<D>, _clock: &Clock, frame: &mut Frame) {
        let phase = body.discretization.nodes.fields.get(self.phase);
        let volumes = &body.active_volumes;
        let solid = phase
            .iter()
            .zip(volumes)
            .filter(|(p, v)| p.is_solid() && **v > 0.0)
            .count();
        frame.scalars.extend([
            (
                "corrosion/volume_loss".to_string(),
                self.change.volume_loss(phase, volumes),
            ),
            ("corrosion/solid_nodes".to_string(), solid as f64),
        ]);
        frame.classes.push(Phase::field(phase));
        frame.events.append(&mut self.events);
    }

    fn save(&self, body: &FieldBody<D>, state: &mut State) {
        let phase = body.discretization.nodes.fields.get(self.phase);
        state.put_u8("phase", phase.iter().map(|&p| p as u8).collect());
    }

    fn restore(&mut self, body: &mut FieldBody<D>, state: &State) -> Result<(), String> {
        let phase = Phase::decode(state.u8("phase", body.len())?)?;
        let fields = &mut body.discretization.nodes.fields;
        fields.get_mut(self.phase).copy_from_slice(&phase);
        Ok(())
    }

    fn owns_section(&self, section: &str) -> bool {
        section == "phase"
    }
}
