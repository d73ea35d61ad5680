//! The solver core's contract, below every physics: the dimension-erased [`Stepper`] that the
//! CLI, sinks, panel and benchmarks drive, the [`Clock`] that owns step, t, Δt and end, named
//! stage timers, the run error type, and the setup every simulation shares. Live parameters
//! reach a running simulation through `Stepper::set_dt` and `Stepper::tune`.

pub mod adaptation;
pub mod clock;
pub mod dt;
pub mod error;
pub mod setup;
pub mod stages;
pub mod state;

pub use adaptation::{Adaptation, Tick};
pub use clock::Clock;
pub use dt::{Asker, Integrator, StableStep, dt_policy};
pub use error::SimError;
pub use stages::{Lap, Stages, StepWall};
pub use state::State;

use crate::frame::Frame;
use crate::scene::{Scene, SceneError};

/// Static facts about a built simulation.
#[derive(Debug, Clone)]
pub struct SimInfo {
    pub dim: usize,
    pub nodes: usize,
    pub bonds: usize,
    pub dt: f64,
    /// The sharp stable limit of the integrator (power iteration on the operator).
    pub stable_dt: f64,
    /// A guaranteed, conservative bound: (3.8) for velocity-Verlet, Gershgorin discs for
    /// forward Euler.
    pub gershgorin_dt: f64,
    /// The integrator whose limit these are.
    pub integrator: Integrator,
    pub total_steps: u64,
    pub frame_every: u64,
    /// Solver memory (bond and node arrays) per directed bond.
    pub bytes_per_bond: f64,
    /// Mean nodes per updated node's stencil, the node itself included: the family (standard
    /// scheme, the papers' counts: 2m+1 in 1D, 441 for m = 12 in 2D) or the collocation set.
    pub stencil: f64,
    /// The names of the scene's `[[metrics.crack_angle]]`: each angle travels as the frame
    /// scalar `crack_angle_deg/<name>`, present once that crack is found.
    pub crack_angles: Vec<String>,
    /// Further lines for `check` (an absorbing layer's conditioning).
    pub notes: Vec<String>,
}

impl SimInfo {
    /// The stable step the run's Δt is checked against (live `set dt` included).
    pub fn stable_step(&self) -> StableStep {
        StableStep {
            sharp: self.stable_dt,
            guaranteed: self.gershgorin_dt,
            integrator: self.integrator,
        }
    }
}

/// The size of a built simulation, for its [`SimInfo`].
#[derive(Debug, Clone, Copy)]
pub struct Size {
    pub dim: usize,
    pub nodes: usize,
    /// Directed bonds, or operator entries.
    pub bonds: usize,
    pub bytes_per_bond: f64,
    pub stencil: f64,
}

impl Size {
    /// The size of a bond-based discretization: each node's stencil is its family and itself.
    pub fn of_bonds(dim: usize, nodes: usize, bonds: usize, bytes_per_bond: f64) -> Size {
        Size {
            dim,
            nodes,
            bonds,
            bytes_per_bond,
            stencil: bonds as f64 / nodes.max(1) as f64 + 1.0,
        }
    }
}

/// What every simulation's run holds besides its state: the clock, the stable step it was
/// checked against, the frame cadence, the stage timers and the wall time per step.
#[derive(Debug, Clone)]
pub struct RunState {
    pub clock: Clock,
    pub stable: StableStep,
    pub frame_every: u64,
    pub stages: Stages,
    pub step_wall: StepWall,
    /// The names of the scene's crack-angle measures (for [`SimInfo::crack_angles`]).
    pub crack_angles: Vec<String>,
}

impl RunState {
    /// The run of `scene` with its stable step: Δt and its refusal, the end, the cadence, and
    /// the integrator's named stages.
    pub fn new(
        scene: &Scene,
        stable: StableStep,
        stages: &[&'static str],
    ) -> Result<RunState, SceneError> {
        let clock = setup::clock(scene, &stable)?;
        Ok(RunState {
            frame_every: setup::frame_every(scene, clock.total_steps()),
            clock,
            stable,
            stages: Stages::new(stages),
            step_wall: StepWall::default(),
            crack_angles: scene.crack_angles.iter().map(|c| c.name.clone()).collect(),
        })
    }

    /// Whether a frame follows the next step at this run's cadence (its end included): what
    /// a step computes only to be shown can be skipped on the others.
    pub fn frame_due_next(&self) -> bool {
        let next = self.clock.step() + 1;
        next.is_multiple_of(self.frame_every.max(1)) || next >= self.clock.total_steps()
    }

    pub fn info(&self, size: Size) -> SimInfo {
        SimInfo {
            dim: size.dim,
            nodes: size.nodes,
            bonds: size.bonds,
            dt: self.clock.dt(),
            stable_dt: self.stable.sharp,
            gershgorin_dt: self.stable.guaranteed,
            integrator: self.stable.integrator,
            total_steps: self.clock.total_steps(),
            frame_every: self.frame_every,
            bytes_per_bond: size.bytes_per_bond,
            stencil: size.stencil,
            crack_angles: self.crack_angles.clone(),
            notes: Vec::new(),
        }
    }

    /// The frame scalars every run has: wall time per step since the last frame, and the time
    /// spent in each stage.
    pub fn timing_scalars(&mut self) -> Vec<(String, f64)> {
        let wall = self.step_wall.per_step(self.clock.step());
        let mut scalars = vec![("timing/step_wall_s".to_string(), wall)];
        scalars.extend(self.stages.scalars());
        scalars
    }
}

/// A live parameter that changes a running simulation in place.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Param {
    /// The hybrid switching margin χ of (3.80), in (0, 1].
    Chi(f64),
    /// φ_c of particle splitting, zeng2024 (15).
    SplitDamage(f64),
    /// α of particle splitting, zeng2024 (16).
    SplitStrain(f64),
    /// φ_applied of the NNPP overpotential (3.102), V.
    AppliedPotential(f64),
}

impl Param {
    /// What the parameter needs, for the note given where a scene has none.
    pub fn unused_note(&self) -> &'static str {
        match self {
            Param::Chi(_) => "this scene has no hybrid scheme: χ is recorded only",
            Param::SplitDamage(_) | Param::SplitStrain(_) => {
                "this scene has no particle splitting ([refinement]): φ_c and α are recorded only"
            }
            Param::AppliedPotential(_) => {
                "this scene has no NNPP reactions ([nernst_planck.reactions]): the applied \
                 potential is recorded only"
            }
        }
    }
}

/// The dimension-erased simulation used by the CLI, sinks, panel and benchmarks.
pub trait Stepper: Send {
    fn step(&mut self) -> Result<(), SimError>;
    fn frame(&mut self) -> Frame;
    fn info(&self) -> SimInfo;
    fn run(&self) -> &RunState;
    fn run_mut(&mut self) -> &mut RunState;
    /// What a checkpoint holds: the clock and every array the step reads that the scene does
    /// not determine (positions, velocities, bond states, masks, fields, phases, …).
    fn save_state(&self) -> State;
    /// Continues from a state saved by the same scene: the run goes on bit for bit. An error
    /// (nothing changed) if the state does not fit this scene.
    fn restore_state(&mut self, state: &State) -> Result<(), String>;

    fn clock(&self) -> &Clock {
        &self.run().clock
    }

    fn stages(&self) -> &Stages {
        &self.run().stages
    }

    fn steps_done(&self) -> u64 {
        self.clock().step()
    }

    fn time(&self) -> f64 {
        self.clock().time()
    }

    /// A new Δt from the next step on; the end time is kept.
    fn set_dt(&mut self, dt: f64) {
        self.run_mut().clock.set_dt(dt);
    }

    /// Changes a live parameter in place; an error (with the reason) where the scene has no
    /// use for it.
    fn tune(&mut self, param: Param) -> Result<(), String> {
        Err(param.unused_note().into())
    }

    /// True when an iterative solve has met its tolerance (dynamic relaxation): the run stops
    /// there, before its step cap.
    fn converged(&self) -> bool {
        false
    }
}
