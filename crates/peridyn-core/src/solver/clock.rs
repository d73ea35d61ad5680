//! The simulation clock: step count, time, Δt and the end of the run, owned in one place so
//! that every reader of t (sources, held values, error norms, switching events, frames) reads
//! the same time, also after Δt changed while running.

use super::state::State;
use crate::scene::Duration;

/// Step, t, Δt and end. Time is `t₀ + (n − n₀) Δt` since the last Δt change at (t₀, n₀): no
/// drift from summing Δt, and exactly `n Δt` for a run whose Δt never changed.
#[derive(Debug, Clone, PartialEq)]
pub struct Clock {
    step: u64,
    dt: f64,
    /// Time and step at the last Δt change.
    origin: (f64, u64),
    /// The end time, kept when Δt changes.
    end: f64,
    total_steps: u64,
}

/// Steps of Δt that reach `span`: the last one may end past it by less than one step (a
/// rounding error of 10⁻⁹ of a step does not add one).
fn steps_to_cover(span: f64, dt: f64) -> u64 {
    ((span / dt) - 1e-9).ceil().max(0.0) as u64
}

impl Clock {
    /// A clock at t = 0 for a run of `duration` with step `dt` (> 0). A step count is turned
    /// into its end time `n Δt`, so that a later Δt change keeps the end time either way.
    pub fn new(dt: f64, duration: Duration) -> Clock {
        let (end, total_steps) = match duration {
            Duration::Steps(n) => (n as f64 * dt, n),
            Duration::End(t) => (t, steps_to_cover(t, dt).max(1)),
        };
        Clock {
            step: 0,
            dt,
            origin: (0.0, 0),
            end,
            total_steps,
        }
    }

    /// A run of one step that takes no time (a static solve).
    pub fn single_step() -> Clock {
        Clock {
            step: 0,
            dt: 0.0,
            origin: (0.0, 0),
            end: 0.0,
            total_steps: 1,
        }
    }

    pub fn step(&self) -> u64 {
        self.step
    }

    pub fn dt(&self) -> f64 {
        self.dt
    }

    /// The time after `self.step()` steps.
    pub fn time(&self) -> f64 {
        self.time_at(self.step)
    }

    /// The time at step `n` of the current Δt (n ≥ the step of the last Δt change).
    pub fn time_at(&self, n: u64) -> f64 {
        let (t0, n0) = self.origin;
        t0 + n.saturating_sub(n0) as f64 * self.dt
    }

    /// The time the step being taken ends at.
    pub fn next_time(&self) -> f64 {
        self.time_at(self.step + 1)
    }

    pub fn end_time(&self) -> f64 {
        self.end
    }

    /// Steps of the whole run: those done plus those left to the end time.
    pub fn total_steps(&self) -> u64 {
        self.total_steps
    }

    pub fn done(&self) -> bool {
        self.step >= self.total_steps
    }

    /// One step was taken.
    pub fn advance(&mut self) {
        self.step += 1;
    }

    /// A new Δt from the next step on; the end time is kept and the steps left recounted.
    pub fn set_dt(&mut self, dt: f64) {
        self.origin = (self.time(), self.step);
        self.dt = dt;
        if dt > 0.0 {
            self.total_steps = self.step + steps_to_cover(self.end - self.origin.0, dt);
        }
    }
}

impl Clock {
    /// Into a checkpoint's state.
    pub fn save(&self, state: &mut State) {
        state.put_u64(
            "clock/steps",
            vec![self.step, self.origin.1, self.total_steps],
        );
        state.put_f64("clock/times", vec![self.dt, self.origin.0, self.end]);
    }

    /// From a checkpoint's state.
    pub fn restore(state: &State) -> Result<Clock, String> {
        let steps = state.u64("clock/steps", 3)?;
        let times = state.f64("clock/times", 3)?;
        Ok(Clock {
            step: steps[0],
            dt: times[0],
            origin: (times[1], steps[1]),
            end: times[2],
            total_steps: steps[2],
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn time_is_steps_times_dt_until_dt_changes() {
        let mut c = Clock::new(1e-5, Duration::End(0.01));
        assert_eq!(c.total_steps(), 1000);
        for _ in 0..500 {
            c.advance();
        }
        assert_eq!(c.time(), 500.0 * 1e-5);
        c.set_dt(5e-6);
        assert_eq!(c.time(), 500.0 * 1e-5);
        assert_eq!(c.total_steps(), 1500, "the end time is kept");
        c.advance();
        assert!((c.time() - (5e-3 + 5e-6)).abs() < 1e-18);
        assert!((c.time_at(1500) - 0.01).abs() < 1e-15);
    }

    #[test]
    fn a_step_count_becomes_an_end_time() {
        let mut c = Clock::new(2.0, Duration::Steps(10));
        assert_eq!((c.total_steps(), c.end_time()), (10, 20.0));
        for _ in 0..4 {
            c.advance();
        }
        c.set_dt(4.0);
        assert_eq!(
            c.total_steps(),
            4 + 3,
            "8 of 20 s done, 12 s left in steps of 4 s"
        );
        while !c.done() {
            c.advance();
        }
        assert_eq!(c.time(), 20.0);
    }

    #[test]
    fn a_saved_clock_restores_to_the_same_time() {
        let mut c = Clock::new(1e-5, Duration::End(0.01));
        (0..7).for_each(|_| c.advance());
        c.set_dt(3e-6);
        c.advance();
        let mut state = State::default();
        c.save(&mut state);
        assert_eq!(Clock::restore(&state).unwrap(), c);
    }

    #[test]
    fn an_end_time_not_a_multiple_of_dt_is_covered() {
        let c = Clock::new(0.3, Duration::End(1.0));
        assert_eq!(c.total_steps(), 4);
        assert!(c.time_at(4) >= 1.0);
    }
}
