//! Dispersion relations of the far field (thesis §4.2–4.3): the frequencies of plane waves
//! exp(i(k N·x − ω t)) on the near field's own lattice quadrature (discrete, thesis (4.85),
//! (4.95), (4.144)–(4.150)), on the continuum PD operator ((4.90), (4.111)) and in the local
//! limit ((4.39), (4.110)). The absorbing layer takes its wave modes' frequencies from the
//! discrete relation: with the continuum or local ones reflections grow (seed-thesis-ch4-5 §3.6).

use crate::discretization::Quadrature;
use crate::model::pmb::{Influence, influence};

/// The offsets ξ of a full lattice family, 0 < ‖ξ‖ ≤ δ (the family of an interior node; the
/// absorbing layer's modes use it even for layer nodes whose own family is cut, thesis §4.2.3).
pub fn lattice_family<const D: usize>(spacing: f64, horizon: f64) -> Vec<[f64; D]> {
    let m = (horizon / spacing).floor() as i64 + 1;
    let limit = horizon * (1.0 + 1e-9);
    let mut out = Vec::new();
    let span = 2 * m + 1;
    let count = span.pow(D as u32);
    for code in 0..count {
        let mut rest = code;
        let xi: [f64; D] = std::array::from_fn(|_| {
            let l = rest % span - m;
            rest /= span;
            l as f64 * spacing
        });
        let r = norm(&xi);
        if r > 0.0 && r <= limit {
            out.push(xi);
        }
    }
    out
}

fn norm<const D: usize>(x: &[f64; D]) -> f64 {
    x.iter().map(|v| v * v).sum::<f64>().sqrt()
}

fn dot<const D: usize>(a: &[f64; D], b: &[f64; D]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}

/// The scalar PD operator L u = Σ_ξ w(ξ) (u(x + ξ) − u(x)) of an interior lattice node, with
/// w = c_s ω(‖ξ‖) β(‖ξ‖) ΔV / ‖ξ‖^p (thesis (3.3), (4.84)): the near field of the diffusion
/// and scalar-wave scenes.
#[derive(Debug, Clone)]
pub struct ScalarLattice<const D: usize> {
    pub offsets: Vec<[f64; D]>,
    pub weights: Vec<f64>,
}

impl<const D: usize> ScalarLattice<D> {
    /// The family of `quadrature`'s lattice with bond weights `kernel(r)` β(r) ΔV.
    pub fn new(quadrature: &Quadrature, kernel: impl Fn(f64) -> f64) -> Self {
        let offsets = lattice_family::<D>(quadrature.spacing, quadrature.horizon);
        let cell = quadrature.spacing.powi(D as i32);
        let weights = offsets
            .iter()
            .map(|xi| {
                let r = norm(xi);
                kernel(r) * quadrature.beta(r) * cell
            })
            .collect();
        ScalarLattice { offsets, weights }
    }

    /// −(L applied to exp(i k N·x)) / exp(i k N·x) = Σ w (1 − cos(k N·ξ)): real, as the family
    /// is symmetric (seed-thesis-ch4-5 §3.6 [derived]); `direction` is the unit N.
    pub fn symbol(&self, k: f64, direction: &[f64; D]) -> f64 {
        self.offsets
            .iter()
            .zip(&self.weights)
            .map(|(xi, w)| w * (1.0 - (k * dot(direction, xi)).cos()))
            .sum()
    }

    /// L applied to the real exponential exp(k N·x), over it: Σ w (cosh(k N·ξ) − 1) (the
    /// discrete rate of a diffusion mode).
    pub fn real_symbol(&self, k: f64, direction: &[f64; D]) -> f64 {
        self.offsets
            .iter()
            .zip(&self.weights)
            .map(|(xi, w)| w * ((k * dot(direction, xi)).cosh() - 1.0))
            .sum()
    }

    /// The undamped frequency √(symbol) of thesis (4.85)/(4.95) with d = 0.
    pub fn frequency(&self, k: f64, direction: &[f64; D]) -> f64 {
        self.symbol(k, direction).max(0.0).sqrt()
    }
}

/// ω̄ of the continuum 1D PD wave with p = 0 and ω0, c_s = 3χ²/δ³ (thesis (4.90), d = 0):
/// ω̄² = 6χ² (kδ − sin kδ) / (kδ³).
pub fn continuum_wave_1d(k: f64, speed_squared: f64, horizon: f64) -> f64 {
    let a = k * horizon;
    if a.abs() < 1e-4 {
        // The series (4.91): 6(a − sin a)/a³ = 1 − a²/20 + …
        return (speed_squared * (1.0 - a * a / 20.0)).sqrt() * k.abs();
    }
    (6.0 * speed_squared * (a - a.sin()) / (k * horizon.powi(3)))
        .max(0.0)
        .sqrt()
}

/// Gauss–Legendre nodes and weights on [0, 1] (n = 20), for the continuum integrals.
fn gauss_unit() -> (Vec<f64>, Vec<f64>) {
    let n = 20;
    let mut nodes = Vec::with_capacity(n);
    let mut weights = Vec::with_capacity(n);
    for i in 0..n {
        // Newton on P_n from the Chebyshev guess.
        let mut x = (std::f64::consts::PI * (i as f64 + 0.75) / (n as f64 + 0.5)).cos();
        let mut dp = 0.0;
        for _ in 0..100 {
            let (mut p0, mut p1) = (1.0, x);
            for j in 2..=n {
                let p2 = ((2 * j - 1) as f64 * x * p1 - (j - 1) as f64 * p0) / j as f64;
                p0 = p1;
                p1 = p2;
            }
            dp = n as f64 * (x * p1 - p0) / (x * x - 1.0);
            let step = p1 / dp;
            x -= step;
            if step.abs() < 1e-16 {
                break;
            }
        }
        nodes.push(0.5 * (1.0 - x));
        weights.push(1.0 / ((1.0 - x * x) * dp * dp));
    }
    (nodes, weights)
}

/// ∫_0^δ ∫_0^{2π} f(r, θ) dθ dr by composite Gauss–Legendre in r (`panels` panels) and the
/// trapezoid rule in θ (spectrally accurate for periodic integrands).
fn polar_integral(horizon: f64, f: impl Fn(f64, f64) -> f64) -> f64 {
    let (gx, gw) = gauss_unit();
    let (panels, angles) = (8, 256);
    let h = horizon / panels as f64;
    let dtheta = std::f64::consts::TAU / angles as f64;
    let mut sum = 0.0;
    for p in 0..panels {
        for (x, w) in gx.iter().zip(&gw) {
            let r = (p as f64 + x) * h;
            let ring: f64 = (0..angles).map(|a| f(r, a as f64 * dtheta)).sum();
            sum += w * h * ring * dtheta;
        }
    }
    sum
}

/// ω̄ of the continuum 2D scalar PD wave with exponent p (thesis (4.43), d = 0):
/// ω̄² = c_s ∫_H ω(r) (1 − cos(k N·ξ)) / r^p dV, along x (the continuum is isotropic).
pub fn continuum_wave_2d(
    k: f64,
    micromodulus: f64,
    exponent: f64,
    kind: Influence,
    horizon: f64,
) -> f64 {
    let s = polar_integral(horizon, |r, theta| {
        influence(kind, r, horizon) * (1.0 - (k * r * theta.cos()).cos()) / r.powf(exponent) * r
    });
    (micromodulus * s).max(0.0).sqrt()
}

/// Frequencies and polarizations of the two plane waves of linearized 2D bond-based PD along a
/// unit direction N (thesis (4.140)–(4.151)).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BondWaves {
    /// The pressure wave (the larger frequency) and its unit polarization.
    pub pressure: (f64, [f64; 2]),
    /// The shear wave and its unit polarization, the pressure one turned by 90°.
    pub shear: (f64, [f64; 2]),
}

/// The eigenpairs of the symmetric 2×2 acoustic matrix M over ρ (thesis (4.148)–(4.151)).
/// seed-thesis-ch4-5 erratum 7: the printed γ_S of (4.151) is not an eigenvector; γ_S is γ_P
/// turned by 90° (M is symmetric), and γ_P lies along the larger diagonal entry if M12 = 0.
pub fn bond_waves(m: [[f64; 2]; 2], density: f64) -> BondWaves {
    let (a, b, c) = (m[0][0], m[0][1], m[1][1]);
    let s = ((a - c).powi(2) + 4.0 * b * b).sqrt();
    let omega_p = ((s + a + c) / (2.0 * density)).max(0.0).sqrt();
    let omega_s = ((a + c - s) / (2.0 * density)).max(0.0).sqrt();
    let gamma = if b.abs() <= 1e-14 * (a.abs() + c.abs()) {
        if a >= c { [1.0, 0.0] } else { [0.0, 1.0] }
    } else {
        let g = [s + a - c, 2.0 * b];
        let n = (g[0] * g[0] + g[1] * g[1]).sqrt();
        [g[0] / n, g[1] / n]
    };
    BondWaves {
        pressure: (omega_p, gamma),
        shear: (omega_s, [-gamma[1], gamma[0]]),
    }
}

/// Linearized 2D bond-based PD on an interior lattice family: bond weights c ω β ΔV / ‖ξ‖³ of
/// the acoustic matrix (4.144)–(4.147).
#[derive(Debug, Clone)]
pub struct BondLattice {
    pub offsets: Vec<[f64; 2]>,
    pub weights: Vec<f64>,
}

impl BondLattice {
    pub fn new(quadrature: &Quadrature, micromodulus: f64, kind: Influence) -> Self {
        let h = quadrature.horizon;
        let inner = ScalarLattice::<2>::new(quadrature, |r| {
            micromodulus * influence(kind, r, h) / r.powi(3)
        });
        BondLattice {
            offsets: inner.offsets,
            weights: inner.weights,
        }
    }

    /// M(k, N) = Σ w ξ⊗ξ (1 − cos(k N·ξ)) (4.144)–(4.147).
    pub fn matrix(&self, k: f64, direction: &[f64; 2]) -> [[f64; 2]; 2] {
        let mut m = [[0.0; 2]; 2];
        for (xi, w) in self.offsets.iter().zip(&self.weights) {
            let f = w * (1.0 - (k * dot(direction, xi)).cos());
            m[0][0] += f * xi[0] * xi[0];
            m[0][1] += f * xi[0] * xi[1];
            m[1][1] += f * xi[1] * xi[1];
        }
        m[1][0] = m[0][1];
        m
    }

    pub fn waves(&self, k: f64, direction: &[f64; 2], density: f64) -> BondWaves {
        bond_waves(self.matrix(k, direction), density)
    }
}

/// The continuum acoustic matrix of linearized 2D bond-based PD (4.111):
/// M_ij = c ∫_H ω n_i n_j (1 − cos(k r N·n)) dr dθ (n the bond's unit direction).
pub fn continuum_bond_matrix(
    k: f64,
    direction: &[f64; 2],
    micromodulus: f64,
    kind: Influence,
    horizon: f64,
) -> [[f64; 2]; 2] {
    let entry = |i: usize, j: usize| {
        micromodulus
            * polar_integral(horizon, |r, theta| {
                let n = [theta.cos(), theta.sin()];
                influence(kind, r, horizon)
                    * n[i]
                    * n[j]
                    * (1.0 - (k * r * dot(direction, &n)).cos())
            })
    };
    let off = entry(0, 1);
    [[entry(0, 0), off], [off, entry(1, 1)]]
}

#[cfg(test)]
mod tests {
    use super::*;

    fn quadrature(spacing: f64, horizon: f64) -> Quadrature {
        Quadrature {
            spacing,
            horizon,
            volume_correction: true,
        }
    }

    /// seed-thesis-ch4-5 §3.9, 1D (p = 0, ω0, χ² = 1, δ = 10; c_s = 3χ²/δ³ (4.87)).
    #[test]
    fn scalar_1d_tables() {
        let delta: f64 = 10.0;
        let cs = 3.0 / delta.powi(3);
        let table = [
            (1.0, 0.09753, [0.10280, 0.09839, 0.09774]),
            (2.0, 0.18089, [0.18717, 0.18189, 0.18114]),
            (std::f64::consts::PI, 0.24495, [0.24495, 0.24495, 0.24495]),
            (5.0, 0.26741, [0.25452, 0.26558, 0.26696]),
        ];
        for (kd, continuum, discrete) in table {
            let k = kd / delta;
            assert!(
                (continuum_wave_1d(k, 1.0, delta) - continuum).abs() < 1e-4,
                "kδ = {kd}"
            );
            for (m, want) in [2.0, 5.0, 10.0].iter().zip(discrete) {
                let lattice = ScalarLattice::<1>::new(&quadrature(delta / m, delta), |_| cs);
                let got = lattice.frequency(k, &[1.0]);
                assert!(
                    (got - want).abs() < 1e-4,
                    "kδ = {kd}, m = {m}: {got} vs {want}"
                );
            }
        }
    }

    /// seed-thesis-ch4-5 §3.9, 2D (p = 2, ω0, χ² = 1, δ = 2, c_s = 4χ²/(πδ²) (4.47)).
    #[test]
    fn scalar_2d_tables() {
        let delta: f64 = 2.0;
        let cs = 4.0 / (std::f64::consts::PI * delta * delta);
        let diagonal = [0.5f64.sqrt(), 0.5f64.sqrt()];
        let table = [
            (1.0, 0.49227, [(0.43869, 0.43958), (0.47963, 0.47954)]),
            (2.0, 0.94013, [(0.83546, 0.84159), (0.91793, 0.91723)]),
            (
                std::f64::consts::PI,
                1.35300,
                [(1.19683, 1.21432), (1.32599, 1.32380)],
            ),
        ];
        for (kd, continuum, discrete) in table {
            let k = kd / delta;
            let c = continuum_wave_2d(k, cs, 2.0, Influence::Constant, delta);
            assert!((c - continuum).abs() < 1e-4, "kδ = {kd}: {c}");
            for (m, (along, diag)) in [2.0, 8.0].iter().zip(discrete) {
                let lattice =
                    ScalarLattice::<2>::new(&quadrature(delta / m, delta), |r| cs / (r * r));
                let (a, d) = (
                    lattice.frequency(k, &[1.0, 0.0]),
                    lattice.frequency(k, &diagonal),
                );
                assert!(
                    (a - along).abs() < 1e-4,
                    "kδ = {kd}, m = {m}: {a} vs {along}"
                );
                assert!(
                    (d - diag).abs() < 1e-4,
                    "kδ = {kd}, m = {m}, π/4: {d} vs {diag}"
                );
            }
        }
    }

    /// seed-thesis-ch4-5 §6 (the BB line below the table): E = ρ = δ = 1, c = 9E/(πδ³), φ = 0.
    #[test]
    fn bond_based_tables() {
        let c = 9.0 / std::f64::consts::PI;
        let along = [1.0, 0.0];
        for (kd, m, p, s) in [
            (1.0, 2.0, 0.96328, 0.49798),
            (1.0, 4.0, 0.97463, 0.57032),
            (1.0, 8.0, 1.00076, 0.58784),
            (std::f64::consts::PI, 4.0, 2.58631, 1.61811),
        ] {
            let waves = BondLattice::new(&quadrature(1.0 / m, 1.0), c, Influence::Constant)
                .waves(kd, &along, 1.0);
            assert!(
                (waves.pressure.0 - p).abs() < 1e-4,
                "kδ = {kd}, m = {m}: {waves:?}"
            );
            assert!(
                (waves.shear.0 - s).abs() < 1e-4,
                "kδ = {kd}, m = {m}: {waves:?}"
            );
            assert_eq!(waves.pressure.1, [1.0, 0.0]);
        }
        for (kd, p, s) in [
            (1.0, 1.03879, 0.60478),
            (std::f64::consts::PI, 2.71464, 1.70586),
        ] {
            let m = continuum_bond_matrix(kd, &along, c, Influence::Constant, 1.0);
            let waves = bond_waves(m, 1.0);
            assert!(
                (waves.pressure.0 - p).abs() < 1e-4,
                "continuum kδ = {kd}: {waves:?}"
            );
            assert!(
                (waves.shear.0 - s).abs() < 1e-4,
                "continuum kδ = {kd}: {waves:?}"
            );
        }
        // The local limit (4.110) with ν = 1/3: √(9E/8ρ) k and √(3E/8ρ) k; Table 4.2 N = 2.
        for kd in [1.0, std::f64::consts::PI] {
            let local = ((9.0f64 / 8.0).sqrt() * kd, (3.0f64 / 8.0).sqrt() * kd);
            assert!((local.0 - [1.06066, 3.33216][(kd > 2.0) as usize]).abs() < 1e-4);
            assert!((local.1 - [0.61237, 1.92382][(kd > 2.0) as usize]).abs() < 1e-4);
            let small = 1e-2 * kd;
            let waves = bond_waves(
                continuum_bond_matrix(small, &along, c, Influence::Constant, 1.0),
                1.0,
            );
            let series = (9.0f64 / 8.0).sqrt() * small * (1.0 - small * small / 24.0).sqrt();
            assert!(
                (waves.pressure.0 / series - 1.0).abs() < 1e-8,
                "{waves:?} vs {series}"
            );
        }
    }

    /// Off the axes the polarizations are orthonormal eigenvectors of M (erratum 7's recipe).
    #[test]
    fn bond_polarizations_are_eigenvectors() {
        let lattice = BondLattice::new(&quadrature(0.25, 1.0), 1.0, Influence::Constant);
        for phi in [0.3f64, 0.7, 1.2, 2.5] {
            let n = [phi.cos(), phi.sin()];
            let m = lattice.matrix(1.7, &n);
            let w = bond_waves(m, 2.0);
            for (omega, g) in [w.pressure, w.shear] {
                let mg = [
                    m[0][0] * g[0] + m[0][1] * g[1],
                    m[1][0] * g[0] + m[1][1] * g[1],
                ];
                let lambda = 2.0 * omega * omega;
                assert!(
                    (mg[0] - lambda * g[0]).abs() < 1e-12 && (mg[1] - lambda * g[1]).abs() < 1e-12
                );
            }
            assert!(
                (w.pressure.1[0] * w.shear.1[0] + w.pressure.1[1] * w.shear.1[1]).abs() < 1e-15
            );
        }
    }
}
