//! A simulation whose time step can change while it runs. `Simulation` keeps one Δt and
//! computes time as steps × Δt; this wrapper keeps the clock across changes, recomputes the
//! number of steps left to the scene's end time, and corrects the time in frames and errors.

use crate::frame::Frame;
use crate::scalar::ScalarSimulation;
use crate::scene::{Duration, Physics, Scene, SceneError};
use crate::sim::{SimError, SimInfo, Simulation, StageTimers, Stepper};

/// A `Stepper` whose Δt can be set between steps.
pub trait Live: Stepper {
    fn set_dt(&mut self, dt: f64);
    /// Sets the hybrid switching margin χ in place; an error without a hybrid scheme.
    fn set_chi(&mut self, chi: f64) -> Result<(), String>;
    fn as_stepper(&mut self) -> &mut dyn Stepper;
}

/// A simulation whose time step can be set from outside: the one field `Controlled` needs.
/// Implement it for every simulation type `sim::build` can return, and add its arm to `build`.
pub trait TimeStepped: Stepper {
    fn dt_mut(&mut self) -> &mut f64;
    /// The scene's duration (an end time is kept when Δt changes; a step count is not).
    fn duration(&self) -> Duration;
    /// The hybrid switching margin χ, where the simulation has one.
    fn set_chi(&mut self, _chi: f64) -> Result<(), String> {
        Err("this scene has no hybrid scheme: χ is recorded only".into())
    }
}

impl<const D: usize> TimeStepped for Simulation<D> {
    fn dt_mut(&mut self) -> &mut f64 {
        &mut self.dt
    }

    fn duration(&self) -> Duration {
        self.scene.time.duration
    }

    fn set_chi(&mut self, chi: f64) -> Result<(), String> {
        match self.hybrid.as_mut() {
            Some(h) => h.set_chi(chi),
            None => Err("this scene has no hybrid scheme: χ is recorded only".into()),
        }
    }
}

impl<const D: usize> TimeStepped for ScalarSimulation<D> {
    fn dt_mut(&mut self) -> &mut f64 {
        self.dt_mut()
    }

    fn duration(&self) -> Duration {
        self.scene().time.duration
    }
}

/// Builds a live simulation of a scene in its dimension (the same dispatch as `sim::build`).
pub fn build(scene: &Scene) -> Result<Box<dyn Live>, SceneError> {
    if scene.physics != Physics::Dynamics {
        return Ok(match scene.dim {
            1 => Box::new(Controlled::new(ScalarSimulation::<1>::new(scene)?)),
            2 => Box::new(Controlled::new(ScalarSimulation::<2>::new(scene)?)),
            _ => Box::new(Controlled::new(ScalarSimulation::<3>::new(scene)?)),
        });
    }
    Ok(match scene.dim {
        1 => Box::new(Controlled::new(Simulation::<1>::new(scene)?)),
        2 => Box::new(Controlled::new(Simulation::<2>::new(scene)?)),
        _ => Box::new(Controlled::new(Simulation::<3>::new(scene)?)),
    })
}

pub struct Controlled<S> {
    sim: S,
    /// Time and step at the last Δt change.
    time0: f64,
    step0: u64,
    total_steps: u64,
    /// The current Δt (kept here: `info()` may cost more than a field read).
    dt: f64,
}

impl<S: TimeStepped> Controlled<S> {
    pub fn new(sim: S) -> Self {
        let info = sim.info();
        Controlled {
            sim,
            time0: 0.0,
            step0: 0,
            total_steps: info.total_steps,
            dt: info.dt,
        }
    }
}

impl<S: TimeStepped + 'static> Live for Controlled<S> {
    fn set_dt(&mut self, dt: f64) {
        self.time0 = self.time();
        self.step0 = self.sim.steps_done();
        *self.sim.dt_mut() = dt;
        self.dt = dt;
        if let Duration::End(end) = self.sim.duration() {
            let left = ((end - self.time0) / dt - 1e-9).ceil().max(0.0) as u64;
            self.total_steps = self.step0 + left;
        }
    }

    fn set_chi(&mut self, chi: f64) -> Result<(), String> {
        self.sim.set_chi(chi)
    }

    fn as_stepper(&mut self) -> &mut dyn Stepper {
        self
    }
}

impl<S: TimeStepped> Stepper for Controlled<S> {
    fn step(&mut self) -> Result<(), SimError> {
        let time = self.time() + self.dt;
        self.sim.step().map_err(|mut e| {
            // The simulation's own clock is steps × its current Δt: give the true time.
            if let SimError::Unstable { time: t, .. } | SimError::Diverged { time: t, .. } = &mut e
            {
                *t = time;
            }
            e
        })
    }

    fn frame(&mut self) -> Frame {
        let mut frame = self.sim.frame();
        frame.time = self.time();
        frame
    }

    fn info(&self) -> SimInfo {
        SimInfo {
            total_steps: self.total_steps,
            ..self.sim.info()
        }
    }

    fn steps_done(&self) -> u64 {
        self.sim.steps_done()
    }

    fn time(&self) -> f64 {
        self.time0 + (self.sim.steps_done() - self.step0) as f64 * self.dt
    }

    fn timers(&self) -> &StageTimers {
        self.sim.timers()
    }

    fn crack_angles(&self) -> Vec<(String, Option<f64>)> {
        self.sim.crack_angles()
    }

    fn broken_bonds(&self) -> u64 {
        self.sim.broken_bonds()
    }

    fn relative_error(&self) -> Option<f64> {
        self.sim.relative_error()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn time_is_kept_across_dt_changes_and_the_end_time_is_kept() {
        let scene = Scene::load("vibrating-plate", Some("small")).unwrap();
        let scene = Scene {
            time: crate::scene::TimeSpec {
                duration: Duration::End(1e-5),
                ..scene.time
            },
            ..scene
        };
        let mut sim = build(&scene).unwrap();
        let dt0 = sim.info().dt;
        for _ in 0..10 {
            sim.step().unwrap();
        }
        sim.set_dt(0.5 * dt0);
        for _ in 0..10 {
            sim.step().unwrap();
        }
        let expected = 10.0 * dt0 + 10.0 * 0.5 * dt0;
        assert!((sim.time() - expected).abs() < 1e-12 * expected);
        assert!((sim.frame().time - expected).abs() < 1e-12 * expected);
        let left = sim.info().total_steps - sim.steps_done();
        let end = sim.time() + left as f64 * 0.5 * dt0;
        assert!(
            end >= 1e-5 * (1.0 - 1e-9) && end < 1e-5 + 0.5 * dt0,
            "{end}"
        );
    }
}
