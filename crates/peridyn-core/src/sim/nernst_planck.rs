//! The NNPP simulation (thesis §2.4, §3.1.2; seed-thesis-ch2-3 §1.7, §2.3): species and
//! potential on one standard-scheme grid, advanced by the semi-implicit step of
//! `integrate::newton` (Poisson for φ with C^n, then each species by the frozen-Jacobian
//! Newton iteration), with the phase change on C₁ and an optional manufactured reference.
//! Reactions (3.98)–(3.103) are not built yet: the sources are the manufactured ones or zero.

use rayon::prelude::*;

use crate::adapt::masks::{GridClass, Phase};
use crate::adapt::multigrid::MultiGrid;
use crate::adapt::phase::solid_volume;
use crate::discretization::{CrossBonds, Discretization, Families, Interpolation};
use crate::frame::{Frame, NodeField};
use crate::integrate::newton::{SemiImplicit, StepReport};
use crate::model::nnpp_reactions::Site;
use crate::scene::nernst_planck::NernstPlanckSpec;
use crate::scene::{CoarseScheme, Condition, Coupling, Scene, SceneError};
use crate::scheme::nnpp::{LinearSource, NnppBonds, NnppFields, NnppOperator, SpeciesLaw};
use crate::solver::{
    Clock, Integrator, Lap, Param, RunState, SimError, SimInfo, Size, StableStep, State, Stepper,
};

const STAGES: &[&str] = &["poisson", "reactions", "species", "phase_change"];
const POISSON: usize = 0;
const REACTIONS: usize = 1;
const SPECIES: usize = 2;
const PHASE_CHANGE: usize = 3;

/// The colour range of φ when no manufactured amplitude sets it (V).
const DEFAULT_POTENTIAL_RANGE: f64 = 0.1;
/// The colour range of the overpotential η (V): 0 to φ_applied − φ0 of Table 3.7 and more.
const OVERPOTENTIAL_RANGE: f64 = 0.25;

pub struct NernstPlanckSimulation<const D: usize> {
    spec: NernstPlanckSpec,
    discretization: Discretization<D>,
    /// The two levels of a multi-grid scene (classes, interpolation); None on one grid.
    multigrid: Option<MultiGrid<D>>,
    /// The cross-level bonds whose exchange is balanced (`multigrid.coupling =
    /// "conservative"`); None: the thesis's interpolated coupling, or one grid.
    cross: Option<CrossBonds>,
    bonds: NnppBonds,
    laws: Vec<SpeciesLaw>,
    fields: NnppFields,
    solver: SemiImplicit,
    sources: Vec<Vec<LinearSource>>,
    /// The manufactured sources (fixed; the reactions' are rebuilt each step).
    manufactured_sources: Option<Vec<Vec<LinearSource>>>,
    poisson_source: Vec<f64>,
    report: StepReport,
    /// The nodes the solve updates (not held): the errors are measured over them.
    free: Vec<bool>,
    /// Each node's volume where it is active, 0 on fictitious nodes: Σ C V is the total.
    active_volumes: Vec<f64>,
    /// Reaction sites (bulk solid, bulk liquid, interface), rebuilt when a phase changes.
    sites: Vec<Site>,
    /// η per node (3.102) at interface sites, 0 elsewhere.
    overpotential: Vec<f64>,
    initial_solid_volume: f64,
    initial_totals: Vec<f64>,
    species_ranges: Vec<f64>,
    potential_range: f64,
    run: RunState,
    events: Vec<String>,
}

impl<const D: usize> NernstPlanckSimulation<D> {
    pub fn new(scene: &Scene) -> Result<Self, SceneError> {
        let Some(spec) = scene.nernst_planck.clone() else {
            return Err(scene.error("nernst_planck", "the scene has no [nernst_planck] table"));
        };
        let (discretization, multigrid) = match &scene.multigrid {
            None => (Discretization::<D>::of_scene(scene)?, None),
            Some(m) if m.coarse != CoarseScheme::Standard => {
                return Err(scene.error(
                    "multigrid.coarse",
                    "the NNPP multi-grid runs the standard scheme on both levels",
                ));
            }
            Some(m) => {
                let (d, grid) = MultiGrid::<D>::discretize(scene, m)?;
                (d, Some(grid))
            }
        };
        let n = discretization.len();
        let positions = discretization.nodes.reference();
        let volumes = discretization.nodes.volumes();
        let manufactured = spec.manufactured.as_ref();
        let (phase, mut concentration, potential, held) =
            initial_state(scene, &spec, &discretization)?;
        let quadrature = |i: usize| match &multigrid {
            Some(g) if g.class[i].is_fine() => g.fine,
            Some(g) => g.coarse,
            None => discretization.quadrature,
        };
        let bonds = NnppBonds::new(
            &spec.kernel,
            &discretization.families,
            volumes,
            &quadrature,
            spec.temperature,
        );
        let laws: Vec<SpeciesLaw> = spec.species.iter().map(|s| s.law.clone()).collect();
        let manufactured_sources: Option<Vec<Vec<LinearSource>>> = manufactured.map(|m| {
            (0..laws.len())
                .map(|k| {
                    positions
                        .iter()
                        .map(|x| [m.species_source(&spec, k, x[0]), 0.0])
                        .collect()
                })
                .collect()
        });
        let sources = manufactured_sources
            .clone()
            .unwrap_or_else(|| vec![vec![[0.0; 2]; n]; laws.len()]);
        let poisson_source = positions
            .iter()
            .map(|x| manufactured.map_or(0.0, |m| m.poisson_source(&spec, x[0])))
            .collect();
        let interpolation = multigrid
            .as_ref()
            .map_or_else(Interpolation::new, |g| g.interpolation.clone());
        let free: Vec<bool> = held.iter().map(|h| !h).collect();
        let conservative = scene
            .multigrid
            .as_ref()
            .is_some_and(|m| m.coupling == Coupling::Conservative);
        let cross = conservative.then(|| {
            let coarse = |i: usize| multigrid.as_ref().is_some_and(|g| !g.class[i].is_fine());
            CrossBonds::new(
                &discretization.families,
                &interpolation,
                volumes,
                |i| free[i],
                coarse,
                |b| bonds.diffusion[b],
            )
        });
        let mut solver = SemiImplicit::new(
            &discretization.families,
            held,
            &phase,
            interpolation.clone(),
            spec.linear,
        );
        solver.tolerance = spec.tolerance;
        solver.max_iterations = spec.max_iterations;
        for c in concentration.iter_mut() {
            interpolation.transfer(c);
        }
        let interface_diffusivity = spec
            .reactions
            .as_ref()
            .filter(|r| r.butler_volmer.is_some())
            .map(|r| (r.metal, vec![laws[r.metal].interface; n]));
        let fields = NnppFields {
            concentration,
            potential,
            phase,
            interface_diffusivity,
        };
        let stable = StableStep {
            sharp: f64::INFINITY,
            guaranteed: explicit_bound(&discretization, &bonds, &laws, &fields),
            integrator: Integrator::Implicit,
        };
        let run = RunState::new(scene, stable, STAGES)?;
        let active_volumes = match &multigrid {
            Some(g) => g.active_volumes(volumes),
            None => volumes.to_vec(),
        };
        let initial_totals = totals(&fields, &active_volumes);
        let species_ranges = fields
            .concentration
            .iter()
            .enumerate()
            .map(|(k, c)| {
                let exact = manufactured.map_or(0.0, |m| m.means[k] + m.amplitudes[k].abs());
                c.iter()
                    .fold(exact, |a, v| a.max(*v))
                    .max(f64::MIN_POSITIVE)
            })
            .collect();
        let potential_range = manufactured.map_or(DEFAULT_POTENTIAL_RANGE, |m| {
            m.potential.abs().max(f64::MIN_POSITIVE)
        });
        let sites = sites(&discretization.families, &fields.phase);
        let initial_solid_volume = solid_volume(&fields.phase, &active_volumes);
        Ok(NernstPlanckSimulation {
            spec,
            discretization,
            multigrid,
            cross,
            bonds,
            laws,
            fields,
            solver,
            sources,
            manufactured_sources,
            poisson_source,
            report: StepReport::default(),
            free,
            active_volumes,
            sites,
            overpotential: vec![0.0; n],
            initial_solid_volume,
            initial_totals,
            species_ranges,
            potential_range,
            run,
            events: Vec::new(),
        })
    }

    /// The relative volume loss V_L = 1 − V_solid(t)/V_solid(0) over active nodes (§1.6).
    pub fn volume_loss(&self) -> f64 {
        if self.initial_solid_volume > 0.0 {
            1.0 - solid_volume(&self.fields.phase, &self.active_volumes) / self.initial_solid_volume
        } else {
            0.0
        }
    }

    /// Each species' Σ C V over active nodes.
    pub fn totals(&self) -> Vec<f64> {
        totals(&self.fields, &self.active_volumes)
    }

    /// η (3.102)–(3.103) at interface sites, the metal's Butler–Volmer interface
    /// diffusivity (3.92) at solid ones, and every species' linearized reaction (3.98)–(3.101),
    /// all from the state at t^n.
    fn update_reactions(&mut self) {
        let Some(law) = &self.spec.reactions else {
            return;
        };
        let thermal = self.bonds.thermal;
        let z = |k: usize| self.laws[k].valence;
        let z1 = z(law.metal);
        let f = &self.fields;
        let c = &f.concentration;
        let sites = &self.sites;
        self.overpotential
            .par_iter_mut()
            .enumerate()
            .for_each(|(i, eta)| {
                *eta = if sites[i] == Site::Interface {
                    law.overpotential(c[law.metal][i], f.potential[i], thermal, z1)
                } else {
                    0.0
                };
            });
        if let Some((_, d)) = &mut self.fields.interface_diffusivity {
            let fallback = self.laws[law.metal].interface;
            for (i, d) in d.iter_mut().enumerate() {
                *d = if sites[i] == Site::Interface {
                    law.interface_diffusivity(self.overpotential[i], thermal, z1)
                        .unwrap_or(fallback)
                } else {
                    fallback
                };
            }
        }
        let f = &self.fields;
        let species = self.laws.len();
        let mut node = vec![[0.0; 2]; species];
        for i in 0..self.discretization.len() {
            law.sources(
                sites[i],
                |k| f.concentration[k][i],
                z,
                self.overpotential[i],
                thermal,
                &mut node,
            );
            for (k, s) in node.iter().enumerate() {
                self.sources[k][i] = match &self.manufactured_sources {
                    Some(m) => [m[k][i][0] + s[0], m[k][i][1] + s[1]],
                    None => *s,
                };
            }
        }
    }

    /// Relative ℓ² errors against the manufactured solution over the free (not held) nodes:
    /// per species, then φ.
    pub fn errors(&self) -> Option<Vec<f64>> {
        let m = self.spec.manufactured.as_ref()?;
        let x: Vec<f64> = self
            .discretization
            .nodes
            .reference()
            .iter()
            .map(|p| p[0])
            .collect();
        let relative = |values: &[f64], exact: &dyn Fn(f64) -> f64| {
            let (mut e, mut r) = (0.0, 0.0);
            for ((v, &xi), _) in values.iter().zip(&x).zip(&self.free).filter(|(_, f)| **f) {
                let ex = exact(xi);
                e += (v - ex) * (v - ex);
                r += ex * ex;
            }
            (e / r.max(f64::MIN_POSITIVE)).sqrt()
        };
        let mut out: Vec<f64> = (0..self.laws.len())
            .map(|k| relative(&self.fields.concentration[k], &|xi| m.concentration(k, xi)))
            .collect();
        out.push(relative(&self.fields.potential, &|xi| m.phi(xi)));
        Some(out)
    }

    pub fn fields(&self) -> &NnppFields {
        &self.fields
    }

    /// Entries of the species and the Poisson matrices.
    pub fn system_entries(&self) -> (usize, usize) {
        self.solver.entries()
    }

    pub fn report(&self) -> &StepReport {
        &self.report
    }

    /// Solid nodes whose C₁ fell below the saturation turn liquid (irreversible).
    fn change_phases(&mut self) {
        let Some(saturation) = self.spec.saturation else {
            return;
        };
        let c1 = &self.fields.concentration[0];
        let mut changed = 0;
        for (p, &c) in self.fields.phase.iter_mut().zip(c1) {
            if p.is_solid() && c < saturation {
                *p = Phase::Liquid;
                changed += 1;
            }
        }
        if changed > 0 {
            self.sites = sites(&self.discretization.families, &self.fields.phase);
            self.events.push(format!(
                "{changed} nodes turned liquid (C₁ < {saturation:e})"
            ));
        }
    }
}

/// Explicit Euler's Gershgorin bound of the diffusion part, 2 / max_i Σ_j 2 D g1 (for the
/// report: the implicit step has no limit).
fn explicit_bound<const D: usize>(
    d: &Discretization<D>,
    bonds: &NnppBonds,
    laws: &[SpeciesLaw],
    f: &NnppFields,
) -> f64 {
    let families = &d.families;
    let largest = (0..families.node_count())
        .flat_map(|i| {
            laws.iter().map(move |law| {
                families
                    .range(i)
                    .map(|b| {
                        let j = families.neighbors[b] as usize;
                        2.0 * law.diffusivity(f.phase[i], f.phase[j]).max(law.interface)
                            * bonds.diffusion[b]
                    })
                    .sum::<f64>()
            })
        })
        .fold(0.0, f64::max);
    if largest > 0.0 {
        2.0 / largest
    } else {
        f64::INFINITY
    }
}

/// `operator(…)` of a simulation's parts, borrowed field by field so that its fields and
/// solver stay free for the step.
macro_rules! operator {
    ($sim:ident) => {
        operator(
            &$sim.discretization,
            &$sim.bonds,
            &$sim.laws,
            &$sim.spec,
            $sim.cross.as_ref(),
        )
    };
}

/// The discrete operator of the grid (borrowing its parts, so the fields stay free).
fn operator<'a, const D: usize>(
    d: &'a Discretization<D>,
    bonds: &'a NnppBonds,
    laws: &'a [SpeciesLaw],
    spec: &NernstPlanckSpec,
    cross: Option<&'a CrossBonds>,
) -> NnppOperator<'a> {
    NnppOperator {
        families: &d.families,
        bonds,
        species: laws,
        conductivity: spec.conductivity,
        concentration_unit: spec.concentration_unit,
        cross,
    }
}

/// Each node's reaction site: bulk solid or liquid (its whole family shares its phase) or
/// interface.
fn sites(families: &Families, phase: &[Phase]) -> Vec<Site> {
    (0..families.node_count())
        .into_par_iter()
        .map(|i| {
            let p = phase[i];
            let mixed = families
                .range(i)
                .any(|b| phase[families.neighbors[b] as usize] != p);
            match (mixed, p.is_solid()) {
                (true, _) => Site::Interface,
                (false, true) => Site::BulkSolid,
                (false, false) => Site::BulkLiquid,
            }
        })
        .collect()
}

fn totals(f: &NnppFields, volumes: &[f64]) -> Vec<f64> {
    f.concentration
        .iter()
        .map(|c| c.iter().zip(volumes).map(|(c, v)| c * v).sum())
        .collect()
}

impl<const D: usize> Stepper for NernstPlanckSimulation<D> {
    fn step(&mut self) -> Result<(), SimError> {
        let mut lap = Lap::start();
        let dt = self.run.clock.dt();
        let op = operator!(self);
        self.report.poisson_residual = self
            .solver
            .solve_potential(&op, &mut self.fields, &self.poisson_source)
            .map_err(|e| SimError::Solve(format!("Poisson: {e}")))?;
        lap.charge(&mut self.run.stages, POISSON);
        self.update_reactions();
        lap.charge(&mut self.run.stages, REACTIONS);
        let op = operator!(self);
        self.solver
            .step_species(&op, &mut self.fields, dt, &self.sources, &mut self.report)
            .map_err(|e| SimError::Solve(format!("species: {e}")))?;
        lap.charge(&mut self.run.stages, SPECIES);
        self.change_phases();
        lap.charge(&mut self.run.stages, PHASE_CHANGE);
        self.run.clock.advance();
        let max_value = self
            .fields
            .concentration
            .iter()
            .flatten()
            .fold(0.0_f64, |a, c| {
                if c.is_finite() {
                    a.max(c.abs())
                } else {
                    f64::NAN
                }
            });
        if !max_value.is_finite() {
            return Err(SimError::Diverged {
                step: self.run.clock.step(),
                time: self.run.clock.time(),
                max_value,
                dt,
                stable_dt: self.run.stable.sharp,
            });
        }
        Ok(())
    }

    fn frame(&mut self) -> Frame {
        let positions: Vec<f64> = self
            .discretization
            .nodes
            .reference()
            .iter()
            .flat_map(|x| x.iter().copied())
            .collect();
        let mut fields: Vec<NodeField> = self
            .laws
            .iter()
            .zip(&self.fields.concentration)
            .zip(&self.species_ranges)
            .map(|((law, c), &range)| NodeField {
                name: format!("species/{}", law.name).into(),
                values: c.clone(),
                range: (0.0, range),
            })
            .collect();
        fields.push(NodeField {
            name: "potential".into(),
            values: self.fields.potential.clone(),
            range: (-self.potential_range, self.potential_range),
        });
        if self.spec.reactions.is_some() {
            fields.push(NodeField {
                name: "overpotential".into(),
                values: self.overpotential.clone(),
                range: (0.0, OVERPOTENTIAL_RANGE),
            });
        }
        let mut scalars = vec![
            ("residual/poisson".to_string(), self.report.poisson_residual),
            (
                "linear/iterations/poisson".to_string(),
                self.report.poisson_iterations as f64,
            ),
        ];
        if self.initial_solid_volume > 0.0 {
            scalars.push(("corrosion/volume_loss".into(), self.volume_loss()));
            let solid = (self.fields.phase.iter().zip(&self.active_volumes))
                .filter(|(p, v)| p.is_solid() && **v > 0.0)
                .count();
            scalars.push(("corrosion/solid_nodes".into(), solid as f64));
            // The summary's mass: Σ C V of the first species (the metal).
            scalars.push(("field/integral".into(), self.totals()[0]));
        }
        if self.spec.reactions.is_some() {
            let at: Vec<f64> = self
                .overpotential
                .iter()
                .zip(&self.sites)
                .filter(|(_, s)| **s == Site::Interface)
                .map(|(e, _)| *e)
                .collect();
            if !at.is_empty() {
                let mean = at.iter().sum::<f64>() / at.len() as f64;
                scalars.push(("interface/overpotential/mean".into(), mean));
                scalars.push(("interface/nodes".into(), at.len() as f64));
            }
        }
        for (k, (law, total)) in self.laws.iter().zip(self.totals()).enumerate() {
            let initial = self.initial_totals[k];
            scalars.push((format!("species/{}/total", law.name), total));
            if initial != 0.0 {
                scalars.push((
                    format!("species/{}/total_drift", law.name),
                    (total - initial) / initial,
                ));
            }
            if let Some(r) = self.report.newton_residual.get(k) {
                scalars.push((format!("residual/newton/{}", law.name), *r));
                scalars.push((
                    format!("residual/linear/{}", law.name),
                    self.report.linear_residual[k],
                ));
                scalars.push((
                    format!("newton/iterations/{}", law.name),
                    self.report.iterations[k] as f64,
                ));
                scalars.push((
                    format!("linear/iterations/{}", law.name),
                    self.report.linear_iterations[k] as f64,
                ));
            }
            if let (Some(moved), true) = (self.report.balanced.get(k), initial != 0.0) {
                scalars.push((format!("coupling/balanced/{}", law.name), moved / initial));
            }
        }
        if let Some(errors) = self.errors() {
            for (law, e) in self.laws.iter().zip(&errors) {
                scalars.push((format!("error/relative_l2/{}", law.name), *e));
            }
            scalars.push((
                "error/relative_l2/potential".into(),
                errors[self.laws.len()],
            ));
            let worst = errors.iter().fold(0.0, |a: f64, &e| a.max(e));
            scalars.push(("error/relative_l2".into(), worst));
        }
        scalars.extend(self.run.timing_scalars());
        let mut classes = vec![Phase::field(&self.fields.phase)];
        let mut radii = Vec::new();
        if let Some(g) = &self.multigrid {
            classes.push(GridClass::field(&g.class));
            radii = GridClass::radii(&g.class, g.coarse.spacing, g.fine.spacing);
            let (coarse, fine, fictitious) = g.counts();
            scalars.push(("nodes/coarse_active".into(), coarse as f64));
            scalars.push(("nodes/fine_active".into(), fine as f64));
            scalars.push(("nodes/fictitious".into(), fictitious as f64));
        }
        Frame {
            step: self.run.clock.step(),
            time: self.run.clock.time(),
            dim: D,
            positions,
            fields,
            classes,
            events: std::mem::take(&mut self.events),
            scalars,
            radii,
        }
    }

    fn info(&self) -> SimInfo {
        let bonds = self.discretization.families.neighbors.len();
        self.run.info(Size::of_bonds(
            D,
            self.discretization.len(),
            bonds,
            // Three bond weights and the family's neighbour index and length.
            3.0 * 8.0 + 4.0 + 8.0,
        ))
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
        for (law, c) in self.laws.iter().zip(&self.fields.concentration) {
            state.put_f64(&format!("species/{}", law.name), c.clone());
        }
        state.put_f64("potential", self.fields.potential.clone());
        state.put_u8(
            "phase",
            self.fields.phase.iter().map(|&p| p as u8).collect(),
        );
        state
    }

    fn restore_state(&mut self, state: &State) -> Result<(), String> {
        let n = self.discretization.len();
        let clock = Clock::restore(state)?;
        let mut concentration = Vec::with_capacity(self.laws.len());
        for law in &self.laws {
            concentration.push(state.f64(&format!("species/{}", law.name), n)?.to_vec());
        }
        let potential = state.f64("potential", n)?.to_vec();
        let phase = Phase::decode(state.u8("phase", n)?)?;
        self.fields.concentration = concentration;
        self.fields.potential = potential;
        self.fields.phase = phase;
        self.sites = sites(&self.discretization.families, &self.fields.phase);
        self.run.clock = clock;
        Ok(())
    }

    /// φ_applied acts in place from the next step's overpotential on.
    fn tune(&mut self, param: Param) -> Result<(), String> {
        match (param, self.spec.reactions.as_mut()) {
            (Param::AppliedPotential(v), Some(r)) => {
                r.applied_potential = v;
                Ok(())
            }
            (param, _) => Err(param.unused_note().into()),
        }
    }
}

/// The initial phases (solid inside `[nernst_planck].solid`), concentrations and potential,
/// and the held nodes (`hold_value` and `hold_reference` layers); an error where nothing is
/// left to solve or φ has no known value anywhere.
#[allow(clippy::type_complexity)]
fn initial_state<const D: usize>(
    scene: &Scene,
    spec: &NernstPlanckSpec,
    discretization: &Discretization<D>,
) -> Result<(Vec<Phase>, Vec<Vec<f64>>, Vec<f64>, Vec<bool>), SceneError> {
    let n = discretization.len();
    let positions = discretization.nodes.reference();
    let phase: Vec<Phase> = positions
        .iter()
        .map(|x| match &spec.solid {
            Some(s) if s.contains(x, 1e-12 * scene.spacing) => Phase::Solid,
            _ => Phase::Liquid,
        })
        .collect();
    let manufactured = spec.manufactured.as_ref();
    let mut concentration: Vec<Vec<f64>> = spec
        .species
        .iter()
        .map(|s| {
            phase
                .iter()
                .map(|p| {
                    if p.is_solid() {
                        s.initial_solid
                    } else {
                        s.initial_liquid
                    }
                })
                .collect()
        })
        .collect();
    let mut potential = vec![0.0; n];
    let mut held = vec![false; n];
    for (layer, nodes) in scene.boundary.iter().zip(&discretization.layers) {
        for &i in nodes {
            let i = i as usize;
            match (layer.condition, manufactured) {
                (Condition::Value, _) => {
                    for (c, s) in concentration.iter_mut().zip(&spec.species) {
                        c[i] = s.boundary;
                    }
                    potential[i] = layer.value.first().copied().unwrap_or(0.0);
                }
                (Condition::Reference, Some(m)) => {
                    for (k, c) in concentration.iter_mut().enumerate() {
                        c[i] = m.concentration(k, positions[i][0]);
                    }
                    potential[i] = m.phi(positions[i][0]);
                }
                _ => continue,
            }
            held[i] = true;
        }
    }
    if held.iter().all(|&h| h) {
        return Err(scene.error(
            "boundary",
            "the held layers cover every node: nothing is left to solve",
        ));
    }
    let any_dirichlet = held.iter().zip(&phase).any(|(h, p)| *h || p.is_solid());
    if !any_dirichlet {
        return Err(scene.error(
            "boundary",
            "φ needs a known value somewhere: hold a layer (`hold_value = 0.0`) or give a \
             solid region (φ = 0 there)",
        ));
    }
    Ok((phase, concentration, potential, held))
}
