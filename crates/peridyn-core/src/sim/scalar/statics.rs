//! Static linear elasticity in 1D (thesis §3.2.5; seed-004 Example 1): one banded solve of
//! 0 = L u + b on the free nodes, the held nodes' values moved to the right-hand side.

use std::ops::Deref;

use super::body::FieldBody;
use super::frame::Shown;
use super::layout::Layout;
use super::operator::{kernel, operator};
use crate::discretization::Discretization;
use crate::frame::Frame;
use crate::integrate::linear::BandMatrix;
use crate::scene::{Scene, SceneError};
use crate::solver::adaptation::refuse_foreign_sections;
use crate::solver::{Clock, Lap, RunState, SimError, SimInfo, StableStep, State, Stepper};

/// A static solve's one stage.
const STAGES: &[&str] = &["solve"];

pub struct StaticSimulation<const D: usize> {
    pub body: FieldBody<D>,
    run: RunState,
}

/// A simulation reads as its body (field, positions, operator) for measurements.
impl<const D: usize> Deref for StaticSimulation<D> {
    type Target = FieldBody<D>;

    fn deref(&self) -> &FieldBody<D> {
        &self.body
    }
}

impl<const D: usize> StaticSimulation<D> {
    pub fn new(scene: &Scene) -> Result<Self, SceneError> {
        let layout = Layout::new(scene, Discretization::<D>::of_scene(scene)?, None)?;
        let kernel = kernel(scene, D);
        let operator = operator(scene, &layout.discretization, None, &kernel, &layout.free)?;
        let body = FieldBody::new(scene, layout, kernel, operator);
        let run = RunState::new(scene, StableStep::NONE, STAGES)?;
        Ok(StaticSimulation { body, run })
    }
}

impl<const D: usize> FieldBody<D> {
    /// One global solve of 0 = L u + b on the free nodes, held values moved to the right.
    fn solve_static(&mut self) -> Result<(), SimError> {
        let n = self.len();
        let mut unknown = vec![u32::MAX; n];
        for (r, &i) in self.operator.rows.iter().enumerate() {
            unknown[i as usize] = r as u32;
        }
        let op = &self.operator;
        let unknown = &unknown;
        let (lower, upper) = BandMatrix::bandwidths((0..op.rows.len()).flat_map(|r| {
            op.columns[op.offsets[r]..op.offsets[r + 1]]
                .iter()
                .filter(|&&j| unknown[j as usize] != u32::MAX)
                .map(move |&j| (r, unknown[j as usize] as usize))
        }));
        let mut matrix = BandMatrix::new(op.rows.len(), lower, upper)
            .map_err(|e| SimError::Solve(e.to_string()))?;
        let mut rhs = vec![0.0; op.rows.len()];
        let (positions, field) = (self.positions(), self.field());
        for (r, &i) in op.rows.iter().enumerate() {
            let x = &positions[i as usize];
            rhs[r] = -self
                .reference
                .map_or(0.0, |rf| rf.forcing(x, 0.0, &self.kernel));
            for e in op.offsets[r]..op.offsets[r + 1] {
                let j = op.columns[e] as usize;
                match unknown[j] {
                    u32::MAX => rhs[r] -= op.weights[e] * field[j],
                    col => matrix.add(r, col as usize, op.weights[e]),
                }
            }
        }
        matrix
            .solve(&mut rhs)
            .map_err(|e| SimError::Solve(e.to_string()))?;
        let field = self.discretization.nodes.fields.get_mut(self.values);
        for (r, &i) in self.operator.rows.iter().enumerate() {
            field[i as usize] = rhs[r];
        }
        Ok(())
    }
}

impl<const D: usize> Stepper for StaticSimulation<D> {
    fn step(&mut self) -> Result<(), SimError> {
        let mut lap = Lap::start();
        self.body.solve_static()?;
        lap.charge(&mut self.run.stages, 0);
        self.run.clock.advance();
        Ok(())
    }

    fn frame(&mut self) -> Frame {
        let shown = Shown {
            name: "displacement",
            nonnegative: false,
        };
        self.body.frame(&mut self.run, shown, None)
    }

    fn info(&self) -> SimInfo {
        self.run.info(self.body.size((0, 0)))
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
        state
    }

    fn restore_state(&mut self, state: &State) -> Result<(), String> {
        let clock = Clock::restore(state)?;
        let field = self.body.read(state)?;
        refuse_foreign_sections(state, |_| false)?;
        self.body.field_mut().copy_from_slice(field);
        self.run.clock = clock;
        Ok(())
    }
}
