//! The simulations of every physics and the one builder above them: a scene becomes a
//! dimension-erased [`Stepper`]. Nothing outside this module names a concrete simulation type
//! (checked by `tests/suite/architecture.rs`).

pub mod dual_horizon;
pub mod dynamics;
mod initial;
pub mod nernst_planck;
pub mod scalar;

pub use dual_horizon::DualHorizonSimulation;
pub use dynamics::DynamicSimulation;
pub use nernst_planck::NernstPlanckSimulation;
pub use scalar::{DiffusionSimulation, StaticSimulation, WaveSimulation};

use crate::scene::{Physics, Scene, SceneError};
use crate::solver::Stepper;

/// Builds the simulation of a scene, in its dimension and for its physics.
pub fn build(scene: &Scene) -> Result<Box<dyn Stepper>, SceneError> {
    fn boxed<S: Stepper + 'static>(
        sim: Result<S, SceneError>,
    ) -> Result<Box<dyn Stepper>, SceneError> {
        Ok(Box::new(sim?))
    }
    if scene.state_based.is_some() {
        return boxed(DualHorizonSimulation::new(scene));
    }
    match (scene.physics, scene.dim) {
        (Physics::Dynamics, 1) => boxed(DynamicSimulation::<1>::new(scene)),
        (Physics::Dynamics, 2) => boxed(DynamicSimulation::<2>::new(scene)),
        (Physics::Dynamics, _) => boxed(DynamicSimulation::<3>::new(scene)),
        (Physics::NernstPlanck, 1) => boxed(NernstPlanckSimulation::<1>::new(scene)),
        (Physics::NernstPlanck, 2) => boxed(NernstPlanckSimulation::<2>::new(scene)),
        (Physics::NernstPlanck, _) => boxed(NernstPlanckSimulation::<3>::new(scene)),
        (Physics::Static, 1) => boxed(StaticSimulation::<1>::new(scene)),
        (Physics::Static, 2) => boxed(StaticSimulation::<2>::new(scene)),
        (Physics::Static, _) => boxed(StaticSimulation::<3>::new(scene)),
        (Physics::ScalarWave, 1) => boxed(WaveSimulation::<1>::new(scene)),
        (Physics::ScalarWave, 2) => boxed(WaveSimulation::<2>::new(scene)),
        (Physics::ScalarWave, _) => boxed(WaveSimulation::<3>::new(scene)),
        (Physics::Diffusion | Physics::Corrosion, 1) => boxed(DiffusionSimulation::<1>::new(scene)),
        (Physics::Diffusion | Physics::Corrosion, 2) => boxed(DiffusionSimulation::<2>::new(scene)),
        (Physics::Diffusion | Physics::Corrosion, _) => boxed(DiffusionSimulation::<3>::new(scene)),
    }
}
