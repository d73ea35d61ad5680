//! The time step: the stable bound a scene's operator sets, and the one policy for a requested
//! Δt against it wherever a Δt is asked for (a preset's `time.dt` when the run is built, a live
//! `set dt … [override]`): a step is given in seconds or as a fraction of the stable bound, must
//! come out a finite number > 0, and may exceed the bound only when the user says so. The
//! refusal says how to say so where it was asked.

use crate::scene::StepSize;

/// The stable step of a scene's operator and how it was found (for messages and `check`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StableStep {
    /// The limit `dt = "F stable"` refers to and an absolute Δt is checked against.
    pub sharp: f64,
    /// A guaranteed but conservative bound: (3.8) or Gershgorin discs.
    pub guaranteed: f64,
    pub integrator: Integrator,
}

/// The explicit integrator whose limit a stable step is.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Integrator {
    /// 2/√λ_max of the mass-normalized stiffness.
    Verlet,
    /// 2/ρ of the (diffusion) operator.
    Euler,
    /// One global solve: no step limit.
    Static,
    /// Semi-implicit (Newton) steps: no step limit, any Δt.
    Implicit,
}

impl StableStep {
    /// No limit (a static solve).
    pub const NONE: StableStep = StableStep {
        sharp: f64::INFINITY,
        guaranteed: f64::INFINITY,
        integrator: Integrator::Static,
    };

    /// How the bound was found, for refusals.
    fn describe(&self) -> String {
        match self.integrator {
            Integrator::Verlet => format!(
                "velocity-Verlet's 2/√λ_max, λ_max by power iteration; the conservative (3.8) \
                 estimate is {:.4e} s",
                self.guaranteed
            ),
            Integrator::Euler => "forward Euler's 2/ρ, ρ the operator's spectral radius (power \
                                  iteration or Gershgorin discs)"
                .into(),
            Integrator::Static => "no limit".into(),
            Integrator::Implicit => "no limit (an implicit step)".into(),
        }
    }
}

/// Where a Δt was asked for: it decides how a refusal tells the user to exceed the bound.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Asker {
    /// A preset's `time.dt` (`time.allow_unstable = true` lifts the bound).
    Preset,
    /// A live `set dt` command (a trailing `override` lifts the bound).
    Command,
}

/// The Δt that `requested` means against `bound`, or why it is refused. A fraction of the
/// bound of an implicit step refers to explicit Euler's bound, kept in `guaranteed` (the
/// implicit step itself has none).
pub fn dt_policy(
    requested: StepSize,
    bound: &StableStep,
    allow_unstable: bool,
    asker: Asker,
) -> Result<f64, String> {
    let dt = match requested {
        StepSize::Absolute(dt) => dt,
        StepSize::FractionOfStable(f) if bound.integrator == Integrator::Implicit => {
            f * bound.guaranteed
        }
        StepSize::FractionOfStable(f) => f * bound.sharp,
    };
    if !(dt.is_finite() && dt > 0.0) {
        return Err(format!("Δt must be > 0 (got {dt:e} s)"));
    }
    if dt <= bound.sharp || allow_unstable {
        return Ok(dt);
    }
    let above = format!(
        "{dt:.4e} s is {:.2}× the stable bound {:.4e} s",
        dt / bound.sharp,
        bound.sharp
    );
    Err(match asker {
        Asker::Preset => format!(
            "{above} ({}); lower it, use dt = \"0.9 stable\", or set time.allow_unstable = true",
            bound.describe()
        ),
        Asker::Command => format!("Δt = {above}; add `override` to run above it"),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    const VERLET: StableStep = StableStep {
        sharp: 2e-8,
        guaranteed: 1e-8,
        integrator: Integrator::Verlet,
    };

    #[test]
    fn a_step_within_the_bound_is_taken_as_given() {
        for asker in [Asker::Preset, Asker::Command] {
            let abs = dt_policy(StepSize::Absolute(1.5e-8), &VERLET, false, asker);
            assert_eq!(abs, Ok(1.5e-8));
            let frac = dt_policy(StepSize::FractionOfStable(0.5), &VERLET, false, asker);
            assert_eq!(frac, Ok(1e-8));
            // The bound itself is stable.
            let at = dt_policy(StepSize::FractionOfStable(1.0), &VERLET, false, asker);
            assert_eq!(at, Ok(2e-8));
        }
    }

    #[test]
    fn above_the_bound_needs_leave_and_the_refusal_says_how_to_give_it() {
        let preset = dt_policy(StepSize::Absolute(3e-8), &VERLET, false, Asker::Preset);
        let e = preset.unwrap_err();
        assert!(
            e.starts_with("3.0000e-8 s is 1.50× the stable bound 2.0000e-8 s"),
            "{e}"
        );
        assert!(e.contains("time.allow_unstable = true"), "{e}");
        let live = dt_policy(
            StepSize::FractionOfStable(1.01),
            &VERLET,
            false,
            Asker::Command,
        );
        let e = live.unwrap_err();
        assert!(
            e.starts_with("Δt = 2.0200e-8 s is 1.01× the stable bound"),
            "{e}"
        );
        assert!(e.ends_with("add `override` to run above it"), "{e}");
        for asker in [Asker::Preset, Asker::Command] {
            let allowed = dt_policy(StepSize::Absolute(3e-8), &VERLET, true, asker);
            assert_eq!(allowed, Ok(3e-8));
        }
    }

    #[test]
    fn a_step_that_is_not_a_positive_number_is_refused_even_with_leave() {
        for requested in [
            StepSize::Absolute(0.0),
            StepSize::Absolute(-1e-9),
            StepSize::Absolute(f64::NAN),
            StepSize::FractionOfStable(0.5),
        ] {
            let unbounded = StableStep::NONE;
            let bound = match requested {
                // Half of no limit is no step at all.
                StepSize::FractionOfStable(_) => &unbounded,
                StepSize::Absolute(_) => &VERLET,
            };
            let e = dt_policy(requested, bound, true, Asker::Command).unwrap_err();
            assert!(e.contains("> 0"), "{requested:?}: {e}");
        }
    }

    #[test]
    fn a_fraction_of_an_implicit_bound_is_one_of_explicit_eulers() {
        let implicit = StableStep {
            sharp: f64::INFINITY,
            guaranteed: 4e-3,
            integrator: Integrator::Implicit,
        };
        for asker in [Asker::Preset, Asker::Command] {
            let dt = dt_policy(StepSize::FractionOfStable(0.5), &implicit, false, asker);
            assert_eq!(dt, Ok(2e-3));
            // Any absolute step: the implicit step has no limit.
            let big = dt_policy(StepSize::Absolute(1.0), &implicit, false, asker);
            assert_eq!(big, Ok(1.0));
        }
    }
}
