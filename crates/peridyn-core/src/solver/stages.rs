//! Named stage timers: each integrator names its own stages (velocity-Verlet's kick, drift,
//! forces; forward Euler's rates and update; a static solve's solve) and charges wall time to
//! them with a [`Lap`] stopwatch.

use std::time::{Duration, Instant};

/// Wall time spent in each named stage of `step()`.
#[derive(Debug, Clone)]
pub struct Stages {
    names: Vec<&'static str>,
    spent: Vec<Duration>,
}

impl Stages {
    pub fn new(names: &[&'static str]) -> Stages {
        Stages {
            names: names.to_vec(),
            spent: vec![Duration::ZERO; names.len()],
        }
    }

    /// The index of the stage called `name`, if the integrator has it.
    pub fn index(&self, name: &str) -> Option<usize> {
        self.names.iter().position(|n| *n == name)
    }

    /// Adds `d` to stage `stage` (an index into the names).
    pub fn add(&mut self, stage: usize, d: Duration) {
        self.spent[stage] += d;
    }

    /// Time spent so far in the stage called `name`, if the integrator has it.
    pub fn get(&self, name: &str) -> Option<Duration> {
        self.index(name).map(|k| self.spent[k])
    }

    /// (name, time spent) in the integrator's order.
    pub fn named(&self) -> impl Iterator<Item = (&'static str, Duration)> + '_ {
        self.names.iter().copied().zip(self.spent.iter().copied())
    }

    /// The frame scalars `timing/<stage>_total_s`.
    pub fn scalars(&self) -> impl Iterator<Item = (String, f64)> + '_ {
        self.named()
            .map(|(n, d)| (format!("timing/{n}_total_s"), d.as_secs_f64()))
    }
}

/// A stopwatch over the stages of one step: `charge(stages, k)` adds the time since the
/// previous charge (or the start) to stage k.
pub struct Lap(Instant);

impl Lap {
    pub fn start() -> Lap {
        Lap(Instant::now())
    }

    pub fn charge(&mut self, stages: &mut Stages, stage: usize) {
        let now = Instant::now();
        stages.add(stage, now - self.0);
        self.0 = now;
    }
}

/// Mean wall time per step between frames (the `timing/step_wall_s` series).
#[derive(Debug, Clone)]
pub struct StepWall {
    last: (u64, Instant),
}

impl Default for StepWall {
    fn default() -> Self {
        StepWall {
            last: (0, Instant::now()),
        }
    }
}

impl StepWall {
    /// Seconds per step since the previous call (0 when no step was taken).
    pub fn per_step(&mut self, step: u64) -> f64 {
        let now = Instant::now();
        let (last_step, last_time) = self.last;
        let steps = step.saturating_sub(last_step);
        self.last = (step, now);
        if steps > 0 {
            (now - last_time).as_secs_f64() / steps as f64
        } else {
            0.0
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn laps_charge_their_stage() {
        let mut stages = Stages::new(&["a", "b"]);
        let mut lap = Lap::start();
        std::thread::sleep(Duration::from_millis(2));
        lap.charge(&mut stages, 1);
        lap.charge(&mut stages, 0);
        assert!(stages.get("b").unwrap() >= Duration::from_millis(2));
        assert!(stages.get("a").unwrap() < stages.get("b").unwrap());
        assert_eq!(stages.get("c"), None);
        let names: Vec<_> = stages.scalars().map(|(n, _)| n).collect();
        assert_eq!(names, ["timing/a_total_s", "timing/b_total_s"]);
    }
}
