//! Which scheme computes which node's force in an elastic body: the [`ElasticScheme`] contract,
//! and its plainest form, the standard scheme on every row ([`Uniform`]). The hybrid
//! (`super::hybrid`) and the two-level multi-adaptive scheme (`super::levels`) implement it too;
//! each is also the plug-in of its own switch (`Adaptation` hooks).

use std::borrow::Cow;

use super::body::{ElasticBody, standard_over};
use crate::adapt::masks::GridClass;
use crate::discretization::Discretization;
use crate::integrate::lattice_symbol::{LatticeSymbol, on_lattice};
use crate::integrate::stability::{self, POWER_ITERATIONS};
use crate::integrate::verlet::ForceTerms;
use crate::model::pmb::PmbLaw;
use crate::scheme::standard::{NodeTerms, Standard};
use crate::solver::{Adaptation, Integrator, StableStep};

/// A scheme of an elastic body: its forces and second kick (`ForceTerms`), its switch's
/// hooks (`Adaptation`), and what frames, checkpoints and the stable step need to know of it.
pub trait ElasticScheme<const D: usize>: ForceTerms<ElasticBody<D>> {
    /// Per node, the damage denominator Σ β V'_j and the pre-cracked numerator (2.36).
    fn damage_weights(
        &self,
        discretization: &Discretization<D>,
        law: &PmbLaw,
        intact: &[u8],
    ) -> (Vec<f64>, Vec<f64>) {
        standard_over(discretization, law, None).damage_weights(intact)
    }

    /// Velocity-Verlet's stable step on this scheme's linearized operator.
    fn stable_step(&self, body: &ElasticBody<D>) -> StableStep;

    /// The nodes that are not integrated (their ü is 0, they carry no mass and no damage is
    /// shown on them); `None`: every node is.
    fn idle(&self) -> Option<&[GridClass]> {
        None
    }

    /// Each node's volume where it carries mass.
    fn mass_volumes<'a>(&self, volumes: &'a [f64]) -> Cow<'a, [f64]> {
        Cow::Borrowed(volumes)
    }

    /// Whether node i's force comes from a WLS row (its bond-loop terms are not kept).
    fn runs_wls(&self, _i: usize) -> bool {
        false
    }

    /// Strain-energy density W_i of one node (J/m³) over the family its scheme sums.
    fn energy_density(&self, body: &ElasticBody<D>, i: usize) -> f64 {
        body.scheme()
            .energy_density(i, body.positions(), &body.intact)
    }

    /// The bond loop's terms, energy densities included, of the rows whose W_i the last
    /// force pass did not leave, from the force loop run again on those rows over a copy of
    /// the bond states (nothing of the body changes: the last pass broke every bond at s0 at
    /// these positions, so the copy breaks none). `None` where every W_i is current, or where
    /// [`Self::energy_density`] is to be asked per node.
    fn stale_energy_terms(&self, body: &ElasticBody<D>) -> Option<Vec<NodeTerms<D>>> {
        if body.energy_current {
            return None;
        }
        Some(body.bond_terms_of(&vec![0; body.positions().len()]))
    }

    /// The cell size of node i (the region metrics weigh each node by its cell's share).
    fn cell_size(&self, body: &ElasticBody<D>, _i: usize) -> f64 {
        body.scene.spacing
    }

    /// The spacing of the finest level (the crack-path metric links nearest neighbours).
    fn finest_spacing(&self, body: &ElasticBody<D>) -> f64 {
        body.scene.spacing
    }

    /// Brings the nodes whose motion another level defines up to date (after positions were
    /// set by hand).
    fn transfer(&mut self, _body: &mut ElasticBody<D>) {}
}

/// The standard scheme on every row.
pub struct Uniform;

impl<const D: usize> Adaptation<ElasticBody<D>> for Uniform {}

impl<const D: usize> ForceTerms<ElasticBody<D>> for Uniform {
    fn forces(&mut self, body: &mut ElasticBody<D>, energy: bool) {
        body.energy_current = energy;
        body.bond_forces::<u8>(None, None, energy);
    }

    fn kick(&mut self, body: &mut ElasticBody<D>, dt: f64) -> f64 {
        body.accelerate::<u8>(Some(dt), None)
    }
}

impl<const D: usize> ElasticScheme<D> for Uniform {
    fn stable_step(&self, body: &ElasticBody<D>) -> StableStep {
        standard_stable_step(&body.scheme(), &body.intact, body.density)
    }
}

/// The lattice symbol's bound is within this share above its supremum (Δt 0.05 % below).
const SYMBOL_TOLERANCE: f64 = 1e-3;
/// Boxes the symbol's branch and bound may evaluate before Lanczos is used instead (a 3D
/// family of 122 offsets needs about 90 000).
const SYMBOL_EVALUATIONS: usize = 2_000_000;

/// The bound of the standard scheme's linearized operator's λ_max from the symbol of the
/// infinite lattice `points` lie on (`integrate::lattice_symbol`): every node of one volume, on
/// the lattice of the quadrature's spacing, its offsets reaching `reach` (the longest bond).
/// `None` off a lattice or where the branch and bound does not settle.
pub(super) fn symbol_bound<const D: usize>(
    scheme: &Standard<'_, D>,
    points: &[[f64; D]],
    reach: f64,
    density: f64,
) -> Option<f64> {
    let volume = scheme.uniform_volume?;
    let spacing = scheme.quadrature.spacing;
    if !on_lattice(points, spacing) {
        return None;
    }
    LatticeSymbol::<D>::of_bonds(spacing, reach, |l| {
        scheme.linearized_coefficient(density, l, volume)
    })?
    .max_eigenvalue_bound(SYMBOL_TOLERANCE, SYMBOL_EVALUATIONS)
}

/// The stable step of velocity-Verlet on the standard scheme's linearized operator: the sharp
/// limit (the lattice symbol's bound on a lattice, else Lanczos's estimate with a margin),
/// never below the guaranteed (3.8).
pub(super) fn standard_stable_step<const D: usize>(
    scheme: &Standard<'_, D>,
    intact: &[u8],
    density: f64,
) -> StableStep {
    let n = scheme.reference.len();
    let gershgorin_dt = crate::integrate::stable_step(density, &scheme.stiffness_sums());
    // On a lattice the infinite lattice's symbol bounds λ_max from above (rigorous: no
    // margin, and milliseconds instead of 26–55 applications of the operator). Elsewhere
    // Lanczos approaches λ_max from below: keep a margin.
    let lambda_bound = symbol_bound(scheme, scheme.reference, scheme.families.longest(), density)
        .unwrap_or_else(|| {
            let masses: Vec<f64> = scheme.volumes.iter().map(|v| v * density).collect();
            let coefficients = scheme.linearized(density);
            let lambda = stability::max_eigenvalue::<D>(n, &masses, POWER_ITERATIONS, |u, out| {
                scheme.apply_linearized(&coefficients, intact, u, out)
            });
            lambda * stability::SPECTRAL_MARGIN
        });
    StableStep {
        sharp: stability::verlet_limit(lambda_bound).max(gershgorin_dt),
        guaranteed: gershgorin_dt,
        integrator: Integrator::Verlet,
    }
}
