//! Adaptive dynamic relaxation (Kilic & Madenci 2010, the method zeng2024 Sect. 4.1 uses for
//! its quasi-static crack opening; the paper gives no formulas, so they follow
//! `seed-002-dual-horizon` §4 [outside seed]): central differences with a unit pseudo time
//! step on a fictitious diagonal density Λ, damped by c from the local stiffness of the last
//! two iterations,
//!
//!   U̇^{n+½} = ((2 − c Δt) U̇^{n−½} + 2 Δt Λ⁻¹ F^n) / (2 + c Δt),   U^{n+1} = U^n + Δt U̇^{n+½},
//!   c^n = 2 √(Uᵀ ¹K U / Uᵀ U),   ¹K_ii = −(F_i^n − F_i^{n−1}) / (Λ_ii Δt U̇_i^{n−½}),
//!
//! and U̇^{½} = (Δt/2) Λ⁻¹ F⁰ at the start. Λ: Madenci's rule Λ_ii ≥ ¼ Δt² Σ_j |K_ij| asks for
//! the stiffness rows; the caller gives a diagonal D of the right shape (a Gershgorin-type row
//! sum) and `scale_density` scales it by the power-iterated largest eigenvalue of D⁻¹K, so the
//! central difference is stable with Δt = 1 by construction (a departure: the scale is measured,
//! not guessed).

use rayon::prelude::*;

/// The margin on the power-iterated λ_max(D⁻¹K) (the iteration approaches it from below).
pub const DENSITY_MARGIN: f64 = 1.1;

/// Damping is capped below 2 (c Δt = 2 would zero the velocity memory).
const MAX_DAMPING: f64 = 1.9;

/// The relaxation state of one body.
#[derive(Debug, Clone)]
pub struct Relaxation {
    /// Λ_ii per particle (one value for both components).
    pub density: Vec<f64>,
    previous_force: Vec<[f64; 2]>,
    started: bool,
    /// The last damping c.
    pub damping: f64,
    /// λ_max(D⁻¹K) the density was scaled by.
    pub lambda: f64,
}

/// Λ = D λ_max(D⁻¹K) / 4 × margin, with Δt = 1.
pub fn scale_density(diagonal: &[f64], lambda_max: f64) -> Vec<f64> {
    diagonal
        .iter()
        .map(|d| d * lambda_max.max(0.0) / 4.0 * DENSITY_MARGIN)
        .collect()
}

impl Relaxation {
    /// A relaxation from rest with density Λ, scaled by `lambda` (kept for rescaling).
    pub fn new(density: Vec<f64>, lambda: f64) -> Relaxation {
        let n = density.len();
        Relaxation {
            density,
            previous_force: vec![[0.0; 2]; n],
            started: false,
            damping: 0.0,
            lambda,
        }
    }

    /// One iteration: advances `velocity` and `displacement` (the current positions) with the
    /// residual `force` (internal + external, N; zero on held components) at the current
    /// positions.
    pub fn iterate(
        &mut self,
        force: &[[f64; 2]],
        velocity: &mut [[f64; 2]],
        positions: &mut [[f64; 2]],
        reference: &[[f64; 2]],
    ) {
        let density = &self.density;
        if !self.started {
            self.started = true;
            velocity
                .par_iter_mut()
                .zip(force)
                .zip(density)
                .for_each(|((v, f), l)| *v = [0.5 * f[0] / l, 0.5 * f[1] / l]);
        } else {
            // c from the local stiffness of the last two iterations.
            let previous = &self.previous_force;
            let [numerator, denominator] = super::ordered_sum(force.len(), |k| {
                let mut n = 0.0;
                let mut d = 0.0;
                for i in 0..2 {
                    let u = positions[k][i] - reference[k][i];
                    let v = velocity[k][i];
                    if v != 0.0 {
                        let stiffness = -(force[k][i] - previous[k][i]) / (density[k] * v);
                        n += u * stiffness * u;
                    }
                    d += u * u;
                }
                [n, d]
            });
            let radicand = if denominator > 0.0 {
                numerator / denominator
            } else {
                0.0
            };
            let c = if radicand > 0.0 {
                (2.0 * radicand.sqrt()).min(MAX_DAMPING)
            } else {
                0.0
            };
            self.damping = c;
            velocity
                .par_iter_mut()
                .zip(force)
                .zip(density)
                .for_each(|((v, f), l)| {
                    for i in 0..2 {
                        v[i] = ((2.0 - c) * v[i] + 2.0 * f[i] / l) / (2.0 + c);
                    }
                });
        }
        positions
            .par_iter_mut()
            .zip(velocity.par_iter())
            .for_each(|(y, v)| {
                y[0] += v[0];
                y[1] += v[1];
            });
        self.previous_force.copy_from_slice(force);
    }
}

/// ‖F‖₂ of the residual over ‖F_ext‖₂ (1 where no load is applied and F ≠ 0).
pub fn residual(force: &[[f64; 2]], external: &[[f64; 2]]) -> f64 {
    let norm = |f: &[[f64; 2]]| {
        let [sum] = super::ordered_sum(f.len(), |k| [f[k][0] * f[k][0] + f[k][1] * f[k][1]]);
        sum.sqrt()
    };
    let (r, e) = (norm(force), norm(external));
    if e > 0.0 {
        r / e
    } else if r > 0.0 {
        1.0
    } else {
        0.0
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A chain of springs fixed at one end and pulled at the other relaxes to the static
    /// solution u_i = i F / k.
    #[test]
    fn a_spring_chain_relaxes_to_its_static_solution() {
        let n = 40;
        let k = 5.0;
        let load = 2.0;
        let reference: Vec<[f64; 2]> = (0..n).map(|i| [i as f64, 0.0]).collect();
        let mut y = reference.clone();
        let mut v = vec![[0.0; 2]; n];
        // Gershgorin row sums: 2k inside, k at the end.
        let diagonal: Vec<f64> = (0..n)
            .map(|i| if i + 1 < n { 2.0 * k } else { k })
            .collect();
        let mut relax = Relaxation::new(scale_density(&diagonal, 4.0 * 1.0), 4.0);
        let forces = |y: &[[f64; 2]]| -> Vec<[f64; 2]> {
            (0..n)
                .map(|i| {
                    if i == 0 {
                        return [0.0; 2];
                    }
                    let u = |j: usize| y[j][0] - j as f64;
                    let mut f = -k * (u(i) - u(i - 1));
                    if i + 1 < n {
                        f += k * (u(i + 1) - u(i));
                    } else {
                        f += load;
                    }
                    [f, 0.0]
                })
                .collect()
        };
        let external: Vec<[f64; 2]> = (0..n)
            .map(|i| if i + 1 == n { [load, 0.0] } else { [0.0; 2] })
            .collect();
        let mut iterations = 0;
        loop {
            let f = forces(&y);
            if residual(&f, &external) < 1e-10 || iterations > 20_000 {
                break;
            }
            relax.iterate(&f, &mut v, &mut y, &reference);
            iterations += 1;
        }
        for (i, yi) in y.iter().enumerate() {
            let exact = i as f64 * load / k;
            assert!(
                (yi[0] - i as f64 - exact).abs() < 1e-8 * (n as f64 * load / k),
                "node {i}"
            );
        }
        assert!(iterations < 5000, "{iterations} iterations");
    }
}
