//! The minimum-norm fit of far-field modes to a cloud's nodal values, collapsed into one row
//! (thesis (4.29)–(4.31), (4.80)–(4.82)): V = ψ M⁺ with M⁺ the Moore–Penrose inverse by SVD.
//! seed-thesis-ch4-5 erratum 4: the systems are underdetermined (fewer cloud values than
//! modes), so this is the minimum-norm solution; §3.7: singular values below `cutoff` × σ_max
//! are dropped (LAPACK's RCOND), a stability parameter of its own.

use nalgebra::{Complex, DMatrix, DVector};

/// One fitted row and the conditioning it came from.
#[derive(Debug, Clone, PartialEq)]
pub struct Fit {
    /// ψ M⁺, one entry per row of M (complex; the layer applies its real part, erratum 5).
    pub row: Vec<Complex<f64>>,
    /// σ_max / σ_min over all singular values of M (∞ if one is 0).
    pub condition: f64,
    /// The singular values kept.
    pub rank: usize,
}

/// How the pseudo-inverse treats small singular values σ (relative to σ_max): dropped below
/// `cutoff` (LAPACK's RCOND, seed-thesis-ch4-5 §3.7), and with `tikhonov` = λ > 0 the kept ones
/// inverted as σ/(σ² + (λ σ_max)²) instead of 1/σ (Tikhonov's filter factors: a smooth
/// roll-off where the cut-off is a step; not in the thesis, docs/validation.md "S10's long run").
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Pseudoinverse {
    pub cutoff: f64,
    pub tikhonov: f64,
}

impl Pseudoinverse {
    /// The plain Moore–Penrose inverse with a relative cut-off.
    pub fn cut(cutoff: f64) -> Self {
        Pseudoinverse {
            cutoff,
            tikhonov: 0.0,
        }
    }

    /// What σ contributes to M⁺ (`None`: dropped), σ_max = `largest`.
    fn inverse(&self, value: f64, largest: f64) -> Option<f64> {
        if value <= self.cutoff * largest || value == 0.0 {
            return None;
        }
        let lambda = self.tikhonov * largest;
        Some(value / (value * value + lambda * lambda))
    }
}

/// ψ M⁺ for `matrix` (cloud values × modes) and the mode row `psi` (one entry per mode).
pub fn min_norm_row(
    matrix: DMatrix<Complex<f64>>,
    psi: &[Complex<f64>],
    inverse: Pseudoinverse,
) -> Fit {
    let mut fits = min_norm_rows(matrix, &[psi], inverse);
    fits.swap_remove(0)
}

/// ψ_c M⁺ for every target row ψ_c (one SVD of `matrix` for all of them: a vector field's
/// components share M, (4.162)–(4.166)).
pub fn min_norm_rows(
    matrix: DMatrix<Complex<f64>>,
    targets: &[&[Complex<f64>]],
    inverse: Pseudoinverse,
) -> Vec<Fit> {
    let svd = matrix.svd(true, true);
    let (Some(u), Some(v_t)) = (svd.u.as_ref(), svd.v_t.as_ref()) else {
        unreachable!("the SVD was asked for both factors");
    };
    let sigma = &svd.singular_values;
    let largest = sigma.iter().fold(0.0f64, |a, &s| a.max(s));
    let smallest = sigma.iter().fold(f64::INFINITY, |a, &s| a.min(s));
    let condition = if smallest > 0.0 {
        largest / smallest
    } else {
        f64::INFINITY
    };
    targets
        .iter()
        .map(|psi| {
            // M⁺ = V Σ⁺ Uᴴ, so ψ M⁺ = ((ψ V) Σ⁺) Uᴴ with V = (Vᵀ)ᴴ.
            let psi = DVector::from_column_slice(psi);
            let mut rank = 0;
            let mut row = vec![Complex::new(0.0, 0.0); u.nrows()];
            for (s, &value) in sigma.iter().enumerate() {
                let Some(inverse) = inverse.inverse(value, largest) else {
                    continue;
                };
                rank += 1;
                // (ψ V)_s = Σ_b ψ_b conj(Vᵀ_{s b}).
                let coefficient: Complex<f64> = (0..psi.len())
                    .map(|b| psi[b] * v_t[(s, b)].conj())
                    .sum::<Complex<f64>>()
                    * inverse;
                for (r, out) in row.iter_mut().enumerate() {
                    *out += coefficient * u[(r, s)].conj();
                }
            }
            Fit {
                row,
                condition,
                rank,
            }
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn c(re: f64) -> Complex<f64> {
        Complex::new(re, 0.0)
    }

    /// An underdetermined system: ψ M⁺ reproduces ψ p for every p in M's row space, and the
    /// fitted row is orthogonal to M's null space (minimum norm).
    #[test]
    fn minimum_norm_of_an_underdetermined_fit() {
        // 2 values, 3 modes.
        let m = DMatrix::from_row_slice(2, 3, &[c(1.0), c(2.0), c(0.0), c(0.0), c(1.0), c(1.0)]);
        let psi = [c(1.0), c(1.0), c(1.0)];
        let fit = min_norm_row(m.clone(), &psi, Pseudoinverse::cut(1e-12));
        assert_eq!(fit.rank, 2);
        // The minimum-norm p for data g is Mᴴ(MMᴴ)⁻¹ g, so V = ψ Mᴴ (M Mᴴ)⁻¹: check against it.
        let mh = m.adjoint();
        let gram = (&m * &mh).try_inverse().expect("full row rank");
        let psi_row = DMatrix::from_row_slice(1, 3, &psi);
        let want = psi_row * mh * gram;
        for (got, want) in fit.row.iter().zip(want.iter()) {
            assert!((got - want).norm() < 1e-13, "{got} vs {want}");
        }
    }

    /// Dropping a tiny singular value: the fit then ignores that direction.
    #[test]
    fn cutoff_drops_small_singular_values() {
        let m = DMatrix::from_row_slice(2, 2, &[c(1.0), c(0.0), c(0.0), c(1e-14)]);
        let fit = min_norm_row(m.clone(), &[c(1.0), c(1.0)], Pseudoinverse::cut(1e-10));
        assert_eq!(fit.rank, 1);
        assert!((fit.row[0] - c(1.0)).norm() < 1e-14 && fit.row[1].norm() < 1e-14);
        assert!((fit.condition - 1e14).abs() < 1.0);
        let all = min_norm_row(m, &[c(1.0), c(1.0)], Pseudoinverse::cut(0.0));
        assert_eq!(all.rank, 2);
        assert!((all.row[1] - c(1e14)).norm() < 1.0);
    }

    /// Tikhonov's filter factors: ψ M⁺ becomes ψ (MᴴM + λ²σ_max² I)⁻¹ Mᴴ, checked against that
    /// closed form on a diagonal M (σ = 1 and 0.01, λ = 0.1: factors 1/1.01 and 0.01/0.0101).
    #[test]
    fn tikhonov_rolls_off_small_singular_values() {
        let m = DMatrix::from_row_slice(2, 2, &[c(1.0), c(0.0), c(0.0), c(0.01)]);
        let inverse = Pseudoinverse {
            cutoff: 1e-12,
            tikhonov: 0.1,
        };
        let fit = min_norm_row(m, &[c(1.0), c(1.0)], inverse);
        assert!((fit.row[0] - c(1.0 / 1.01)).norm() < 1e-14, "{:?}", fit.row);
        assert!(
            (fit.row[1] - c(0.01 / (1e-4 + 1e-2))).norm() < 1e-12,
            "{:?}",
            fit.row
        );
    }

    /// Complex modes: a cloud sampled exactly on one mode is extrapolated exactly.
    #[test]
    fn a_sampled_mode_extrapolates_exactly() {
        let k = [0.4, 0.9, 1.3];
        let xs = [0.0, -0.5, -1.0, -1.5, -2.0];
        let mode = |x: f64, kk: f64| Complex::new(0.0, kk * x).exp();
        let m = DMatrix::from_fn(xs.len(), k.len(), |r, b| mode(xs[r], k[b]));
        let psi: Vec<_> = k.iter().map(|&kk| mode(0.7, kk)).collect();
        let fit = min_norm_row(m, &psi, Pseudoinverse::cut(1e-14));
        let data: Vec<_> = xs.iter().map(|&x| 2.0 * mode(x, 0.9)).collect();
        let got: Complex<f64> = fit.row.iter().zip(&data).map(|(v, g)| v * g).sum();
        assert!((got - 2.0 * mode(0.7, 0.9)).norm() < 1e-11, "{got}");
    }
}
