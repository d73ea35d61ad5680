//! The particle body of a dual-horizon simulation (zeng2024 Sect. 2): particles with their
//! own horizons and cells in the `Nodes` store (children inherit every column), the directed
//! dual bonds, the buckets that find a child's neighbours, the held components, and the OSB
//! force pass with its accelerations; the velocity-Verlet body and force terms of the driver.

use rayon::prelude::*;

use crate::adapt::splitting::{self, SplitColumns};
use crate::discretization::buckets::Buckets;
use crate::discretization::family::crosses;
use crate::discretization::{Field, Lattice, NodeValue, Nodes, layers};
use crate::integrate::adr::Relaxation;
use crate::integrate::verlet::{self, ForceTerms, VerletBody};
use crate::model::osb::{OsbHorizon, OsbMaterial};
use crate::scene::{Condition, Scene, SceneError, StateBasedSpec};
use crate::scheme::dual_horizon::{Body, DualBonds, ParticleTerms};
use crate::solver::Adaptation;

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
pub(super) struct Columns {
    pub split: SplitColumns,
    pub velocity: Field<[f64; 2]>,
    pub acceleration: Field<[f64; 2]>,
    pub terms: Field<ParticleTerms>,
    /// Bit flags: which components are held (velocity bits, then displacement bits).
    pub held: Field<u8>,
    /// Held velocity and held displacement values.
    pub held_velocity: Field<[f64; 2]>,
    pub held_displacement: Field<[f64; 2]>,
    /// Body force density b (N/m³).
    pub body_force: Field<[f64; 2]>,
}

pub struct ParticleBody {
    pub scene: Scene,
    pub spec: StateBasedSpec,
    pub(super) nodes: Nodes<2>,
    pub(super) columns: Columns,
    pub bonds: DualBonds,
    pub(super) buckets: Buckets,
    pub density: f64,
    held: Vec<Held>,
    /// The smallest particle's Δ (the blow-up check's length; it shrinks only by a split).
    smallest_spacing: f64,
    /// Directed bonds broken so far.
    pub broken: u64,
    /// The color range of the speed field: the initial largest speed.
    pub velocity_scale: f64,
}

impl ParticleBody {
    /// The lattice of `scene` at rest (initial velocities added), its dual bonds with the
    /// pre-cracks cut and the quadrature refitted around them. The held components are
    /// listed by [`Self::particles_changed`].
    pub fn new(scene: &Scene, spec: StateBasedSpec, density: f64) -> Result<Self, SceneError> {
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
        super::super::initial::add_initial_velocity(
            scene,
            nodes.base.reference(),
            nodes.fields.get_mut(columns.velocity),
        );
        // Cells wide enough for a parent's horizon plus the reach of its children.
        let buckets = Buckets::new(
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
        Ok(ParticleBody {
            scene: scene.clone(),
            spec,
            nodes,
            columns,
            bonds,
            buckets,
            density,
            held: Vec::new(),
            smallest_spacing: scene.spacing,
            broken: 0,
            velocity_scale: 1.0,
        })
    }

    pub fn material(&self) -> &OsbMaterial {
        &self.spec.material
    }

    /// The particles' geometry and constants as the bond passes read them.
    pub(super) fn body(&self) -> Body<'_> {
        body(&self.nodes, &self.columns, &self.spec.material)
    }

    /// [`Self::body`] with the bonds to evaluate on it.
    pub(super) fn body_and_bonds(&mut self) -> (Body<'_>, &mut DualBonds) {
        (
            body(&self.nodes, &self.columns, &self.spec.material),
            &mut self.bonds,
        )
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

    /// Each particle's cell length Δ_k.
    pub fn spacings(&self) -> &[f64] {
        self.nodes.fields.get(self.columns.split.spacing)
    }

    pub fn constants(&self) -> &[OsbHorizon] {
        self.nodes.fields.get(self.columns.split.constants)
    }

    pub fn terms(&self) -> &[ParticleTerms] {
        self.nodes.fields.get(self.columns.terms)
    }

    pub fn density(&self) -> f64 {
        self.density
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
    pub fn hold(&mut self) {
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

    /// Damage (14) of every particle.
    pub fn damage(&self) -> Vec<f64> {
        self.bonds.damage(self.nodes.volumes())
    }

    /// Splits `parents` (distinct, below the level cap) with children of `horizon_ratio`
    /// times their parent's horizon, and brings what depends on the particle set up to date.
    pub fn split(&mut self, parents: &[u32], horizon_ratio: f64) {
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
        self.particles_changed();
    }

    /// The held components listed from the columns (children carry their parent's flags),
    /// and the smallest cell.
    pub fn particles_changed(&mut self) {
        self.held = held_list(&self.nodes, &self.columns);
        self.smallest_spacing = self
            .spacings()
            .iter()
            .copied()
            .fold(f64::INFINITY, f64::min);
    }

    /// The split criteria of every particle (see `super::split`).
    pub fn set_criteria(&mut self, criteria: impl Iterator<Item = f64>) {
        self.bonds.criteria.clear();
        self.bonds.criteria.extend(criteria);
    }

    /// (kinetic energy, strain energy, momentum).
    pub fn energies(&self) -> (f64, f64, [f64; 2]) {
        let volumes = self.nodes.volumes();
        let (kinetic, momentum) =
            crate::metrics::kinetic_energy_and_momentum(self.velocities(), volumes, self.density);
        let terms = self.terms();
        let [strain] =
            crate::integrate::ordered_sum(terms.len(), |k| [terms[k].energy_density * volumes[k]]);
        (kinetic, strain, momentum)
    }

    /// Total mass Σ ρ V.
    pub fn mass(&self) -> f64 {
        self.density * self.nodes.volumes().iter().sum::<f64>()
    }

    /// ADR's residual forces of the free components (force-pass force plus body force) and
    /// their external part; held components get 0.
    pub(super) fn residual_forces(&self, force: &mut [[f64; 2]], external: &mut [[f64; 2]]) {
        let c = self.columns;
        let fields = &self.nodes.fields;
        let volumes = self.nodes.base.volumes();
        let (terms, body_force) = (fields.get(c.terms), fields.get(c.body_force));
        let free = fields.get(c.held);
        force
            .par_iter_mut()
            .zip(external.par_iter_mut())
            .enumerate()
            .for_each(|(k, (f, e))| {
                for i in 0..2usize {
                    let held =
                        free[k] & ((1 << i) | (1 << (i + usize::from(HOLD_DISPLACEMENT_SHIFT))));
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

    /// One ADR iteration's update of positions and velocities from `force`.
    pub(super) fn relax(&mut self, relaxation: &mut Relaxation, force: &[[f64; 2]]) {
        let c = self.columns;
        let reference = self.nodes.base.reference();
        let (positions, velocities) = self.nodes.fields.pair_mut(c.split.position, c.velocity);
        relaxation.iterate(force, velocities, positions, reference);
    }

    /// Copies a checkpoint's accelerations and force-pass terms (7 values per particle).
    pub(super) fn write_forces(&mut self, acceleration: &[f64], terms: &[f64]) {
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
    }
}

impl VerletBody for ParticleBody {
    fn kick_drift(&mut self, dt: f64) {
        let c = self.columns;
        {
            let (v, a) = self.nodes.fields.pair_mut(c.velocity, c.acceleration);
            verlet::half_kick(v, a, dt);
        }
        self.hold();
        {
            let (y, v) = self.nodes.fields.pair_mut(c.split.position, c.velocity);
            verlet::drift(y, v, dt);
        }
        self.hold();
    }

    fn constraints(&mut self) {
        self.hold();
    }

    fn blowup_length(&self) -> f64 {
        self.smallest_spacing
    }
}

/// The OSB dual-horizon force pass (zeng2024 (7)–(13)), and the kick from its accelerations.
pub struct OsbForces;

impl Adaptation<ParticleBody> for OsbForces {}

impl ForceTerms<ParticleBody> for OsbForces {
    fn forces(&mut self, body: &mut ParticleBody, _energy: bool) {
        body.update_forces();
    }

    fn kick(&mut self, body: &mut ParticleBody, dt: f64) -> f64 {
        let c = body.columns;
        let (v, a) = body.nodes.fields.pair_mut(c.velocity, c.acceleration);
        v.par_iter_mut()
            .zip(a.par_iter())
            .map(|(v, a)| verlet::kick_node(v, a, dt))
            .reduce(|| 0.0, verlet::max_or_nan)
    }
}

fn body<'a>(nodes: &'a Nodes<2>, columns: &Columns, material: &OsbMaterial) -> Body<'a> {
    Body {
        reference: nodes.reference(),
        volumes: nodes.volumes(),
        constants: nodes.fields.get(columns.split.constants),
        thickness: material.thickness,
    }
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
