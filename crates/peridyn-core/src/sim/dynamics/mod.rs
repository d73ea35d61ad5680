//! Elastodynamics with bond failure: the elastic body (`body`: PMB law (2.33)–(2.34), bond
//! sums (3.1)) stepped by the velocity-Verlet driver (`integrate::verlet`, thesis
//! (3.5)–(3.6)) with its scheme — the standard scheme on every row (`scheme::Uniform`), the
//! hybrid (`hybrid`, thesis §3.3) or the multi-adaptive levels (`levels`, thesis §3.5) — and
//! its plug-ins (the absorbing layer, `layer`). Emits plain-data `Frame`s (`frame`); knows
//! nothing of viewers or user interfaces.

mod body;
mod frame;
mod hybrid;
mod layer;
mod levels;
mod scheme;

pub use body::ElasticBody;
pub use hybrid::HybridScheme;
pub use levels::LevelScheme;
pub use scheme::{ElasticScheme, Uniform};

use std::any::Any;
use std::ops::{Deref, DerefMut};

use crate::absorb::bond_layer::BondLayer;
use crate::adapt::hybrid::{self as switch, Hybrid};
use crate::adapt::multiadaptive::MultiAdaptive;
use crate::discretization::Discretization;
use crate::frame::Frame;
use crate::integrate::verlet;
use crate::metrics::probes;
use crate::model::pmb::PmbLaw;
use crate::scene::{CoarseScheme, Scene, SceneError};
use crate::scheme::wls_rows::WlsRows;
use crate::solver::adaptation::{notes_of, restore_each, save_each, tune_each};
use crate::solver::{Adaptation, Clock, Param, RunState, SimError, SimInfo, Size, State, Stepper};

pub struct DynamicSimulation<const D: usize> {
    pub body: ElasticBody<D>,
    scheme: Box<dyn ElasticScheme<D>>,
    plugins: Vec<Box<dyn Adaptation<ElasticBody<D>>>>,
    /// `[[metrics.probe]]`: (name, nearest node).
    probes: Vec<(String, usize)>,
    run: RunState,
}

/// A simulation reads as its body (positions, velocities, bonds, law) for measurements.
impl<const D: usize> Deref for DynamicSimulation<D> {
    type Target = ElasticBody<D>;

    fn deref(&self) -> &ElasticBody<D> {
        &self.body
    }
}

impl<const D: usize> DerefMut for DynamicSimulation<D> {
    fn deref_mut(&mut self) -> &mut ElasticBody<D> {
        &mut self.body
    }
}

/// The discretization of `scene`, with the multi-adaptive levels where it has them.
fn discretize<const D: usize>(
    scene: &Scene,
) -> Result<(Discretization<D>, Option<MultiAdaptive<D>>), SceneError> {
    match &scene.multigrid {
        None => Ok((Discretization::<D>::of_scene(scene)?, None)),
        Some(spec) => {
            let (grid, levels) = MultiAdaptive::<D>::build(scene, spec)?;
            let d =
                Discretization::of_nodes(scene, levels.positions, levels.volumes, levels.families)?;
            Ok((d, Some(grid)))
        }
    }
}

/// The scheme `scene` asks for on `discretization`: the multi-adaptive levels (with WLS rows
/// on the active coarse nodes in "adaptive, hybrid"), the hybrid, or the standard scheme.
fn scheme_of<const D: usize>(
    scene: &Scene,
    discretization: &Discretization<D>,
    law: &PmbLaw,
    grid: Option<MultiAdaptive<D>>,
) -> Result<Box<dyn ElasticScheme<D>>, SceneError> {
    let reference = discretization.nodes.reference();
    let families = &discretization.families;
    if let Some(grid) = grid {
        let coarse_wls = match scene.multigrid.as_ref().map(|m| m.coarse) {
            Some(CoarseScheme::Wls(collocation)) => {
                let rows: Vec<u32> = (0..grid.coarse_count as u32)
                    .filter(|&i| grid.class[i as usize].is_active())
                    .collect();
                // Over the coarse level alone (its families hold no fine node): the fine
                // level grows during the run.
                let coarse = &reference[..grid.coarse_count];
                let w = WlsRows::elasticity(&rows, coarse, families, law, collocation).map_err(
                    |e| scene.error(&format!("multigrid.{}", collocation.field()), e.to_string()),
                )?;
                Some(w)
            }
            _ => None,
        };
        return Ok(Box::new(LevelScheme {
            grid,
            coarse_wls,
            coarse_broken: 0,
        }));
    }
    let Some(spec) = scene.hybrid else {
        return Ok(Box::new(Uniform));
    };
    let mask = switch::initial_mask(
        reference,
        &scene.solid,
        &scene.precracks,
        spec.band,
        scene.spacing,
    );
    let collocation = scene.scheme.collocation;
    let h = Hybrid::new(spec, mask, reference, families, law, collocation)
        .map_err(|e| scene.error(&format!("hybrid.{}", collocation.field()), e.to_string()))?;
    Ok(Box::new(HybridScheme::new(h)))
}

impl<const D: usize> DynamicSimulation<D> {
    pub fn new(scene: &Scene) -> Result<Self, SceneError> {
        let (discretization, grid) = discretize::<D>(scene)?;
        let intact = discretization.intact_bonds(scene)?;
        let Some(m) = scene.material.as_ref() else {
            return Err(scene.error(
                "material",
                "dynamics needs an elastic material (density, youngs_modulus or micromodulus)",
            ));
        };
        let law = PmbLaw::new(&m.constants, scene.horizon, D);
        let scheme = scheme_of(scene, &discretization, &law, grid)?;
        let weights = scheme.damage_weights(&discretization, &law, &intact);
        let body = ElasticBody::new(scene, discretization, intact, (law, m.density), weights);
        let layer = BondLayer::new(scene, body.reference(), &body.law, body.density)?;
        let stable = scheme.stable_step(&body);
        let probes = probes::probes(scene, body.reference());
        let mut sim = DynamicSimulation {
            body,
            scheme,
            plugins: Vec::new(),
            probes,
            run: RunState::new(scene, stable, &[])?,
        };
        if let Some(layer) = layer {
            let dt = sim.run.clock.dt();
            sim.plugins
                .push(Box::new(layer::Layer::start(layer, &sim.body, dt)));
        }
        sim.run.stages =
            crate::solver::Stages::new(&verlet::stage_names(&*sim.scheme, &sim.plugins));
        sim.update_accelerations();
        Ok(sim)
    }

    fn update_accelerations(&mut self) {
        self.scheme.forces(&mut self.body, true);
        self.body.accelerate(None, self.scheme.idle());
    }

    /// Recomputes forces after positions were set by hand (tests, restarts); on a multi-grid
    /// scene the interpolated nodes first follow the other level.
    pub fn refresh_forces(&mut self) {
        self.scheme.transfer(&mut self.body);
        self.update_accelerations();
    }

    /// The scheme, if it is an `S`.
    fn scheme_as<S: ElasticScheme<D>>(&self) -> Option<&S> {
        (&*self.scheme as &dyn Any).downcast_ref::<S>()
    }

    fn scheme_as_mut<S: ElasticScheme<D>>(&mut self) -> Option<&mut S> {
        (&mut *self.scheme as &mut dyn Any).downcast_mut::<S>()
    }

    /// The hybrid switch, on a hybrid scene.
    pub fn hybrid(&self) -> Option<&Hybrid<D>> {
        let h = self.scheme_as::<HybridScheme<D>>()?;
        Some(&h.hybrid)
    }

    pub fn hybrid_mut(&mut self) -> Option<&mut Hybrid<D>> {
        let h = self.scheme_as_mut::<HybridScheme<D>>()?;
        Some(&mut h.hybrid)
    }

    /// Runs the hybrid scheme `hybrid` on this body from now on (tests: a mask set by hand).
    pub fn set_hybrid(&mut self, hybrid: Hybrid<D>) {
        self.scheme = Box::new(HybridScheme::new(hybrid));
    }

    /// Bonds found broken with an Ω_w end so far (0 off a hybrid scene).
    pub fn hybrid_violations(&self) -> u64 {
        let h = self.scheme_as::<HybridScheme<D>>();
        h.map_or(0, |h| h.violations)
    }

    /// The hybrid invariant: bonds broken with an Ω_w end. Damage that reached Ω_w (possible
    /// only with a check policy other than every bond every step) switches those nodes at once.
    pub fn enforce_hybrid_invariant(&mut self) -> usize {
        let (scheme, body, clock) = (&mut *self.scheme, &self.body, &self.run.clock);
        match (scheme as &mut dyn Any).downcast_mut::<HybridScheme<D>>() {
            Some(h) => h.enforce_invariant(body, clock),
            None => 0,
        }
    }

    /// The multi-adaptive levels, on such a scene.
    pub fn multigrid(&self) -> Option<&MultiAdaptive<D>> {
        let l = self.scheme_as::<LevelScheme<D>>()?;
        Some(&l.grid)
    }

    /// On a multi-adaptive scene: the λ_max bound its stable step takes (from the sharp
    /// step, 2/√λ), and the spectral radius of the coupled linearized operator now (the
    /// levels' fictitious nodes interpolated), for a check of the bound.
    pub fn multigrid_stability(&self) -> Option<(f64, f64)> {
        let l = self.scheme_as::<LevelScheme<D>>()?;
        let sharp = l.stable_step(&self.body).sharp;
        Some(((2.0 / sharp).powi(2), l.coupled_spectral_radius(&self.body)))
    }

    /// Damage recomputed from the bond states in one pass over all bonds (a check of
    /// `damage`).
    pub fn damage_from_bonds(&self) -> Vec<f64> {
        self.body.scheme().damage(&self.body.intact)
    }

    pub fn strain_energy(&self) -> f64 {
        let body = &self.body;
        body.scheme().strain_energy(body.positions(), &body.intact)
    }

    /// Strain-energy density W_i of one node (J/m³), over its own level's family on a
    /// multi-grid scene.
    pub fn energy_density(&self, i: usize) -> f64 {
        self.scheme.energy_density(&self.body, i)
    }

    /// Over the nodes that carry mass (the active ones of a multi-grid scene).
    pub fn kinetic_energy_and_momentum(&self) -> (f64, [f64; D]) {
        let volumes = self.scheme.mass_volumes(self.body.volumes());
        self.body.kinetic_energy_and_momentum_over(&volumes)
    }

    /// Force density on each node at the current positions (N/m³), without body forces.
    pub fn force_density(&self) -> Vec<[f64; D]> {
        self.body.terms().iter().map(|t| t.force).collect()
    }
}

impl<const D: usize> Stepper for DynamicSimulation<D> {
    fn step(&mut self) -> Result<(), SimError> {
        verlet::step(
            &mut self.body,
            &mut *self.scheme,
            &mut self.plugins,
            &mut self.run,
        )
    }

    fn frame(&mut self) -> Frame {
        self.build_frame()
    }

    fn info(&self) -> SimInfo {
        let body = &self.body;
        let (nodes, bonds) = (body.nodes().len(), body.families().bond_count());
        let bytes_per_bond = body.memory_bytes() as f64 / bonds.max(1) as f64;
        let mut info = self
            .run
            .info(Size::of_bonds(D, nodes, bonds, bytes_per_bond));
        info.notes = notes_of(&self.plugins);
        info
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
        self.body
            .save(&mut state, |i| self.scheme.energy_density(&self.body, i));
        save_each(
            Some(&*self.scheme as &dyn Adaptation<_>),
            &self.plugins,
            &self.body,
            &mut state,
        );
        state
    }

    fn restore_state(&mut self, state: &State) -> Result<(), String> {
        let clock = Clock::restore(state)?;
        // The plug-ins first: a multi-adaptive scheme replays its refinements, which add the
        // nodes and bonds the body's part then fills.
        let scheme = Some(&mut *self.scheme as &mut dyn Adaptation<_>);
        restore_each(scheme, &mut self.plugins, &mut self.body, state)?;
        let saved = self.body.read_state(state)?;
        self.body.write_state(saved);
        self.run.clock = clock;
        Ok(())
    }

    fn tune(&mut self, param: Param) -> Result<(), String> {
        tune_each(&mut *self.scheme, &mut self.plugins, &mut self.body, param)
    }
}

impl<const D: usize> DynamicSimulation<D> {
    /// Crack angles `(name, degrees)` of the scene's `[[metrics.crack_angle]]` now (None where
    /// no crack was found).
    pub fn crack_angles(&self) -> Vec<(String, Option<f64>)> {
        self.crack_angles_for(&self.body.damage())
    }

    /// The bonds broken so far.
    pub fn broken_bonds(&self) -> u64 {
        self.body.broken
    }
}
