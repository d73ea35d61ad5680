//! The multi-adaptive scheme as an elastic body's scheme (thesis §3.5, seed-thesis-ch2-3 §7):
//! two grid levels, each active row run with its own level's quadrature (the coarse level on
//! WLS rows in "adaptive, hybrid"), fictitious nodes interpolated from the other level; its
//! switch as plug-in hooks — transfer and refinement after the drift, grid classes and counts
//! in frames, the refined cells in checkpoints, χ live.

use std::borrow::Cow;

use rayon::prelude::*;

use super::body::{ElasticBody, standard_over};
use super::hybrid::HYBRID_KRYLOV_DIMENSION;
use super::scheme::ElasticScheme;
use crate::adapt::masks::GridClass;
use crate::adapt::multiadaptive::MultiAdaptive;
use crate::discretization::Discretization;
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
        let g = &mut self.grid;
        let s0 = body.law.critical_stretch;
        let (reference, families, positions, velocities) = body.motion_mut();
        g.transfer(reference, positions, velocities);
        let critical = g.critical_bonds(reference, positions, families, s0);
        if !critical.is_empty() {
            g.refine(
                tick.step, tick.time, &critical, families, reference, positions, velocities,
            );
            g.transfer(reference, positions, velocities);
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
        let keep: Vec<bool> = g.class.iter().map(|c| !c.is_inactive()).collect();
        frame.retain_nodes(&keep);
    }

    fn save(&self, _body: &ElasticBody<D>, state: &mut State) {
        state.put_u8("multigrid/refined", self.grid.refined_cells());
        state.put_u64("multigrid/coarse_broken", vec![self.coarse_broken]);
    }

    fn restore(&mut self, body: &mut ElasticBody<D>, state: &State) -> Result<(), String> {
        let refined = state.u8("multigrid/refined", self.grid.coarse_count)?;
        let coarse_broken = state.u64("multigrid/coarse_broken", 1)?[0];
        self.grid
            .restore_refined(refined, &body.discretization.families)?;
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
            w.forces(reference, positions, |i| g.class[i].is_active());
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

    /// (3.8) over every node of the standard levels (any may become active), and the
    /// power-iterated sharp limit of the operator on the initially active standard rows of
    /// both levels (each with its own quadrature). With a WLS coarse level its rows' spectral
    /// radius bounds Δt too ((3.8) does not cover them; the levels' coupling through
    /// fictitious nodes is left out of both estimates).
    fn stable_step(&self, body: &ElasticBody<D>) -> StableStep {
        let g = &self.grid;
        let (intact, density) = (&body.intact, body.density);
        let coarse = body.level_scheme(Some(&g.coarse));
        let fine = body.level_scheme(Some(&g.fine));
        let split = body.families().offsets[g.coarse_count];
        let mut guaranteed =
            crate::integrate::stable_step(density, &fine.stiffness_sums()[g.coarse_count..]);
        if self.coarse_wls.is_none() {
            guaranteed = guaranteed.min(crate::integrate::stable_step(
                density,
                &coarse.stiffness_sums()[..g.coarse_count],
            ));
        }
        let mut coefficients = coarse.linearized_coefficients(density);
        coefficients[split..].copy_from_slice(&fine.linearized_coefficients(density)[split..]);
        let coefficients = Linearized::PerBond(coefficients);
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
        let mut sharp = stability::verlet_step(lambda_max).max(guaranteed);
        if let Some(w) = &self.coarse_wls {
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
