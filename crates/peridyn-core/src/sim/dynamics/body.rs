//! The elastic body of a dynamic simulation: its discretization, per-node columns (positions,
//! velocities, accelerations, the force loop's node terms), bond states, held components and
//! the PMB law (2.33)–(2.34). It knows how to kick, drift and hold itself and how to run the
//! standard bond sums (3.1) on its rows; which rows run which scheme is its scheme's business
//! (`super::scheme`).

use rayon::prelude::*;

use crate::adapt::multiadaptive::Growth;
use crate::discretization::nodes::Base;
use crate::discretization::{Discretization, Families, Field, Nodes, Quadrature, family};
use crate::integrate::verlet::{self, VerletBody};
use crate::metrics;
use crate::model::pmb::PmbLaw;
use crate::scene::{BoundarySpec, Condition, Scene};
use crate::scheme::RowMask;
use crate::scheme::standard::{NodeTerms, Standard};
use crate::solver::State;

/// A prescribed node component: node, axis, value.
type Held = (u32, u8, f64);

/// The per-node columns of a dynamic simulation.
#[derive(Debug, Clone, Copy)]
pub(super) struct Columns<const D: usize> {
    /// Current positions y = x + u.
    pub position: Field<[f64; D]>,
    pub velocity: Field<[f64; D]>,
    pub acceleration: Field<[f64; D]>,
    /// What the force loop produces per node (force, energy density, broken weight); a node
    /// on a WLS row holds its WLS force here.
    pub terms: Field<NodeTerms<D>>,
    /// Σ β V'_j over each node's family: the damage denominator (see `damage_weights`).
    pub family_weight: Field<f64>,
    /// Only where a `body_force` layer exists.
    pub body_force: Option<Field<[f64; D]>>,
}

pub struct ElasticBody<const D: usize> {
    pub scene: Scene,
    pub discretization: Discretization<D>,
    pub(super) columns: Columns<D>,
    pub intact: Vec<u8>,
    held_velocity: Vec<Held>,
    held_displacement: Vec<Held>,
    pub law: PmbLaw,
    pub density: f64,
    /// Directed bonds broken so far.
    pub broken: u64,
    /// The color range of the speed field: twice the initial largest speed.
    pub velocity_scale: f64,
    /// Whether the node terms' strain-energy densities belong to the last force pass. The
    /// pass sums them only when a frame is due after its step (`RunState::frame_due_next`);
    /// a frame or checkpoint taken at another step evaluates them afresh.
    pub energy_current: bool,
    /// Kinetic plus strain energy per node at the last frame (where a region metric, probe
    /// or plug-in reads it; empty otherwise).
    pub node_energy: Vec<f64>,
}

impl<const D: usize> ElasticBody<D> {
    /// The body of `scene` at rest in its reference configuration, with its bond states, law
    /// and each node's damage denominator and pre-cracked numerator; then the initial
    /// velocities and displacements and the held components.
    pub fn new(
        scene: &Scene,
        mut discretization: Discretization<D>,
        intact: Vec<u8>,
        (law, density): (PmbLaw, f64),
        (family_weight, precracked): (Vec<f64>, Vec<f64>),
    ) -> ElasticBody<D> {
        let nodes = &mut discretization.nodes;
        let n = nodes.len();
        let position = nodes
            .fields
            .add_values("position", nodes.base.reference().to_vec());
        let terms = precracked
            .iter()
            .map(|&w| NodeTerms {
                broken_weight: w,
                ..NodeTerms::default()
            })
            .collect();
        let mut columns = Columns {
            position,
            velocity: nodes.fields.add("velocity", [0.0; D]),
            acceleration: nodes.fields.add("acceleration", [0.0; D]),
            terms: nodes.fields.add_values("terms", terms),
            family_weight: nodes.fields.add_values("family_weight", family_weight),
            body_force: None,
        };
        let (held_velocity, held_displacement, body_force) =
            boundary_conditions::<D>(scene, &discretization.layers, n);
        if let Some(body) = body_force {
            columns.body_force = Some(discretization.nodes.fields.add_values("body_force", body));
        }
        let mut body = ElasticBody {
            scene: scene.clone(),
            discretization,
            columns,
            intact,
            held_velocity,
            held_displacement,
            law,
            density,
            broken: 0,
            velocity_scale: 1.0,
            energy_current: false,
            node_energy: Vec::new(),
        };
        body.apply_initial_velocity();
        body.apply_initial_displacement();
        body.apply_constraints();
        body.velocity_scale = body.initial_velocity_scale();
        body
    }

    fn apply_initial_velocity(&mut self) {
        let nodes = &mut self.discretization.nodes;
        let velocities = nodes.fields.get_mut(self.columns.velocity);
        super::super::initial::add_initial_velocity(
            &self.scene,
            nodes.base.reference(),
            velocities,
        );
    }

    /// Displacement pulses (thesis (4.168)): y = x + Σ u⁰(x).
    fn apply_initial_displacement(&mut self) {
        let nodes = &mut self.discretization.nodes;
        let positions = nodes.fields.get_mut(self.columns.position);
        for pulse in &self.scene.initial_pulses {
            for (y, x) in positions.iter_mut().zip(nodes.base.reference()) {
                pulse.add_displacement(x, y);
            }
        }
    }

    fn initial_velocity_scale(&self) -> f64 {
        let max = self
            .velocities()
            .iter()
            .map(|v| v.iter().map(|x| x * x).sum::<f64>().sqrt())
            .fold(0.0, f64::max);
        if max > 0.0 { 2.0 * max } else { 1.0 }
    }

    pub fn density(&self) -> f64 {
        self.density
    }

    pub fn nodes(&self) -> &Nodes<D> {
        &self.discretization.nodes
    }

    /// Reference positions x.
    pub fn reference(&self) -> &[[f64; D]] {
        self.nodes().reference()
    }

    pub fn volumes(&self) -> &[f64] {
        self.nodes().volumes()
    }

    pub fn families(&self) -> &Families {
        &self.discretization.families
    }

    pub fn quadrature(&self) -> &Quadrature {
        &self.discretization.quadrature
    }

    /// Current positions y = x + u.
    pub fn positions(&self) -> &[[f64; D]] {
        self.nodes().fields.get(self.columns.position)
    }

    pub fn positions_mut(&mut self) -> &mut [[f64; D]] {
        let c = self.columns.position;
        self.discretization.nodes.fields.get_mut(c)
    }

    pub fn velocities(&self) -> &[[f64; D]] {
        self.nodes().fields.get(self.columns.velocity)
    }

    pub fn velocities_mut(&mut self) -> &mut [[f64; D]] {
        let c = self.columns.velocity;
        self.discretization.nodes.fields.get_mut(c)
    }

    /// The reference positions and families with the current positions and velocities, to
    /// change in place (a level transfer, an absorbing layer).
    #[allow(clippy::type_complexity)]
    pub fn motion_mut(&mut self) -> (&[[f64; D]], &Families, &mut [[f64; D]], &mut [[f64; D]]) {
        let c = self.columns;
        let Discretization {
            nodes, families, ..
        } = &mut self.discretization;
        let (positions, velocities) = nodes.fields.pair_mut(c.position, c.velocity);
        (nodes.base.reference(), families, positions, velocities)
    }

    pub fn accelerations(&self) -> &[[f64; D]] {
        self.nodes().fields.get(self.columns.acceleration)
    }

    pub fn terms(&self) -> &[NodeTerms<D>] {
        self.nodes().fields.get(self.columns.terms)
    }

    pub(super) fn terms_mut(&mut self) -> &mut [NodeTerms<D>] {
        let c = self.columns.terms;
        self.discretization.nodes.fields.get_mut(c)
    }

    /// The standard scheme over the whole discretization.
    pub fn scheme(&self) -> Standard<'_, D> {
        self.level_scheme(None)
    }

    /// The standard scheme with `level`'s quadrature and cell volume (a grid level of a
    /// multi-grid discretization, whose families hold only its own nodes), or the
    /// discretization's own.
    pub fn level_scheme<'a>(&'a self, level: Option<&'a Quadrature>) -> Standard<'a, D> {
        standard_over(&self.discretization, &self.law, level)
    }

    /// The bond loop's terms, energy densities included, of the rows `skip` does not skip,
    /// from the force loop run on a copy of the bond states (the body is left as it is).
    pub fn bond_terms_of(&self, skip: &[u8]) -> Vec<NodeTerms<D>> {
        let mut intact = self.intact.clone();
        let mut terms = vec![NodeTerms::default(); self.positions().len()];
        self.scheme()
            .forces_masked(self.positions(), &mut intact, &mut terms, Some(skip), true);
        terms
    }

    /// The PMB bond loop on the rows `skip` does not skip (all without a mask), with `level`'s
    /// quadrature (see [`Self::level_scheme`]): forces, broken bonds and, where `energy` is
    /// set, strain-energy densities. Returns the directed bonds broken in this pass.
    pub fn bond_forces<M: RowMask>(
        &mut self,
        level: Option<&Quadrature>,
        skip: Option<&[M]>,
        energy: bool,
    ) -> u64 {
        let c = self.columns;
        let Discretization {
            nodes,
            families,
            quadrature,
            uniform_volume,
            ..
        } = &mut self.discretization;
        let own = (&*quadrature, *uniform_volume);
        let scheme = standard_of(&nodes.base, families, own, &self.law, level);
        let (positions, terms) = nodes.fields.pair_mut(c.position, c.terms);
        let broken = scheme.forces_masked(positions, &mut self.intact, terms, skip, energy);
        self.broken += broken;
        broken
    }

    /// ü = (f + b)/ρ per node, skipping the nodes `idle` marks (not integrated: interpolated
    /// or idle levels, whose ü is 0). With `kick = Some(Δt)` the second half kick (3.5) runs in
    /// the same pass; returns the largest squared speed then (NaN-propagating), 0 otherwise.
    pub fn accelerate<M: RowMask>(&mut self, kick: Option<f64>, idle: Option<&[M]>) -> f64 {
        let inv_rho = 1.0 / self.density;
        let c = self.columns;
        let fields = &mut self.discretization.nodes.fields;
        let (accelerations, velocities, terms, body): (_, _, &mut [NodeTerms<D>], &[[f64; D]]) =
            match c.body_force {
                Some(b) => {
                    let (a, v, t, b) = fields.quad_mut(c.acceleration, c.velocity, c.terms, b);
                    (a, v, t, b)
                }
                None => {
                    let (a, v, t) = fields.triple_mut(c.acceleration, c.velocity, c.terms);
                    (a, v, t, &[])
                }
            };
        let terms = &*terms;
        accelerations
            .par_iter_mut()
            .zip(velocities)
            .enumerate()
            .with_min_len(4096)
            .map(|(i, (a, v))| {
                if idle.is_some_and(|m| m[i].skipped()) {
                    *a = [0.0; D];
                    return 0.0;
                }
                let force = terms[i].force;
                for k in 0..D {
                    let b = if body.is_empty() { 0.0 } else { body[i][k] };
                    a[k] = (force[k] + b) * inv_rho;
                }
                kick.map_or(0.0, |dt| verlet::kick_node(v, a, dt))
            })
            .reduce(|| 0.0, verlet::max_or_nan)
    }

    fn hold_velocities(&mut self) {
        let c = self.columns.velocity;
        let velocities = self.discretization.nodes.fields.get_mut(c);
        for &(i, a, value) in &self.held_velocity {
            velocities[i as usize][a as usize] = value;
        }
    }

    /// Held velocities and displacements (velocity layers also move the node).
    pub fn apply_constraints(&mut self) {
        self.hold_velocities();
        let nodes = &mut self.discretization.nodes;
        let (positions, velocities) = nodes
            .fields
            .pair_mut(self.columns.position, self.columns.velocity);
        let reference = nodes.base.reference();
        for &(i, a, value) in &self.held_displacement {
            let (i, a) = (i as usize, a as usize);
            positions[i][a] = reference[i][a] + value;
            velocities[i][a] = 0.0;
        }
    }

    /// Damage φ_i (2.36), kept up to date by the force loop as bonds break.
    pub fn damage(&self) -> Vec<f64> {
        let family_weight = self.nodes().fields.get(self.columns.family_weight);
        self.terms()
            .iter()
            .zip(family_weight)
            .map(|(t, &all)| {
                if all > 0.0 {
                    t.broken_weight / all
                } else {
                    0.0
                }
            })
            .collect()
    }

    /// Bytes held by the solver state: bond arrays and the per-node store.
    pub fn memory_bytes(&self) -> usize {
        use std::mem::size_of_val;
        self.families().memory_bytes()
            + size_of_val(self.intact.as_slice())
            + self.nodes().memory_bytes()
    }

    /// Kinetic energy and momentum over the nodes that carry mass (`mass_volumes`).
    pub fn kinetic_energy_and_momentum_over(&self, mass_volumes: &[f64]) -> (f64, [f64; D]) {
        metrics::kinetic_energy_and_momentum(self.velocities(), mass_volumes, self.density)
    }
}

/// The body's part of a checkpoint, read and checked against the body before anything
/// changes.
pub struct SavedBody<'a> {
    position: &'a [f64],
    velocity: &'a [f64],
    acceleration: &'a [f64],
    terms: &'a [f64],
    intact: &'a [u8],
    broken: u64,
}

impl<const D: usize> ElasticBody<D> {
    /// Into a checkpoint: positions, velocities, accelerations, the node terms (with every
    /// W_i: `energy_density` gives those the last pass did not sum), bond states and the
    /// broken count.
    pub fn save(&self, state: &mut State, energy_density: impl Fn(usize) -> f64 + Sync) {
        state.put_f64("position", self.positions().as_flattened().to_vec());
        state.put_f64("velocity", self.velocities().as_flattened().to_vec());
        state.put_f64("acceleration", self.accelerations().as_flattened().to_vec());
        let current = self.energy_current;
        let terms: Vec<f64> = self
            .terms()
            .par_iter()
            .enumerate()
            .flat_map_iter(|(i, t)| {
                let energy = if current {
                    t.energy_density
                } else {
                    energy_density(i)
                };
                t.force.into_iter().chain([energy, t.broken_weight])
            })
            .collect();
        state.put_f64("terms", terms);
        state.put_u8("intact", self.intact.clone());
        state.put_u64("broken", vec![self.broken]);
    }

    /// A checkpoint's body part, if it fits this body.
    pub fn read_state<'a>(&self, state: &'a State) -> Result<SavedBody<'a>, String> {
        let n = self.nodes().len();
        Ok(SavedBody {
            position: state.f64("position", n * D)?,
            velocity: state.f64("velocity", n * D)?,
            acceleration: state.f64("acceleration", n * D)?,
            terms: state.f64("terms", n * (D + 2))?,
            intact: state.u8("intact", self.intact.len())?,
            broken: state.u64("broken", 1)?[0],
        })
    }

    /// Continues from a checkpoint's body part (read by [`Self::read_state`]).
    pub fn write_state(&mut self, saved: SavedBody<'_>) {
        let c = self.columns;
        let fields = &mut self.discretization.nodes.fields;
        let (y, v, a) = fields.triple_mut(c.position, c.velocity, c.acceleration);
        y.as_flattened_mut().copy_from_slice(saved.position);
        v.as_flattened_mut().copy_from_slice(saved.velocity);
        a.as_flattened_mut().copy_from_slice(saved.acceleration);
        for (t, s) in fields
            .get_mut(c.terms)
            .iter_mut()
            .zip(saved.terms.chunks_exact(D + 2))
        {
            t.force.copy_from_slice(&s[..D]);
            (t.energy_density, t.broken_weight) = (s[D], s[D + 1]);
        }
        self.intact.copy_from_slice(saved.intact);
        self.energy_current = true;
        self.broken = saved.broken;
    }
}

impl<const D: usize> VerletBody for ElasticBody<D> {
    fn kick_drift(&mut self, dt: f64) {
        let c = self.columns;
        {
            let fields = &mut self.discretization.nodes.fields;
            let (velocities, accelerations) = fields.pair_mut(c.velocity, c.acceleration);
            verlet::half_kick(velocities, accelerations, dt);
        }
        self.hold_velocities();
        let fields = &mut self.discretization.nodes.fields;
        let (positions, velocities) = fields.pair_mut(c.position, c.velocity);
        verlet::drift(positions, velocities, dt);
    }

    fn constraints(&mut self) {
        self.apply_constraints();
    }

    fn blowup_length(&self) -> f64 {
        self.scene.spacing
    }
}

impl<const D: usize> ElasticBody<D> {
    /// Appends the nodes of a multi-adaptive refinement (`MultiAdaptive::refine`): their
    /// columns at rest, their families with the scene's pre-cracks cut, the re-pointed bonds,
    /// their damage weights with `level`'s quadrature, and the boundary layers they fall in.
    pub fn grow(&mut self, growth: &Growth<D>, level: &Quadrature) {
        let count = growth.reference.len();
        let nodes = &mut self.discretization.nodes;
        let new = nodes.append(
            &growth.reference,
            &vec![growth.volume; count],
            &vec![u32::MAX; count],
        );
        let c = self.columns;
        nodes.fields.get_mut(c.position)[new.clone()].copy_from_slice(&growth.reference);
        let families = &mut self.discretization.families;
        let first_bond = families.bond_count();
        families.append_rows(&growth.rows);
        for &(b, j) in &growth.rewrites {
            families.neighbors[b] = j;
        }
        let reference = self.discretization.nodes.reference();
        let families = &self.discretization.families;
        let cut: Vec<usize> = new
            .clone()
            .into_par_iter()
            .flat_map_iter(|i| {
                let cracks = self.scene.precracks.iter();
                cracks.flat_map(move |k| family::cut_bonds(k, reference, families, i))
            })
            .collect();
        self.intact.resize(families.bond_count(), 1);
        for b in cut {
            self.intact[b] = 0;
        }
        debug_assert!(families.range(new.start).start >= first_bond);
        let weights: Vec<(f64, f64)> = {
            let scheme = self.level_scheme(Some(level));
            new.clone()
                .into_par_iter()
                .map(|i| scheme.row_damage_weights(i, &self.intact))
                .collect()
        };
        let fields = &mut self.discretization.nodes.fields;
        for (i, &(all, lost)) in new.clone().zip(&weights) {
            fields.get_mut(c.family_weight)[i] = all;
            fields.get_mut(c.terms)[i].broken_weight = lost;
        }
        self.hold_new_nodes(new);
    }

    /// Adds nodes `new` to the boundary layers that select them, with their held components
    /// and body forces.
    fn hold_new_nodes(&mut self, new: std::ops::Range<usize>) {
        let scene = &self.scene;
        let (lo, hi) = scene.solid.bounds();
        let eps = 1e-9 * scene.spacing;
        let reference = self.discretization.nodes.reference();
        let mut selected: Vec<(usize, u32)> = Vec::new();
        for (l, layer) in scene.boundary.iter().enumerate() {
            selected.extend(
                new.clone()
                    .filter(|&i| layer.contains(&reference[i], &lo, &hi, eps))
                    .map(|i| (l, i as u32)),
            );
        }
        let fields = &mut self.discretization.nodes.fields;
        for (l, i) in selected {
            self.discretization.layers[l].push(i);
            let (velocity, displacement) = (&mut self.held_velocity, &mut self.held_displacement);
            apply_layer(
                &self.scene.boundary[l],
                i,
                velocity,
                displacement,
                |a, value| {
                    let column = self
                        .columns
                        .body_force
                        .expect("a body-force layer's column");
                    fields.get_mut(column)[i as usize][a] += value;
                },
            );
        }
    }
}

/// The standard scheme over `discretization` with `level`'s quadrature and cell volume, or
/// the discretization's own (see [`ElasticBody::level_scheme`]).
pub fn standard_over<'a, const D: usize>(
    discretization: &'a Discretization<D>,
    law: &'a PmbLaw,
    level: Option<&'a Quadrature>,
) -> Standard<'a, D> {
    let d = discretization;
    let own = (&d.quadrature, d.uniform_volume);
    standard_of(&d.nodes.base, &d.families, own, law, level)
}

/// [`standard_over`] from the discretization's parts (`own`: its quadrature and uniform
/// volume), so the caller may hold its node columns mutably meanwhile.
fn standard_of<'a, const D: usize>(
    base: &'a Base<D>,
    families: &'a Families,
    own: (&'a Quadrature, Option<f64>),
    law: &'a PmbLaw,
    level: Option<&'a Quadrature>,
) -> Standard<'a, D> {
    Standard {
        reference: base.reference(),
        volumes: base.volumes(),
        uniform_volume: match level {
            Some(q) => Some(q.spacing.powi(D as i32)),
            None => own.1,
        },
        families,
        law,
        quadrature: level.unwrap_or(own.0),
    }
}

/// Held velocities, held displacements and body forces of the scene's layers (`layers`: the
/// nodes each selects). Scalar-field conditions are refused for dynamics by validation.
#[allow(clippy::type_complexity)]
fn boundary_conditions<const D: usize>(
    scene: &Scene,
    layers: &[Vec<u32>],
    n: usize,
) -> (Vec<Held>, Vec<Held>, Option<Vec<[f64; D]>>) {
    let (mut velocity, mut displacement) = (Vec::new(), Vec::new());
    let mut body: Option<Vec<[f64; D]>> = None;
    for (layer, nodes) in scene.boundary.iter().zip(layers) {
        for &i in nodes {
            apply_layer(layer, i, &mut velocity, &mut displacement, |a, value| {
                body.get_or_insert_with(|| vec![[0.0; D]; n])[i as usize][a] += value;
            });
        }
    }
    (velocity, displacement, body)
}

/// What `layer` prescribes at node i: its held components, into the list of its condition,
/// or its body force, component by component through `body_force(axis, value)`.
fn apply_layer(
    layer: &BoundarySpec,
    i: u32,
    velocity: &mut Vec<Held>,
    displacement: &mut Vec<Held>,
    mut body_force: impl FnMut(usize, f64),
) {
    let held = layer.axes.iter().map(|&a| (i, a as u8, layer.value[a]));
    match layer.condition {
        Condition::Velocity => velocity.extend(held),
        Condition::Displacement => displacement.extend(held),
        Condition::Reference | Condition::Value => {}
        Condition::BodyForce => {
            for &a in &layer.axes {
                body_force(a, layer.value[a]);
            }
        }
    }
}
