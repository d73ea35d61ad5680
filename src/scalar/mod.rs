//! Scalar-field simulations: a static linear solve (1D elasticity, seed-004 §4.1) or transient
//! PD diffusion with forward Euler (31) (§4.2), on either scheme. The field is held at the
//! reference solution in `hold_reference` layers; frames carry the field and its pointwise
//! error against the reference, and the relative ℓ² error (66)/(3.79).

use std::time::Instant;

use rayon::prelude::*;

pub mod hybrid;

use crate::adapt;
use crate::family::{self, Families};
use crate::frame::{ClassField, Frame, NodeField};
use crate::grid::Lattice;
use crate::integrate::linear::BandMatrix;
use crate::integrate::stability;
use crate::model::corrosion::{self, Corrosion};
use crate::model::diffusion::DiffusionKernel;
use crate::scene::{
    Condition, Duration, Influence, Physics, Reference, Scene, SceneError, StepSize,
};
use crate::scheme::runs::RowRuns;
use crate::scheme::standard::{self, Quadrature};
use crate::scheme::wls::{self, Basis};
use crate::scheme::{ScalarOperator, VectorOperator};
use crate::sim::{SimError, SimInfo, StageTimers, Stepper};

/// Power iterations for the forward-Euler bound of a (possibly non-symmetric) operator, and
/// the margin kept on the spectral radius found.
const POWER_ITERATIONS: usize = 300;
const SPECTRAL_MARGIN: f64 = 1.02;
/// A field this many times larger than its scale has diverged.
const DIVERGENCE_FACTOR: f64 = 1e6;

struct FixedHybrid {
    mask: Vec<u8>,
    /// WLS diffusion on Ω_w in stencil form, evaluated over translation runs.
    wls: VectorOperator<1>,
    runs: RowRuns,
    rate: Vec<f64>,
}

pub struct ScalarSimulation<const D: usize> {
    scene: Scene,
    positions: Vec<[f64; D]>,
    volumes: Vec<f64>,
    /// Rows: the free nodes, in increasing order.
    operator: ScalarOperator,
    held: Vec<u32>,
    field: Vec<f64>,
    /// The operator's value on each free node (row order).
    rate: Vec<f64>,
    reference: Option<Reference>,
    /// Corrosion scenes: phases and bond classes.
    corrosion: Option<Corrosion>,
    /// The fixed hybrid: per-node scheme mask, and the WLS rows (Ω_w) with their rates;
    /// `operator` then holds the Ω_s rows only.
    hybrid: Option<FixedHybrid>,
    dt: f64,
    stable_dt: f64,
    gershgorin_dt: f64,
    total_steps: u64,
    frame_every: u64,
    step: u64,
    timers: StageTimers,
    /// |field| scale for the color range and the divergence check.
    amplitude: f64,
    last_frame: (u64, Instant),
    /// Events since the last frame.
    events: Vec<String>,
}

/// The kernel whose operator the scene solves: diffusion's κ ω/‖ξ‖^q, or in 1D static
/// elasticity the bond-based force c ω (u_j − u_i)/|ξ|, i.e. κ = c, q = 1 (2.33) linearized.
fn kernel(scene: &Scene) -> DiffusionKernel {
    match (&scene.diffusion, &scene.material) {
        (Some(d), _) => DiffusionKernel {
            // Corrosion: κ depends on the bond's class; the operator is assembled with κ = 1.
            diffusivity: if d.corrosion.is_some() {
                1.0
            } else {
                d.diffusivity
            },
            exponent: d.exponent,
            influence: d.influence,
            horizon: scene.horizon,
        },
        (None, m) => DiffusionKernel {
            diffusivity: m.as_ref().map_or(0.0, |m| m.micromodulus),
            exponent: 1.0,
            influence: m.as_ref().map_or(Influence::Constant, |m| m.influence),
            horizon: scene.horizon,
        },
    }
}

/// Assembles the scheme's operator on the rows `free` (standard (3.4) or WLS §3.4).
pub fn assemble<const D: usize>(
    scene: &Scene,
    lattice: &Lattice<D>,
    families: &Families,
    free: &[u32],
) -> Result<ScalarOperator, String> {
    let kernel = kernel(scene);
    match scene.scheme.kind.wls_order() {
        None => {
            // Identical cells and nominal β, also on a perturbed grid (seed-004 §4.2).
            let quadrature = Quadrature {
                spacing: scene.spacing,
                horizon: scene.horizon,
                volume_correction: scene.volume_correction,
            };
            Ok(standard::diffusion_operator::<D>(
                free,
                &lattice.volumes,
                families,
                &quadrature,
                &kernel,
            ))
        }
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
                &lattice.positions,
                families,
                &basis,
                &l,
                scene.horizon,
                scene.scheme.collocation_factor,
            )
            .map_err(|e| e.to_string())
        }
    }
}

impl<const D: usize> ScalarSimulation<D> {
    pub fn new(scene: &Scene) -> Result<Self, SceneError> {
        let error = |field: &str, message: String| scene.error(field, message);
        let lattice = Lattice::<D>::of_scene(scene)?;
        let (lo, hi) = scene.solid.bounds();
        let eps = 1e-9 * scene.spacing;
        let mut is_held = vec![false; lattice.len()];
        for (l, layer) in scene.boundary.iter().enumerate() {
            let mut count = 0;
            for (i, x) in lattice.positions.iter().enumerate() {
                let holds = matches!(layer.condition, Condition::Reference | Condition::Value);
                if holds && layer.contains(x, &lo, &hi, eps) {
                    is_held[i] = true;
                    count += 1;
                }
            }
            if count == 0 {
                return Err(error(
                    &format!("boundary[{l}]"),
                    format!(
                        "layer `{}` selects no node; widen its region or thickness",
                        layer.name
                    ),
                ));
            }
        }
        let free: Vec<u32> = (0..lattice.len() as u32)
            .filter(|&i| !is_held[i as usize])
            .collect();
        let held: Vec<u32> = (0..lattice.len() as u32)
            .filter(|&i| is_held[i as usize])
            .collect();
        if free.is_empty() {
            return Err(error(
                "boundary",
                "the held layers cover every node: nothing is left to solve".into(),
            ));
        }
        let radius = family::search_radius(scene.family_radius, scene.horizon, scene.spacing);
        let families = Families::build(&lattice.positions, radius);

        let reference = scene.reference;
        let eps = 1e-9 * scene.spacing;
        let mut field: Vec<f64> = lattice
            .positions
            .iter()
            .map(|x| {
                let set = scene
                    .initial_concentration
                    .iter()
                    .rev()
                    .find(|(region, _)| region.contains(x, eps))
                    .map(|(_, v)| *v);
                set.unwrap_or_else(|| reference.map_or(0.0, |r| r.value(x, 0.0)))
            })
            .collect();
        // Value layers hold their value from the start (later layers win).
        for layer in scene
            .boundary
            .iter()
            .filter(|b| b.condition == Condition::Value)
        {
            for (i, x) in lattice.positions.iter().enumerate() {
                if layer.contains(x, &lo, &hi, eps) {
                    field[i] = layer.value[0];
                }
            }
        }
        let corrosion = scene.diffusion.and_then(|d| {
            d.corrosion
                .map(|c| Corrosion::new(d.diffusivity, c, &field, &lattice.volumes))
        });
        let hybrid = match (&scene.hybrid, &corrosion, scene.diffusion) {
            (Some(spec), Some(c), Some(d)) => {
                let solid: Vec<bool> = c.phase.iter().map(|&p| p == corrosion::SOLID).collect();
                let mask = hybrid::corrosion_mask(&lattice.positions, &solid, &is_held, spec.band);
                let liquid = DiffusionKernel {
                    diffusivity: d.diffusivity,
                    ..kernel(scene)
                };
                let wls = hybrid::liquid_operator(
                    &mask,
                    &lattice.positions,
                    &families,
                    &liquid,
                    scene.scheme.collocation_factor,
                )
                .map_err(|e| error("hybrid.collocation_factor", e.to_string()))?;
                let rows = wls.rows.len();
                Some(FixedHybrid {
                    mask,
                    runs: RowRuns::new(&wls),
                    wls,
                    rate: vec![0.0; rows],
                })
            }
            _ => None,
        };
        let standard_rows: Vec<u32> = match &hybrid {
            Some(h) => free
                .iter()
                .copied()
                .filter(|&i| h.mask[i as usize] == adapt::hybrid::STANDARD)
                .collect(),
            None => free,
        };
        let operator = assemble(scene, &lattice, &families, &standard_rows)
            .map_err(|m| error("discretization.collocation_factor", m))?;
        // The unit operator times the largest bond κ bounds the corrosion operator's spectrum.
        let kappa_scale = corrosion.as_ref().map_or(1.0, |c| c.kappa_max());
        let amplitude = reference
            .map_or(0.0, |r| {
                r.amplitude(lattice.positions.iter().map(|x| x.as_slice()))
            })
            .max(field.iter().fold(0.0, |a: f64, v| a.max(v.abs())));

        let (dt, stable_dt, gershgorin_dt, total_steps) = match scene.physics {
            Physics::Static => (0.0, f64::INFINITY, f64::INFINITY, 1),
            _ => {
                // Every eigenvalue lies in a Gershgorin disc: |λ| ≤ max_r Σ_e |w_re|. A step
                // below 2/that needs no power iteration (which costs 300 operator passes).
                let disc_radius = |op: &ScalarOperator, scale: f64| {
                    (0..op.rows.len())
                        .into_par_iter()
                        .map(|r| {
                            scale
                                * op.weights[op.offsets[r]..op.offsets[r + 1]]
                                    .iter()
                                    .map(|w| w.abs())
                                    .sum::<f64>()
                        })
                        .reduce(|| 0.0, f64::max)
                };
                let gershgorin = disc_radius(&operator, kappa_scale).max(
                    hybrid
                        .as_ref()
                        .map_or(0.0, |h| h.wls.max_absolute_row_sum()),
                );
                let gershgorin_dt = stability::euler_limit(gershgorin);
                let stable_dt = match scene.time.step {
                    StepSize::Absolute(dt) if dt <= gershgorin_dt => gershgorin_dt,
                    _ => {
                        let n = lattice.len();
                        let radius = stability::spectral_radius(n, POWER_ITERATIONS, |v, out| {
                            operator.apply(v, out);
                            out.iter_mut().for_each(|o| *o *= kappa_scale);
                            if let Some(h) = &hybrid {
                                for (r, &i) in h.wls.rows.iter().enumerate() {
                                    out[i as usize] = h.wls.apply_row_with(r, |j| [v[j]])[0];
                                }
                            }
                        });
                        stability::euler_limit(radius * SPECTRAL_MARGIN)
                    }
                };
                let dt = match scene.time.step {
                    StepSize::Absolute(dt) => {
                        if dt > stable_dt && !scene.time.allow_unstable {
                            return Err(error(
                                "time.dt",
                                format!(
                                    "{dt:.4e} s is {:.2}× forward Euler's bound {stable_dt:.4e} s \
                                     (2/ρ, ρ the operator's spectral radius by power iteration); \
                                     lower it, use dt = \"0.9 stable\", or set time.allow_unstable = true",
                                    dt / stable_dt
                                ),
                            ));
                        }
                        dt
                    }
                    StepSize::FractionOfStable(f) => f * stable_dt,
                };
                let steps = match scene.time.duration {
                    Duration::Steps(n) => n,
                    Duration::End(t) => ((t / dt) - 1e-9).ceil().max(1.0) as u64,
                };
                (dt, stable_dt, gershgorin_dt, steps)
            }
        };
        let rows = operator.rows.len();
        Ok(ScalarSimulation {
            scene: scene.clone(),
            positions: lattice.positions,
            volumes: lattice.volumes,
            operator,
            held,
            field,
            rate: vec![0.0; rows],
            reference,
            corrosion,
            hybrid,
            dt,
            stable_dt,
            gershgorin_dt,
            total_steps,
            frame_every: scene.output_every.unwrap_or((total_steps / 100).max(1)),
            step: 0,
            timers: StageTimers::default(),
            amplitude,
            last_frame: (0, Instant::now()),
            events: Vec::new(),
        })
    }

    /// The time step, settable between steps (live control).
    pub fn dt_mut(&mut self) -> &mut f64 {
        &mut self.dt
    }

    pub fn scene(&self) -> &Scene {
        &self.scene
    }

    /// The current field, one value per node.
    pub fn field(&self) -> &[f64] {
        &self.field
    }

    pub fn positions(&self) -> &[[f64; D]] {
        &self.positions
    }

    pub fn operator(&self) -> &ScalarOperator {
        &self.operator
    }

    /// Relative ℓ² error (66)/(3.79) over all nodes against the reference, if any.
    pub fn relative_error(&self) -> Option<f64> {
        let r = self.reference?;
        let t = self.time();
        let (num, den) =
            self.positions
                .iter()
                .zip(&self.field)
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
            for &i in &self.held {
                self.field[i as usize] = r.value(&self.positions[i as usize], t);
            }
        }
    }

    /// One global solve of 0 = L u + b on the free nodes, held values moved to the right.
    fn solve_static(&mut self) -> Result<(), SimError> {
        let n = self.positions.len();
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
        let horizon = self.scene.horizon;
        for (r, &i) in op.rows.iter().enumerate() {
            let x = &self.positions[i as usize];
            rhs[r] = -self.reference.map_or(0.0, |rf| rf.forcing(x, 0.0, horizon));
            for e in op.offsets[r]..op.offsets[r + 1] {
                let j = op.columns[e] as usize;
                match unknown[j] {
                    u32::MAX => rhs[r] -= op.weights[e] * self.field[j],
                    col => matrix.add(r, col as usize, op.weights[e]),
                }
            }
        }
        matrix
            .solve(&mut rhs)
            .map_err(|e| SimError::Solve(e.to_string()))?;
        for (r, &i) in op.rows.iter().enumerate() {
            self.field[i as usize] = rhs[r];
        }
        Ok(())
    }

    /// Forward Euler (31): C⁺ = C + Δt (L C + S) on the free nodes (both schemes' rows of a
    /// hybrid); returns max |C⁺|.
    fn euler_update(&mut self, t: f64) -> f64 {
        let mut updated = self.euler_rows(t, false);
        if self.hybrid.is_some() {
            updated = updated.max(self.euler_rows(t, true));
        }
        updated
    }

    /// [`Self::euler_update`] on one row set: the Ω_w rows of the hybrid if `liquid`, else
    /// `operator`'s. The new values go to the rate buffer first (the update is Jacobi-like).
    fn euler_rows(&mut self, t: f64, liquid: bool) -> f64 {
        let (dt, horizon) = (self.dt, self.scene.horizon);
        let reference = self.reference;
        let positions = &self.positions;
        let field = &self.field;
        let (rows, rates) = match (&mut self.hybrid, liquid) {
            (Some(h), true) => (&h.wls.rows, &mut h.rate),
            _ => (&self.operator.rows, &mut self.rate),
        };
        let updated: f64 = rates
            .par_iter_mut()
            .enumerate()
            .map(|(r, rate)| {
                let i = rows[r] as usize;
                let source = reference.map_or(0.0, |rf| rf.forcing(&positions[i], t, horizon));
                *rate = field[i] + dt * (*rate + source);
                rate.abs()
            })
            .reduce(|| 0.0, f64::max);
        updated
    }

    /// Writes the updated values held in the rate buffers into the field.
    fn commit_update(&mut self) {
        for (r, &i) in self.operator.rows.iter().enumerate() {
            self.field[i as usize] = self.rate[r];
        }
        if let Some(h) = &self.hybrid {
            for (r, &i) in h.wls.rows.iter().enumerate() {
                self.field[i as usize] = h.rate[r];
            }
        }
    }
}

impl<const D: usize> Stepper for ScalarSimulation<D> {
    fn step(&mut self) -> Result<(), SimError> {
        let t0 = Instant::now();
        if self.scene.physics == Physics::Static {
            self.solve_static()?;
            self.timers.forces += t0.elapsed();
            self.step += 1;
            return Ok(());
        }
        let t = self.time();
        match &self.corrosion {
            Some(c) => c.rates(&self.operator, &self.field, &mut self.rate),
            None => self.operator.apply_rows(&self.field, &mut self.rate),
        }
        if let Some(h) = self.hybrid.as_mut() {
            let (rates, _) = h.rate.as_chunks_mut::<1>();
            h.runs.apply(&h.wls, [&self.field], |_| true, rates);
        }
        let t1 = Instant::now();
        let max_value = self.euler_update(t);
        self.commit_update();
        let t2 = Instant::now();
        self.hold_reference(t + self.dt);
        if let Some(c) = self.corrosion.as_mut() {
            let changed = c.update_phases(&self.field);
            if changed > 0 {
                self.events.push(format!(
                    "t = {:.4e} s (step {}): {changed} nodes turned liquid",
                    t + self.dt,
                    self.step + 1
                ));
            }
        }
        let t3 = Instant::now();
        self.timers.forces += t1 - t0;
        self.timers.kick += t2 - t1;
        self.timers.constraints += t3 - t2;
        self.step += 1;
        let scale = self.amplitude.max(f64::MIN_POSITIVE);
        if !max_value.is_finite() || max_value > DIVERGENCE_FACTOR * scale {
            return Err(SimError::Diverged {
                step: self.step,
                time: self.time(),
                max_value,
                dt: self.dt,
                stable_dt: self.stable_dt,
            });
        }
        Ok(())
    }

    fn frame(&mut self) -> Frame {
        let t = self.time();
        // The pointwise error exists only against a reference (none in corrosion scenes).
        let error: Option<Vec<f64>> = self.reference.map(|r| {
            self.positions
                .iter()
                .zip(&self.field)
                .map(|(x, v)| v - r.value(x, t))
                .collect()
        });
        let now = Instant::now();
        let steps_since = self.step.saturating_sub(self.last_frame.0);
        let step_wall = if steps_since > 0 {
            (now - self.last_frame.1).as_secs_f64() / steps_since as f64
        } else {
            0.0
        };
        self.last_frame = (self.step, now);
        let integral: f64 = self
            .field
            .iter()
            .zip(&self.volumes)
            .map(|(c, v)| c * v)
            .sum();
        let mut scalars = vec![
            ("field/integral".to_string(), integral),
            ("timing/step_wall_s".to_string(), step_wall),
        ];
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
        let mut fields = vec![NodeField {
            name: match self.scene.physics {
                Physics::Static => "displacement",
                _ => "concentration",
            },
            values: self.field.clone(),
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
                name: "error",
                values: error,
                range: (-range, range),
            });
        }
        let mut classes = Vec::new();
        if let Some(c) = &self.corrosion {
            scalars.push((
                "corrosion/volume_loss".to_string(),
                c.volume_loss(&self.volumes),
            ));
            let solid = c.phase.iter().filter(|&&p| p == corrosion::SOLID).count();
            scalars.push(("corrosion/solid_nodes".to_string(), solid as f64));
            if let Some(h) = &self.hybrid {
                // No node of Ω_w may be solid (a phase change there): counted, never expected.
                let violations = h
                    .mask
                    .iter()
                    .zip(&c.phase)
                    .filter(|(m, p)| **m == adapt::hybrid::WLS && **p == corrosion::SOLID)
                    .count();
                scalars.push(("hybrid/violations".to_string(), violations as f64));
            }
            classes.push(ClassField {
                name: "phase",
                ids: c.phase.iter().map(|&p| u16::from(p)).collect(),
                classes: &[
                    (corrosion::LIQUID as u16, "liquid", [107, 174, 214]),
                    (corrosion::SOLID as u16, "solid", [150, 150, 150]),
                ],
            });
        }
        if let Some(h) = &self.hybrid {
            scalars.push((
                "hybrid/omega_s_fraction".to_string(),
                hybrid::standard_fraction(&h.mask),
            ));
            classes.push(ClassField {
                name: "scheme",
                ids: h.mask.iter().map(|&m| u16::from(m)).collect(),
                classes: adapt::hybrid::SCHEME_CLASSES,
            });
        }
        Frame {
            step: self.step,
            time: t,
            dim: D,
            positions: self.positions.iter().flatten().copied().collect(),
            fields,
            classes,
            events: std::mem::take(&mut self.events),
            scalars,
        }
    }

    fn info(&self) -> SimInfo {
        let op = &self.operator;
        let (wls_entries, wls_rows) = self
            .hybrid
            .as_ref()
            .map_or((0, 0), |h| (h.wls.columns.len(), h.wls.rows.len()));
        let entries = op.columns.len() + wls_entries;
        SimInfo {
            dim: D,
            nodes: self.positions.len(),
            bonds: entries,
            dt: self.dt,
            stable_dt: self.stable_dt,
            gershgorin_dt: self.gershgorin_dt,
            total_steps: self.total_steps,
            frame_every: self.frame_every,
            bytes_per_bond: 12.0,
            stencil: entries as f64 / (op.rows.len() + wls_rows).max(1) as f64,
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

    fn relative_error(&self) -> Option<f64> {
        ScalarSimulation::relative_error(self)
    }
}
