//! The analytic PD integrals of the WLS scheme: the weight (3.26), the radial and angular
//! moments over the ball, and the L operators of diffusion, bond-based elasticity and the
//! linearized LPS terms (seed-thesis-ch2-3 §3.5; seed-004 §2.5).

use super::*;

/// WLS weight (3.26), w̄(d) = (1 − e^{64 − 16 d²/r̄²})/(1 − e^{64}), in the equivalent form
/// (e^{−16 d²/r̄²} − e^{−64})/(1 − e^{−64}) that does not overflow.
pub fn weight(d: f64, r_max: f64) -> f64 {
    weight_with(PAPERS_WEIGHT_EXPONENT, d, r_max)
}

/// The weight (3.26) with exponent a in place of 16: (e^{−a d²/r̄²} − e^{−4a})/(1 − e^{−4a}),
/// so that w̄(0) = 1 and w̄(2 r̄) = 0 as in the papers' form.
pub fn weight_with(a: f64, d: f64, r_max: f64) -> f64 {
    let floor = (-4.0 * a).exp();
    ((-a * d * d / (r_max * r_max)).exp() - floor) / (1.0 - floor)
}

/// Radial moment R(s) = ∫_0^δ ω(r) r^s dr (seed-thesis-ch2-3 §3.5), s > −1.
pub fn radial_moment(s: f64, horizon: f64, influence: Influence) -> f64 {
    match influence {
        Influence::Constant => horizon.powf(s + 1.0) / (s + 1.0),
        Influence::Linear => horizon.powf(s + 1.0) / ((s + 1.0) * (s + 2.0)),
    }
}

/// Γ(m/2) for a whole m ≥ 1.
pub(super) fn gamma_half(m: u32) -> f64 {
    let (mut x, mut g) = if m.is_multiple_of(2) {
        (1.0, 1.0) // Γ(1)
    } else {
        (0.5, std::f64::consts::PI.sqrt()) // Γ(1/2)
    };
    while (2.0 * x) < m as f64 {
        g *= x;
        x += 1.0;
    }
    g
}

/// Angular moment S(β) = ∫ over the unit sphere of θ^β (seed-thesis-ch2-3 §3.5): 2 Π Γ((β_i+1)/2) /
/// Γ((|β|+n_d)/2) if every β_i is even, else 0; in 1D, 2 for even β.
pub fn angular_moment(beta: [u32; 3], dim: usize) -> f64 {
    if beta[..dim].iter().any(|b| b % 2 == 1) {
        return 0.0;
    }
    let total: u32 = beta[..dim].iter().sum();
    2.0 * beta[..dim]
        .iter()
        .map(|&b| gamma_half(b + 1))
        .product::<f64>()
        / gamma_half(total + dim as u32)
}

/// One L entry per monomial of degree n ≥ 1; the constant monomial gives 0
/// (seed-thesis-ch2-3 §3.5).
pub(super) fn per_monomial(basis: &Basis, entry: impl Fn([u32; 3], u32) -> f64) -> Vec<f64> {
    basis
        .exponents
        .iter()
        .map(|&alpha| {
            let n: u32 = alpha.iter().sum();
            if n == 0 { 0.0 } else { entry(alpha, n) }
        })
        .collect()
}

/// L_C of diffusion with kernel κ ω ‖ξ‖^{−q} (3.60)–(3.67): L_C[α] = κ R(n − q + n_d − 1) S(α).
pub fn diffusion_l(
    basis: &Basis,
    kappa: f64,
    q: f64,
    horizon: f64,
    influence: Influence,
) -> Vec<f64> {
    let nd = basis.dim as f64;
    per_monomial(basis, |alpha, n| {
        kappa
            * radial_moment(n as f64 - q + nd - 1.0, horizon, influence)
            * angular_moment(alpha, basis.dim)
    })
}

/// Blocks [k][l][α] = factor · R(n + n_d − 1 − p) S(α + e_k + e_l) of a pair kernel
/// factor · ω ξ⊗ξ/‖ξ‖^(1+p) acting on (u' − u) (seed-thesis-ch2-3 §3.5).
pub(super) fn pair_l(
    basis: &Basis,
    factor: f64,
    p: f64,
    horizon: f64,
    influence: Influence,
) -> Vec<Vec<Vec<f64>>> {
    let d = basis.dim;
    (0..d)
        .map(|k| {
            (0..d)
                .map(|l| {
                    per_monomial(basis, |alpha, n| {
                        let mut beta = alpha;
                        beta[k] += 1;
                        beta[l] += 1;
                        factor
                            * radial_moment(n as f64 + d as f64 - 1.0 - p, horizon, influence)
                            * angular_moment(beta, d)
                    })
                })
                .collect()
        })
        .collect()
}

/// L blocks of linearized bond-based elasticity (3.54)–(3.56): entry [k][l][α] is the
/// coefficient of the α-monomial of displacement component l in force component k,
/// c R(n + n_d − 2) S(α + e_k + e_l) (kernel c ω ξ⊗ξ/‖ξ‖³).
pub fn bond_l(basis: &Basis, c: f64, horizon: f64, influence: Influence) -> Vec<Vec<Vec<f64>>> {
    pair_l(basis, c, 1.0, horizon, influence)
}

/// Weighted volume m̄ = ∫_H ω ‖ξ‖² dV (LPS).
pub fn weighted_volume(dim: usize, horizon: f64, influence: Influence) -> f64 {
    radial_moment(dim as f64 + 1.0, horizon, influence) * angular_moment([0; 3], dim)
}

/// L_J of the linearized LPS shear term J = ∫ 30G/m̄ ω ξ⊗ξ/‖ξ‖² (u' − u) dV (seed-004 §2.5,
/// thesis (3.51)): entry [k][l][α] = 30G/m̄ R(n + n_d − 1) S(α + e_k + e_l) — "seed-004 (51) with
/// λ → 6G" (u = (x², 0, 0) gives 6G).
pub fn lps_shear_l(
    basis: &Basis,
    shear_modulus: f64,
    horizon: f64,
    influence: Influence,
) -> Vec<Vec<Vec<f64>>> {
    let factor = 30.0 * shear_modulus / weighted_volume(basis.dim, horizon, influence);
    pair_l(basis, factor, 0.0, horizon, influence)
}

/// L_θ of the linearized dilatation θ = 3/m̄ ∫ ω ξ·(u' − u) dV: entry [l][α] =
/// 3/m̄ R(n + n_d) S(α + e_l). With the 3/m̄ prefactor (seed-thesis-ch2-3 erratum 3; seed-004 §2.5)
/// the C² rows are exactly 1 at the linear monomials: θ = a_x + a_y + a_z.
pub fn lps_dilatation_l(basis: &Basis, horizon: f64, influence: Influence) -> Vec<Vec<f64>> {
    let d = basis.dim;
    let factor = 3.0 / weighted_volume(d, horizon, influence);
    (0..d)
        .map(|l| {
            per_monomial(basis, |alpha, n| {
                let mut beta = alpha;
                beta[l] += 1;
                factor
                    * radial_moment(n as f64 + d as f64, horizon, influence)
                    * angular_moment(beta, d)
            })
        })
        .collect()
}

/// L_I of the dilatation term I = ∫ (3K − 5G)/m̄ ω (θ + θ') ξ dV fitted on the nodal θ
/// (seed-004 §2.5; seed-thesis-ch2-3 erratum 2: (3.51)'s first term reads L_I Q_i Θ_i): entry
/// [k][α] = (3K − 5G)/m̄ R(n + n_d) S(α + e_k), = (3K − 5G)/3 at α = e_k.
pub fn lps_dilatation_force_l(
    basis: &Basis,
    bulk_modulus: f64,
    shear_modulus: f64,
    horizon: f64,
    influence: Influence,
) -> Vec<Vec<f64>> {
    let scale = (3.0 * bulk_modulus - 5.0 * shear_modulus) / 3.0;
    lps_dilatation_l(basis, horizon, influence)
        .into_iter()
        .map(|row| row.into_iter().map(|v| v * scale).collect())
        .collect()
}
