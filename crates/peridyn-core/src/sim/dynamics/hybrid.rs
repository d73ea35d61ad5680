//! The hybrid configuration as an elastic body's scheme (thesis §3.3): the standard bond loop
//! on Ω_s rows, WLS rows on Ω_w (`adapt::hybrid`), and the switch between them as its plug-in
//! hooks — the check on u^{n+1} after the drift, the interface damping after the kick, the
//! invariant, events and mask in frames, the mask in checkpoints, χ live.

use rayon::prelude::*;

use super::body::ElasticBody;
use super::scheme::{ElasticScheme, standard_stable_step};
use crate::adapt::hybrid::Hybrid;
use crate::adapt::masks::SchemeClass;
use crate::frame::Frame;
use crate::integrate::stability;
use crate::integrate::verlet::ForceTerms;
use crate::scheme::standard::NodeTerms;
use crate::solver::{Adaptation, Clock, Param, StableStep, State, Tick};

/// Krylov vectors (operator applications) for the (non-symmetric) hybrid operator's spectral
/// radius by Arnoldi (200 power iterations before).
pub(super) const HYBRID_KRYLOV_DIMENSION: usize = 40;

pub struct HybridScheme<const D: usize> {
    pub hybrid: Hybrid<D>,
    /// Bonds found broken with an Ω_w end (the hybrid invariant; 0 when it holds).
    pub violations: u64,
}

impl<const D: usize> HybridScheme<D> {
    pub fn new(hybrid: Hybrid<D>) -> HybridScheme<D> {
        HybridScheme {
            hybrid,
            violations: 0,
        }
    }

    /// The hybrid invariant: bonds broken with an Ω_w end. Damage that reached Ω_w (possible
    /// only with a check policy other than every bond every step) switches those nodes at
    /// once; returns how many were found.
    pub fn enforce_invariant(&mut self, body: &ElasticBody<D>, clock: &Clock) -> usize {
        let found = self.hybrid.enforce(
            clock.step(),
            clock.time(),
            &body.intact,
            &body.discretization.families,
        );
        self.violations += found as u64;
        found
    }
}

impl<const D: usize> Adaptation<ElasticBody<D>> for HybridScheme<D> {
    fn stage(&self) -> Option<&'static str> {
        Some("switching")
    }

    /// The check on u^{n+1}, before the force pass evaluates damage on it (seed-thesis-ch2-3
    /// §5 steps 4–5).
    fn after_move(&mut self, body: &mut ElasticBody<D>, tick: Tick) {
        let s0 = body.law.critical_stretch;
        self.hybrid.check(
            tick.step,
            tick.time,
            body.reference(),
            body.positions(),
            body.families(),
            s0,
        );
    }

    fn damp(&mut self, body: &mut ElasticBody<D>, tick: Tick) {
        self.hybrid
            .damp_interface(body.velocities_mut(), tick.dt, tick.stable_dt);
    }

    /// The scheme mask, Ω_s fraction, switching events and the invariant: damage found in Ω_w
    /// switches its nodes here (the frame's body is the one it found it on).
    fn frame(&mut self, body: &ElasticBody<D>, clock: &Clock, frame: &mut Frame) {
        self.enforce_invariant(body, clock);
        let violations = self.violations;
        let h = &mut self.hybrid;
        frame
            .events
            .extend(h.take_events().iter().map(|e| e.to_string()));
        let scalars = [
            ("hybrid/omega_s_fraction", h.standard_fraction()),
            ("hybrid/chi", h.spec.chi),
            ("hybrid/violations", violations as f64),
            ("hybrid/checked_bonds", h.checked_bonds as f64),
            ("hybrid/full_checks", h.full_checks as f64),
            ("hybrid/reused_slacks", h.reused_slacks as f64),
            ("hybrid/filtered_checks", h.filtered_checks as f64),
        ];
        frame
            .scalars
            .extend(scalars.iter().map(|(n, v)| (n.to_string(), *v)));
        frame.classes.push(SchemeClass::field(h.mask(), false));
    }

    fn save(&self, _body: &ElasticBody<D>, state: &mut State) {
        self.hybrid.save(state);
        state.put_u64("hybrid/violations", vec![self.violations]);
    }

    fn restore(&mut self, body: &mut ElasticBody<D>, state: &State) -> Result<(), String> {
        let violations = state.u64("hybrid/violations", 1)?[0];
        self.hybrid.restore(state, &body.discretization.families)?;
        self.violations = violations;
        Ok(())
    }

    fn owns_section(&self, section: &str) -> bool {
        section.starts_with("hybrid/")
    }

    fn tune(&mut self, _body: &mut ElasticBody<D>, param: Param) -> Option<Result<(), String>> {
        match param {
            Param::Chi(chi) => Some(self.hybrid.set_chi(chi)),
            _ => None,
        }
    }
}

impl<const D: usize> ForceTerms<ElasticBody<D>> for HybridScheme<D> {
    /// The PMB bond loop on Ω_s rows, the WLS product on Ω_w, whose forces go to the node
    /// terms (an Ω_w node's bond-loop terms are otherwise never read).
    fn forces(&mut self, body: &mut ElasticBody<D>, energy: bool) {
        body.energy_current = energy;
        body.bond_forces(None, Some(self.hybrid.mask()), energy);
        let h = &mut self.hybrid;
        let (reference, _, positions, _) = body.motion_mut();
        h.wls_forces(reference, positions);
        let h = &self.hybrid;
        body.terms_mut()
            .par_iter_mut()
            .with_min_len(4096)
            .enumerate()
            .for_each(|(i, t)| {
                if let Some(f) = h.wls_force_of(i) {
                    t.force = f;
                }
            });
    }

    fn kick(&mut self, body: &mut ElasticBody<D>, dt: f64) -> f64 {
        body.accelerate::<u8>(Some(dt), None)
    }
}

impl<const D: usize> ElasticScheme<D> for HybridScheme<D> {
    /// The standard scheme's step, and the hybrid operator's spectral radius (Arnoldi): the
    /// WLS blocks are not symmetric and their stencil is tighter than the family's, and (3.8)
    /// does not cover them.
    fn stable_step(&self, body: &ElasticBody<D>) -> StableStep {
        let scheme = body.scheme();
        let (intact, density) = (&body.intact, body.density);
        let mut step = standard_stable_step(&scheme, intact, density);
        let coefficients = scheme.linearized(density);
        let n = body.positions().len();
        let h = &self.hybrid;
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
        step.sharp = step.sharp.min(stability::verlet_step(radius));
        step
    }

    fn runs_wls(&self, i: usize) -> bool {
        self.hybrid.mask()[i] == SchemeClass::Wls
    }

    /// Ω_w nodes have no local energy density from their WLS force (−½ u_i·f_i sums to the
    /// energy only over a whole WLS body): their PMB bond energy over the family, and every
    /// node's where the last pass skipped the sum.
    fn stale_energy_terms(&self, body: &ElasticBody<D>) -> Option<Vec<NodeTerms<D>>> {
        let mask = self.hybrid.mask();
        let current = body.energy_current;
        let skip: Vec<u8> = (0..mask.len())
            .into_par_iter()
            .map(|i| u8::from(current && mask[i] != SchemeClass::Wls))
            .collect();
        Some(body.bond_terms_of(&skip))
    }
}
