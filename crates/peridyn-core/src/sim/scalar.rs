//! Scalar-field simulations: a static linear solve (1D elasticity, thesis §3.2.5; seed-004
//! Example 1) or transient PD diffusion with forward Euler (3.10) (thesis §3.2.6; seed-004
//! Example 2), on either scheme, and bi-material corrosion (thesis §2.3.3; seed-thesis-ch2-3
//! §1.6) with its phase change, optionally on the fixed hybrid. The field is held at the
//! reference solution in `hold_reference` layers (or at a value in `hold_value` layers); frames
//! carry the field and its pointwise error against the reference, and the relative ℓ² error
//! (3.79) (seed-004 (66)).

use rayon::prelude::*;

use super::wave::Wave;
use crate::absorb::scalar_layer::Absorber;
use crate::adapt::fixed::{self, FixedHybrid};
use crate::adapt::masks::{GridClass, Phase, SchemeClass};
use crate::adapt::multigrid::MultiGrid;
use crate::adapt::phase::PhaseChange;
use crate::discretization::{Discretization, Families, Field, Quadrature};
use crate::frame::{Frame, NodeField};
use crate::integrate::linear::BandMatrix;
use crate::integrate::stability;
use crate::metrics::probes::{self, Probe};
use crate::model::corrosion::CorrosionLaw;
use crate::model::diffusion::DiffusionKernel;
use crate::model::pmb::{Influence, PmbLaw};
use crate::scene::{CoarseScheme, Condition, Physics, Reference, Scene, SceneError, StepSize};
use crate::scheme::standard;
use crate::scheme::wls::{self, Basis, Collocation};
use crate::scheme::{ScalarOperator, VectorOperator};
use crate::solver::{
    Clock, Integrator, Lap, RunState, SimError, SimInfo, Size, StableStep, State, Stepper,
};

/// A static solve's one stage.
const STATIC_STAGES: &[&str] = &["solve"];
/// The stages of forward Euler and of a wave's damped velocity-Verlet, in the order `step()`
/// runs them (`rates`: L u; `update`: the new values, for Verlet both half steps; `hold`: held
/// values, a multi-grid scene's fictitious values and the absorbing layer).
const EULER_STAGES: &[&str] = &["rates", "update", "hold", "phase_change"];
const RATES: usize = 0;
const UPDATE: usize = 1;
const HOLD: usize = 2;
const PHASE_CHANGE: usize = 3;

/// Power iterations for the forward-Euler bound of a (possibly non-symmetric) operator.
const POWER_ITERATIONS: usize = 300;
/// A field this many times larger than its scale has diverged.
const DIVERGENCE_FACTOR: f64 = 1e6;

/// Corrosion scenes: the law of the bond classes and the phase change with its column.
struct Corrosion {
    law: CorrosionLaw,
    change: PhaseChange,
    phase: Field<Phase>,
}

pub struct ScalarSimulation<const D: usize> {
    scene: Scene,
    discretization: Discretization<D>,
    field: Field<f64>,
    /// The kernel of the scalar operator: diffusion's κ ω/‖ξ‖^q, or in 1D static elasticity
    /// the linearized bond force c ω/|ξ| (κ = c, q = 1).
    kernel: DiffusionKernel,
    /// Rows: the free nodes (Ω_s's only, in a hybrid), in increasing order.
    operator: ScalarOperator,
    held: Vec<u32>,
    /// The operator's value on each of its rows, then (forward Euler) the row's new value.
    rate: Vec<f64>,
    reference: Option<Reference>,
    corrosion: Option<Corrosion>,
    hybrid: Option<FixedHybrid>,
    /// Multi-grid scenes: the levels' classes and the fictitious nodes' interpolation.
    multigrid: Option<MultiGrid<D>>,
    /// Unbounded-domain scenes: the absorbing layer (thesis Chapter 4).
    absorber: Option<Absorber<D>>,
    /// Scalar-wave scenes: the velocity state of (4.62).
    wave: Option<Wave>,
    probes: Vec<Probe>,
    /// Each node's volume where it is active (0 on fictitious nodes): Σ C V over these is the
    /// total.
    active_volumes: Vec<f64>,
    run: RunState,
    /// |field| scale for the color range and the divergence check.
    amplitude: f64,
    /// Events since the last frame.
    events: Vec<String>,
}

/// The physical kernel of the scene's scalar operator (κ_liq for corrosion).
fn kernel(scene: &Scene, dim: usize) -> DiffusionKernel {
    match (&scene.diffusion, &scene.material) {
        (Some(d), _) => DiffusionKernel {
            diffusivity: d.diffusivity,
            exponent: d.exponent,
            influence: d.influence,
            horizon: scene.horizon,
        },
        (None, m) => DiffusionKernel {
            diffusivity: m.as_ref().map_or(0.0, |m| {
                PmbLaw::new(&m.constants, scene.horizon, dim).micromodulus
            }),
            exponent: 1.0,
            influence: m
                .as_ref()
                .map_or(Influence::Constant, |m| m.constants.influence),
            horizon: scene.horizon,
        },
    }
}

/// Assembles the scheme's operator with `kernel` on the rows `free` (standard (3.4) or WLS
/// seed-thesis-ch2-3 §3.4).
pub fn assemble<const D: usize>(
    scene: &Scene,
    positions: &[[f64; D]],
    volumes: &[f64],
    families: &Families,
    kernel: &DiffusionKernel,
    free: &[u32],
) -> Result<ScalarOperator, String> {
    match scene.scheme.kind.wls_order() {
        // Identical cells and nominal β, also on a perturbed grid
        // (seed-004 Example 2; seed-thesis-ch2-3 §4.2).
        None => Ok(standard::diffusion_operator::<D>(
            free,
            volumes,
            families,
            &Quadrature::of_scene(scene),
            kernel,
        )),
        Some(order) => {
            let basis = Basis::new(D, order);
            let l = wls::diffusion_l(
                &basis,
                kernel.diffusivity,
                kernel.exponent,
                scene.horizon,
                kernel.influence,
            );
            wls::diffusion_operator(
                free,
                positions,
                families,
                &basis,
                &l,
                scene.horizon,
                scene.scheme.collocation,
            )
            .map_err(|e| e.to_string())
        }
    }
}

/// The initial field: the initial-concentration regions (later ones win), else the reference
/// at t = 0, else 0; `hold_value` layers hold their value from the start (later layers win).
fn initial_field<const D: usize>(
    scene: &Scene,
    positions: &[[f64; D]],
    layers: &[Vec<u32>],
) -> Vec<f64> {
    let eps = 1e-9 * scene.spacing;
    let mut field: Vec<f64> = positions
        .iter()
        .map(|x| {
            let set = scene
                .initial_concentration
                .iter()
                .rev()
                .find(|(region, _)| region.contains(x, eps))
                .map(|(_, v)| *v);
            let base = set.unwrap_or_else(|| scene.reference.map_or(0.0, |r| r.value(x, 0.0)));
            base + scene.initial_pulses.iter().map(|p| p.value(x)).sum::<f64>()
        })
        .collect();
    for (layer, nodes) in scene.boundary.iter().zip(layers) {
        if layer.condition == Condition::Value {
            for &i in nodes {
                field[i as usize] = layer.value[0];
            }
        }
    }
    field
}

/// Forward Euler's stable step for `operator` (its rows scaled by `kappa_scale`) and the
/// hybrid's WLS rows: Gershgorin discs first; the power iteration (300 operator passes) only
/// when the requested step is above the discs' bound.
fn euler_stable_step(
    scene: &Scene,
    n: usize,
    operator: &ScalarOperator,
    kappa_scale: f64,
    hybrid: Option<&FixedHybrid>,
) -> StableStep {
    let wave = scene.physics == Physics::ScalarWave;
    let gershgorin = (kappa_scale * operator.max_absolute_row_sum())
        .max(hybrid.map_or(0.0, |h| h.wls.max_absolute_row_sum()));
    // A wave's ü = L u: velocity-Verlet's 2/√λ_max with λ_max the spectral radius of −L.
    type Bound = fn(f64) -> f64;
    let (limit, step): (Bound, Bound) = if wave {
        (stability::verlet_limit, stability::verlet_step)
    } else {
        (stability::euler_limit, stability::euler_step)
    };
    let guaranteed = limit(gershgorin);
    let sharp = match scene.time.step {
        StepSize::Absolute(dt) if dt <= guaranteed => guaranteed,
        _ => {
            let radius = stability::spectral_radius(n, POWER_ITERATIONS, |v, out| {
                operator.apply(v, out);
                out.iter_mut().for_each(|o| *o *= kappa_scale);
                if let Some(h) = hybrid {
                    for (r, &i) in h.wls.rows.iter().enumerate() {
                        out[i as usize] = h.wls.apply_row_with(r, |j| [v[j]])[0];
                    }
                }
            });
            step(radius)
        }
    };
    StableStep {
        sharp,
        guaranteed,
        integrator: if wave {
            Integrator::Verlet
        } else {
            Integrator::Euler
        },
    }
}

/// The WLS rows of a scalar scene, with the collocation rule and the preset table it came
/// from: Ω_w of the fixed corrosion hybrid (`hybrid`), or the active coarse nodes of a
/// multi-grid scene whose coarse level runs WLS (`multigrid.coarse = "wls"`, the thesis's
/// §3.5.2 screw: "coarse WLS elsewhere"). On the multi-grid, coarse nodes within δ of the
/// initial solid stay standard (their bonds carry the phases' classes; the solid only
/// shrinks, so a WLS row never sees one), as do held, fictitious and fine nodes.
fn wls_mask<const D: usize>(
    scene: &Scene,
    positions: &[[f64; D]],
    corrosion: &Option<(CorrosionLaw, PhaseChange, Vec<Phase>)>,
    multigrid: &Option<MultiGrid<D>>,
    is_held: &[bool],
) -> Option<(Vec<SchemeClass>, Collocation, &'static str)> {
    let solid = |band: f64| {
        let solid: Vec<bool> = match corrosion {
            Some((_, _, phase)) => phase.iter().map(|p| p.is_solid()).collect(),
            None => vec![false; positions.len()],
        };
        fixed::corrosion_mask(positions, &solid, is_held, band)
    };
    match (&scene.hybrid, multigrid, scene.multigrid.as_ref()) {
        (Some(spec), None, _) if corrosion.is_some() => {
            Some((solid(spec.band), scene.scheme.collocation, "hybrid"))
        }
        (_, Some(g), Some(spec)) => {
            let CoarseScheme::Wls(rule) = spec.coarse else {
                return None;
            };
            let mut mask = solid(scene.horizon);
            for (m, class) in mask.iter_mut().zip(&g.class) {
                if *m == SchemeClass::Wls && *class != GridClass::CoarseActive {
                    *m = SchemeClass::Standard;
                }
            }
            Some((mask, rule, "multigrid"))
        }
        _ => None,
    }
}

impl<const D: usize> ScalarSimulation<D> {
    pub fn new(scene: &Scene) -> Result<Self, SceneError> {
        let (mut discretization, multigrid) = match &scene.multigrid {
            None => (Discretization::<D>::of_scene(scene)?, None),
            Some(spec) => {
                let (d, grid) = MultiGrid::<D>::discretize(scene, spec)?;
                (d, Some(grid))
            }
        };
        if !scene.precracks.is_empty() {
            // Scalar fields: a notch removes the bonds across it (no flux through a defect).
            discretization.families = discretization
                .families
                .without_crossing(discretization.nodes.reference(), &scene.precracks);
        }
        let n = discretization.len();
        let mut is_held = vec![false; n];
        for (layer, nodes) in scene.boundary.iter().zip(&discretization.layers) {
            if matches!(layer.condition, Condition::Reference | Condition::Value) {
                nodes.iter().for_each(|&i| is_held[i as usize] = true);
            }
        }
        // The absorbing layer's values are overwritten each step, never solved for.
        let absorbing_nodes = Absorber::<D>::nodes(scene, discretization.nodes.reference());
        if scene.absorbing.is_some() && absorbing_nodes.is_empty() {
            return Err(scene.error(
                "absorbing.width",
                "the layer holds no node: widen it (e.g. width = \"1 horizon\")",
            ));
        }
        absorbing_nodes
            .iter()
            .for_each(|(i, _)| is_held[*i as usize] = true);
        // Fictitious nodes of a multi-grid scene are neither solved nor held: interpolated.
        let active = |i: u32| {
            multigrid
                .as_ref()
                .is_none_or(|g| g.class[i as usize].is_active())
        };
        let (free, held): (Vec<u32>, Vec<u32>) = (0..n as u32)
            .filter(|&i| active(i) || is_held[i as usize])
            .partition(|&i| !is_held[i as usize]);
        let active_volumes = match &multigrid {
            Some(g) => g.active_volumes(discretization.nodes.volumes()),
            None => discretization.nodes.volumes().to_vec(),
        };
        if free.is_empty() {
            return Err(scene.error(
                "boundary",
                "the held layers cover every node: nothing is left to solve",
            ));
        }
        let positions = discretization.nodes.reference();
        let volumes = discretization.nodes.volumes();
        let mut field = initial_field(scene, positions, &discretization.layers);
        if let Some(g) = &multigrid {
            g.transfer(&mut field);
        }
        let kernel = kernel(scene, D);
        let corrosion = scene.diffusion.and_then(|d| d.corrosion).map(|c| {
            let law = CorrosionLaw {
                kappa_liquid: kernel.diffusivity,
                kappa_interface: c.interface_diffusivity,
                saturation: c.saturation,
            };
            let (change, phase) = PhaseChange::initial(&law, &field, &active_volumes);
            (law, change, phase)
        });
        let hybrid = match wls_mask(scene, positions, &corrosion, &multigrid, &is_held) {
            Some((mask, rule, table)) => Some(
                FixedHybrid::new(mask, positions, &discretization.families, &kernel, rule)
                    .map_err(|e| {
                        scene.error(&format!("{table}.{}", rule.field()), e.to_string())
                    })?,
            ),
            None => None,
        };
        let standard_rows: Vec<u32> = match &hybrid {
            Some(h) => free
                .into_iter()
                .filter(|&i| h.mask[i as usize] == SchemeClass::Standard)
                .collect(),
            None => free,
        };
        // Corrosion: κ depends on the bond's class; the operator is assembled with κ = 1 and
        // the bond sum weights each bond by its κ.
        let assembled = match corrosion {
            Some(_) => DiffusionKernel {
                diffusivity: 1.0,
                ..kernel
            },
            None => kernel,
        };
        let operator = match &multigrid {
            // Each level's rows with its own quadrature (β of its spacing).
            Some(g) => {
                let level = |fine: bool, quadrature: &Quadrature| {
                    let rows: Vec<u32> = standard_rows
                        .iter()
                        .copied()
                        .filter(|&i| g.class[i as usize].is_fine() == fine)
                        .collect();
                    standard::diffusion_operator::<D>(
                        &rows,
                        volumes,
                        &discretization.families,
                        quadrature,
                        &assembled,
                    )
                };
                ScalarOperator::concat(level(false, &g.coarse), level(true, &g.fine))
            }
            None => assemble(
                scene,
                positions,
                volumes,
                &discretization.families,
                &assembled,
                &standard_rows,
            )
            .map_err(|m| scene.error("discretization.collocation_factor", m))?,
        };
        let amplitude = scene
            .reference
            .map_or(0.0, |r| r.amplitude(positions.iter().map(|x| x.as_slice())))
            .max(field.iter().fold(0.0, |a: f64, v| a.max(v.abs())));
        let (stable, stage_names) = match scene.physics {
            Physics::Static => (StableStep::NONE, STATIC_STAGES),
            Physics::ScalarWave => (
                euler_stable_step(scene, n, &operator, 1.0, None),
                EULER_STAGES,
            ),
            _ => {
                // The unit operator times the largest bond κ bounds the corrosion operator's
                // spectrum.
                let kappa_scale = corrosion.as_ref().map_or(1.0, |(law, ..)| law.kappa_max());
                let stable = euler_stable_step(scene, n, &operator, kappa_scale, hybrid.as_ref());
                (stable, EULER_STAGES)
            }
        };
        let run = RunState::new(scene, stable, stage_names)?;
        let absorber = scene.absorbing.map(|spec| {
            let mut a = Absorber::new(scene, spec, absorbing_nodes, &kernel, n);
            a.ensure_fitted(run.clock.dt(), positions, &discretization.families);
            a
        });
        let probes = Probe::resolve(&scene.probes, positions, &operator);
        let wave = scene
            .wave
            .map(|w| Wave::new(w.damping, &field, operator.rows.len()));
        let nodes = &mut discretization.nodes;
        let field = nodes.fields.add_values("field", field);
        let corrosion = corrosion.map(|(law, change, phase)| Corrosion {
            law,
            change,
            phase: nodes.fields.add_values("phase", phase),
        });
        let rows = operator.rows.len();
        Ok(ScalarSimulation {
            scene: scene.clone(),
            discretization,
            field,
            kernel,
            operator,
            held,
            rate: vec![0.0; rows],
            reference: scene.reference,
            corrosion,
            hybrid,
            multigrid,
            absorber,
            wave,
            probes,
            active_volumes,
            run,
            amplitude,
            events: Vec::new(),
        })
    }

    pub fn scene(&self) -> &Scene {
        &self.scene
    }

    /// The current field, one value per node.
    pub fn field(&self) -> &[f64] {
        self.discretization.nodes.fields.get(self.field)
    }

    pub fn positions(&self) -> &[[f64; D]] {
        self.discretization.nodes.reference()
    }

    /// Sets the field (tests, restarts): `values` per node, a multi-grid scene's fictitious
    /// values replaced by their interpolation from the other level.
    pub fn set_field(&mut self, values: &mut [f64]) {
        if let Some(g) = &self.multigrid {
            g.transfer(values);
        }
        self.discretization
            .nodes
            .fields
            .get_mut(self.field)
            .copy_from_slice(values);
        if let Some(w) = self.wave.as_mut() {
            w.forces_fresh = false;
        }
    }

    /// A scalar wave's u̇ per node.
    pub fn velocity(&self) -> Option<&[f64]> {
        self.wave.as_ref().map(|w| w.velocity.as_slice())
    }

    /// The absorbing layer's nodes, in the layer's order.
    pub fn absorbing_nodes(&self) -> &[u32] {
        self.absorber
            .as_ref()
            .map_or(&[], |a| a.layer.nodes.as_slice())
    }

    /// `check`'s lines on the absorbing layer (its ‖V‖ and cond(M)).
    pub fn absorbing_report(&self) -> Vec<String> {
        self.absorber.as_ref().map_or(Vec::new(), |a| a.report())
    }

    pub fn operator(&self) -> &ScalarOperator {
        &self.operator
    }

    /// The WLS rows (Ω_w of a fixed corrosion hybrid, or a multi-grid scene's WLS coarse
    /// level), with the liquid's κ, if any.
    pub fn wls_operator(&self) -> Option<&VectorOperator<1>> {
        self.hybrid.as_ref().map(|h| &h.wls)
    }

    fn phase(&self) -> Option<&[Phase]> {
        let c = self.corrosion.as_ref()?;
        Some(self.discretization.nodes.fields.get(c.phase))
    }

    /// Relative ℓ² error (3.79) (seed-004 (66)) over all nodes against the reference, if any.
    pub fn relative_error(&self) -> Option<f64> {
        let r = self.reference?;
        let t = self.run.clock.time();
        let (num, den) =
            self.positions()
                .iter()
                .zip(self.field())
                .fold((0.0, 0.0), |(n, d), (x, v)| {
                    let e = r.value(x, t);
                    (n + (v - e).powi(2), d + e * e)
                });
        Some(if den > 0.0 {
            (num / den).sqrt()
        } else {
            num.sqrt()
        })
    }

    fn hold_reference(&mut self, t: f64) {
        if let Some(r) = self.reference {
            let nodes = &mut self.discretization.nodes;
            let (positions, field) = (nodes.base.reference(), nodes.fields.get_mut(self.field));
            for &i in &self.held {
                field[i as usize] = r.value(&positions[i as usize], t);
            }
        }
    }

    /// One global solve of 0 = L u + b on the free nodes, held values moved to the right.
    fn solve_static(&mut self) -> Result<(), SimError> {
        let n = self.discretization.len();
        let mut unknown = vec![u32::MAX; n];
        for (r, &i) in self.operator.rows.iter().enumerate() {
            unknown[i as usize] = r as u32;
        }
        let op = &self.operator;
        let unknown = &unknown;
        let (lower, upper) = BandMatrix::bandwidths((0..op.rows.len()).flat_map(|r| {
            op.columns[op.offsets[r]..op.offsets[r + 1]]
                .iter()
                .filter(|&&j| unknown[j as usize] != u32::MAX)
                .map(move |&j| (r, unknown[j as usize] as usize))
        }));
        let mut matrix = BandMatrix::new(op.rows.len(), lower, upper)
            .map_err(|e| SimError::Solve(e.to_string()))?;
        let mut rhs = vec![0.0; op.rows.len()];
        let (positions, field) = (self.positions(), self.field());
        for (r, &i) in op.rows.iter().enumerate() {
            let x = &positions[i as usize];
            rhs[r] = -self
                .reference
                .map_or(0.0, |rf| rf.forcing(x, 0.0, &self.kernel));
            for e in op.offsets[r]..op.offsets[r + 1] {
                let j = op.columns[e] as usize;
                match unknown[j] {
                    u32::MAX => rhs[r] -= op.weights[e] * field[j],
                    col => matrix.add(r, col as usize, op.weights[e]),
                }
            }
        }
        matrix
            .solve(&mut rhs)
            .map_err(|e| SimError::Solve(e.to_string()))?;
        let field = self.discretization.nodes.fields.get_mut(self.field);
        for (r, &i) in self.operator.rows.iter().enumerate() {
            field[i as usize] = rhs[r];
        }
        Ok(())
    }

    /// L C on every row: the standard rows (bond-weighted in corrosion scenes) and the
    /// hybrid's WLS rows.
    fn rates(&mut self) {
        let fields = &self.discretization.nodes.fields;
        let field = fields.get(self.field);
        match &self.corrosion {
            Some(c) => {
                let (law, phase) = (&c.law, fields.get(c.phase));
                self.operator
                    .apply_rows_bond_weighted(field, &mut self.rate, |i, j| {
                        law.bond_diffusivity(phase[i].is_solid(), phase[j].is_solid())
                    });
            }
            None => self.operator.apply_rows(field, &mut self.rate),
        }
        if let Some(h) = self.hybrid.as_mut() {
            h.rates(field);
        }
    }

    /// Forward Euler (3.10): C⁺ = C + Δt (L C + S) on the free nodes (both schemes' rows of a
    /// hybrid), into the rate buffers, then written to the field; returns max |C⁺|.
    fn euler_update(&mut self, t: f64) -> f64 {
        let mut updated = self.euler_rows(t, false);
        if self.hybrid.is_some() {
            updated = updated.max(self.euler_rows(t, true));
        }
        let field = self.discretization.nodes.fields.get_mut(self.field);
        for (r, &i) in self.operator.rows.iter().enumerate() {
            field[i as usize] = self.rate[r];
        }
        if let Some(h) = &self.hybrid {
            for (r, &i) in h.wls.rows.iter().enumerate() {
                field[i as usize] = h.rate[r];
            }
        }
        updated
    }

    /// [`Self::euler_update`] on one row set: the Ω_w rows of the hybrid if `liquid`, else
    /// `operator`'s. The new values go to the rate buffer first (the update is Jacobi-like).
    fn euler_rows(&mut self, t: f64, liquid: bool) -> f64 {
        let dt = self.run.clock.dt();
        let (reference, kernel) = (self.reference, &self.kernel);
        let nodes = &self.discretization.nodes;
        let (positions, field) = (nodes.base.reference(), nodes.fields.get(self.field));
        let (rows, rates) = match (&mut self.hybrid, liquid) {
            (Some(h), true) => (&h.wls.rows, &mut h.rate),
            _ => (&self.operator.rows, &mut self.rate),
        };
        rates
            .par_iter_mut()
            .with_min_len(crate::scheme::MIN_ROWS_PER_TASK)
            .enumerate()
            .map(|(r, rate)| {
                let i = rows[r] as usize;
                let source = reference.map_or(0.0, |rf| rf.forcing(&positions[i], t, kernel));
                *rate = field[i] + dt * (*rate + source);
                rate.abs()
            })
            .reduce(|| 0.0, f64::max)
    }

    /// The absorbing layer's new values (and a wave's rates) from the state at t^n (and
    /// t^{n−1}), before anything is advanced; rows refitted first if Δt changed.
    fn absorb_prepare(&mut self) {
        let Some(a) = self.absorber.as_mut() else {
            return;
        };
        let nodes = &self.discretization.nodes;
        a.ensure_fitted(
            self.run.clock.dt(),
            nodes.base.reference(),
            &self.discretization.families,
        );
        let field = nodes.fields.get(self.field);
        match &self.wave {
            Some(w) => {
                a.layer.values(field, &w.previous_field, &mut a.values);
                a.layer.rates(
                    [field, &w.previous_field],
                    [&w.velocity, &w.previous_velocity],
                    &mut a.rates,
                );
            }
            None => a.layer.values(field, field, &mut a.values),
        }
    }

    /// One forward-Euler step (3.10), then the held values, a multi-grid scene's fictitious
    /// values and the absorbing layer; returns max |C^{n+1}| of the solved rows.
    fn euler_step(&mut self, lap: &mut Lap) -> f64 {
        let t = self.run.clock.time();
        self.rates();
        self.absorb_prepare();
        lap.charge(&mut self.run.stages, RATES);
        let max_value = self.euler_update(t);
        lap.charge(&mut self.run.stages, UPDATE);
        self.hold_reference(self.run.clock.next_time());
        let field = self.discretization.nodes.fields.get_mut(self.field);
        // The fictitious nodes of a multi-grid scene take their values from the other level.
        if let Some(g) = &self.multigrid {
            g.transfer(field);
        }
        if let Some(a) = &self.absorber {
            a.overwrite(field);
        }
        lap.charge(&mut self.run.stages, HOLD);
        max_value
    }

    /// One damped velocity-Verlet step (4.62) of a scalar wave, the absorbing layer overwritten
    /// after each half (its u^{n+1} before L u^{n+1} is taken, its u̇^{n+1} at the end);
    /// returns max |u^{n+1}|.
    fn verlet_step(&mut self, lap: &mut Lap) -> f64 {
        let dt = self.run.clock.dt();
        if !self.wave.as_ref().is_some_and(|w| w.forces_fresh) {
            self.rates();
        }
        self.absorb_prepare();
        lap.charge(&mut self.run.stages, RATES);
        let Some(w) = self.wave.as_mut() else {
            return 0.0;
        };
        let d = w.damping;
        let field = self.discretization.nodes.fields.get_mut(self.field);
        w.previous_field.copy_from_slice(field);
        w.previous_velocity.copy_from_slice(&w.velocity);
        for (r, &i) in self.operator.rows.iter().enumerate() {
            let i = i as usize;
            let acceleration = self.rate[r] - 2.0 * d * w.velocity[i];
            field[i] += dt * w.velocity[i] + 0.5 * dt * dt * acceleration;
            w.half[r] = w.velocity[i] + 0.5 * dt * acceleration;
        }
        if let Some(a) = &self.absorber {
            a.overwrite(field);
        }
        lap.charge(&mut self.run.stages, UPDATE);
        self.rates();
        lap.charge(&mut self.run.stages, RATES);
        let Some(w) = self.wave.as_mut() else {
            return 0.0;
        };
        for (r, &i) in self.operator.rows.iter().enumerate() {
            w.velocity[i as usize] = (w.half[r] + 0.5 * dt * self.rate[r]) / (1.0 + dt * d);
        }
        if let Some(a) = &self.absorber {
            a.overwrite_rates(&mut w.velocity);
        }
        w.forces_fresh = true;
        lap.charge(&mut self.run.stages, UPDATE);
        let field = self.discretization.nodes.fields.get(self.field);
        field.iter().fold(0.0, |m: f64, v| m.max(v.abs()))
    }

    /// Solid nodes below C_sat turn liquid (corrosion scenes), logged as an event.
    fn change_phases(&mut self) {
        let Some(c) = &self.corrosion else {
            return;
        };
        let fields = &mut self.discretization.nodes.fields;
        let (phase, field) = fields.pair_mut(c.phase, self.field);
        let changed = c.change.update(phase, field);
        if changed > 0 {
            self.events.push(format!(
                "t = {:.4e} s (step {}): {changed} nodes turned liquid",
                self.run.clock.next_time(),
                self.run.clock.step() + 1
            ));
        }
    }

    /// The frame's corrosion figures and masks: volume loss, solid count, phase and scheme.
    fn corrosion_frame(&self, scalars: &mut Vec<(String, f64)>) -> Vec<crate::frame::ClassField> {
        let mut classes = Vec::new();
        if let (Some(c), Some(phase)) = (&self.corrosion, self.phase()) {
            scalars.push((
                "corrosion/volume_loss".to_string(),
                c.change.volume_loss(phase, &self.active_volumes),
            ));
            let solid = phase
                .iter()
                .zip(&self.active_volumes)
                .filter(|(p, v)| p.is_solid() && **v > 0.0)
                .count();
            scalars.push(("corrosion/solid_nodes".to_string(), solid as f64));
            if let Some(h) = &self.hybrid {
                scalars.push(("hybrid/violations".to_string(), h.violations(phase) as f64));
            }
            classes.push(Phase::field(phase));
        }
        if let Some(g) = &self.multigrid {
            let (coarse, fine, fictitious) = g.counts();
            scalars.push(("grid/coarse_active".to_string(), coarse as f64));
            scalars.push(("grid/fine_active".to_string(), fine as f64));
            scalars.push(("grid/fictitious".to_string(), fictitious as f64));
            classes.push(GridClass::field(&g.class));
        }
        if let Some(h) = &self.hybrid {
            scalars.push((
                "hybrid/omega_s_fraction".to_string(),
                SchemeClass::standard_fraction(&h.mask),
            ));
            classes.push(SchemeClass::field(&h.mask, true));
        }
        classes
    }
}

impl<const D: usize> Stepper for ScalarSimulation<D> {
    fn step(&mut self) -> Result<(), SimError> {
        let mut lap = Lap::start();
        if self.scene.physics == Physics::Static {
            self.solve_static()?;
            lap.charge(&mut self.run.stages, 0);
            self.run.clock.advance();
            return Ok(());
        }
        let max_value = if self.wave.is_some() {
            self.verlet_step(&mut lap)
        } else {
            self.euler_step(&mut lap)
        };
        self.change_phases();
        lap.charge(&mut self.run.stages, PHASE_CHANGE);
        self.run.clock.advance();
        let scale = self.amplitude.max(f64::MIN_POSITIVE);
        if !max_value.is_finite() || max_value > DIVERGENCE_FACTOR * scale {
            return Err(SimError::Diverged {
                step: self.run.clock.step(),
                time: self.run.clock.time(),
                max_value,
                dt: self.run.clock.dt(),
                stable_dt: self.run.stable.sharp,
            });
        }
        Ok(())
    }

    fn frame(&mut self) -> Frame {
        let t = self.run.clock.time();
        let (positions, field) = (self.positions(), self.field());
        // The pointwise error exists only against a reference (none in corrosion scenes).
        let error: Option<Vec<f64>> = self.reference.map(|r| {
            positions
                .iter()
                .zip(field)
                .map(|(x, v)| v - r.value(x, t))
                .collect()
        });
        let integral: f64 = field
            .iter()
            .zip(&self.active_volumes)
            .map(|(c, v)| c * v)
            .sum();
        let mut scalars = vec![("field/integral".to_string(), integral)];
        scalars.extend(self.run.timing_scalars());
        let amplitude = if self.amplitude > 0.0 {
            self.amplitude
        } else {
            1.0
        };
        // Concentrations of corrosion scenes are never negative: the colormap spans [0, max].
        let lowest = if self.corrosion.is_some() {
            0.0
        } else {
            -amplitude
        };
        if self.absorber.is_some() || self.wave.is_some() {
            let energy = probes::near_field_energy(
                &self.operator,
                self.field(),
                self.wave.as_ref().map(|w| w.velocity.as_slice()),
                &self.active_volumes,
                self.absorber.as_ref().map(|a| a.is_absorbing.as_slice()),
            );
            scalars.push(("energy/near_field".to_string(), energy));
        }
        let mut fields = vec![NodeField {
            name: match self.scene.physics {
                Physics::Static | Physics::ScalarWave => "displacement",
                _ => "concentration",
            }
            .into(),
            values: self.field().to_vec(),
            range: (lowest, amplitude),
        }];
        if let Some(error) = error {
            let max_error = error.iter().fold(0.0, |a: f64, v| a.max(v.abs()));
            scalars.push(("error/max_abs".to_string(), max_error));
            if let Some(e) = self.relative_error() {
                scalars.push(("error/relative_l2".to_string(), e));
            }
            let range = if max_error > 0.0 { max_error } else { 1.0 };
            fields.push(NodeField {
                name: "error".into(),
                values: error,
                range: (-range, range),
            });
        }
        for p in &self.probes {
            let velocity = self.wave.as_ref().map(|w| w.velocity.as_slice());
            scalars.extend(p.scalars(&self.operator, self.field(), velocity));
        }
        if let Some(w) = &self.wave {
            let top = w.velocity.iter().fold(0.0, |a: f64, v| a.max(v.abs()));
            let range = if top > 0.0 { top } else { 1.0 };
            fields.push(NodeField {
                name: "velocity".into(),
                values: w.velocity.clone(),
                range: (-range, range),
            });
        }
        let mut classes = self.corrosion_frame(&mut scalars);
        if let Some(a) = &self.absorber {
            classes.push(a.class_field(&[]));
        }
        let radii = self.multigrid.as_ref().map_or(Vec::new(), |g| {
            GridClass::radii(&g.class, g.coarse.spacing, g.fine.spacing)
        });
        Frame {
            step: self.run.clock.step(),
            time: t,
            dim: D,
            positions: self.positions().as_flattened().to_vec(),
            fields,
            classes,
            events: std::mem::take(&mut self.events),
            scalars,
            radii,
        }
    }

    fn info(&self) -> SimInfo {
        let op = &self.operator;
        let (wls_entries, wls_rows) = self
            .hybrid
            .as_ref()
            .map_or((0, 0), |h| (h.wls.columns.len(), h.wls.rows.len()));
        let entries = op.columns.len() + wls_entries;
        self.run.info(Size {
            dim: D,
            nodes: self.discretization.len(),
            bonds: entries,
            bytes_per_bond: 12.0,
            stencil: entries as f64 / (op.rows.len() + wls_rows).max(1) as f64,
        })
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
        state.put_f64("field", self.field().to_vec());
        if let Some(w) = &self.wave {
            state.put_f64("velocity", w.velocity.clone());
            state.put_f64("previous_field", w.previous_field.clone());
            state.put_f64("previous_velocity", w.previous_velocity.clone());
        }
        if let Some(phase) = self.phase() {
            state.put_u8("phase", phase.iter().map(|&p| p as u8).collect());
        }
        state
    }

    fn restore_state(&mut self, state: &State) -> Result<(), String> {
        let n = self.discretization.len();
        let clock = Clock::restore(state)?;
        let field = state.f64("field", n)?;
        let phase = match &self.corrosion {
            Some(_) => {
                let saved = state.u8("phase", n)?;
                let phase: Vec<Phase> = saved
                    .iter()
                    .enumerate()
                    .map(|(i, &p)| match p {
                        0 => Ok(Phase::Liquid),
                        1 => Ok(Phase::Solid),
                        _ => Err(format!("phase: node {i} has no phase {p}")),
                    })
                    .collect::<Result<_, _>>()?;
                Some(phase)
            }
            None if state.has("phase") => {
                return Err("the checkpoint is of a corrosion scene; this scene is not".into());
            }
            None => None,
        };
        let fields = &mut self.discretization.nodes.fields;
        fields.get_mut(self.field).copy_from_slice(field);
        if let (Some(c), Some(phase)) = (&self.corrosion, phase) {
            fields.get_mut(c.phase).copy_from_slice(&phase);
        }
        if let Some(w) = self.wave.as_mut() {
            w.velocity.copy_from_slice(state.f64("velocity", n)?);
            w.previous_field
                .copy_from_slice(state.f64("previous_field", n)?);
            w.previous_velocity
                .copy_from_slice(state.f64("previous_velocity", n)?);
            w.forces_fresh = false;
        }
        self.run.clock = clock;
        Ok(())
    }

    fn relative_error(&self) -> Option<f64> {
        ScalarSimulation::relative_error(self)
    }

    fn check_notes(&self) -> Vec<String> {
        self.absorbing_report()
    }
}
