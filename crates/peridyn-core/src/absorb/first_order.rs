//! The conventional first-order absorbing boundary, the baseline the fitted layers are measured
//! against (thesis §4.2.2, (4.63)–(4.75); seed-thesis-ch4-5 §3.4): u̇ + χ ∂_n u + d u = 0 on the
//! truncation. The thesis discretizes it for local FEM only; in a PD layer of width δ every
//! absorbing node takes it, with ∂_n u the least-squares gradient over the node's backward
//! cloud (upwind: the outgoing wave arrives from there), advanced explicitly:
//! u̇_i^{n+1} = −A ∂_n u^n − d u_i^n, u_i^{n+1} = u_i^n + Δt u̇_i^{n+1}.
//! For bond-based PD the same paraxial condition with A = c_P N Nᵀ + c_S T Tᵀ (a plane P wave
//! along N moves at c_P, an S wave at c_S; Clayton–Engquist's first-order condition, the
//! elastic counterpart of (4.75)).

use nalgebra::{DMatrix, DVector};

use super::Clouds;
use super::layer::{AbsorbingLayer, Levels, NodeReport};

/// The first-order layer: `celerity(normal)` is A (components × components, row-major), `damping`
/// is d; the clouds are the fitted layer's (backward cone, radius d∞).
pub(crate) fn first_order_layer<const D: usize>(
    clouds: &Clouds<'_, D>,
    nodes: &[(u32, [f64; D])],
    components: usize,
    dt: f64,
    celerity: impl Fn(&[f64; D]) -> Vec<f64>,
    damping: f64,
) -> AbsorbingLayer {
    let nc = components;
    let mut layer = AbsorbingLayer::empty(Levels::Two, nc);
    layer.rates_from_field = true;
    for (i, normal) in nodes {
        let cloud = clouds.of(*i, normal, 0);
        let x = clouds.positions[*i as usize];
        let (weights, condition) = normal_derivative(clouds.positions, &x, &cloud[1..], normal);
        let a = celerity(normal);
        // Per cloud entry (the node first): 2 levels × nc inputs × nc outputs; level 1 is 0.
        let per_entry = 2 * nc * nc;
        let mut rate = vec![0.0; cloud.len() * per_entry];
        let own: f64 = weights.iter().sum();
        for (e, g) in std::iter::once(-own)
            .chain(weights.iter().copied())
            .enumerate()
        {
            for q in 0..nc {
                for c in 0..nc {
                    let mut w = -a[c * nc + q] * g;
                    if e == 0 && c == q {
                        w -= damping;
                    }
                    rate[e * per_entry + q * nc + c] = w;
                }
            }
        }
        let mut value: Vec<f64> = rate.iter().map(|w| dt * w).collect();
        for q in 0..nc {
            value[q * nc + q] += 1.0;
        }
        let norm = value.iter().fold(0.0f64, |m, w| m.max(w.abs()));
        let report = NodeReport {
            node: *i,
            cloud: cloud.len(),
            modes: 0,
            norm,
            condition,
            rank: D,
        };
        layer.push(*i, &cloud, &value, &rate, report);
    }
    layer
}

/// Weights G_j with ∂_n u(x) ≈ Σ_j G_j (u_j − u(x)) over `cloud`: N·g of the least-squares
/// gradient g = (Σ x̄ x̄ᵀ)⁻¹ Σ x̄ (u_j − u(x)); and cond(Σ x̄ x̄ᵀ). A cloud that does not
/// span D dimensions gets no gradient (zero weights, condition ∞).
fn normal_derivative<const D: usize>(
    positions: &[[f64; D]],
    x: &[f64; D],
    cloud: &[u32],
    normal: &[f64; D],
) -> (Vec<f64>, f64) {
    let offsets: Vec<[f64; D]> = cloud
        .iter()
        .map(|&j| std::array::from_fn(|k| positions[j as usize][k] - x[k]))
        .collect();
    let moment = DMatrix::<f64>::from_fn(D, D, |a, b| offsets.iter().map(|o| o[a] * o[b]).sum());
    let eigen = moment.clone().symmetric_eigenvalues();
    let (lo, hi) = eigen
        .iter()
        .fold((f64::INFINITY, 0.0f64), |(l, h), &v| (l.min(v), h.max(v)));
    let Some(inverse) = moment.try_inverse().filter(|_| lo > 1e-12 * hi) else {
        return (vec![0.0; cloud.len()], f64::INFINITY);
    };
    let n = DVector::from_column_slice(normal);
    let row: DVector<f64> = inverse * n;
    let weights = offsets
        .iter()
        .map(|o| o.iter().zip(row.iter()).map(|(a, b)| a * b).sum::<f64>())
        .collect();
    (weights, hi / lo)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The least-squares normal derivative is exact on linear fields (any cloud spanning 2D).
    #[test]
    fn normal_derivative_is_exact_on_linear_fields() {
        let positions: Vec<[f64; 2]> = vec![[0.0, 0.0], [-1.0, 0.0], [-1.0, 1.0], [-2.0, -1.0]];
        let normal = [0.6, 0.8];
        let (g, cond) = normal_derivative(&positions, &[0.0, 0.0], &[1, 2, 3], &normal);
        let field = |p: &[f64; 2]| 3.0 * p[0] - 2.0 * p[1] + 7.0;
        let got: f64 = [1, 2, 3]
            .iter()
            .zip(&g)
            .map(|(&j, w)| w * (field(&positions[j]) - field(&positions[0])))
            .sum();
        let want = 3.0 * 0.6 - 2.0 * 0.8;
        assert!((got - want).abs() < 1e-12, "{got} vs {want}");
        assert!(cond.is_finite());
    }
}
