//! The stable step of an explicit scalar integrator on the assembled operator: forward Euler's
//! 2/ρ (diffusion, corrosion) or velocity-Verlet's 2/√λ_max (a wave's ü = L u, λ_max the
//! spectral radius of −L).

use crate::integrate::stability;
use crate::scene::{Scene, StepSize};
use crate::scheme::{ScalarOperator, VectorOperator};
use crate::solver::{Integrator, StableStep};

/// Power iterations for the bound of a (possibly non-symmetric) operator.
const POWER_ITERATIONS: usize = 300;

/// `integrator`'s stable step for `operator` (its rows scaled by `kappa_scale`) and the WLS
/// rows `wls` beside it: Gershgorin discs first; the power iteration (300 operator passes)
/// only when the requested step is above the discs' bound.
pub fn stable_step(
    scene: &Scene,
    n: usize,
    operator: &ScalarOperator,
    kappa_scale: f64,
    wls: Option<&VectorOperator<1>>,
    integrator: Integrator,
) -> StableStep {
    let gershgorin = (kappa_scale * operator.max_absolute_row_sum())
        .max(wls.map_or(0.0, |w| w.max_absolute_row_sum()));
    type Bound = fn(f64) -> f64;
    let (limit, step): (Bound, Bound) = match integrator {
        Integrator::Verlet => (stability::verlet_limit, stability::verlet_step),
        _ => (stability::euler_limit, stability::euler_step),
    };
    let guaranteed = limit(gershgorin);
    let sharp = match scene.time.step {
        StepSize::Absolute(dt) if dt <= guaranteed => guaranteed,
        _ => {
            let radius = stability::spectral_radius(n, POWER_ITERATIONS, |v, out| {
                operator.apply(v, out);
                out.iter_mut().for_each(|o| *o *= kappa_scale);
                if let Some(w) = wls {
                    for (r, &i) in w.rows.iter().enumerate() {
                        out[i as usize] = w.apply_row_with(r, |j| [v[j]])[0];
                    }
                }
            });
            step(radius)
        }
    };
    StableStep {
        sharp,
        guaranteed,
        integrator,
    }
}
