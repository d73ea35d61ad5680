//! Dual-horizon OSB fracture in 2D with adaptive particle splitting (zeng2024 Sect. 2–4):
//! velocity-Verlet for dynamics (the paper's leapfrog (26)–(27) in kick-drift-kick form) or
//! adaptive dynamic relaxation for quasi-static scenes (zeng2024 Sect. 4.1), the particle store
//! growing through `Nodes::split` as parents meet (15)–(16). Emits plain-data frames; knows
//! nothing of viewers.

use rayon::prelude::*;

use crate::adapt::splitting::{self, SplitColumns, SplitRule};
use crate::discretization::buckets::Buckets;
use crate::discretization::family::crosses;
use crate::discretization::{Families, Field, Lattice, NodeValue, Nodes, layers};
use crate::frame::{ClassField, Frame, NodeField};
use crate::integrate::adr::{self, Relaxation};
use crate::integrate::stability::POWER_ITERATIONS;
use crate::integrate::{stability, verlet};
use crate::metrics;
use crate::model::osb::{OsbHorizon, OsbMaterial};
use crate::scene::{Condition, Scene, SceneError, StateBasedSpec};
use crate::scheme::dual_horizon::{Body, DualBonds, ParticleTerms};
use crate::solver::{
    Clock, Integrator, Lap, Param, RunState, SimError, SimInfo, Size, StableStep, State, Stepper,
};

const STAGES: &[&str] = &["kick_drift", "forces", "kick", "constraints", "refine"];
const KICK_DRIFT: usize = 0;
const FORCES: usize = 1;
const KICK: usize = 2;
const CONSTRAINTS: usize = 3;
const REFINE: usize = 4;

/// Held-component flags: bit i holds the velocity along axis i, bit 2 + i the displacement.
const HOLD_DISPLACEMENT_SHIFT: u8 = 2;

#[derive(Debug, Clone, Copy, PartialEq)]
enum HeldKind {
    Velocity,
    Displacement,
}

/// One held component of one particle.
#[derive(Debug, Clone, Copy)]
struct Held {
    node: u32,
    axis: u8,
    kind: HeldKind,
    value: f64,
}

/// The held components listed from the columns (children carry their parent's flags).
fn held_list(nodes: &Nodes<2>, c: &Columns) -> Vec<Held> {
    let flags = nodes.fields.get(c.held);
    let velocity = nodes.fields.get(c.held_velocity);
    let displacement = nodes.fields.get(c.held_displacement);
    let mut list = Vec::new();
    for (k, &f) in flags.iter().enumerate() {
        for axis in 0..2u8 {
            let node = k as u32;
            if f & (1 << axis) != 0 {
                let value = velocity[k][axis as usize];
                list.push(Held {
                    node,
                    axis,
                    kind: HeldKind::Velocity,
                    value,
                });
            }
            if f & (1 << (axis + HOLD_DISPLACEMENT_SHIFT)) != 0 {
                let value = displacement[k][axis as usize];
                list.push(Held {
                    node,
                    axis,
                    kind: HeldKind::Displacement,
                    value,
                });
            }
        }
    }
    list
}

impl NodeValue for ParticleTerms {
    const EMPTY: Self = ParticleTerms {
        force: [0.0; 2],
        dilatation: 0.0,
        energy_density: 0.0,
        damage: 0.0,
        strains: [0.0; 2],
    };
}

impl NodeValue for OsbHorizon {
    const EMPTY: Self = OsbHorizon {
        horizon: 0.0,
        a: 0.0,
        b: 0.0,
        d: 0.0,
        critical_stretch: f64::INFINITY,
    };
}

/// The per-particle columns (children inherit every one from their parent).
#[derive(Debug, Clone, Copy)]
struct Columns {
    split: SplitColumns,
    velocity: Field<[f64; 2]>,
    acceleration: Field<[f64; 2]>,
    terms: Field<ParticleTerms>,
    /// Bit flags: which components are held (`HOLD_VELOCITY` bits, then displacement bits).
    held: Field<u8>,
    /// Held velocity and held displacement values.
    held_velocity: Field<[f64; 2]>,
    held_displacement: Field<[f64; 2]>,
    /// Body force density b (N/m³).
    body_force: Field<[f64; 2]>,
}

enum Motion {
    Verlet,
    Relaxation {
        relaxation: Relaxation,
        tolerance: f64,
        residual: f64,
        /// Scratch: the residual force and the external force of the free components.
        force: Vec<[f64; 2]>,
        external: Vec<[f64; 2]>,
    },
}

pub struct DualHorizonSimulation {
    pub scene: Scene,
    spec: StateBasedSpec,
    nodes: Nodes<2>,
    columns: Columns,
    pub bonds: DualBonds,
    buckets: Buckets,
    density: f64,
    run: RunState,
    motion: Motion,
    held: Vec<Held>,
    /// The smallest particle's Δ (the blow-up check's length; it shrinks only by a split).
    smallest_spacing: f64,
    broken: u64,
    /// Splitting passes and particles split so far; events since the last frame.
    pub splits: u64,
    pub split_parents: u64,
    /// The parents of every split since the scene was built, in order: a checkpoint replays
    /// them to rebuild the same particles and bond layout.
    split_log: Vec<Vec<u32>>,
    events: Vec<String>,
    velocity_scale: f64,
    /// Whether (16)'s strains are skipped below the energy gate (`gate_strains`).
    strain_gate: bool,
}

fn body<'a>(nodes: &'a Nodes<2>, columns: &Columns, material: &OsbMaterial) -> Body<'a> {
    Body {
        reference: nodes.reference(),
        volumes: nodes.volumes(),
        constants: nodes.fields.get(columns.split.constants),
        thickness: material.thickness,
    }
}

impl DualHorizonSimulation {
    pub fn new(scene: &Scene) -> Result<Self, SceneError> {
        let Some(spec) = scene.state_based.clone() else {
            return Err(scene.error("material.model", "needs \"osb\""));
        };
        let Some(m) = scene.material.as_ref() else {
            return Err(scene.error("material", "needs a density"));
        };
        let material = spec.material;
        let lattice = Lattice::<2>::of_scene(scene)?;
        let layers = layers::select(scene, &lattice.positions)?;
        let volumes: Vec<f64> = lattice
            .volumes
            .iter()
            .map(|v| v * material.thickness)
            .collect();
        let mut nodes = Nodes::new(lattice.positions.clone(), volumes);
        let f = &mut nodes.fields;
        let columns = Columns {
            split: SplitColumns {
                position: f.add_values("position", lattice.positions),
                constants: f.add("constants", material.at(scene.horizon)),
                level: f.add("level", 0u8),
                spacing: f.add("spacing", scene.spacing),
            },
            velocity: f.add("velocity", [0.0; 2]),
            acceleration: f.add("acceleration", [0.0; 2]),
            terms: f.add("terms", ParticleTerms::EMPTY),
            held: f.add("held", 0u8),
            held_velocity: f.add("held_velocity", [0.0; 2]),
            held_displacement: f.add("held_displacement", [0.0; 2]),
            body_force: f.add("body_force", [0.0; 2]),
        };
        apply_boundary(scene, &layers, &mut nodes, &columns);
        super::add_initial_velocity(
            scene,
            nodes.base.reference(),
            nodes.fields.get_mut(columns.velocity),
        );
        // Cells wide enough for a parent's horizon plus the reach of its children.
        let mut buckets = Buckets::new(
            nodes.reference(),
            scene.horizon + scene.spacing,
            scene.spacing,
        );
        let mut bonds =
            DualBonds::build(&body(&nodes, &columns, &material), &buckets, spec.weights);
        cut_precracks(scene, &nodes, &mut bonds)?;
        if !scene.precracks.is_empty() {
            bonds.refit(&body(&nodes, &columns, &material));
        }
        let density = m.density;
        // A refined lattice's limit is 2⁻ˡ of the unsplit one's (the stiffness per mass scales
        // with 1/Δ² at δ ∝ Δ): measured before any split, so that particles splitting later
        // where the body is still intact cannot outrun the step (the power iteration on the
        // split body alone misses a few children beside broken bonds).
        let verlet = spec.relaxation.is_none();
        let unsplit = match spec.refinement {
            Some(_) if verlet => Some(stable_step(&spec, &nodes, &columns, &mut bonds, density)),
            _ => None,
        };
        // Pre-processing step 4 (zeng2024 Sect. 3.3): refine every particle past φ_c.
        let mut splits = (0, 0);
        if let Some(rule) = spec.refinement {
            for _ in 0..rule.levels {
                let mut parents = candidates(&rule, &nodes, &columns, &bonds, true);
                if let Some(region) = &spec.refined_region {
                    let levels = nodes.fields.get(columns.split.level);
                    parents.extend((0..nodes.len() as u32).filter(|&k| {
                        let k = k as usize;
                        levels[k] < rule.levels && region.contains(&nodes.reference()[k], 1e-12)
                    }));
                    parents.sort_unstable();
                    parents.dedup();
                }
                if parents.is_empty() {
                    break;
                }
                splitting::split(
                    &parents,
                    &mut nodes,
                    &columns.split,
                    &mut bonds,
                    &mut buckets,
                    &material,
                    rule.horizon_ratio,
                    &scene.precracks,
                );
                splits = (splits.0 + 1, splits.1 + parents.len() as u64);
            }
        }
        // ADR iterates with a unit pseudo step: no limit to measure.
        let stable = if verlet {
            let mut stable = stable_step(&spec, &nodes, &columns, &mut bonds, density);
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
        let run = RunState::new(scene, stable, STAGES)?;
        let motion = match spec.relaxation {
            None => Motion::Verlet,
            Some(tolerance) => Motion::Relaxation {
                relaxation: relaxation_of(&nodes, &columns, &mut bonds, &material),
                tolerance,
                residual: 1.0,
                force: vec![[0.0; 2]; nodes.len()],
                external: vec![[0.0; 2]; nodes.len()],
            },
        };
        let mut sim = DualHorizonSimulation {
            scene: scene.clone(),
            spec,
            nodes,
            columns,
            bonds,
            buckets,
            density,
            run,
            motion,
            held: Vec::new(),
            smallest_spacing: scene.spacing,
            broken: 0,
            splits: splits.0,
            split_parents: splits.1,
            split_log: Vec::new(),
            events: Vec::new(),
            velocity_scale: 1.0,
            strain_gate: true,
        };
        if sim.split_parents > 0 {
            sim.events.push(format!(
                "pre-processing: {} particles past φ_c split before the run",
                sim.split_parents
            ));
        }
        sim.held = held_list(&sim.nodes, &sim.columns);
        sim.smallest_spacing = sim.smallest();
        sim.mark_splittable();
        sim.hold();
        sim.velocity_scale = initial_scale(sim.nodes.fields.get(sim.columns.velocity));
        sim.update_forces();
        Ok(sim)
    }

    pub fn material(&self) -> &OsbMaterial {
        &self.spec.material
    }

    pub fn len(&self) -> usize {
        self.nodes.len()
    }

    pub fn is_empty(&self) -> bool {
        self.nodes.is_empty()
    }

    pub fn reference(&self) -> &[[f64; 2]] {
        self.nodes.reference()
    }

    pub fn volumes(&self) -> &[f64] {
        self.nodes.volumes()
    }

    pub fn positions(&self) -> &[[f64; 2]] {
        self.nodes.fields.get(self.columns.split.position)
    }

    pub fn positions_mut(&mut self) -> &mut [[f64; 2]] {
        self.nodes.fields.get_mut(self.columns.split.position)
    }

    pub fn velocities(&self) -> &[[f64; 2]] {
        self.nodes.fields.get(self.columns.velocity)
    }

    pub fn velocities_mut(&mut self) -> &mut [[f64; 2]] {
        self.nodes.fields.get_mut(self.columns.velocity)
    }

    pub fn accelerations(&self) -> &[[f64; 2]] {
        self.nodes.fields.get(self.columns.acceleration)
    }

    pub fn levels(&self) -> &[u8] {
        self.nodes.fields.get(self.columns.split.level)
    }

    pub fn terms(&self) -> &[ParticleTerms] {
        self.nodes.fields.get(self.columns.terms)
    }

    pub fn density(&self) -> f64 {
        self.density
    }

    /// The residual of the last ADR iteration (None for dynamics).
    pub fn residual(&self) -> Option<f64> {
        match &self.motion {
            Motion::Relaxation { residual, .. } => Some(*residual),
            Motion::Verlet => None,
        }
    }

    /// The force pass at the current positions; accelerations from it and the body force.
    pub fn update_forces(&mut self) {
        let c = self.columns;
        let thickness = self.spec.material.thickness;
        let base = &self.nodes.base;
        let fields = &mut self.nodes.fields;
        let (positions, constants, terms) =
            fields.triple_mut(c.split.position, c.split.constants, c.terms);
        let body = Body {
            reference: base.reference(),
            volumes: base.volumes(),
            constants,
            thickness,
        };
        self.broken += self.bonds.evaluate(&body, positions, terms);
        let density = self.density;
        let (acceleration, terms, body_force) =
            fields.triple_mut(c.acceleration, c.terms, c.body_force);
        acceleration
            .par_iter_mut()
            .zip(terms.par_iter())
            .zip(body_force.par_iter())
            .zip(base.volumes().par_iter())
            .for_each(|(((a, t), b), v)| {
                for i in 0..2 {
                    a[i] = (t.force[i] + b[i] * v) / (density * v);
                }
            });
    }

    /// Held velocities and displacements (allocation-free: the list of held components is
    /// rebuilt from the columns only when particles split).
    fn hold(&mut self) {
        let c = self.columns;
        let reference = self.nodes.base.reference();
        let (positions, velocities) = self.nodes.fields.pair_mut(c.split.position, c.velocity);
        for h in &self.held {
            let (k, i) = (h.node as usize, h.axis as usize);
            match h.kind {
                HeldKind::Velocity => velocities[k][i] = h.value,
                HeldKind::Displacement => {
                    positions[k][i] = reference[k][i] + h.value;
                    velocities[k][i] = 0.0;
                }
            }
        }
    }

    fn smallest(&self) -> f64 {
        let spacing = self.nodes.fields.get(self.columns.split.spacing);
        spacing.iter().copied().fold(f64::INFINITY, f64::min)
    }

    /// Damage (14) of every particle.
    pub fn damage(&self) -> Vec<f64> {
        self.bonds.damage(self.nodes.volumes())
    }

    /// The particles below the level cap get their split criteria from the force pass; those
    /// at the cap (children of the last level) skip them. The strains of (16) are computed
    /// only where they can pass α s_c: if ε_xx and ε_yy both exceed t, the classical energy
    /// density μ ε_dev:ε_dev + ½ κ (tr ε)² is at least 2 κ t², so a particle whose PD energy
    /// density W_k is below a quarter of that (a margin for the horizon's averaging) and
    /// whose bonds are all intact cannot meet (16); any broken bond computes them.
    fn mark_splittable(&mut self) {
        let Some(rule) = self.spec.refinement else {
            return;
        };
        let (kappa, gated) = (self.spec.material.bulk_modulus(), self.strain_gate);
        let levels = self.nodes.fields.get(self.columns.split.level);
        let constants = self.nodes.fields.get(self.columns.split.constants);
        self.bonds.criteria.clear();
        self.bonds
            .criteria
            .extend(levels.iter().zip(constants).map(|(&l, c)| {
                if l >= rule.levels {
                    f64::INFINITY
                } else if gated {
                    let t = rule.strain_factor * c.critical_stretch;
                    0.5 * kappa * t * t
                } else {
                    f64::MIN
                }
            }));
    }

    /// Verification: `false` computes (16)'s strains for every particle that may split, as
    /// without the energy gate of `mark_splittable` (the same splits, bit for bit, where the
    /// gate's bound holds).
    pub fn gate_strains(&mut self, on: bool) {
        self.strain_gate = on;
        self.mark_splittable();
    }

    /// Splits every particle that meets (15) or (16); returns the number split.
    fn refine(&mut self) -> usize {
        let Some(rule) = self.spec.refinement else {
            return 0;
        };
        let parents = candidates(&rule, &self.nodes, &self.columns, &self.bonds, false);
        if parents.is_empty() {
            return 0;
        }
        self.split_particles(&parents, rule.horizon_ratio);
        self.events.push(format!(
            "split {} particles at t = {:.4e} s ({} particles now)",
            parents.len(),
            self.run.clock.time(),
            self.nodes.len()
        ));
        parents.len()
    }

    /// Replays a checkpoint's split log on this freshly built scene.
    fn replay_splits(&mut self, state: &State) -> Result<(), String> {
        let field = "dual_horizon/split_log";
        let Some(rule) = self.spec.refinement else {
            return Err(format!(
                "the checkpoint's `{field}` lists splits, but this scene has no refinement"
            ));
        };
        if !self.split_log.is_empty() {
            return Err("splits can be replayed on a freshly built scene only".into());
        }
        let len = state.u64("dual_horizon/split_log_len", 1)?[0] as usize;
        let log = state.u64(field, len)?;
        let mut at = 0;
        while at < log.len() {
            let count = log[at] as usize;
            let end = (at + 1)
                .checked_add(count)
                .filter(|&e| count > 0 && e <= log.len());
            let Some(end) = end else {
                return Err(format!(
                    "`{field}` holds a split of {count} parents where {} values are left",
                    log.len() - at - 1
                ));
            };
            let n = self.len();
            let parents: Vec<u32> = log[at + 1..end]
                .iter()
                .map(|&k| u32::try_from(k).unwrap_or(u32::MAX))
                .collect();
            let mut distinct = parents.clone();
            distinct.sort_unstable();
            distinct.dedup();
            let levels = self.nodes.fields.get(self.columns.split.level);
            if distinct.len() != count
                || distinct
                    .iter()
                    .any(|&k| k as usize >= n || levels[k as usize] >= rule.levels)
            {
                return Err(format!(
                    "`{field}` names a particle twice, one beyond the {n} particles, or one at \
                     the level cap {}",
                    rule.levels
                ));
            }
            self.split_particles(&parents, rule.horizon_ratio);
            at = end;
        }
        Ok(())
    }

    /// Splits `parents` and brings what depends on the particle set up to date: the held
    /// components, the smallest cell, the split criteria and ADR's density (the new rows'
    /// from the measured scale: no new eigenvalue estimate, the row sums keep the shape, so
    /// λ_max(D⁻¹K) stays; never below 1, the bound of exact absolute row sums).
    fn split_particles(&mut self, parents: &[u32], horizon_ratio: f64) {
        let material = self.spec.material;
        splitting::split(
            parents,
            &mut self.nodes,
            &self.columns.split,
            &mut self.bonds,
            &mut self.buckets,
            &material,
            horizon_ratio,
            &self.scene.precracks,
        );
        self.held = held_list(&self.nodes, &self.columns);
        self.smallest_spacing = self.smallest();
        self.mark_splittable();
        self.splits += 1;
        self.split_parents += parents.len() as u64;
        self.split_log.push(parents.to_vec());
        if matches!(self.motion, Motion::Relaxation { .. }) {
            let diagonal = self
                .bonds
                .stiffness_rows(&body(&self.nodes, &self.columns, &material));
            let n = self.nodes.len();
            if let Motion::Relaxation {
                relaxation,
                force,
                external,
                ..
            } = &mut self.motion
            {
                *relaxation = Relaxation::new(
                    adr::scale_density(&diagonal, relaxation.lambda.max(1.0)),
                    relaxation.lambda,
                );
                force.resize(n, [0.0; 2]);
                external.resize(n, [0.0; 2]);
            }
        }
    }

    fn step_verlet(&mut self) -> Result<(), SimError> {
        let dt = self.run.clock.dt();
        let c = self.columns;
        let mut lap = Lap::start();
        {
            let fields = &mut self.nodes.fields;
            let (v, a) = fields.pair_mut(c.velocity, c.acceleration);
            verlet::half_kick(v, a, dt);
        }
        self.hold();
        {
            let fields = &mut self.nodes.fields;
            let (y, v) = fields.pair_mut(c.split.position, c.velocity);
            verlet::drift(y, v, dt);
        }
        self.hold();
        lap.charge(&mut self.run.stages, KICK_DRIFT);
        self.update_forces();
        lap.charge(&mut self.run.stages, FORCES);
        let max_speed2 = {
            let fields = &mut self.nodes.fields;
            let (v, a) = fields.pair_mut(c.velocity, c.acceleration);
            v.par_iter_mut()
                .zip(a.par_iter())
                .map(|(v, a)| verlet::kick_node(v, a, dt))
                .reduce(|| 0.0, verlet::max_or_nan)
        };
        lap.charge(&mut self.run.stages, KICK);
        self.hold();
        lap.charge(&mut self.run.stages, CONSTRAINTS);
        // No force pass after a split: the children carry their parent's acceleration (per
        // unit mass) into the next step's half kick, so the split falls between two kicks by
        // the unrefined forces at y^i, exactly the paper's leapfrog order (zeng2024 Sect. 3.3,
        // seed-002 §4: forces, update, damage and strain, refine; the next step's forces see
        // the refined body). Σ m a stays 0, so momentum is kept through the split.
        self.refine();
        lap.charge(&mut self.run.stages, REFINE);
        self.run.clock.advance();
        let max_speed = max_speed2.sqrt();
        if max_speed.is_nan() || max_speed * dt > 0.5 * self.smallest_spacing {
            return Err(SimError::Unstable {
                step: self.run.clock.step(),
                time: self.run.clock.time(),
                max_speed,
                dt,
                stable_dt: self.run.stable.sharp,
            });
        }
        Ok(())
    }

    /// One ADR iteration (zeng2024 Sect. 4.1; `integrate::adr`).
    fn step_relaxation(&mut self) {
        let c = self.columns;
        let mut lap = Lap::start();
        let Motion::Relaxation {
            relaxation,
            residual,
            force,
            external,
            ..
        } = &mut self.motion
        else {
            return;
        };
        let reference = self.nodes.base.reference();
        let volumes = self.nodes.base.volumes();
        let fields = &mut self.nodes.fields;
        {
            let (terms, body_force) = (fields.get(c.terms), fields.get(c.body_force));
            let free = fields.get(c.held);
            force
                .par_iter_mut()
                .zip(external.par_iter_mut())
                .enumerate()
                .for_each(|(k, (f, e))| {
                    for i in 0..2usize {
                        let held = free[k]
                            & ((1 << i) | (1 << (i + usize::from(HOLD_DISPLACEMENT_SHIFT))));
                        e[i] = if held == 0 {
                            body_force[k][i] * volumes[k]
                        } else {
                            0.0
                        };
                        f[i] = if held == 0 {
                            terms[k].force[i] + e[i]
                        } else {
                            0.0
                        };
                    }
                });
        }
        *residual = adr::residual(force, external);
        let (positions, velocities) = fields.pair_mut(c.split.position, c.velocity);
        relaxation.iterate(force, velocities, positions, reference);
        lap.charge(&mut self.run.stages, KICK_DRIFT);
        self.hold();
        lap.charge(&mut self.run.stages, CONSTRAINTS);
        self.update_forces();
        lap.charge(&mut self.run.stages, FORCES);
        if self.refine() > 0 {
            self.update_forces();
        }
        lap.charge(&mut self.run.stages, REFINE);
        self.run.clock.advance();
    }

    /// (kinetic energy, strain energy, momentum).
    pub fn energies(&self) -> (f64, f64, [f64; 2]) {
        let volumes = self.nodes.volumes();
        let (kinetic, momentum) =
            metrics::kinetic_energy_and_momentum(self.velocities(), volumes, self.density);
        let strain = self
            .terms()
            .par_iter()
            .zip(volumes.par_iter())
            .map(|(t, v)| t.energy_density * v)
            .sum();
        (kinetic, strain, momentum)
    }

    /// Total mass Σ ρ V.
    pub fn mass(&self) -> f64 {
        self.density * self.nodes.volumes().iter().sum::<f64>()
    }

    /// The opening at a crack mouth (see `schema::OpeningTable`).
    pub fn opening(&self, mouth: &[f64], axis: usize) -> Option<f64> {
        let other = 1 - axis;
        let (x, y) = (self.reference(), self.positions());
        let spacing = self.nodes.fields.get(self.columns.split.spacing);
        let nearest = |upper: bool| -> Option<usize> {
            (0..x.len())
                .filter(|&k| (x[k][axis] > mouth[axis]) == upper)
                .filter(|&k| (x[k][other] - mouth[other]).abs() < spacing[k])
                .min_by(|&a, &b| {
                    let d = |k: usize| (x[k][0] - mouth[0]).powi(2) + (x[k][1] - mouth[1]).powi(2);
                    d(a).total_cmp(&d(b))
                })
        };
        // Each face's displacement along `axis`, extrapolated linearly to the mouth from its
        // particle nearest the mouth and the next one of the same row inwards (Tada's d0 is
        // the opening at the edge, the particles sit Δ/2 and 3Δ/2 inside it); the nearest
        // particle's own value when the row has no second one.
        let face = |k: usize| -> f64 {
            let u = |i: usize| y[i][axis] - x[i][axis];
            let inward = (x[k][other] - mouth[other]).signum();
            let same_row = |i: usize| (x[i][axis] - x[k][axis]).abs() < 1e-9 * spacing[k];
            let next = (0..x.len())
                .filter(|&i| same_row(i) && (x[i][other] - x[k][other]) * inward > 0.0)
                .min_by(|&a, &b| {
                    let d = |i: usize| (x[i][other] - x[k][other]).abs();
                    d(a).total_cmp(&d(b))
                });
            match next {
                Some(n) => {
                    let slope = (u(n) - u(k)) / (x[n][other] - x[k][other]);
                    u(k) + slope * (mouth[other] - x[k][other])
                }
                None => u(k),
            }
        };
        let (up, down) = (nearest(true)?, nearest(false)?);
        Some(face(up) - face(down))
    }

    /// The bonds as a `Families` view (crack-angle connectivity).
    fn families(&self) -> Families {
        let x = self.reference();
        let (offsets, neighbors) = self.bonds.compact_rows();
        let lengths = (0..self.bonds.particle_count())
            .flat_map(|k| {
                neighbors[offsets[k]..offsets[k + 1]].iter().map(move |&j| {
                    let j = j as usize;
                    ((x[j][0] - x[k][0]).powi(2) + (x[j][1] - x[k][1]).powi(2)).sqrt()
                })
            })
            .collect();
        Families::from_rows(offsets, neighbors, lengths)
    }

    fn crack_angles_for(&self, damage: &[f64]) -> Vec<(String, Option<f64>)> {
        if self.scene.crack_angles.is_empty() {
            return Vec::new();
        }
        let families = self.families();
        self.scene
            .crack_angles
            .iter()
            .map(|spec| {
                let angle = metrics::crack_angle(
                    spec,
                    self.reference(),
                    damage,
                    &families,
                    self.scene.spacing,
                    self.scene.horizon,
                );
                (spec.name.clone(), angle)
            })
            .collect()
    }
}

/// `[[boundary]]` layers → held flags and values, body forces.
fn apply_boundary(scene: &Scene, layers: &[Vec<u32>], nodes: &mut Nodes<2>, c: &Columns) {
    let fields = &mut nodes.fields;
    for (layer, selected) in scene.boundary.iter().zip(layers) {
        for &k in selected {
            let k = k as usize;
            for &a in &layer.axes {
                match layer.condition {
                    Condition::Velocity => {
                        fields.get_mut(c.held)[k] |= 1 << a;
                        fields.get_mut(c.held_velocity)[k][a] = layer.value[a];
                    }
                    Condition::Displacement => {
                        fields.get_mut(c.held)[k] |= 1 << (a as u8 + HOLD_DISPLACEMENT_SHIFT);
                        fields.get_mut(c.held_displacement)[k][a] = layer.value[a];
                    }
                    Condition::BodyForce => fields.get_mut(c.body_force)[k][a] += layer.value[a],
                    Condition::Reference | Condition::Value => {}
                }
            }
        }
    }
}

/// Cuts every bond crossing a pre-crack; an error names one that cuts none.
fn cut_precracks(scene: &Scene, nodes: &Nodes<2>, bonds: &mut DualBonds) -> Result<(), SceneError> {
    let x = nodes.reference();
    for (c, crack) in scene.precracks.iter().enumerate() {
        let mut cut = 0;
        for k in 0..bonds.particle_count() {
            for b in bonds.range(k) {
                let j = bonds.neighbors[b] as usize;
                if crosses(crack, &x[k], &x[j]) || crosses(crack, &x[j], &x[k]) {
                    bonds.intact[b] = 0;
                    cut += 1;
                }
            }
        }
        if cut == 0 {
            return Err(scene.error(
                &format!("precracks[{c}]"),
                "cuts no bond: the pre-crack lies outside the body (or between nodes)",
            ));
        }
    }
    Ok(())
}

/// The particles that meet (15) (and (16) unless `damage_only`: pre-processing, before any
/// force pass). During the run both come from the last force pass (`ParticleTerms`).
fn candidates(
    rule: &SplitRule,
    nodes: &Nodes<2>,
    c: &Columns,
    bonds: &DualBonds,
    damage_only: bool,
) -> Vec<u32> {
    let levels = nodes.fields.get(c.split.level);
    let constants = nodes.fields.get(c.split.constants);
    let terms = nodes.fields.get(c.terms);
    let wants = |k: usize| {
        if levels[k] >= rule.levels {
            return false;
        }
        let (damage, strains) = if damage_only {
            (bonds.damage_of(k, nodes.volumes()), [0.0; 2])
        } else {
            (terms[k].damage, terms[k].strains)
        };
        splitting::wants(rule, damage, strains, &constants[k], levels[k])
    };
    // Most steps split nothing: look first, allocate only when something splits.
    if !(0..nodes.len()).into_par_iter().any(wants) {
        return Vec::new();
    }
    (0..nodes.len())
        .into_par_iter()
        .filter(|&k| wants(k))
        .map(|k| k as u32)
        .collect()
}

/// λ_max of W⁻¹K for the weights W (masses: Verlet's limit; ADR's diagonal: its density
/// scale), by power iteration on K u = −F(x + εu)/ε about the reference configuration (where
/// F = 0), ε keeping the largest displacement at 10⁻⁶ of the smallest cell.
fn stiffness_eigenvalue(
    nodes: &Nodes<2>,
    c: &Columns,
    bonds: &mut DualBonds,
    material: &OsbMaterial,
    weights: &[f64],
) -> f64 {
    let body = body(nodes, c, material);
    let n = nodes.len();
    let smallest = nodes
        .fields
        .get(c.split.spacing)
        .iter()
        .copied()
        .fold(f64::INFINITY, f64::min);
    let mut y = vec![[0.0; 2]; n];
    let mut terms = vec![ParticleTerms::EMPTY; n];
    // Probing must not touch the bond states: the tiny strains stay far below s_c.
    let states = bonds.intact.clone();
    let lambda = stability::max_eigenvalue::<2>(n, weights, POWER_ITERATIONS, |u, out| {
        let largest = u
            .iter()
            .map(|v| v[0].abs().max(v[1].abs()))
            .fold(0.0, f64::max);
        if largest == 0.0 {
            out.fill([0.0; 2]);
            return;
        }
        let eps = 1e-6 * smallest / largest;
        for ((y, x), u) in y.iter_mut().zip(body.reference).zip(u) {
            *y = [x[0] + eps * u[0], x[1] + eps * u[1]];
        }
        bonds.evaluate(&body, &y, &mut terms);
        for ((o, t), w) in out.iter_mut().zip(&terms).zip(weights) {
            *o = [-t.force[0] / (eps * w), -t.force[1] / (eps * w)];
        }
    });
    bonds.intact.copy_from_slice(&states);
    lambda
}

/// Velocity-Verlet's stable step: the power-iterated sharp limit and a Gershgorin-type
/// estimate from the stiffness row sums. A scene that refines deeper than the particles it
/// starts with has the smallest level's limit, 2⁻ˡ of the present one (the lattice stiffness
/// per mass scales with 1/Δ² at δ ∝ Δ).
fn stable_step(
    spec: &StateBasedSpec,
    nodes: &Nodes<2>,
    c: &Columns,
    bonds: &mut DualBonds,
    density: f64,
) -> StableStep {
    let material = &spec.material;
    let masses: Vec<f64> = nodes.volumes().iter().map(|v| v * density).collect();
    let lambda = stiffness_eigenvalue(nodes, c, bonds, material, &masses);
    let diagonal = bonds.stiffness_rows(&body(nodes, c, material));
    let gershgorin = masses
        .iter()
        .zip(&diagonal)
        .map(|(m, d)| 2.0 * (m / d).sqrt())
        .fold(f64::INFINITY, f64::min);
    let present = nodes
        .fields
        .get(c.split.level)
        .iter()
        .copied()
        .max()
        .unwrap_or(0);
    let deeper = spec
        .refinement
        .map_or(0, |r| r.levels.saturating_sub(present));
    let factor = 0.5f64.powi(i32::from(deeper));
    StableStep {
        sharp: stability::verlet_step(lambda) * factor,
        guaranteed: gershgorin * factor,
        integrator: Integrator::Verlet,
    }
}

/// ADR's fictitious density Λ: the stiffness row sums scaled by λ_max of their D⁻¹K.
fn relaxation_of(
    nodes: &Nodes<2>,
    c: &Columns,
    bonds: &mut DualBonds,
    material: &OsbMaterial,
) -> Relaxation {
    let diagonal = bonds.stiffness_rows(&body(nodes, c, material));
    let lambda = stiffness_eigenvalue(nodes, c, bonds, material, &diagonal);
    Relaxation::new(adr::scale_density(&diagonal, lambda), lambda)
}

fn initial_scale(velocities: &[[f64; 2]]) -> f64 {
    let max = velocities
        .iter()
        .map(|v| (v[0] * v[0] + v[1] * v[1]).sqrt())
        .fold(0.0, f64::max);
    if max > 0.0 { max } else { 1.0 }
}

/// The `nodes/level` classes: the splitting generation.
const LEVELS: &[(u16, &str, [u8; 3])] = &[
    (0, "parent", [120, 120, 120]),
    (1, "child", [230, 85, 13]),
    (2, "grandchild", [49, 130, 189]),
    (3, "great-grandchild", [49, 163, 84]),
];

impl Stepper for DualHorizonSimulation {
    fn step(&mut self) -> Result<(), SimError> {
        match self.motion {
            Motion::Verlet => self.step_verlet(),
            Motion::Relaxation { .. } => {
                self.step_relaxation();
                Ok(())
            }
        }
    }

    fn converged(&self) -> bool {
        match &self.motion {
            Motion::Relaxation {
                residual,
                tolerance,
                ..
            } => self.run.clock.step() > 0 && *residual < *tolerance,
            Motion::Verlet => false,
        }
    }

    fn frame(&mut self) -> Frame {
        let damage = self.damage();
        let speed: Vec<f64> = self
            .velocities()
            .iter()
            .map(|v| (v[0] * v[0] + v[1] * v[1]).sqrt())
            .collect();
        let (kinetic, strain, momentum) = self.energies();
        let mut scalars = vec![
            ("energy/kinetic".to_string(), kinetic),
            ("energy/strain".to_string(), strain),
            ("energy/total".to_string(), kinetic + strain),
            ("bonds/broken".to_string(), self.broken as f64),
            ("momentum/x".to_string(), momentum[0]),
            ("momentum/y".to_string(), momentum[1]),
            ("refine/particles".to_string(), self.len() as f64),
            (
                "metrics/refine/splits".to_string(),
                self.split_parents as f64,
            ),
        ];
        scalars.extend(self.run.timing_scalars());
        if let Motion::Relaxation {
            residual,
            relaxation,
            ..
        } = &self.motion
        {
            scalars.push(("adr/residual".to_string(), *residual));
            scalars.push(("adr/damping".to_string(), relaxation.damping));
        }
        for o in &self.spec.openings {
            if let Some(d) = self.opening(&o.mouth, o.axis) {
                scalars.push((format!("opening/{}", o.name), d));
            }
        }
        metrics::damage_counts(&self.scene, self.reference(), &damage, &mut scalars);
        for (name, angle) in self.crack_angles_for(&damage) {
            if let Some(a) = angle {
                scalars.push((format!("crack_angle_deg/{name}"), a));
            }
        }
        let levels = self.levels();
        let spacing = self.nodes.fields.get(self.columns.split.spacing);
        Frame {
            step: self.run.clock.step(),
            time: self.run.clock.time(),
            dim: 2,
            positions: self.positions().as_flattened().to_vec(),
            fields: vec![
                NodeField {
                    name: "damage".into(),
                    values: damage,
                    range: (0.0, 1.0),
                },
                NodeField {
                    name: "velocity".into(),
                    values: speed,
                    range: (0.0, self.velocity_scale),
                },
            ],
            classes: vec![ClassField {
                name: "level",
                ids: levels.iter().map(|&l| u16::from(l)).collect(),
                classes: LEVELS,
            }],
            events: std::mem::take(&mut self.events),
            scalars,
            radii: spacing.iter().map(|&d| (0.5 * d) as f32).collect(),
        }
    }

    fn info(&self) -> SimInfo {
        let (nodes, bonds) = (self.len(), self.bonds.bond_count());
        self.run
            .info(Size::of_bonds(2, nodes, bonds, self.bonds.bytes_per_bond()))
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
        state.put_u64("dual_horizon/particles", vec![self.len() as u64]);
        state.put_f64("position", self.positions().as_flattened().to_vec());
        state.put_f64("velocity", self.velocities().as_flattened().to_vec());
        state.put_u8("intact", self.bonds.intact.clone());
        state.put_u64("broken", vec![self.broken, self.splits, self.split_parents]);
        // Every split as its parent count then its parents.
        let log: Vec<u64> = self
            .split_log
            .iter()
            .flat_map(|p| std::iter::once(p.len() as u64).chain(p.iter().map(|&k| u64::from(k))))
            .collect();
        state.put_u64("dual_horizon/split_log_len", vec![log.len() as u64]);
        state.put_u64("dual_horizon/split_log", log);
        // The step's own accelerations and force-pass terms: a split at the checkpoint's step
        // left its children with their parent's, which a new force pass would not give.
        state.put_f64("acceleration", self.accelerations().as_flattened().to_vec());
        let terms: Vec<f64> = self
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
        state
    }

    /// Restores a state of this scene: the splits since the start are replayed from the
    /// checkpoint's log (the same parents in the same order give the same particles and
    /// bond layout; positions, velocities, bond states and force-pass results then come
    /// from the checkpoint), so the resumed run continues bit for bit.
    fn restore_state(&mut self, state: &State) -> Result<(), String> {
        let saved = state.u64("dual_horizon/particles", 1)?[0] as usize;
        if saved != self.len() && state.has("dual_horizon/split_log") {
            self.replay_splits(state)?;
        }
        let n = self.len();
        if saved != n {
            return Err(format!(
                "the checkpoint holds {saved} particles, this scene {n} after replaying its \
                 splits: it belongs to another scene or another version"
            ));
        }
        let clock = Clock::restore(state)?;
        let position = state.f64("position", 2 * n)?;
        let velocity = state.f64("velocity", 2 * n)?;
        let intact = state.u8("intact", self.bonds.slot_count())?;
        let counters = state.u64("broken", 3)?;
        self.positions_mut()
            .as_flattened_mut()
            .copy_from_slice(position);
        self.velocities_mut()
            .as_flattened_mut()
            .copy_from_slice(velocity);
        self.bonds.intact.copy_from_slice(intact);
        (self.broken, self.splits, self.split_parents) = (counters[0], counters[1], counters[2]);
        self.run.clock = clock;
        if state.has("dual_horizon/terms") {
            let acceleration = state.f64("acceleration", 2 * n)?;
            let terms = state.f64("dual_horizon/terms", 7 * n)?;
            let c = self.columns;
            let fields = &mut self.nodes.fields;
            fields
                .get_mut(c.acceleration)
                .as_flattened_mut()
                .copy_from_slice(acceleration);
            for (t, v) in fields
                .get_mut(c.terms)
                .iter_mut()
                .zip(terms.chunks_exact(7))
            {
                *t = ParticleTerms {
                    force: [v[0], v[1]],
                    dilatation: v[2],
                    energy_density: v[3],
                    damage: v[4],
                    strains: [v[5], v[6]],
                };
            }
        } else {
            // A checkpoint without them (an earlier version, no split since the start).
            self.update_forces();
        }
        Ok(())
    }

    fn crack_angles(&self) -> Vec<(String, Option<f64>)> {
        self.crack_angles_for(&self.damage())
    }

    fn broken_bonds(&self) -> u64 {
        self.broken
    }

    /// φ_c and α act in place from the next step's check on.
    fn tune(&mut self, param: Param) -> Result<(), String> {
        let Some(rule) = self.spec.refinement.as_mut() else {
            return Err(param.unused_note().into());
        };
        match param {
            Param::SplitDamage(phi) => rule.damage = crate::scene::check_split_damage(phi)?,
            Param::SplitStrain(alpha) => {
                rule.strain_factor = crate::scene::check_split_strain(alpha)?;
                self.mark_splittable();
            }
            Param::Chi(_) => {
                return Err("a dual-horizon scene has no hybrid scheme: χ is recorded only".into());
            }
            Param::AppliedPotential(_) => return Err(param.unused_note().into()),
        }
        Ok(())
    }
}
