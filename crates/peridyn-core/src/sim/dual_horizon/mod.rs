//! Dual-horizon OSB fracture in 2D with adaptive particle splitting (zeng2024 Sect. 2–4): the
//! particle body (`body`) stepped by the velocity-Verlet driver (`integrate::verlet`; the
//! paper's leapfrog (26)–(27) in kick-drift-kick form) or by adaptive dynamic relaxation for
//! quasi-static scenes (zeng2024 Sect. 4.1), the particle store growing through the splitting
//! plug-in (`split`, (15)–(16)). Emits plain-data frames; knows nothing of viewers.

mod body;
mod measure;
mod split;
mod stable;

pub use body::{OsbForces, ParticleBody};
pub use split::Splitting;

use std::ops::{Deref, DerefMut};

use crate::frame::{ClassField, Frame, NodeField};
use crate::integrate::adr::{self, Relaxation};
use crate::integrate::verlet;
use crate::metrics;
use crate::scene::{Scene, SceneError};
use crate::solver::adaptation::{refuse_foreign_sections, tune_each};
use crate::solver::{
    Adaptation, Clock, Integrator, Lap, Param, RunState, SimError, SimInfo, Size, StableStep,
    Stages, State, Stepper, Tick,
};

/// Adaptive dynamic relaxation's state (zeng2024 Sect. 4.1; `integrate::adr`).
struct Relaxing {
    relaxation: Relaxation,
    tolerance: f64,
    residual: f64,
    /// Scratch: the residual force and the external force of the free components.
    force: Vec<[f64; 2]>,
    external: Vec<[f64; 2]>,
}

pub struct DualHorizonSimulation {
    pub body: ParticleBody,
    forces: OsbForces,
    plugins: Vec<Box<dyn Adaptation<ParticleBody>>>,
    /// Quasi-static scenes: ADR instead of velocity-Verlet.
    relaxing: Option<Relaxing>,
    run: RunState,
}

/// A simulation reads as its body (particles, bonds, levels) for measurements.
impl Deref for DualHorizonSimulation {
    type Target = ParticleBody;

    fn deref(&self) -> &ParticleBody {
        &self.body
    }
}

impl DerefMut for DualHorizonSimulation {
    fn deref_mut(&mut self) -> &mut ParticleBody {
        &mut self.body
    }
}

/// The `nodes/level` classes: the splitting generation.
const LEVELS: &[(u16, &str, [u8; 3])] = &[
    (0, "parent", [120, 120, 120]),
    (1, "child", [230, 85, 13]),
    (2, "grandchild", [49, 130, 189]),
    (3, "great-grandchild", [49, 163, 84]),
];

impl DualHorizonSimulation {
    pub fn new(scene: &Scene) -> Result<Self, SceneError> {
        let Some(spec) = scene.state_based.clone() else {
            return Err(scene.error("material.model", "needs \"osb\""));
        };
        let Some(m) = scene.material.as_ref() else {
            return Err(scene.error("material", "needs a density"));
        };
        let mut body = ParticleBody::new(scene, spec.clone(), m.density)?;
        // A refined lattice's limit is 2⁻ˡ of the unsplit one's (the stiffness per mass scales
        // with 1/Δ² at δ ∝ Δ): measured before any split, so that particles splitting later
        // where the body is still intact cannot outrun the step (the power iteration on the
        // split body alone misses a few children beside broken bonds).
        let verlet = spec.relaxation.is_none();
        let unsplit = match spec.refinement {
            Some(_) if verlet => Some(stable::stable_step(&mut body)),
            _ => None,
        };
        let mut plugins: Vec<Box<dyn Adaptation<ParticleBody>>> = Vec::new();
        if let Some(rule) = spec.refinement {
            let region = spec.refined_region.as_ref();
            plugins.push(Box::new(Splitting::new(rule, &mut body, region)));
        }
        body.particles_changed();
        // ADR iterates with a unit pseudo step: no limit to measure.
        let stable = if verlet {
            let mut stable = stable::stable_step(&mut body);
            if let Some(u) = unsplit {
                stable.sharp = stable.sharp.min(u.sharp);
                stable.guaranteed = stable.guaranteed.min(u.guaranteed);
            }
            stable
        } else {
            StableStep {
                sharp: 1.0,
                guaranteed: 1.0,
                integrator: Integrator::Verlet,
            }
        };
        let stages = verlet::stage_names(&OsbForces, &plugins);
        let run = RunState::new(scene, stable, &stages)?;
        let relaxing = spec.relaxation.map(|tolerance| Relaxing {
            relaxation: stable::relaxation_of(&mut body),
            tolerance,
            residual: 1.0,
            force: vec![[0.0; 2]; body.len()],
            external: vec![[0.0; 2]; body.len()],
        });
        body.hold();
        body.velocity_scale = initial_scale(body.velocities());
        body.update_forces();
        Ok(DualHorizonSimulation {
            body,
            forces: OsbForces,
            plugins,
            relaxing,
            run,
        })
    }

    /// The residual of the last ADR iteration (None for dynamics).
    pub fn residual(&self) -> Option<f64> {
        self.relaxing.as_ref().map(|r| r.residual)
    }

    fn splitting(&self) -> Option<&Splitting> {
        self.plugins
            .iter()
            .find_map(|p| (&**p as &dyn std::any::Any).downcast_ref::<Splitting>())
    }

    /// Particles split so far (pre-processing included).
    pub fn split_parents(&self) -> u64 {
        self.splitting().map_or(0, |s| s.split_parents)
    }

    /// Verification: `false` computes (16)'s strains for every particle that may split, as
    /// without the energy gate (the same splits, bit for bit, where the gate's bound holds).
    pub fn gate_strains(&mut self, on: bool) {
        let body = &mut self.body;
        for p in &mut self.plugins {
            if let Some(s) = (&mut **p as &mut dyn std::any::Any).downcast_mut::<Splitting>() {
                s.set_strain_gate(on, body);
            }
        }
    }

    /// One ADR iteration (zeng2024 Sect. 4.1; `integrate::adr`): the residual of the free
    /// components, the damped update, held values, the force pass; a split grows ADR's
    /// density with the body and is followed by a force pass on the refined body.
    fn step_relaxation(&mut self) {
        let Some(r) = self.relaxing.as_mut() else {
            return;
        };
        let body = &mut self.body;
        let stages = &mut self.run.stages;
        let at = |stages: &Stages, name| stages.index(name).unwrap_or(0);
        let tick = Tick::next(&self.run.clock, self.run.stable.sharp);
        let mut lap = Lap::start();
        body.residual_forces(&mut r.force, &mut r.external);
        r.residual = adr::residual(&r.force, &r.external);
        body.relax(&mut r.relaxation, &r.force);
        lap.charge(stages, at(stages, verlet::KICK_DRIFT));
        body.hold();
        lap.charge(stages, at(stages, verlet::CONSTRAINTS));
        body.update_forces();
        lap.charge(stages, at(stages, verlet::FORCES));
        let before = body.len();
        for p in &mut self.plugins {
            p.after_step(body, tick);
        }
        if body.len() != before {
            grow_relaxation(r, body);
            body.update_forces();
        }
        lap.charge(stages, at(stages, "refine"));
        self.run.clock.advance();
    }
}

/// ADR's density and scratch for a body that grew by splits (see
/// `stable::relaxation_after_split`).
fn grow_relaxation(r: &mut Relaxing, body: &ParticleBody) {
    r.relaxation = stable::relaxation_after_split(body, r.relaxation.lambda);
    r.force.resize(body.len(), [0.0; 2]);
    r.external.resize(body.len(), [0.0; 2]);
}

fn initial_scale(velocities: &[[f64; 2]]) -> f64 {
    let max = velocities
        .iter()
        .map(|v| (v[0] * v[0] + v[1] * v[1]).sqrt())
        .fold(0.0, f64::max);
    if max > 0.0 { max } else { 1.0 }
}

impl Stepper for DualHorizonSimulation {
    fn step(&mut self) -> Result<(), SimError> {
        if self.relaxing.is_some() {
            self.step_relaxation();
            return Ok(());
        }
        verlet::step(
            &mut self.body,
            &mut self.forces,
            &mut self.plugins,
            &mut self.run,
        )
    }

    fn converged(&self) -> bool {
        let r = self.relaxing.as_ref();
        r.is_some_and(|r| self.run.clock.step() > 0 && r.residual < r.tolerance)
    }

    fn frame(&mut self) -> Frame {
        let body = &self.body;
        let damage = body.damage();
        let speed: Vec<f64> = body
            .velocities()
            .iter()
            .map(|v| (v[0] * v[0] + v[1] * v[1]).sqrt())
            .collect();
        let (kinetic, strain, momentum) = body.energies();
        let mut scalars = vec![
            ("energy/kinetic".to_string(), kinetic),
            ("energy/strain".to_string(), strain),
            ("energy/total".to_string(), kinetic + strain),
            ("bonds/broken".to_string(), body.broken as f64),
            ("momentum/x".to_string(), momentum[0]),
            ("momentum/y".to_string(), momentum[1]),
            ("refine/particles".to_string(), body.len() as f64),
        ];
        scalars.extend(self.run.timing_scalars());
        if let Some(r) = &self.relaxing {
            scalars.push(("adr/residual".to_string(), r.residual));
            scalars.push(("adr/damping".to_string(), r.relaxation.damping));
        }
        for o in &body.spec.openings {
            if let Some(d) = body.opening(&o.mouth, o.axis) {
                scalars.push((format!("opening/{}", o.name), d));
            }
        }
        metrics::damage_counts(&body.scene, body.reference(), &damage, &mut scalars);
        let (scene, reference) = (&body.scene, body.reference());
        metrics::crack_scalars(scene, reference, &damage, scene.spacing, &mut scalars);
        let mut frame = Frame {
            step: self.run.clock.step(),
            time: self.run.clock.time(),
            dim: 2,
            positions: body.positions().as_flattened().to_vec(),
            fields: vec![
                NodeField::damage(damage),
                NodeField::speed(speed, body.velocity_scale),
            ],
            classes: vec![ClassField {
                name: "level",
                ids: body.levels().iter().map(|&l| u16::from(l)).collect(),
                classes: LEVELS,
            }],
            events: Vec::new(),
            scalars,
            radii: body.spacings().iter().map(|&d| (0.5 * d) as f32).collect(),
        };
        let clock = self.run.clock.clone();
        for p in &mut self.plugins {
            p.frame(&self.body, &clock, &mut frame);
        }
        frame
    }

    fn info(&self) -> SimInfo {
        let (nodes, bonds) = (self.body.len(), self.body.bonds.bond_count());
        let bytes = self.body.bonds.bytes_per_bond();
        self.run.info(Size::of_bonds(2, nodes, bonds, bytes))
    }

    fn run(&self) -> &RunState {
        &self.run
    }

    fn run_mut(&mut self) -> &mut RunState {
        &mut self.run
    }

    fn save_state(&self) -> State {
        let body = &self.body;
        let mut state = State::default();
        self.run.clock.save(&mut state);
        state.put_u64("dual_horizon/particles", vec![body.len() as u64]);
        state.put_f64("position", body.positions().as_flattened().to_vec());
        state.put_f64("velocity", body.velocities().as_flattened().to_vec());
        state.put_u8("intact", body.bonds.intact.clone());
        state.put_u64("broken", vec![body.broken]);
        // The step's own accelerations and force-pass terms: a split at the checkpoint's step
        // left its children with their parent's, which a new force pass would not give.
        state.put_f64("acceleration", body.accelerations().as_flattened().to_vec());
        let terms: Vec<f64> = body
            .terms()
            .iter()
            .flat_map(|t| {
                [
                    t.force[0],
                    t.force[1],
                    t.dilatation,
                    t.energy_density,
                    t.damage,
                    t.strains[0],
                    t.strains[1],
                ]
            })
            .collect();
        state.put_f64("dual_horizon/terms", terms);
        for p in &self.plugins {
            p.save(body, &mut state);
        }
        state
    }

    /// Restores a state of this scene: the splits since the start are replayed from the
    /// checkpoint's log (the same parents in the same order give the same particles and
    /// bond layout; positions, velocities, bond states and force-pass results then come
    /// from the checkpoint), so the resumed run continues bit for bit.
    fn restore_state(&mut self, state: &State) -> Result<(), String> {
        let saved = state.u64("dual_horizon/particles", 1)?[0] as usize;
        let plugins = &self.plugins;
        refuse_foreign_sections(state, |s| plugins.iter().any(|p| p.owns_section(s)))?;
        if saved != self.body.len() {
            if self.plugins.is_empty() {
                return Err(
                    "the checkpoint's `dual_horizon/split_log` lists splits, but this \
                            scene has no refinement"
                        .into(),
                );
            }
            for p in &mut self.plugins {
                p.restore(&mut self.body, state)?;
            }
            if let Some(r) = self.relaxing.as_mut() {
                grow_relaxation(r, &self.body);
            }
        }
        let body = &mut self.body;
        let n = body.len();
        if saved != n {
            return Err(format!(
                "the checkpoint holds {saved} particles, this scene {n} after replaying its \
                 splits: it belongs to another scene or another version"
            ));
        }
        let clock = Clock::restore(state)?;
        let position = state.f64("position", 2 * n)?;
        let velocity = state.f64("velocity", 2 * n)?;
        let intact = state.u8("intact", body.bonds.slot_count())?;
        let broken = state.u64("broken", 1)?[0];
        let acceleration = state.f64("acceleration", 2 * n)?;
        let terms = state.f64("dual_horizon/terms", 7 * n)?;
        body.positions_mut()
            .as_flattened_mut()
            .copy_from_slice(position);
        body.velocities_mut()
            .as_flattened_mut()
            .copy_from_slice(velocity);
        body.bonds.intact.copy_from_slice(intact);
        body.broken = broken;
        body.write_forces(acceleration, terms);
        self.run.clock = clock;
        Ok(())
    }

    fn tune(&mut self, param: Param) -> Result<(), String> {
        if self.plugins.is_empty() {
            return Err(param.unused_note().into());
        }
        if let Param::Chi(_) = param {
            return Err("a dual-horizon scene has no hybrid scheme: χ is recorded only".into());
        }
        tune_each(&mut self.forces, &mut self.plugins, &mut self.body, param)
    }
}

impl DualHorizonSimulation {
    /// Crack angles `(name, degrees)` of the scene's `[[metrics.crack_angle]]` now (None where
    /// no crack was found).
    pub fn crack_angles(&self) -> Vec<(String, Option<f64>)> {
        self.body.crack_angles_for(&self.body.damage())
    }

    /// The bonds broken so far.
    pub fn broken_bonds(&self) -> u64 {
        self.body.broken
    }
}
