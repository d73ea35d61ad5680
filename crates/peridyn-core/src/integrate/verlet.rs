//! Velocity-Verlet, thesis (3.5)–(3.6), (3.9): half kick, drift, force, half kick — the one
//! explicit driver of every second-order physics (elastodynamics, dual-horizon OSB, scalar
//! waves). [`step`] owns the sequence, the stage timers and the unstable-step stop; the body
//! supplies its kick-drift and constraints ([`VerletBody`]), its scheme the forces and the
//! second kick ([`ForceTerms`]), and plug-ins ([`Adaptation`]) run between the stages.

use rayon::prelude::*;

use crate::solver::adaptation::{Adaptation, Tick};
use crate::solver::{Lap, RunState, SimError, Stages};

/// What a velocity-Verlet body supplies to [`step`].
pub trait VerletBody {
    /// The first half kick u̇ += (Δt/2) ü, the held velocities, and the drift y += Δt u̇.
    fn kick_drift(&mut self, dt: f64);
    /// Held velocities and displacements, after the second half kick.
    fn constraints(&mut self);
    /// A step stops the run when its largest motion max |u̇| Δt exceeds half this length.
    fn blowup_length(&self) -> f64;
}

/// How a body's forces are evaluated (its scheme), and the second half kick they drive. A
/// scheme is an [`Adaptation`] too: its hooks run before the plug-ins' at each point.
pub trait ForceTerms<B>: Adaptation<B> {
    /// Forces at the drifted positions; strain-energy densities too where `energy` is set (a
    /// frame follows the step).
    fn forces(&mut self, body: &mut B, energy: bool);
    /// ü from the forces and the second half kick u̇ += (Δt/2) ü; returns the largest squared
    /// speed (NaN if any is NaN: a blow-up check must see it).
    fn kick(&mut self, body: &mut B, dt: f64) -> f64;
}

pub const KICK_DRIFT: &str = "kick_drift";
pub const FORCES: &str = "forces";
pub const KICK: &str = "kick";
pub const CONSTRAINTS: &str = "constraints";

/// The stages a run of [`step`] times, in the order they are listed: the driver's own and
/// those the scheme and plug-ins name (`switching` before the forces, the others after).
pub fn stage_names<B: 'static>(
    terms: &dyn ForceTerms<B>,
    plugins: &[Box<dyn Adaptation<B>>],
) -> Vec<&'static str> {
    let named: Vec<&'static str> = terms
        .stage()
        .into_iter()
        .chain(plugins.iter().filter_map(|p| p.stage()))
        .collect();
    let mut names = vec![KICK_DRIFT];
    names.extend(named.iter().filter(|&&n| n == "switching"));
    names.extend([FORCES, KICK, CONSTRAINTS]);
    for n in named {
        if !names.contains(&n) {
            names.push(n);
        }
    }
    names
}

/// One velocity-Verlet step of `body`: hooks before the step, kick-drift, hooks on the moved
/// body, forces, second kick, damping hooks, constraints and their hooks, the step's closing
/// hooks; then the clock advances, and a step whose largest motion exceeds half the body's
/// blow-up length (or is NaN) stops the run.
pub fn step<B: VerletBody + 'static>(
    body: &mut B,
    terms: &mut dyn ForceTerms<B>,
    plugins: &mut [Box<dyn Adaptation<B>>],
    run: &mut RunState,
) -> Result<(), SimError> {
    let tick = Tick::next(&run.clock, run.stable.sharp);
    let energy = run.frame_due_next();
    let stages = &mut run.stages;
    let at = |stages: &Stages, name| stages.index(name).unwrap_or(0);
    let (kick_drift, kick) = (at(stages, KICK_DRIFT), at(stages, KICK));
    let mut lap = Lap::start();
    each(terms, plugins, stages, &mut lap, kick_drift, |p| {
        p.before_step(body, tick)
    });
    body.kick_drift(tick.dt);
    lap.charge(stages, kick_drift);
    each(terms, plugins, stages, &mut lap, kick_drift, |p| {
        p.after_move(body, tick)
    });
    terms.forces(body, energy);
    lap.charge(stages, at(stages, FORCES));
    let max_speed2 = terms.kick(body, tick.dt);
    lap.charge(stages, kick);
    terms.damp(body, tick);
    for p in plugins.iter_mut() {
        p.damp(body, tick);
    }
    lap.charge(stages, kick);
    body.constraints();
    let constraints = at(stages, CONSTRAINTS);
    lap.charge(stages, constraints);
    each(terms, plugins, stages, &mut lap, constraints, |p| {
        p.after_constraints(body, tick)
    });
    each(terms, plugins, stages, &mut lap, constraints, |p| {
        p.after_step(body, tick)
    });
    run.clock.advance();
    let max_speed = max_speed2.sqrt();
    if max_speed.is_nan() || max_speed * tick.dt > 0.5 * body.blowup_length() {
        return Err(SimError::Unstable {
            step: run.clock.step(),
            time: run.clock.time(),
            max_speed,
            dt: tick.dt,
            stable_dt: run.stable.sharp,
        });
    }
    Ok(())
}

/// Runs `hook` on the scheme and then each plug-in, timing each in its own stage (`default`
/// for those that name none).
fn each<B: 'static>(
    terms: &mut dyn ForceTerms<B>,
    plugins: &mut [Box<dyn Adaptation<B>>],
    stages: &mut Stages,
    lap: &mut Lap,
    default: usize,
    mut hook: impl FnMut(&mut dyn Adaptation<B>),
) {
    let mut timed = |p: &mut dyn Adaptation<B>| {
        let stage = p.stage().and_then(|s| stages.index(s)).unwrap_or(default);
        hook(p);
        lap.charge(stages, stage);
    };
    timed(terms);
    for p in plugins.iter_mut() {
        timed(&mut **p);
    }
}

/// u̇ += (Δt/2) ü.
pub fn half_kick<const D: usize>(velocity: &mut [[f64; D]], acceleration: &[[f64; D]], dt: f64) {
    velocity
        .par_iter_mut()
        .zip(acceleration)
        .with_min_len(4096)
        .for_each(|(v, a)| {
            for k in 0..D {
                v[k] += 0.5 * dt * a[k];
            }
        });
}

/// Second half kick of one node, u̇ += (Δt/2) ü; returns its squared speed (the caller
/// fuses this into the pass that computes ü).
#[inline(always)]
pub fn kick_node<const D: usize>(velocity: &mut [f64; D], acceleration: &[f64; D], dt: f64) -> f64 {
    let mut s2 = 0.0;
    for k in 0..D {
        velocity[k] += 0.5 * dt * acceleration[k];
        s2 += velocity[k] * velocity[k];
    }
    s2
}

/// max(a, b), NaN if either is NaN (a blow-up check must see a NaN speed).
#[inline]
pub fn max_or_nan(a: f64, b: f64) -> f64 {
    if a.is_nan() || b.is_nan() {
        f64::NAN
    } else {
        a.max(b)
    }
}

/// y += Δt u̇.
pub fn drift<const D: usize>(position: &mut [[f64; D]], velocity: &[[f64; D]], dt: f64) {
    position
        .par_iter_mut()
        .zip(velocity)
        .with_min_len(4096)
        .for_each(|(y, v)| {
            for k in 0..D {
                y[k] += dt * v[k];
            }
        });
}
