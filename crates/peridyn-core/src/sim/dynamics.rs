//! Elastodynamics with bond failure: velocity-Verlet (thesis (3.5)–(3.6)) over the standard
//! bond sums (3.1) with the PMB law (2.33)–(2.34), optionally the hybrid configuration
//! (thesis §3.3) switching nodes from WLS to the standard scheme between steps. Runs `step()` as
//! named, timed stages and emits plain-data `Frame`s; it knows nothing of viewers or user
//! interfaces.

use rayon::prelude::*;

use super::unbounded::{self, BondLayer};
use crate::adapt::hybrid::{self, Hybrid};
use crate::adapt::masks::{GridClass, SchemeClass};
use crate::adapt::multiadaptive::MultiAdaptive;
use crate::discretization::{Discretization, Families, Field, Nodes, Quadrature};
use crate::frame::{ClassField, Frame, NodeField};
use crate::integrate::lattice_symbol::{LatticeSymbol, on_lattice};
use crate::integrate::stability::POWER_ITERATIONS;
use crate::integrate::{self, stability, verlet};
use crate::metrics;
use crate::model::pmb::PmbLaw;
use crate::scene::{CoarseScheme, Condition, Scene, SceneError};
use crate::scheme::standard::{Linearized, NodeTerms, Standard};
use crate::scheme::wls_rows::WlsRows;
use crate::solver::{
    Clock, Integrator, Lap, Param, RunState, SimError, SimInfo, Size, StableStep, State, Stepper,
};

/// Velocity-Verlet's stages, in the order `step()` runs them.
const STAGES: &[&str] = &[
    "kick_drift",
    "switching",
    "forces",
    "kick",
    "constraints",
    "absorbing",
];
const KICK_DRIFT: usize = 0;
const SWITCHING: usize = 1;
const FORCES: usize = 2;
const KICK: usize = 3;
const CONSTRAINTS: usize = 4;
const ABSORBING: usize = 5;

/// Krylov vectors (operator applications) for the (non-symmetric) hybrid operator's spectral
/// radius by Arnoldi (200 power iterations before).
const HYBRID_KRYLOV_DIMENSION: usize = 40;

/// A prescribed node component: node, axis, value.
type Held = (u32, u8, f64);

/// The per-node columns of a dynamic simulation.
#[derive(Debug, Clone, Copy)]
struct Columns<const D: usize> {
    /// Current positions y = x + u.
    position: Field<[f64; D]>,
    velocity: Field<[f64; D]>,
    acceleration: Field<[f64; D]>,
    /// What the force loop produces per node (force, energy density, broken weight).
    terms: Field<NodeTerms<D>>,
    /// Σ β V'_j over each node's family: the damage denominator (see `damage_weights`).
    family_weight: Field<f64>,
    /// Only where a `body_force` layer exists.
    body_force: Option<Field<[f64; D]>>,
}

pub struct DynamicSimulation<const D: usize> {
    pub scene: Scene,
    pub discretization: Discretization<D>,
    columns: Columns<D>,
    pub intact: Vec<u8>,
    held_velocity: Vec<Held>,
    held_displacement: Vec<Held>,
    pub law: PmbLaw,
    density: f64,
    run: RunState,
    broken: u64,
    velocity_scale: f64,
    /// Hybrid schemes: the Ω_s/Ω_w mask, the WLS blocks and the switching state.
    pub hybrid: Option<Hybrid<D>>,
    /// Bonds found broken with an Ω_w end (the hybrid invariant; 0 when it holds).
    pub hybrid_violations: u64,
    /// Multi-adaptive scenes (thesis §3.5): the two levels' roles and the switch.
    pub multigrid: Option<MultiAdaptive<D>>,
    /// Coarse bonds broken (the multi-adaptive invariant: damage stays on the fine level).
    pub coarse_broken: u64,
    /// "Adaptive, hybrid" (thesis §3.5): WLS rows of the initially active coarse nodes (the
    /// coarse active set only shrinks); `None` runs the standard scheme on the coarse level.
    pub coarse_wls: Option<WlsRows<D>>,
    /// Unbounded-domain scenes: the absorbing layer of the linear far field (thesis §4.3).
    pub absorbing: Option<BondLayer<D>>,
    /// `[[metrics.probe]]`: (name, nearest node).
    probes: Vec<(String, usize)>,
    /// Whether the node terms' strain-energy densities belong to the last force pass. The
    /// pass sums them only when a frame is due after its step (`RunState::frame_due_next`);
    /// a frame or checkpoint taken at another step evaluates them afresh.
    energy_current: bool,
}

/// The standard scheme over one discretization's reference configuration.
fn standard<'a, const D: usize>(
    discretization: &'a Discretization<D>,
    law: &'a PmbLaw,
) -> Standard<'a, D> {
    Standard {
        reference: discretization.nodes.base.reference(),
        volumes: discretization.nodes.base.volumes(),
        uniform_volume: discretization.uniform_volume,
        families: &discretization.families,
        law,
        quadrature: &discretization.quadrature,
    }
}

/// The standard scheme over one level of a multi-grid discretization: its quadrature (β of its
/// spacing) and its cell volume (a level's families hold only its own nodes).
fn level_scheme<'a, const D: usize>(
    discretization: &'a Discretization<D>,
    law: &'a PmbLaw,
    quadrature: &'a Quadrature,
) -> Standard<'a, D> {
    Standard {
        uniform_volume: Some(quadrature.spacing.powi(D as i32)),
        quadrature,
        ..standard(discretization, law)
    }
}

/// Per node, the damage denominator and pre-cracked numerator of its own level.
fn level_damage_weights<const D: usize>(
    discretization: &Discretization<D>,
    law: &PmbLaw,
    grid: &MultiAdaptive<D>,
    intact: &[u8],
) -> (Vec<f64>, Vec<f64>) {
    let coarse = level_scheme(discretization, law, &grid.coarse).damage_weights(intact);
    let fine = level_scheme(discretization, law, &grid.fine).damage_weights(intact);
    let pick = |c: &[f64], f: &[f64]| -> Vec<f64> {
        (0..c.len())
            .map(|i| if i < grid.coarse_count { c[i] } else { f[i] })
            .collect()
    };
    (pick(&coarse.0, &fine.0), pick(&coarse.1, &fine.1))
}

/// The stable step of a multi-adaptive scene: (3.8) over every node of the standard levels
/// (any may become active), and the power-iterated sharp limit of the operator on the initially
/// active standard rows of both levels (each with its own quadrature). With a WLS coarse level
/// its rows' spectral radius bounds Δt too ((3.8) does not cover them; the levels' coupling
/// through fictitious nodes is left out of both estimates).
fn level_stable_step<const D: usize>(
    discretization: &Discretization<D>,
    law: &PmbLaw,
    grid: &MultiAdaptive<D>,
    intact: &[u8],
    density: f64,
    coarse_wls: Option<&WlsRows<D>>,
) -> StableStep {
    let (coarse, fine) = (
        level_scheme(discretization, law, &grid.coarse),
        level_scheme(discretization, law, &grid.fine),
    );
    let split = discretization.families.offsets[grid.coarse_count];
    let mut guaranteed =
        integrate::stable_step(density, &fine.stiffness_sums()[grid.coarse_count..]);
    if coarse_wls.is_none() {
        guaranteed = guaranteed.min(integrate::stable_step(
            density,
            &coarse.stiffness_sums()[..grid.coarse_count],
        ));
    }
    let mut coefficients = coarse.linearized_coefficients(density);
    coefficients[split..].copy_from_slice(&fine.linearized_coefficients(density)[split..]);
    let coefficients = Linearized::PerBond(coefficients);
    let masses: Vec<f64> = grid
        .active_volumes(discretization.nodes.volumes())
        .iter()
        .map(|v| v * density)
        .collect();
    let n = discretization.len();
    let rows = &grid.rows;
    let wls = coarse_wls.is_some();
    let lambda_max = stability::max_eigenvalue::<D>(n, &masses, POWER_ITERATIONS, |u, out| {
        out.fill([0.0; D]);
        coarse.apply_linearized_masked(&coefficients, intact, u, out, |i| {
            wls || rows.coarse[i] != 0
        });
        fine.apply_linearized_masked(&coefficients, intact, u, out, |i| rows.fine[i] != 0);
    });
    let mut sharp = stability::verlet_step(lambda_max).max(guaranteed);
    if let Some(w) = coarse_wls {
        let radius =
            stability::arnoldi_spectral_radius(n * D, HYBRID_KRYLOV_DIMENSION, |v, out| {
                let u = v.as_chunks::<D>().0;
                let out = out.as_chunks_mut::<D>().0;
                out.fill([0.0; D]);
                w.apply_linearized(u, density, out, |i| rows.coarse[i] == 0);
            });
        sharp = sharp.min(stability::verlet_step(radius));
    }
    StableStep {
        sharp,
        guaranteed,
        integrator: Integrator::Verlet,
    }
}

/// The lattice symbol's bound is within this share above its supremum (Δt 0.05 % below).
const SYMBOL_TOLERANCE: f64 = 1e-3;
/// Boxes the symbol's branch and bound may evaluate before Lanczos is used instead (a 3D
/// family of 122 offsets needs about 90 000).
const SYMBOL_EVALUATIONS: usize = 2_000_000;

/// The symbol of the scheme's linearized operator on the infinite lattice, where it bounds the
/// operator's λ_max (`integrate::lattice_symbol`): every node of one volume, on the lattice of
/// the quadrature's spacing. Its offsets reach the longest bond.
fn lattice_symbol<const D: usize>(
    scheme: &Standard<'_, D>,
    density: f64,
) -> Option<LatticeSymbol<D>> {
    let volume = scheme.uniform_volume?;
    let spacing = scheme.quadrature.spacing;
    if !on_lattice(scheme.reference, spacing) {
        return None;
    }
    LatticeSymbol::of_bonds(spacing, scheme.families.longest(), |l| {
        scheme.linearized_coefficient(density, l, volume)
    })
}

/// The stable step of velocity-Verlet on the linearized operator (with the hybrid's WLS rows
/// where there is one): the sharp limit (the lattice symbol's bound on a lattice, else Lanczos's
/// estimate with a margin), never below the guaranteed (3.8).
fn stable_step<const D: usize>(
    scheme: &Standard<'_, D>,
    intact: &[u8],
    density: f64,
    hybrid: Option<&Hybrid<D>>,
) -> StableStep {
    let n = scheme.reference.len();
    let gershgorin_dt = integrate::stable_step(density, &scheme.stiffness_sums());
    let masses: Vec<f64> = scheme.volumes.iter().map(|v| v * density).collect();
    let coefficients = scheme.linearized(density);
    // On a lattice the infinite lattice's symbol bounds λ_max from above (rigorous: no
    // margin, and milliseconds instead of 26–55 applications of the operator). Elsewhere
    // Lanczos approaches λ_max from below: keep a margin. Never below the guaranteed (3.8)
    // bound.
    let lambda_bound = lattice_symbol(scheme, density)
        .and_then(|symbol| symbol.max_eigenvalue_bound(SYMBOL_TOLERANCE, SYMBOL_EVALUATIONS))
        .unwrap_or_else(|| {
            let lambda = stability::max_eigenvalue::<D>(n, &masses, POWER_ITERATIONS, |u, out| {
                scheme.apply_linearized(&coefficients, intact, u, out)
            });
            lambda * stability::SPECTRAL_MARGIN
        });
    let mut sharp = stability::verlet_limit(lambda_bound).max(gershgorin_dt);
    if let Some(h) = hybrid {
        // The WLS blocks are not symmetric and their stencil is tighter than the family's: the
        // hybrid operator's spectral radius (Arnoldi) bounds Δt too, and (3.8) does not
        // cover it.
        let radius =
            stability::arnoldi_spectral_radius(n * D, HYBRID_KRYLOV_DIMENSION, |v, out| {
                let u = v.as_chunks::<D>().0;
                let out = out.as_chunks_mut::<D>().0;
                let mask = h.mask();
                scheme.apply_linearized_masked(&coefficients, intact, u, out, |i| {
                    mask[i] == SchemeClass::Wls
                });
                h.apply_linearized(u, density, out);
            });
        sharp = sharp.min(stability::verlet_step(radius));
    }
    StableStep {
        sharp,
        guaranteed: gershgorin_dt,
        integrator: Integrator::Verlet,
    }
}

impl<const D: usize> DynamicSimulation<D> {
    pub fn new(scene: &Scene) -> Result<Self, SceneError> {
        let (mut discretization, multigrid) = match &scene.multigrid {
            None => (Discretization::<D>::of_scene(scene)?, None),
            Some(spec) => {
                let (grid, levels) = MultiAdaptive::<D>::build(scene, spec)?;
                let d = Discretization::of_nodes(
                    scene,
                    levels.positions,
                    levels.volumes,
                    levels.families,
                )?;
                (d, Some(grid))
            }
        };
        let intact = discretization.intact_bonds(scene)?;
        let Some(m) = scene.material.as_ref() else {
            return Err(scene.error(
                "material",
                "dynamics needs an elastic material (density, youngs_modulus or micromodulus)",
            ));
        };
        let law = PmbLaw::new(&m.constants, scene.horizon, D);
        let density = m.density;
        let hybrid = match scene.hybrid {
            None => None,
            Some(spec) => {
                let reference = discretization.nodes.reference();
                let mask = hybrid::initial_mask(
                    reference,
                    &scene.solid,
                    &scene.precracks,
                    spec.band,
                    scene.spacing,
                );
                let h = Hybrid::new(
                    spec,
                    mask,
                    reference,
                    &discretization.families,
                    &law,
                    scene.scheme.collocation,
                )
                .map_err(|e| {
                    let field = format!("hybrid.{}", scene.scheme.collocation.field());
                    scene.error(&field, e.to_string())
                })?;
                Some(h)
            }
        };
        let coarse_wls = match (&multigrid, scene.multigrid.as_ref().map(|m| m.coarse)) {
            (Some(g), Some(CoarseScheme::Wls(collocation))) => {
                let rows: Vec<u32> = (0..g.coarse_count as u32)
                    .filter(|&i| g.class[i as usize].is_active())
                    .collect();
                let w = WlsRows::elasticity(
                    &rows,
                    discretization.nodes.reference(),
                    &discretization.families,
                    &law,
                    collocation,
                )
                .map_err(|e| {
                    let field = format!("multigrid.{}", collocation.field());
                    scene.error(&field, e.to_string())
                })?;
                Some(w)
            }
            _ => None,
        };
        let scheme = standard(&discretization, &law);
        let (stable, (family_weight, precracked)) = match &multigrid {
            Some(g) => (
                level_stable_step(
                    &discretization,
                    &law,
                    g,
                    &intact,
                    density,
                    coarse_wls.as_ref(),
                ),
                level_damage_weights(&discretization, &law, g, &intact),
            ),
            None => (
                stable_step(&scheme, &intact, density, hybrid.as_ref()),
                scheme.damage_weights(&intact),
            ),
        };
        // The "absorbing" stage (last) is listed only where a layer exists.
        let stages = match scene.absorbing {
            Some(_) => STAGES,
            None => &STAGES[..ABSORBING],
        };
        let run = RunState::new(scene, stable, stages)?;

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
        let absorbing = BondLayer::new(scene, discretization.nodes.reference(), &law, density)?;
        let probes = unbounded::probes(scene, discretization.nodes.reference());
        let mut sim = DynamicSimulation {
            scene: scene.clone(),
            discretization,
            columns,
            intact,
            held_velocity,
            held_displacement,
            law,
            density,
            run,
            broken: 0,
            velocity_scale: 1.0,
            hybrid,
            hybrid_violations: 0,
            multigrid,
            coarse_broken: 0,
            coarse_wls,
            absorbing,
            probes,
            energy_current: false,
        };
        sim.apply_initial_velocity();
        sim.apply_initial_displacement();
        sim.apply_constraints();
        if let Some(b) = sim.absorbing.as_mut() {
            let nodes = &sim.discretization.nodes;
            let positions = nodes.fields.get(sim.columns.position);
            let families = &sim.discretization.families;
            b.start(sim.run.clock.dt(), nodes.reference(), families, positions);
        }
        sim.velocity_scale = sim.initial_velocity_scale();
        sim.update_accelerations();
        Ok(sim)
    }

    fn apply_initial_velocity(&mut self) {
        let nodes = &mut self.discretization.nodes;
        let velocities = nodes.fields.get_mut(self.columns.velocity);
        super::add_initial_velocity(&self.scene, nodes.base.reference(), velocities);
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

    fn nodes(&self) -> &Nodes<D> {
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

    /// Current positions, to set by hand (tests, restarts); call `refresh_forces` after.
    pub fn positions_mut(&mut self) -> &mut [[f64; D]] {
        self.discretization
            .nodes
            .fields
            .get_mut(self.columns.position)
    }

    pub fn velocities(&self) -> &[[f64; D]] {
        self.nodes().fields.get(self.columns.velocity)
    }

    pub fn velocities_mut(&mut self) -> &mut [[f64; D]] {
        self.discretization
            .nodes
            .fields
            .get_mut(self.columns.velocity)
    }

    pub fn accelerations(&self) -> &[[f64; D]] {
        self.nodes().fields.get(self.columns.acceleration)
    }

    fn terms(&self) -> &[NodeTerms<D>] {
        self.nodes().fields.get(self.columns.terms)
    }

    pub fn density(&self) -> f64 {
        self.density
    }

    fn hold_velocities(&mut self) {
        let velocities = self
            .discretization
            .nodes
            .fields
            .get_mut(self.columns.velocity);
        for &(i, a, value) in &self.held_velocity {
            velocities[i as usize][a as usize] = value;
        }
    }

    /// Held velocities and displacements (velocity layers also move the node).
    fn apply_constraints(&mut self) {
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

    fn initial_velocity_scale(&self) -> f64 {
        let max = self
            .velocities()
            .iter()
            .map(|v| v.iter().map(|x| x * x).sum::<f64>().sqrt())
            .fold(0.0, f64::max);
        if max > 0.0 { 2.0 * max } else { 1.0 }
    }

    /// The standard scheme over this simulation's discretization.
    pub fn scheme(&self) -> Standard<'_, D> {
        standard(&self.discretization, &self.law)
    }

    fn update_accelerations(&mut self) {
        self.compute_forces(true);
        self.accelerate(None);
    }

    /// Force densities at the current positions: the PMB bond loop (Ω_s rows only in a
    /// hybrid) and the WLS product on Ω_w; the bond loop's strain-energy densities too where
    /// `energy` is set.
    fn compute_forces(&mut self, energy: bool) {
        self.energy_current = energy;
        let Discretization {
            nodes,
            families,
            quadrature,
            uniform_volume,
            ..
        } = &mut self.discretization;
        let scheme = Standard {
            reference: nodes.base.reference(),
            volumes: nodes.base.volumes(),
            uniform_volume: *uniform_volume,
            families,
            law: &self.law,
            quadrature,
        };
        let (positions, terms) = nodes
            .fields
            .pair_mut(self.columns.position, self.columns.terms);
        if let Some(g) = &self.multigrid {
            // Each level's active rows with its own quadrature; every neighbour of an active
            // node is active or fictitious (interpolated before this pass).
            if let Some(w) = self.coarse_wls.as_mut() {
                // Every row is a coarse node's; the inactive ones are left alone.
                w.forces(nodes.base.reference(), positions, |i| {
                    g.class[i].is_active()
                });
            }
            let wls = self.coarse_wls.is_some();
            for (quadrature, rows, coarse) in [
                (&g.coarse, &g.rows.coarse, true),
                (&g.fine, &g.rows.fine, false),
            ] {
                if coarse && wls {
                    continue;
                }
                let scheme = Standard {
                    reference: nodes.base.reference(),
                    volumes: nodes.base.volumes(),
                    uniform_volume: Some(quadrature.spacing.powi(D as i32)),
                    families,
                    law: &self.law,
                    quadrature,
                };
                let broken = scheme.forces_masked(
                    positions,
                    &mut self.intact,
                    terms,
                    Some(rows.as_slice()),
                    energy,
                );
                self.broken += broken;
                if coarse {
                    self.coarse_broken += broken;
                }
            }
            return;
        }
        let mask = self.hybrid.as_ref().map(|h| h.mask());
        self.broken += scheme.forces_masked(positions, &mut self.intact, terms, mask, energy);
        if let Some(h) = self.hybrid.as_mut() {
            h.wls_forces(nodes.base.reference(), positions);
        }
    }

    /// ü = (f + b)/ρ per node, Ω_w nodes taking their WLS force (their `terms` are left
    /// alone: nothing reads an Ω_w node's bond-loop terms). With `kick = Some(Δt)` the second
    /// half kick (3.5) runs in the same pass; returns the largest squared speed then
    /// (NaN-propagating), 0 otherwise.
    fn accelerate(&mut self, kick: Option<f64>) -> f64 {
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
        let class = self.multigrid.as_ref().map(|g| g.class.as_slice());
        let (hybrid, coarse_wls) = (self.hybrid.as_ref(), self.coarse_wls.as_ref());
        let wls_force = |i: usize| wls_force_of(hybrid, coarse_wls.zip(self.multigrid.as_ref()), i);
        accelerations
            .par_iter_mut()
            .zip(velocities)
            .enumerate()
            .with_min_len(4096)
            .map(|(i, (a, v))| {
                // Nodes not active on their level are not integrated (interpolated or idle).
                if class.is_some_and(|c| !c[i].is_active()) {
                    *a = [0.0; D];
                    return 0.0;
                }
                let force = wls_force(i).unwrap_or(terms[i].force);
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

    /// Damage recomputed from the bond states in one pass over all bonds (a check of
    /// `damage`).
    pub fn damage_from_bonds(&self) -> Vec<f64> {
        self.scheme().damage(&self.intact)
    }

    pub fn strain_energy(&self) -> f64 {
        self.scheme().strain_energy(self.positions(), &self.intact)
    }

    /// Bytes held by the solver state: bond arrays and the per-node store.
    pub fn memory_bytes(&self) -> usize {
        use std::mem::size_of_val;
        let families = self.families();
        families.memory_bytes() + size_of_val(self.intact.as_slice()) + self.nodes().memory_bytes()
    }

    /// Strain-energy density W_i of one node (J/m³), over its own level's family on a
    /// multi-grid scene.
    pub fn energy_density(&self, i: usize) -> f64 {
        let scheme = match &self.multigrid {
            Some(g) if i < g.coarse_count => {
                level_scheme(&self.discretization, &self.law, &g.coarse)
            }
            Some(g) => level_scheme(&self.discretization, &self.law, &g.fine),
            None => self.scheme(),
        };
        scheme.energy_density(i, self.positions(), &self.intact)
    }

    /// The bond loop's terms, energy densities included, of the rows whose W_i the last force
    /// pass did not leave (Ω_w nodes, or every node when that pass skipped the energy sum),
    /// from the force loop run again on those rows alone over a copy of the bond states: the
    /// vector kernels instead of a scalar loop per node, and nothing of the solver's state
    /// changes (an Ω_w bond is below χ s0 < s0, and the last pass broke every other bond at
    /// s0 at these positions, so the copy breaks none and each W_i is the per-node sum's to
    /// rounding). `None` on a multi-grid scene (its levels' families differ: per node there)
    /// and where every W_i is current.
    fn stale_energy_terms(&self) -> Option<Vec<NodeTerms<D>>> {
        if self.multigrid.is_some() || (self.hybrid.is_none() && self.energy_current) {
            return None;
        }
        let n = self.positions().len();
        let current: Vec<u8> = (0..n)
            .into_par_iter()
            .map(|i| u8::from(self.energy_current && !self.runs_wls(i)))
            .collect();
        let mut intact = self.intact.clone();
        let mut terms = vec![NodeTerms::default(); n];
        self.scheme().forces_masked(
            self.positions(),
            &mut intact,
            &mut terms,
            Some(&current),
            true,
        );
        Some(terms)
    }

    /// Over the nodes that carry mass (the active ones of a multi-grid scene).
    pub fn kinetic_energy_and_momentum(&self) -> (f64, [f64; D]) {
        metrics::kinetic_energy_and_momentum(self.velocities(), &self.mass_volumes(), self.density)
    }

    /// Force density on each node at the current positions (N/m³), without body forces.
    pub fn force_density(&self) -> Vec<[f64; D]> {
        self.terms()
            .iter()
            .enumerate()
            .map(|(i, t)| self.wls_force_of(i).unwrap_or(t.force))
            .collect()
    }

    /// Node i's force from a WLS row (the hybrid's Ω_w, or an active node of a WLS coarse
    /// level) from the last force pass; `None` where the bond loop's terms hold it.
    fn wls_force_of(&self, i: usize) -> Option<[f64; D]> {
        let coarse = self.coarse_wls.as_ref().zip(self.multigrid.as_ref());
        wls_force_of(self.hybrid.as_ref(), coarse, i)
    }

    /// Whether node i's force comes from a WLS row (its bond-loop terms are not kept).
    fn runs_wls(&self, i: usize) -> bool {
        match (&self.hybrid, &self.multigrid) {
            (Some(h), _) => h.mask()[i] == SchemeClass::Wls,
            (None, Some(g)) => self.coarse_wls.is_some() && i < g.coarse_count,
            (None, None) => false,
        }
    }

    /// Recomputes forces after positions were set by hand (tests, restarts); on a multi-grid
    /// scene the interpolated nodes first follow the other level.
    pub fn refresh_forces(&mut self) {
        if let Some(g) = self.multigrid.as_mut() {
            let c = self.columns;
            let nodes = &mut self.discretization.nodes;
            let reference = nodes.base.reference();
            let (positions, velocities) = nodes.fields.pair_mut(c.position, c.velocity);
            g.transfer(reference, positions, velocities);
        }
        self.update_accelerations();
    }

    /// The hybrid invariant: bonds broken with an Ω_w end. Damage that reached Ω_w (possible
    /// only with a check policy other than every bond every step) switches those nodes at once.
    pub fn enforce_hybrid_invariant(&mut self) -> usize {
        let (step, time) = (self.run.clock.step(), self.run.clock.time());
        match self.hybrid.as_mut() {
            Some(h) => {
                let found = h.enforce(step, time, &self.intact, &self.discretization.families);
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
        let events: Vec<String> = h.take_events().iter().map(|e| e.to_string()).collect();
        scalars.push(("hybrid/omega_s_fraction".into(), h.standard_fraction()));
        scalars.push(("hybrid/chi".into(), h.spec.chi));
        scalars.push(("hybrid/violations".into(), violations));
        scalars.push(("hybrid/checked_bonds".into(), h.checked_bonds as f64));
        scalars.push(("hybrid/full_checks".into(), h.full_checks as f64));
        scalars.push(("hybrid/reused_slacks".into(), h.reused_slacks as f64));
        scalars.push(("hybrid/filtered_checks".into(), h.filtered_checks as f64));
        (vec![SchemeClass::field(h.mask(), false)], events)
    }

    /// The multi-adaptive step between drift and forces (seed-thesis-ch2-3 §7 steps 3 and 6):
    /// the interpolated nodes take u^{n+1} and u̇^{n+½} from the other level, then every bond
    /// of an active coarse node is checked and the critical ones refine their neighbourhoods,
    /// before the force pass evaluates damage on u^{n+1}.
    fn switch_levels(&mut self) {
        let Some(g) = self.multigrid.as_mut() else {
            return;
        };
        let (step, time) = (self.run.clock.step() + 1, self.run.clock.next_time());
        let c = self.columns;
        let Discretization {
            nodes, families, ..
        } = &mut self.discretization;
        let reference = nodes.base.reference();
        let (positions, velocities) = nodes.fields.pair_mut(c.position, c.velocity);
        g.transfer(reference, positions, velocities);
        let critical = g.critical_bonds(reference, positions, families, self.law.critical_stretch);
        if !critical.is_empty() {
            g.refine(
                step, time, &critical, families, reference, positions, velocities,
            );
            g.transfer(reference, positions, velocities);
        }
    }

    /// Each node's volume where it carries mass: every node, or the active ones of a
    /// multi-grid scene.
    fn mass_volumes(&self) -> std::borrow::Cow<'_, [f64]> {
        match &self.multigrid {
            Some(g) => std::borrow::Cow::Owned(g.active_volumes(self.volumes())),
            None => std::borrow::Cow::Borrowed(self.volumes()),
        }
    }

    /// The spacing of the finest level (the crack-path metric links nearest neighbours).
    fn finest_spacing(&self) -> f64 {
        self.multigrid
            .as_ref()
            .map_or(self.scene.spacing, |g| g.fine.spacing)
    }

    /// Metrics of the scene's energy circles and damage counts, from per-node kinetic plus
    /// strain energy and damage (zero on nodes that carry no mass).
    fn region_metrics(
        &self,
        node_energy: &[f64],
        damage: &[f64],
        scalars: &mut Vec<(String, f64)>,
    ) {
        let reference = self.reference();
        let cell_of = |i: usize| match &self.multigrid {
            Some(g) if i < g.coarse_count => g.coarse.spacing,
            Some(g) => g.fine.spacing,
            None => self.scene.spacing,
        };
        for c in &self.scene.energy_circles {
            // ∫ over the circle of the energy density: each node's energy weighted by the
            // fraction of its cell inside (node centres alone sample the circle's area to
            // ≈ 1 % on a 15-cell radius, differently on each level).
            let energy: f64 = (0..reference.len())
                .into_par_iter()
                .map(|i| {
                    let e = node_energy[i];
                    if e == 0.0 {
                        return 0.0;
                    }
                    e * metrics::ball_fraction(&reference[i], cell_of(i), &c.center, c.radius)
                })
                .sum();
            scalars.push((format!("energy/circle/{}", c.name), energy));
        }
        metrics::damage_counts(&self.scene, reference, damage, scalars);
    }

    /// The grid classes, counts, switch events and invariant of a multi-adaptive frame.
    fn multigrid_frame(
        &mut self,
        scalars: &mut Vec<(String, f64)>,
        events: &mut Vec<String>,
    ) -> Option<ClassField> {
        let g = self.multigrid.as_mut()?;
        let (coarse, fine, fictitious) = g.counts();
        scalars.push(("grid/coarse_active".into(), coarse as f64));
        scalars.push(("grid/fine_active".into(), fine as f64));
        scalars.push(("grid/fictitious".into(), fictitious as f64));
        scalars.push(("grid/refined_by_switch".into(), g.refined_by_switch as f64));
        scalars.push(("grid/chi".into(), g.chi));
        scalars.push(("grid/coarse_broken".into(), self.coarse_broken as f64));
        events.extend(g.take_events().iter().map(|e| e.to_string()));
        Some(GridClass::field(&g.class))
    }

    fn crack_angles_for(&self, damage: &[f64]) -> Vec<(String, Option<f64>)> {
        self.scene
            .crack_angles
            .iter()
            .map(|spec| {
                let angle = metrics::crack_angle(
                    spec,
                    self.reference(),
                    damage,
                    self.families(),
                    self.finest_spacing(),
                    self.scene.horizon,
                );
                (spec.name.clone(), angle)
            })
            .collect()
    }
}

/// Node i's force from a WLS row, if it has one: the hybrid's Ω_w, or an active node of a WLS
/// coarse level (the force of the last pass).
#[inline]
fn wls_force_of<const D: usize>(
    hybrid: Option<&Hybrid<D>>,
    coarse: Option<(&WlsRows<D>, &MultiAdaptive<D>)>,
    i: usize,
) -> Option<[f64; D]> {
    if let Some(h) = hybrid {
        return h.wls_force_of(i);
    }
    let (w, g) = coarse?;
    (i < g.coarse_count && g.class[i].is_active()).then(|| w.force_of(i))
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
            let held = layer.axes.iter().map(|&a| (i, a as u8, layer.value[a]));
            match layer.condition {
                Condition::Velocity => velocity.extend(held),
                Condition::Displacement => displacement.extend(held),
                Condition::Reference | Condition::Value => {}
                Condition::BodyForce => {
                    let body = body.get_or_insert_with(|| vec![[0.0; D]; n]);
                    for &a in &layer.axes {
                        body[i as usize][a] += layer.value[a];
                    }
                }
            }
        }
    }
    (velocity, displacement, body)
}

impl<const D: usize> Stepper for DynamicSimulation<D> {
    fn step(&mut self) -> Result<(), SimError> {
        let dt = self.run.clock.dt();
        let mut lap = Lap::start();
        if let Some(b) = self.absorbing.as_mut() {
            let d = &self.discretization;
            let fields = &d.nodes.fields;
            b.prepare(
                dt,
                d.nodes.reference(),
                &d.families,
                fields.get(self.columns.position),
                fields.get(self.columns.velocity),
            );
            lap.charge(&mut self.run.stages, ABSORBING);
        }
        {
            let c = self.columns;
            let fields = &mut self.discretization.nodes.fields;
            let (velocities, accelerations) = fields.pair_mut(c.velocity, c.acceleration);
            verlet::half_kick(velocities, accelerations, dt);
        }
        self.hold_velocities();
        {
            let c = self.columns;
            let fields = &mut self.discretization.nodes.fields;
            let (positions, velocities) = fields.pair_mut(c.position, c.velocity);
            verlet::drift(positions, velocities, dt);
        }
        lap.charge(&mut self.run.stages, KICK_DRIFT);
        if let Some(b) = &self.absorbing {
            let nodes = &mut self.discretization.nodes;
            b.overwrite_positions(
                nodes.base.reference(),
                nodes.fields.get_mut(self.columns.position),
            );
            lap.charge(&mut self.run.stages, ABSORBING);
        }
        // Switch before the force pass evaluates damage on u^{n+1}
        // (seed-thesis-ch2-3 §5 steps 4–5).
        self.switch_levels();
        if let Some(h) = self.hybrid.as_mut() {
            let d = &self.discretization;
            h.check(
                self.run.clock.step() + 1,
                self.run.clock.next_time(),
                d.nodes.reference(),
                d.nodes.fields.get(self.columns.position),
                &d.families,
                self.law.critical_stretch,
            );
        }
        lap.charge(&mut self.run.stages, SWITCHING);
        self.compute_forces(self.run.frame_due_next());
        lap.charge(&mut self.run.stages, FORCES);
        let max_speed2 = self.accelerate(Some(dt));
        {
            // The damped bands: the hybrid's interface and the absorbing layer's inside.
            let velocities = self
                .discretization
                .nodes
                .fields
                .get_mut(self.columns.velocity);
            let stable = self.run.stable.sharp;
            if let Some(h) = self.hybrid.as_mut() {
                h.damp_interface(velocities, dt, stable);
            }
            if let Some(b) = self.absorbing.as_mut() {
                b.damp(velocities, dt, stable);
            }
        }
        lap.charge(&mut self.run.stages, KICK);
        self.apply_constraints();
        lap.charge(&mut self.run.stages, CONSTRAINTS);
        if let Some(b) = &self.absorbing {
            let fields = &mut self.discretization.nodes.fields;
            b.overwrite_velocities(fields.get_mut(self.columns.velocity));
            lap.charge(&mut self.run.stages, ABSORBING);
        }
        self.run.clock.advance();
        let max_speed = max_speed2.sqrt();
        if max_speed.is_nan() || max_speed * dt > 0.5 * self.scene.spacing {
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

    fn frame(&mut self) -> Frame {
        let mut damage = self.damage();
        let mass_volumes = self.mass_volumes().into_owned();
        if self.multigrid.is_some() {
            // Only active nodes carry the solution (fictitious ones mirror the other level).
            for (d, &v) in damage.iter_mut().zip(&mass_volumes) {
                if v == 0.0 {
                    *d = 0.0;
                }
            }
        }
        let speed: Vec<f64> = self
            .velocities()
            .iter()
            .map(|v| v.iter().map(|x| x * x).sum::<f64>().sqrt())
            .collect();
        let (kinetic, momentum) =
            metrics::kinetic_energy_and_momentum(self.velocities(), &mass_volumes, self.density);
        // W_i from the last force evaluation, at the current positions. An Ω_w node's WLS
        // force has no local energy density (−½ u_i·f_i sums to the energy only over a whole
        // WLS body): its PMB bond energy over its family is evaluated here, at frame time.
        let terms = self.terms();
        let recomputed = self.stale_energy_terms();
        let strain_energy: Vec<f64> = (0..mass_volumes.len())
            .into_par_iter()
            .map(|i| {
                if mass_volumes[i] == 0.0 {
                    return 0.0;
                }
                let w = match &recomputed {
                    _ if !self.runs_wls(i) && self.energy_current => terms[i].energy_density,
                    Some(fresh) => fresh[i].energy_density,
                    None => self.energy_density(i),
                };
                w * mass_volumes[i]
            })
            .collect();
        let strain: f64 = strain_energy.iter().sum();
        let mut scalars = vec![
            ("energy/kinetic".to_string(), kinetic),
            ("energy/strain".to_string(), strain),
            ("energy/total".to_string(), kinetic + strain),
            ("bonds/broken".to_string(), self.broken as f64),
        ];
        scalars.extend(self.run.timing_scalars());
        for (k, p) in momentum.iter().enumerate() {
            scalars.push((format!("momentum/{}", ["x", "y", "z"][k]), *p));
        }
        let regions =
            !(self.scene.energy_circles.is_empty() && self.scene.damage_counts.is_empty());
        let layer_or_probes = self.absorbing.is_some() || !self.probes.is_empty();
        // Kinetic plus strain energy per node, for the region metrics, the near field and probes.
        let node_energy: Vec<f64> = if regions || layer_or_probes {
            strain_energy
                .iter()
                .zip(&speed)
                .zip(&mass_volumes)
                .map(|((w, s), v)| w + 0.5 * self.density * v * s * s)
                .collect()
        } else {
            Vec::new()
        };
        if regions {
            self.region_metrics(&node_energy, &damage, &mut scalars);
        }
        if layer_or_probes {
            if let Some(b) = &self.absorbing {
                scalars.push(("energy/near_field".to_string(), b.near_field(&node_energy)));
            }
            let density = |i: usize| node_energy[i] / mass_volumes[i].max(f64::MIN_POSITIVE);
            let (reference, positions) = (self.reference(), self.positions());
            unbounded::probe_scalars(&self.probes, reference, positions, density, &mut scalars);
        }
        let (mut classes, mut events) = self.hybrid_frame(&mut scalars);
        if let Some(b) = &self.absorbing {
            classes.push(b.absorber.class_field(b.damped()));
        }
        classes.extend(self.multigrid_frame(&mut scalars, &mut events));
        for (name, angle) in self.crack_angles_for(&damage) {
            if let Some(a) = angle {
                scalars.push((format!("crack_angle_deg/{name}"), a));
            }
        }
        let mut frame = Frame {
            step: self.run.clock.step(),
            time: self.run.clock.time(),
            dim: D,
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
            classes,
            events,
            scalars,
            radii: Vec::new(),
        };
        if let Some(g) = &self.multigrid {
            frame.radii = GridClass::radii(&g.class, g.coarse.spacing, g.fine.spacing);
            // Inactive nodes are not drawn: the point cloud follows the active levels.
            let keep: Vec<bool> = g.class.iter().map(|c| !c.is_inactive()).collect();
            frame.retain_nodes(&keep);
        }
        frame
    }

    fn info(&self) -> SimInfo {
        let (nodes, bonds) = (self.nodes().len(), self.families().bond_count());
        let bytes_per_bond = self.memory_bytes() as f64 / bonds.max(1) as f64;
        self.run
            .info(Size::of_bonds(D, nodes, bonds, bytes_per_bond))
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
        state.put_f64("position", self.positions().as_flattened().to_vec());
        state.put_f64("velocity", self.velocities().as_flattened().to_vec());
        state.put_f64("acceleration", self.accelerations().as_flattened().to_vec());
        let terms: Vec<f64> = self
            .terms()
            .par_iter()
            .enumerate()
            .flat_map_iter(|(i, t)| {
                let energy = if self.energy_current {
                    t.energy_density
                } else {
                    self.energy_density(i)
                };
                t.force.into_iter().chain([energy, t.broken_weight])
            })
            .collect();
        state.put_f64("terms", terms);
        state.put_u8("intact", self.intact.clone());
        state.put_u64("broken", vec![self.broken, self.hybrid_violations]);
        if let Some(h) = &self.hybrid {
            h.save(&mut state);
        }
        if let Some(b) = &self.absorbing {
            b.save(&mut state);
        }
        if let Some(g) = &self.multigrid {
            state.put_u8("multigrid/refined", g.refined_cells());
            state.put_u64("multigrid/coarse_broken", vec![self.coarse_broken]);
        }
        state
    }

    fn restore_state(&mut self, state: &State) -> Result<(), String> {
        let n = self.nodes().len();
        let clock = Clock::restore(state)?;
        let position = state.f64("position", n * D)?;
        let velocity = state.f64("velocity", n * D)?;
        let acceleration = state.f64("acceleration", n * D)?;
        let terms = state.f64("terms", n * (D + 2))?;
        let intact = state.u8("intact", self.intact.len())?;
        let broken = state.u64("broken", 2)?;
        // Validated in full before anything changes.
        if let Some(h) = self.hybrid.as_mut() {
            h.restore(state, &self.discretization.families)?;
        } else if state.has("hybrid/mask") {
            return Err("the checkpoint is of a hybrid scene; this scene has none".into());
        }
        match self.multigrid.as_mut() {
            Some(g) => {
                let refined = state.u8("multigrid/refined", g.coarse_count)?;
                let coarse_broken = state.u64("multigrid/coarse_broken", 1)?[0];
                g.restore_refined(refined, &self.discretization.families)?;
                self.coarse_broken = coarse_broken;
            }
            None if state.has("multigrid/refined") => {
                return Err(
                    "the checkpoint is of a multi-grid scene; this scene has one grid".into(),
                );
            }
            None => {}
        }
        match self.absorbing.as_mut() {
            Some(b) => b.restore(state)?,
            None if state.has("absorbing/previous_displacement") => {
                return Err(
                    "the checkpoint is of a scene with an absorbing layer; this one has none"
                        .into(),
                );
            }
            None => {}
        }
        let c = self.columns;
        let fields = &mut self.discretization.nodes.fields;
        let (y, v, a) = fields.triple_mut(c.position, c.velocity, c.acceleration);
        y.as_flattened_mut().copy_from_slice(position);
        v.as_flattened_mut().copy_from_slice(velocity);
        a.as_flattened_mut().copy_from_slice(acceleration);
        for (t, saved) in fields
            .get_mut(c.terms)
            .iter_mut()
            .zip(terms.chunks_exact(D + 2))
        {
            t.force.copy_from_slice(&saved[..D]);
            (t.energy_density, t.broken_weight) = (saved[D], saved[D + 1]);
        }
        self.intact.copy_from_slice(intact);
        self.energy_current = true;
        (self.broken, self.hybrid_violations) = (broken[0], broken[1]);
        self.run.clock = clock;
        Ok(())
    }

    fn tune(&mut self, param: Param) -> Result<(), String> {
        if let (Param::Chi(chi), Some(g)) = (param, self.multigrid.as_mut()) {
            g.chi = crate::scene::check_chi(chi)?;
            return Ok(());
        }
        match (param, self.hybrid.as_mut()) {
            (Param::Chi(chi), Some(h)) => h.set_chi(chi),
            (param, _) => Err(param.unused_note().into()),
        }
    }

    fn crack_angles(&self) -> Vec<(String, Option<f64>)> {
        self.crack_angles_for(&self.damage())
    }

    fn check_notes(&self) -> Vec<String> {
        self.absorbing.as_ref().map_or(Vec::new(), |b| b.report())
    }

    fn broken_bonds(&self) -> u64 {
        self.broken
    }
}
