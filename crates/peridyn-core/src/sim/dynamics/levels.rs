//! The multi-adaptive scheme as an elastic body's scheme (thesis §3.5, seed-thesis-ch2-3 §7):
//! two grid levels, each active row run with its own level's quadrature (the coarse level on
//! WLS rows in "adaptive, hybrid"), fictitious nodes interpolated from the other level; its
//! switch as plug-in hooks — transfer and refinement after the drift, grid classes and counts
//! in frames, the refined cells in checkpoints, χ live.

use std::borrow::Cow;

use rayon::prelude::*;

use super::body::{ElasticBody, standard_over};
use super::hybrid::HYBRID_KRYLOV_DIMENSION;
use super::scheme::{ElasticScheme, symbol_bound};
use crate::adapt::masks::GridClass;
use crate::adapt::multiadaptive::{Growth, MultiAdaptive};
use crate::discretization::Discretization;
use crate::discretization::Quadrature;
use crate::discretization::family::search_radius;
use crate::frame::Frame;
use crate::integrate::stability::{self, POWER_ITERATIONS};
use crate::integrate::verlet::ForceTerms;
use crate::model::pmb::PmbLaw;
use crate::scheme::standard::{Linearized, NodeTerms};
use crate::scheme::wls_rows::WlsRows;
use crate::solver::{Adaptation, Clock, Integrator, Param, StableStep, State, Tick};

pub struct LevelScheme<const D: usize> {
    pub grid: MultiAdaptive<D>,
    /// "Adaptive, hybrid" (thesis §3.5): WLS rows of the initially active coarse nodes (the
    /// coarse active set only shrinks); `None` runs the standard scheme on the coarse level.
    pub coarse_wls: Option<WlsRows<D>>,
    /// Coarse bonds broken (the multi-adaptive invariant: damage stays on the fine level).
    pub coarse_broken: u64,
}

impl<const D: usize> LevelScheme<D> {
    /// Appends a refinement's fine nodes to the body and brings them in: the new active
    /// nodes take the coarse solution, the interpolated nodes the other level's.
    fn add_cells(&mut self, body: &mut ElasticBody<D>, growth: &Growth<D>, tick: (u64, f64)) {
        body.grow(growth, &self.grid.fine);
        let g = &mut self.grid;
        let (reference, families, positions, velocities) = body.motion_mut();
        g.activate(tick, growth, families, reference, positions, velocities);
        g.transfer(reference, positions, velocities);
    }

    /// Velocity-Verlet's step from the power-iterated λ_max of the standard levels' active
    /// rows, each with its own quadrature, the levels uncoupled (fictitious nodes free).
    fn lanczos_step(&self, body: &ElasticBody<D>) -> f64 {
        let g = &self.grid;
        let (intact, density) = (&body.intact, body.density);
        let (coarse, fine) = (
            body.level_scheme(Some(&g.coarse)),
            body.level_scheme(Some(&g.fine)),
        );
        let coefficients = self.level_coefficients(body);
        let masses: Vec<f64> = g
            .active_volumes(body.volumes())
            .iter()
            .map(|v| v * density)
            .collect();
        let n = body.positions().len();
        let rows = &g.rows;
        let wls = self.coarse_wls.is_some();
        let lambda_max = stability::max_eigenvalue::<D>(n, &masses, POWER_ITERATIONS, |u, out| {
            out.fill([0.0; D]);
            coarse.apply_linearized_masked(&coefficients, intact, u, out, |i| {
                wls || rows.coarse[i] != 0
            });
            fine.apply_linearized_masked(&coefficients, intact, u, out, |i| rows.fine[i] != 0);
        });
        stability::verlet_step(lambda_max)
    }

    /// Each bond's linearized coefficient with its level's quadrature.
    fn level_coefficients(&self, body: &ElasticBody<D>) -> Linearized {
        let g = &self.grid;
        let (coarse, fine) = (
            body.level_scheme(Some(&g.coarse)),
            body.level_scheme(Some(&g.fine)),
        );
        let split = body.families().offsets[g.coarse_count];
        let mut coefficients = coarse.linearized_coefficients(body.density);
        coefficients[split..].copy_from_slice(&fine.linearized_coefficients(body.density)[split..]);
        Linearized::PerBond(coefficients)
    }

    /// The spectral radius (Arnoldi) of the coupled linearized operator per unit mass on the
    /// standard levels' active rows: the fictitious nodes' values interpolated from the other
    /// level as in a step (a check of the stable step's bound; a WLS coarse level's rows left
    /// out).
    pub fn coupled_spectral_radius(&self, body: &ElasticBody<D>) -> f64 {
        let g = &self.grid;
        let intact = &body.intact;
        let (coarse, fine) = (
            body.level_scheme(Some(&g.coarse)),
            body.level_scheme(Some(&g.fine)),
        );
        let coefficients = self.level_coefficients(body);
        let (rows, wls) = (&g.rows, self.coarse_wls.is_some());
        let n = body.positions().len();
        stability::arnoldi_spectral_radius(n * D, HYBRID_KRYLOV_DIMENSION, |v, out| {
            let mut u = v.as_chunks::<D>().0.to_vec();
            g.interpolate_in_place(&mut u);
            let out = out.as_chunks_mut::<D>().0;
            out.fill([0.0; D]);
            coarse.apply_linearized_masked(&coefficients, intact, &u, out, |i| {
                wls || rows.coarse[i] != 0
            });
            fine.apply_linearized_masked(&coefficients, intact, &u, out, |i| rows.fine[i] != 0);
        })
    }

    /// Node i's level quadrature.
    fn level_of(&self, i: usize) -> &crate::discretization::Quadrature {
        if i < self.grid.coarse_count {
            &self.grid.coarse
        } else {
            &self.grid.fine
        }
    }
}

impl<const D: usize> Adaptation<ElasticBody<D>> for LevelScheme<D> {
    fn stage(&self) -> Option<&'static str> {
        Some("switching")
    }

    /// The multi-adaptive step between drift and forces (seed-thesis-ch2-3 §7 steps 3 and 6):
    /// the interpolated nodes take u^{n+1} and u̇^{n+½} from the other level, then every bond
    /// of an active coarse node is checked and the critical ones refine their neighbourhoods,
    /// before the force pass evaluates damage on u^{n+1}.
    fn after_move(&mut self, body: &mut ElasticBody<D>, tick: Tick) {
        let s0 = body.law.critical_stretch;
        let g = &mut self.grid;
        let (reference, families, positions, velocities) = body.motion_mut();
        g.transfer(reference, positions, velocities);
        let critical = g.critical_bonds(reference, positions, families, s0);
        if let Some(growth) = g.refine(&critical, families) {
            self.add_cells(body, &growth, (tick.step, tick.time));
        }
    }

    /// The grid classes, counts, refinement events and the invariant; the cloud keeps the
    /// active and fictitious nodes, each drawn at its level's size.
    fn frame(&mut self, _body: &ElasticBody<D>, _clock: &Clock, frame: &mut Frame) {
        let g = &mut self.grid;
        let (coarse, fine, fictitious) = g.counts();
        let scalars = [
            ("grid/coarse_active", coarse as f64),
            ("grid/fine_active", fine as f64),
            ("grid/fictitious", fictitious as f64),
            ("grid/refined_by_switch", g.refined_by_switch as f64),
            ("grid/chi", g.chi),
            ("grid/coarse_broken", self.coarse_broken as f64),
        ];
        frame
            .scalars
            .extend(scalars.iter().map(|(n, v)| (n.to_string(), *v)));
        frame
            .events
            .extend(g.take_events().iter().map(|e| e.to_string()));
        frame.classes.push(GridClass::field(&g.class));
        frame.radii = GridClass::radii(&g.class, g.coarse.spacing, g.fine.spacing);
        // In the order of a level built whole, whatever order the fine nodes were made in.
        frame.select_nodes(&g.shown_in_lattice_order());
    }

    fn save(&self, _body: &ElasticBody<D>, state: &mut State) {
        state.put_log("multigrid/refine_log", self.grid.refinements());
        state.put_u64("multigrid/coarse_broken", vec![self.coarse_broken]);
    }

    /// The refinements since the start are replayed on the freshly built levels (the same
    /// cells in the same order give the same nodes and bond layout); the body's columns and
    /// bond states are read after.
    fn restore(&mut self, body: &mut ElasticBody<D>, state: &State) -> Result<(), String> {
        let events = state.log("multigrid/refine_log", "cells")?;
        self.grid.check_refinements(&events)?;
        let coarse_broken = state.u64("multigrid/coarse_broken", 1)?[0];
        if self.grid.refined_by_switch != 0 {
            return Err("refinements can be replayed on freshly built levels only".into());
        }
        for cells in events {
            let cells: Vec<usize> = cells.iter().map(|&c| c as usize).collect();
            let growth = self.grid.replay(&cells, &body.discretization.families);
            self.add_cells(body, &growth, (0, 0.0));
        }
        self.grid.take_events();
        self.coarse_broken = coarse_broken;
        Ok(())
    }

    fn owns_section(&self, section: &str) -> bool {
        section.starts_with("multigrid/")
    }

    fn tune(&mut self, _body: &mut ElasticBody<D>, param: Param) -> Option<Result<(), String>> {
        match param {
            Param::Chi(chi) => Some(crate::scene::check_chi(chi).map(|chi| self.grid.chi = chi)),
            _ => None,
        }
    }
}

impl<const D: usize> ForceTerms<ElasticBody<D>> for LevelScheme<D> {
    /// Each level's active rows with its own quadrature; every neighbour of an active node is
    /// active or fictitious (interpolated before this pass). A WLS coarse level's forces go
    /// to its active nodes' terms.
    fn forces(&mut self, body: &mut ElasticBody<D>, energy: bool) {
        body.energy_current = energy;
        let g = &self.grid;
        if let Some(w) = self.coarse_wls.as_mut() {
            let (reference, _, positions, _) = body.motion_mut();
            // Every row is a coarse node's; the inactive ones are left alone.
            let c = g.coarse_count;
            w.forces(&reference[..c], &positions[..c], |i| g.class[i].is_active());
        }
        if self.coarse_wls.is_none() {
            self.coarse_broken += body.bond_forces(Some(&g.coarse), Some(&g.rows.coarse), energy);
        }
        body.bond_forces(Some(&g.fine), Some(&g.rows.fine), energy);
        if let Some(w) = &self.coarse_wls {
            let coarse = &mut body.terms_mut()[..g.coarse_count];
            coarse.par_iter_mut().enumerate().for_each(|(i, t)| {
                if g.class[i].is_active() {
                    t.force = w.force_of(i);
                }
            });
        }
    }

    fn kick(&mut self, body: &mut ElasticBody<D>, dt: f64) -> f64 {
        body.accelerate(Some(dt), Some(&self.grid.class))
    }
}

impl<const D: usize> ElasticScheme<D> for LevelScheme<D> {
    /// Per node, the damage denominator and pre-cracked numerator of its own level.
    fn damage_weights(
        &self,
        discretization: &Discretization<D>,
        law: &PmbLaw,
        intact: &[u8],
    ) -> (Vec<f64>, Vec<f64>) {
        let g = &self.grid;
        let coarse = standard_over(discretization, law, Some(&g.coarse)).damage_weights(intact);
        let fine = standard_over(discretization, law, Some(&g.fine)).damage_weights(intact);
        let pick = |c: &[f64], f: &[f64]| -> Vec<f64> {
            (0..c.len())
                .map(|i| if i < g.coarse_count { c[i] } else { f[i] })
                .collect()
        };
        (pick(&coarse.0, &fine.0), pick(&coarse.1, &fine.1))
    }

    /// (3.8) over every node of the standard levels, and the sharp limit from each standard
    /// level's lattice symbol: each level's active rows are rows of its lattice's operator
    /// (one volume, its own β), so the symbol bounds each level's λ_max rigorously
    /// (`integrate::lattice_symbol`) at any refinement, and the larger bound sets Δt, without
    /// building or iterating the operator. The levels' coupling (fictitious nodes take convex
    /// IDW combinations of the other level) is outside that argument; the coupled operator's
    /// spectral radius, interpolation included, is checked against the bound on the scenes
    /// (`coupled_spectral_radius`; tests/suite/multiadaptive.rs). With a WLS coarse level its
    /// rows' spectral radius (Arnoldi) bounds Δt too. Off a lattice, Lanczos on the active
    /// rows.
    fn stable_step(&self, body: &ElasticBody<D>) -> StableStep {
        let g = &self.grid;
        let density = body.density;
        let coarse = body.level_scheme(Some(&g.coarse));
        let fine = body.level_scheme(Some(&g.fine));
        let mut guaranteed =
            crate::integrate::stable_step(density, &fine.stiffness_sums()[g.coarse_count..]);
        if self.coarse_wls.is_none() {
            guaranteed = guaranteed.min(crate::integrate::stable_step(
                density,
                &coarse.stiffness_sums()[..g.coarse_count],
            ));
        }
        let scene = &body.scene;
        let reach = |q: &Quadrature| search_radius(scene.family_radius, scene.horizon, q.spacing);
        let fine_bound = symbol_bound(&fine, g.fine_lattice(), reach(&g.fine), density);
        let coarse_bound = match self.coarse_wls {
            Some(_) => Some(0.0),
            None => {
                let points = &body.reference()[..g.coarse_count];
                symbol_bound(&coarse, points, reach(&g.coarse), density)
            }
        };
        let mut sharp = match fine_bound.zip(coarse_bound) {
            Some((f, c)) => stability::verlet_limit(f.max(c)),
            None => self.lanczos_step(body),
        }
        .max(guaranteed);
        if let Some(w) = &self.coarse_wls {
            let rows = &g.rows;
            let radius = stability::arnoldi_spectral_radius(
                g.coarse_count * D,
                HYBRID_KRYLOV_DIMENSION,
                |v, out| {
                    let u = v.as_chunks::<D>().0;
                    let out = out.as_chunks_mut::<D>().0;
                    out.fill([0.0; D]);
                    w.apply_linearized(u, density, out, |i| rows.coarse[i] == 0);
                },
            );
            sharp = sharp.min(stability::verlet_step(radius));
        }
        StableStep {
            sharp,
            guaranteed,
            integrator: Integrator::Verlet,
        }
    }

    fn idle(&self) -> Option<&[GridClass]> {
        Some(&self.grid.class)
    }

    fn mass_volumes<'a>(&self, volumes: &'a [f64]) -> Cow<'a, [f64]> {
        Cow::Owned(self.grid.active_volumes(volumes))
    }

    fn runs_wls(&self, i: usize) -> bool {
        self.coarse_wls.is_some() && i < self.grid.coarse_count
    }

    /// Over node i's own level's family.
    fn energy_density(&self, body: &ElasticBody<D>, i: usize) -> f64 {
        body.level_scheme(Some(self.level_of(i)))
            .energy_density(i, body.positions(), &body.intact)
    }

    /// The levels' families differ: energy densities are evaluated per node.
    fn stale_energy_terms(&self, _body: &ElasticBody<D>) -> Option<Vec<NodeTerms<D>>> {
        None
    }

    fn cell_size(&self, _body: &ElasticBody<D>, i: usize) -> f64 {
        self.level_of(i).spacing
    }

    fn finest_spacing(&self, _body: &ElasticBody<D>) -> f64 {
        self.grid.fine.spacing
    }

    fn transfer(&mut self, body: &mut ElasticBody<D>) {
        let (reference, _, positions, velocities) = body.motion_mut();
        self.grid.transfer(reference, positions, velocities);
    }
}
