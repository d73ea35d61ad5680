//! The two levels of a multi-grid scene (`adapt::multigrid`, thesis §3.4) as a plug-in of its
//! forward-Euler steps: after each update the fictitious nodes take their values from the
//! other level; frames carry the levels' node counts, classes and cell radii.

use super::body::FieldBody;
use crate::adapt::masks::GridClass;
use crate::adapt::multigrid::MultiGrid;
use crate::frame::Frame;
use crate::solver::{Adaptation, Clock, Tick};

impl<const D: usize> Adaptation<FieldBody<D>> for MultiGrid<D> {
    fn after_move(&mut self, body: &mut FieldBody<D>, _tick: Tick) {
        self.transfer(body.field_mut());
    }

    fn frame(&mut self, _body: &FieldBody<D>, _clock: &Clock, frame: &mut Frame) {
        let (coarse, fine, fictitious) = self.counts();
        frame.scalars.extend([
            ("grid/coarse_active".to_string(), coarse as f64),
            ("grid/fine_active".to_string(), fine as f64),
            ("grid/fictitious".to_string(), fictitious as f64),
        ]);
        frame.classes.push(GridClass::field(&self.class));
        frame.radii = GridClass::radii(&self.class, self.coarse.spacing, self.fine.spacing);
    }
}
