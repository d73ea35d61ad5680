//! The stepping simulation: owns the state, runs `step()` as named, timed stages and emits
//! plain-data `Frame`s. It knows nothing of viewers or user interfaces.

use std::time::{Duration as WallDuration, Instant};

use rayon::prelude::*;

use crate::adapt::hybrid::{self, Hybrid};
use crate::family::{self, Families};
use crate::frame::{ClassField, Frame, NodeField};
use crate::grid::Lattice;
use crate::integrate::{self, stability, verlet};
use crate::metrics;
use crate::model::pmb::PmbLaw;
use crate::scalar::ScalarSimulation;
use crate::scene::{Condition, Duration, InitialVelocity, Physics, Scene, SceneError, StepSize};
use crate::scheme::standard::{self, NodeTerms, Quadrature, Standard};

/// A run that had to stop.
#[derive(Debug, Clone, PartialEq)]
pub enum SimError {
    /// The state blew up: a node moved more than half a spacing in one step, or became NaN.
    Unstable {
        step: u64,
        time: f64,
        max_speed: f64,
        dt: f64,
        stable_dt: f64,
    },
    /// Forward Euler diverged: the field grew past 10⁶× its scale, or became NaN.
    Diverged {
        step: u64,
        time: f64,
        max_value: f64,
        dt: f64,
        stable_dt: f64,
    },
    /// A static solve failed.
    Solve(String),
}

impl std::fmt::Display for SimError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            SimError::Unstable {
                step,
                time,
                max_speed,
                dt,
                stable_dt,
            } => write!(
                f,
                "numerical instability at step {step} (t = {time:.4e} s): max speed {max_speed:.3e} m/s \
                 moves a node more than half a spacing per step. Δt = {dt:.3e} s is {:.2}× the stable \
                 bound {stable_dt:.3e} s; lower time.dt. The run was stopped \
                 before writing a non-finite frame.",
                dt / stable_dt
            ),
            SimError::Diverged {
                step,
                time,
                max_value,
                dt,
                stable_dt,
            } => write!(
                f,
                "forward Euler diverged at step {step} (t = {time:.4e} s): max |field| = \
                 {max_value:.3e}, over 10⁶× its scale. Δt = {dt:.3e} s is {:.2}× the bound \
                 {stable_dt:.3e} s (2/ρ, ρ the operator's spectral radius by power iteration); \
                 lower time.dt. The run was stopped before writing a non-finite frame.",
                dt / stable_dt
            ),
            SimError::Solve(message) => write!(f, "static solve failed: {message}"),
        }
    }
}

impl std::error::Error for SimError {}

/// Wall time spent in each stage of `step()`.
#[derive(Debug, Clone, Default)]
pub struct StageTimers {
    pub kick_drift: WallDuration,
    pub forces: WallDuration,
    pub constraints: WallDuration,
    pub kick: WallDuration,
    /// The hybrid scheme's switching check (3.80).
    pub switching: WallDuration,
}

impl StageTimers {
    pub fn named(&self) -> [(&'static str, WallDuration); 5] {
        [
            ("kick_drift", self.kick_drift),
            ("switching", self.switching),
            ("forces", self.forces),
            ("constraints", self.constraints),
            ("kick", self.kick),
        ]
    }
}

/// Static facts about a built simulation.
#[derive(Debug, Clone)]
pub struct SimInfo {
    pub dim: usize,
    pub nodes: usize,
    pub bonds: usize,
    pub dt: f64,
    /// Velocity-Verlet's limit from the operator's spectral radius (power iteration).
    pub stable_dt: f64,
    /// The (3.8) estimate, a guaranteed (Gershgorin) but conservative bound.
    pub gershgorin_dt: f64,
    pub total_steps: u64,
    pub frame_every: u64,
    /// Solver memory (bond and node arrays) per directed bond.
    pub bytes_per_bond: f64,
    /// Mean nodes per updated node's stencil, the node itself included: the family (standard
    /// scheme, the papers' counts: 2m+1 in 1D, 441 for m = 12 in 2D) or the collocation set.
    pub stencil: f64,
}

/// Dimension-erased interface used by the CLI, sinks and benchmarks.
pub trait Stepper: Send {
    fn step(&mut self) -> Result<(), SimError>;
    fn frame(&mut self) -> Frame;
    fn info(&self) -> SimInfo;
    fn steps_done(&self) -> u64;
    fn time(&self) -> f64;
    fn timers(&self) -> &StageTimers;
    /// Final crack angles `(name, degrees)` (None where no crack was found).
    fn crack_angles(&self) -> Vec<(String, Option<f64>)> {
        Vec::new()
    }
    fn broken_bonds(&self) -> u64 {
        0
    }
    /// Relative ℓ² error (3.79) against the scene's reference solution, if it has one.
    fn relative_error(&self) -> Option<f64> {
        None
    }
}

/// Builds the simulation of a scene in its dimension.
pub fn build(scene: &Scene) -> Result<Box<dyn Stepper>, SceneError> {
    if scene.physics != Physics::Dynamics {
        return Ok(match scene.dim {
            1 => Box::new(ScalarSimulation::<1>::new(scene)?),
            2 => Box::new(ScalarSimulation::<2>::new(scene)?),
            _ => Box::new(ScalarSimulation::<3>::new(scene)?),
        });
    }
    Ok(match scene.dim {
        1 => Box::new(Simulation::<1>::new(scene)?),
        2 => Box::new(Simulation::<2>::new(scene)?),
        _ => Box::new(Simulation::<3>::new(scene)?),
    })
}

fn standard_view<'a, const D: usize>(
    lattice: &'a Lattice<D>,
    families: &'a Families,
    law: &'a PmbLaw,
    quadrature: &'a Quadrature,
    uniform_volume: Option<f64>,
) -> Standard<'a, D> {
    Standard {
        reference: &lattice.positions,
        volumes: &lattice.volumes,
        uniform_volume,
        families,
        law,
        quadrature,
    }
}

/// Power iterations for the stable-step estimate, and the margin on the eigenvalue found.
const POWER_ITERATIONS: usize = 60;
/// Power iterations for the (non-symmetric) hybrid operator's spectral radius.
const HYBRID_ITERATIONS: usize = 200;
const SPECTRAL_MARGIN: f64 = 1.02;

/// A prescribed node component: node, axis, value.
type Held = (u32, u8, f64);

pub struct Simulation<const D: usize> {
    pub scene: Scene,
    pub lattice: Lattice<D>,
    pub families: Families,
    pub intact: Vec<u8>,
    pub positions: Vec<[f64; D]>,
    pub velocities: Vec<[f64; D]>,
    pub accelerations: Vec<[f64; D]>,
    terms: Vec<NodeTerms<D>>,
    /// Σ β V'_j over each node's family: the damage denominator (see `damage_weights`).
    family_weight: Vec<f64>,
    body_force: Vec<[f64; D]>,
    held_velocity: Vec<Held>,
    held_displacement: Vec<Held>,
    pub law: PmbLaw,
    pub quadrature: Quadrature,
    pub dt: f64,
    pub stable_dt: f64,
    pub gershgorin_dt: f64,
    pub total_steps: u64,
    pub frame_every: u64,
    step: u64,
    broken: u64,
    timers: StageTimers,
    velocity_scale: f64,
    uniform_volume: Option<f64>,
    last_frame: (u64, Instant),
    /// Hybrid schemes: the Ω_s/Ω_w mask, the WLS blocks and the switching state.
    pub hybrid: Option<Hybrid<D>>,
    /// Bonds found broken with an Ω_w end (the hybrid invariant; 0 when it holds).
    pub hybrid_violations: u64,
}

impl<const D: usize> Simulation<D> {
    pub fn new(scene: &Scene) -> Result<Self, SceneError> {
        let error = |field: &str, message: String| scene.error(field, message);
        let lattice = Lattice::<D>::of_scene(scene)?;
        let radius = family::search_radius(scene.family_radius, scene.horizon, scene.spacing);
        let families = Families::build(&lattice.positions, radius);
        let mut intact = standard::intact_bonds(families.bond_count());
        for (c, crack) in scene.precracks.iter().enumerate() {
            let mut cut = 0usize;
            for i in 0..lattice.len() {
                for b in families.range(i) {
                    let j = families.neighbors[b] as usize;
                    let (a, bpos) = (&lattice.positions[i], &lattice.positions[j]);
                    if family::crosses(crack, a, bpos) || family::crosses(crack, bpos, a) {
                        intact[b] = 0;
                        cut += 1;
                    }
                }
            }
            if cut == 0 {
                return Err(error(
                    &format!("precracks[{c}]"),
                    "cuts no bond: the pre-crack lies outside the body (or between nodes)".into(),
                ));
            }
        }
        let Some(m) = scene.material.as_ref() else {
            return Err(error(
                "material",
                "dynamics needs an elastic material (density, youngs_modulus or micromodulus)"
                    .into(),
            ));
        };
        let law = PmbLaw {
            micromodulus: m.micromodulus,
            critical_stretch: m.critical_stretch.unwrap_or(f64::INFINITY),
            influence: m.influence,
            horizon: scene.horizon,
        };
        let quadrature = Quadrature {
            spacing: scene.spacing,
            horizon: scene.horizon,
            volume_correction: scene.volume_correction,
        };
        let v0 = lattice.volumes[0];
        let uniform_volume = lattice.volumes.iter().all(|&v| v == v0).then_some(v0);
        let scheme = standard_view(&lattice, &families, &law, &quadrature, uniform_volume);
        let gershgorin_dt = integrate::stable_step(m.density, &scheme.stiffness_sums());
        let masses: Vec<f64> = lattice.volumes.iter().map(|v| v * m.density).collect();
        let coefficients = scheme.linearized_coefficients(m.density);
        let lambda_max =
            stability::max_eigenvalue::<D>(lattice.len(), &masses, POWER_ITERATIONS, |u, out| {
                scheme.apply_linearized(&coefficients, &intact, u, out)
            });
        // The Rayleigh quotient approaches λ_max from below: keep a margin, and never go
        // below the guaranteed (3.8) bound.
        let mut stable_dt =
            (stability::verlet_limit(lambda_max * SPECTRAL_MARGIN)).max(gershgorin_dt);
        let hybrid = match scene.hybrid {
            None => None,
            Some(spec) => {
                let mask = hybrid::initial_mask(
                    &lattice.positions,
                    &scene.solid,
                    &scene.precracks,
                    spec.band,
                    scene.spacing,
                );
                let h = Hybrid::new(
                    spec,
                    mask,
                    &lattice.positions,
                    &families,
                    &law,
                    scene.scheme.collocation_factor,
                )
                .map_err(|e| error("hybrid.collocation_factor", e.to_string()))?;
                // The WLS blocks are not symmetric and their stencil is tighter than the
                // family's: the hybrid operator's spectral radius (power iteration) bounds Δt
                // too, and (3.8) does not cover it.
                let radius =
                    stability::spectral_radius(lattice.len() * D, HYBRID_ITERATIONS, |v, out| {
                        let u = v.as_chunks::<D>().0;
                        let out = out.as_chunks_mut::<D>().0;
                        let mask = h.mask();
                        scheme.apply_linearized_masked(&coefficients, &intact, u, out, |i| {
                            mask[i] == hybrid::WLS
                        });
                        h.apply_linearized(u, m.density, out);
                    });
                stable_dt = stable_dt.min(stability::verlet_limit(radius * SPECTRAL_MARGIN));
                Some(h)
            }
        };
        let dt = match scene.time.step {
            StepSize::Absolute(dt) => {
                if dt > stable_dt && !scene.time.allow_unstable {
                    return Err(error(
                        "time.dt",
                        format!(
                            "{dt:.4e} s is above the stable bound {stable_dt:.4e} s ({:.2}×; the \
                             conservative (3.8) estimate is {gershgorin_dt:.4e} s); lower it, use dt = \"0.9 stable\", or set time.allow_unstable = true",
                            dt / stable_dt
                        ),
                    ));
                }
                dt
            }
            StepSize::FractionOfStable(f) => f * stable_dt,
        };
        let total_steps = match scene.time.duration {
            Duration::Steps(n) => n,
            Duration::End(t) => ((t / dt) - 1e-9).ceil().max(1.0) as u64,
        };
        let frame_every = scene.output_every.unwrap_or((total_steps / 100).max(1));

        let n = lattice.len();
        let (family_weight, precracked) = scheme.damage_weights(&intact);
        let terms = precracked
            .iter()
            .map(|&w| NodeTerms {
                broken_weight: w,
                ..NodeTerms::default()
            })
            .collect();
        let mut sim = Simulation {
            positions: lattice.positions.clone(),
            velocities: vec![[0.0; D]; n],
            accelerations: vec![[0.0; D]; n],
            terms,
            family_weight,
            body_force: Vec::new(),
            held_velocity: Vec::new(),
            held_displacement: Vec::new(),
            scene: scene.clone(),
            lattice,
            families,
            intact,
            law,
            quadrature,
            dt,
            stable_dt,
            gershgorin_dt,
            total_steps,
            frame_every,
            step: 0,
            broken: 0,
            timers: StageTimers::default(),
            velocity_scale: 1.0,
            uniform_volume,
            last_frame: (0, Instant::now()),
            hybrid,
            hybrid_violations: 0,
        };

        sim.apply_initial_velocity();
        sim.collect_boundary_layers()
            .map_err(|(f, msg)| error(&f, msg))?;
        sim.apply_constraints();
        sim.velocity_scale = sim.initial_velocity_scale();
        sim.update_accelerations();
        Ok(sim)
    }

    fn apply_initial_velocity(&mut self) {
        let (lo, hi) = self.scene.solid.bounds();
        for field in &self.scene.initial_velocity {
            for (v, x) in self.velocities.iter_mut().zip(&self.lattice.positions) {
                match *field {
                    InitialVelocity::Uniform(ref value) => {
                        for k in 0..D {
                            v[k] += value[k];
                        }
                    }
                    InitialVelocity::Ramp {
                        component,
                        axis,
                        from,
                        to,
                    } => {
                        let t = (x[axis] - lo[axis]) / (hi[axis] - lo[axis]);
                        v[component] += from + t * (to - from);
                    }
                    InitialVelocity::Sine {
                        component,
                        axis,
                        amplitude,
                        modes,
                    } => {
                        let t = (x[axis] - lo[axis]) / (hi[axis] - lo[axis]);
                        v[component] += amplitude * (std::f64::consts::PI * modes * t).sin();
                    }
                }
            }
        }
    }

    fn density(&self) -> f64 {
        self.scene.material.as_ref().map_or(1.0, |m| m.density)
    }

    fn collect_boundary_layers(&mut self) -> Result<(), (String, String)> {
        let (lo, hi) = self.scene.solid.bounds();
        let eps = 1e-9 * self.scene.spacing;
        for (l, layer) in self.scene.boundary.iter().enumerate() {
            let mut count = 0;
            for (i, x) in self.lattice.positions.iter().enumerate() {
                if !layer.contains(x, &lo, &hi, eps) {
                    continue;
                }
                count += 1;
                match layer.condition {
                    Condition::Velocity => self.held_velocity.extend(
                        layer
                            .axes
                            .iter()
                            .map(|&a| (i as u32, a as u8, layer.value[a])),
                    ),
                    Condition::Displacement => self.held_displacement.extend(
                        layer
                            .axes
                            .iter()
                            .map(|&a| (i as u32, a as u8, layer.value[a])),
                    ),
                    // Scalar-field scenes only (refused for dynamics by validation).
                    Condition::Reference | Condition::Value => {}
                    Condition::BodyForce => {
                        if self.body_force.is_empty() {
                            self.body_force = vec![[0.0; D]; self.lattice.len()];
                        }
                        for &a in &layer.axes {
                            self.body_force[i][a] += layer.value[a];
                        }
                    }
                }
            }
            if count == 0 {
                return Err((
                    format!("boundary[{l}]"),
                    format!(
                        "layer `{}` selects no node; widen its region or thickness",
                        layer.name
                    ),
                ));
            }
        }
        Ok(())
    }

    fn hold_velocities(&mut self) {
        for &(i, a, value) in &self.held_velocity {
            self.velocities[i as usize][a as usize] = value;
        }
    }

    /// Held velocities and displacements (velocity layers also move the node).
    fn apply_constraints(&mut self) {
        self.hold_velocities();
        for &(i, a, value) in &self.held_displacement {
            let (i, a) = (i as usize, a as usize);
            self.positions[i][a] = self.lattice.positions[i][a] + value;
            self.velocities[i][a] = 0.0;
        }
    }

    fn initial_velocity_scale(&self) -> f64 {
        let max = self
            .velocities
            .iter()
            .map(|v| v.iter().map(|x| x * x).sum::<f64>().sqrt())
            .fold(0.0, f64::max);
        if max > 0.0 { 2.0 * max } else { 1.0 }
    }

    /// The standard scheme over this simulation's discretization.
    pub fn scheme(&self) -> Standard<'_, D> {
        standard_view(
            &self.lattice,
            &self.families,
            &self.law,
            &self.quadrature,
            self.uniform_volume,
        )
    }

    fn update_accelerations(&mut self) {
        self.compute_forces();
        self.accelerate(None);
    }

    /// Force densities at the current positions: the PMB bond loop (Ω_s rows only in a
    /// hybrid) and the WLS product on Ω_w.
    fn compute_forces(&mut self) {
        // Built from the fields it needs, so `intact` and `terms` stay free to borrow.
        let scheme = standard_view(
            &self.lattice,
            &self.families,
            &self.law,
            &self.quadrature,
            self.uniform_volume,
        );
        let mask = self.hybrid.as_ref().map(|h| h.mask());
        self.broken +=
            scheme.forces_masked(&self.positions, &mut self.intact, &mut self.terms, mask);
        if let Some(h) = self.hybrid.as_mut() {
            h.wls_forces(&self.lattice.positions, &self.positions);
        }
    }

    /// ü = (f + b)/ρ per node, Ω_w nodes taking their WLS force (their `terms` are left
    /// alone: nothing reads an Ω_w node's bond-loop terms). With `kick = Some(Δt)` the second
    /// half kick (3.6) runs in the same pass; returns the largest squared speed then
    /// (NaN-propagating), 0 otherwise.
    fn accelerate(&mut self, kick: Option<f64>) -> f64 {
        let inv_rho = 1.0 / self.density();
        let (body, hybrid, terms) = (&self.body_force, self.hybrid.as_ref(), &self.terms);
        self.accelerations
            .par_iter_mut()
            .zip(&mut self.velocities)
            .enumerate()
            .with_min_len(4096)
            .map(|(i, (a, v))| {
                let force = match hybrid.and_then(|h| h.wls_force_of(i)) {
                    Some(force) => force,
                    None => terms[i].force,
                };
                for k in 0..D {
                    let b = if body.is_empty() { 0.0 } else { body[i][k] };
                    a[k] = (force[k] + b) * inv_rho;
                }
                kick.map_or(0.0, |dt| verlet::kick_node(v, a, dt))
            })
            .reduce(|| 0.0, verlet::max_or_nan)
    }

    /// Damage φ_i (2.36), kept up to date by the force loop as bonds break.
    pub fn damage(&self) -> Vec<f64> {
        self.terms
            .iter()
            .zip(&self.family_weight)
            .map(|(t, &all)| {
                if all > 0.0 {
                    t.broken_weight / all
                } else {
                    0.0
                }
            })
            .collect()
    }

    /// Damage recomputed from the bond states in one pass over all bonds (a check of
    /// `damage`).
    pub fn damage_from_bonds(&self) -> Vec<f64> {
        self.scheme().damage(&self.intact)
    }

    pub fn strain_energy(&self) -> f64 {
        self.scheme().strain_energy(&self.positions, &self.intact)
    }

    /// Bytes held by the solver state: bond arrays and per-node arrays.
    pub fn memory_bytes(&self) -> usize {
        use std::mem::size_of_val;
        size_of_val(self.families.neighbors.as_slice())
            + size_of_val(self.families.lengths.as_slice())
            + size_of_val(self.families.offsets.as_slice())
            + size_of_val(self.intact.as_slice())
            + size_of_val(self.lattice.positions.as_slice())
            + size_of_val(self.lattice.volumes.as_slice())
            + size_of_val(self.positions.as_slice())
            + size_of_val(self.velocities.as_slice())
            + size_of_val(self.accelerations.as_slice())
            + size_of_val(self.terms.as_slice())
            + size_of_val(self.family_weight.as_slice())
            + size_of_val(self.body_force.as_slice())
    }

    /// Strain-energy density W_i of one node (J/m³).
    pub fn energy_density(&self, i: usize) -> f64 {
        self.scheme()
            .energy_density(i, &self.positions, &self.intact)
    }

    pub fn kinetic_energy_and_momentum(&self) -> (f64, [f64; D]) {
        metrics::kinetic_energy_and_momentum(
            &self.velocities,
            &self.lattice.volumes,
            self.density(),
        )
    }

    /// Force density on each node at the current positions (N/m³), without body forces.
    pub fn force_density(&self) -> Vec<[f64; D]> {
        let hybrid = self.hybrid.as_ref();
        self.terms
            .iter()
            .enumerate()
            .map(|(i, t)| hybrid.and_then(|h| h.wls_force_of(i)).unwrap_or(t.force))
            .collect()
    }

    /// Recomputes forces after positions were set by hand (tests, restarts).
    pub fn refresh_forces(&mut self) {
        self.update_accelerations();
    }

    /// The hybrid invariant: bonds broken with an Ω_w end. Damage that reached Ω_w (possible
    /// only with a check policy other than every bond every step) switches those nodes at once.
    pub fn enforce_hybrid_invariant(&mut self) -> usize {
        let (step, time) = (self.step, self.step as f64 * self.dt);
        match self.hybrid.as_mut() {
            Some(h) => {
                let found = h.enforce(step, time, &self.intact, &self.families);
                self.hybrid_violations += found as u64;
                found
            }
            None => 0,
        }
    }

    /// The scheme mask, Ω_s fraction, switching events and invariant count of a frame.
    fn hybrid_frame(&mut self, scalars: &mut Vec<(String, f64)>) -> (Vec<ClassField>, Vec<String>) {
        if self.hybrid.is_none() {
            return (Vec::new(), Vec::new());
        }
        self.enforce_hybrid_invariant();
        let violations = self.hybrid_violations as f64;
        let Some(h) = self.hybrid.as_mut() else {
            return (Vec::new(), Vec::new());
        };
        let events: Vec<String> = h
            .take_events()
            .iter()
            .map(|e| {
                if e.forced {
                    format!(
                        "t = {:.4e} s (step {}): damage reached Ω_w; {} nodes switched to the standard scheme",
                        e.time, e.step, e.nodes
                    )
                } else {
                    format!(
                        "t = {:.4e} s (step {}): {} nodes switched to the standard scheme",
                        e.time, e.step, e.nodes
                    )
                }
            })
            .collect();
        scalars.push(("hybrid/omega_s_fraction".into(), h.standard_fraction()));
        scalars.push(("hybrid/chi".into(), h.spec.chi));
        scalars.push(("hybrid/violations".into(), violations));
        scalars.push(("hybrid/checked_bonds".into(), h.checked_bonds as f64));
        scalars.push(("hybrid/full_checks".into(), h.full_checks as f64));
        scalars.push(("hybrid/filtered_checks".into(), h.filtered_checks as f64));
        let ids = h.mask().iter().map(|&m| u16::from(m)).collect();
        (
            vec![ClassField {
                name: "scheme",
                ids,
                classes: &hybrid::SCHEME_CLASSES[..2],
            }],
            events,
        )
    }

    fn crack_angles_for(&self, damage: &[f64]) -> Vec<(String, Option<f64>)> {
        self.scene
            .crack_angles
            .iter()
            .map(|spec| {
                let angle = metrics::crack_angle(
                    spec,
                    &self.lattice.positions,
                    damage,
                    &self.families,
                    self.scene.spacing,
                    self.scene.horizon,
                );
                (spec.name.clone(), angle)
            })
            .collect()
    }
}

impl<const D: usize> Stepper for Simulation<D> {
    fn step(&mut self) -> Result<(), SimError> {
        let dt = self.dt;
        let t0 = Instant::now();
        verlet::half_kick(&mut self.velocities, &self.accelerations, dt);
        self.hold_velocities();
        verlet::drift(&mut self.positions, &self.velocities, dt);
        let t1 = Instant::now();
        // Switch before the force pass evaluates damage on u^{n+1} (§5 step 4–5).
        let time = (self.step + 1) as f64 * dt;
        if let Some(h) = self.hybrid.as_mut() {
            h.check(
                self.step + 1,
                time,
                &self.lattice.positions,
                &self.positions,
                &self.families,
                self.law.critical_stretch,
            );
        }
        let t_switch = Instant::now();
        self.timers.switching += t_switch - t1;
        self.compute_forces();
        let t2 = Instant::now();
        let max_speed2 = self.accelerate(Some(dt));
        let t3 = Instant::now();
        self.apply_constraints();
        let t4 = Instant::now();
        self.timers.kick_drift += t1 - t0;
        self.timers.forces += t2 - t_switch;
        self.timers.kick += t3 - t2;
        self.timers.constraints += t4 - t3;
        self.step += 1;
        let max_speed = max_speed2.sqrt();
        if max_speed.is_nan() || max_speed * dt > 0.5 * self.scene.spacing {
            return Err(SimError::Unstable {
                step: self.step,
                time: self.time(),
                max_speed,
                dt,
                stable_dt: self.stable_dt,
            });
        }
        Ok(())
    }

    fn frame(&mut self) -> Frame {
        let damage = self.damage();
        let speed: Vec<f64> = self
            .velocities
            .iter()
            .map(|v| v.iter().map(|x| x * x).sum::<f64>().sqrt())
            .collect();
        let (kinetic, momentum) = self.kinetic_energy_and_momentum();
        // W_i from the last force evaluation, at the current positions. An Ω_w node's WLS
        // force has no local energy density (−½ u_i·f_i sums to the energy only over a whole
        // WLS body): its PMB bond energy over its family is evaluated here, at frame time.
        let mask = self.hybrid.as_ref().map(|h| h.mask());
        let node_energy: Vec<f64> = (0..self.lattice.len())
            .into_par_iter()
            .map(|i| {
                let w = match mask {
                    Some(m) if m[i] == hybrid::WLS => self.energy_density(i),
                    _ => self.terms[i].energy_density,
                };
                w * self.lattice.volumes[i]
            })
            .collect();
        let strain: f64 = node_energy.iter().sum();
        let now = Instant::now();
        let (last_step, last_time) = self.last_frame;
        let steps_since = self.step.saturating_sub(last_step);
        let step_wall = if steps_since > 0 {
            (now - last_time).as_secs_f64() / steps_since as f64
        } else {
            0.0
        };
        self.last_frame = (self.step, now);
        let mut scalars = vec![
            ("energy/kinetic".to_string(), kinetic),
            ("energy/strain".to_string(), strain),
            ("energy/total".to_string(), kinetic + strain),
            ("bonds/broken".to_string(), self.broken as f64),
            ("timing/step_wall_s".to_string(), step_wall),
        ];
        for (stage, spent) in self.timers.named() {
            scalars.push((format!("timing/{stage}_total_s"), spent.as_secs_f64()));
        }
        for (k, p) in momentum.iter().enumerate() {
            scalars.push((format!("momentum/{}", ["x", "y", "z"][k]), *p));
        }
        let (classes, events) = self.hybrid_frame(&mut scalars);
        for (name, angle) in self.crack_angles_for(&damage) {
            if let Some(a) = angle {
                scalars.push((format!("crack_angle_deg/{name}"), a));
            }
        }
        Frame {
            step: self.step,
            time: self.time(),
            dim: D,
            positions: self.positions.iter().flatten().copied().collect(),
            fields: vec![
                NodeField {
                    name: "damage",
                    values: damage,
                    range: (0.0, 1.0),
                },
                NodeField {
                    name: "velocity",
                    values: speed,
                    range: (0.0, self.velocity_scale),
                },
            ],
            classes,
            events,
            scalars,
        }
    }

    fn info(&self) -> SimInfo {
        SimInfo {
            dim: D,
            nodes: self.lattice.len(),
            bonds: self.families.bond_count(),
            dt: self.dt,
            stable_dt: self.stable_dt,
            gershgorin_dt: self.gershgorin_dt,
            total_steps: self.total_steps,
            frame_every: self.frame_every,
            bytes_per_bond: self.memory_bytes() as f64 / self.families.bond_count().max(1) as f64,
            stencil: self.families.bond_count() as f64 / self.lattice.len().max(1) as f64 + 1.0,
        }
    }

    fn steps_done(&self) -> u64 {
        self.step
    }

    fn time(&self) -> f64 {
        self.step as f64 * self.dt
    }

    fn timers(&self) -> &StageTimers {
        &self.timers
    }

    fn crack_angles(&self) -> Vec<(String, Option<f64>)> {
        self.crack_angles_for(&self.damage())
    }

    fn broken_bonds(&self) -> u64 {
        self.broken
    }
}
