//! Absorbing layers at the truncation of unbounded domains (thesis Chapter 4;
//! seed-thesis-ch4-5 §1–§4): the far field's dispersion relations, the minimum-norm fit of
//! its modes, and the layer's precomputed update rows; the layers of the scalar equations
//! (diffusion (§4.1), scalar waves (§4.2): `scalar_layer`) and of bond-based PD (§4.3:
//! `bond_layer`), built from a scene. The simulations call them through thin plug-ins.

pub mod bond_layer;
pub mod dispersion;
pub mod first_order;
pub mod fit;
pub mod layer;
pub mod scalar_layer;

pub use dispersion::{BondLattice, ScalarLattice};
pub use fit::Pseudoinverse;
pub use layer::{AbsorbingLayer, CloudSpec, Levels, Mode, NodeReport};

use nalgebra::Complex;

use crate::discretization::Families;
use crate::scene::{AbsorbingSpec, Dispersion, Solid, WaveNumberSet};

/// The scalar far field a layer's modes solve.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum ScalarFarField {
    /// Ċ = L C: real modes exp(k N·x + ω̄ t), k < 0 (4.25); `diffusivity` D for local modes.
    Diffusion { diffusivity: f64 },
    /// ü = L u − 2 d u̇: outgoing modes e^{−dt} exp(i(k N·x − ω̃ t)) (4.53), (4.57); χ² for
    /// local modes.
    Wave { speed_squared: f64, damping: f64 },
}

/// The nodes within `width` of the truncation surface (strictly: a node whose whole family
/// lies inside is not absorbing) and their unit outward normals.
pub fn layer_nodes<const D: usize>(
    solid: &Solid,
    positions: &[[f64; D]],
    width: f64,
    eps: f64,
) -> Vec<(u32, [f64; D])> {
    positions
        .iter()
        .enumerate()
        .filter_map(|(i, x)| {
            let (distance, normal) = solid.truncation(x, width)?;
            (distance < width - eps).then(|| (i as u32, std::array::from_fn(|k| normal[k])))
        })
        .collect()
}

/// The mode directions about an outward normal: diffusion's first quadrant of the frame
/// turned by θ_n − π/4 ((4.22), (4.24)), the waves' θ_n + [−Δφ, Δφ] ((4.56)).
fn directions<const D: usize>(
    normal: &[f64; D],
    spec: &AbsorbingSpec,
    wave: bool,
) -> Vec<[f64; D]> {
    if D == 1 {
        return vec![*normal];
    }
    let theta = normal[1].atan2(normal[0]);
    let (start, span) = if wave {
        (theta - spec.spread, 2.0 * spec.spread)
    } else {
        (
            theta - std::f64::consts::FRAC_PI_4,
            std::f64::consts::FRAC_PI_2,
        )
    };
    let n = spec.directions;
    (0..n)
        .map(|l| {
            let phi = if n == 1 {
                theta
            } else {
                start + span * l as f64 / (n - 1) as f64
            };
            std::array::from_fn(|k| if k == 0 { phi.cos() } else { phi.sin() })
        })
        .collect()
}

/// The wave numbers: diffusion k ∈ Δk·[−1, 0) (4.25); waves (0, Δk] (4.154, erratum 6) or the
/// printed symmetric [−Δk, Δk] (4.56).
fn wave_numbers(spec: &AbsorbingSpec, wave: bool) -> Vec<f64> {
    let (n, dk) = (spec.wave_numbers, spec.max_wave_number);
    (0..n)
        .map(|m| match (wave, spec.wave_number_set) {
            (false, _) => -dk + dk * m as f64 / n as f64,
            (true, WaveNumberSet::Positive) => dk * (m + 1) as f64 / n as f64,
            (true, WaveNumberSet::Symmetric) if n == 1 => 0.0,
            (true, WaveNumberSet::Symmetric) => -dk + 2.0 * dk * m as f64 / (n - 1) as f64,
        })
        .collect()
}

/// The modes of one absorbing node with outward normal `normal`.
pub fn scalar_modes<const D: usize>(
    normal: &[f64; D],
    spec: &AbsorbingSpec,
    lattice: &ScalarLattice<D>,
    far: ScalarFarField,
) -> Vec<Mode<D>> {
    let wave = matches!(far, ScalarFarField::Wave { .. });
    let ks = wave_numbers(spec, wave);
    let mut modes = Vec::new();
    for n in directions(normal, spec, wave) {
        for &k in &ks {
            let mode = match far {
                ScalarFarField::Diffusion { diffusivity } => {
                    // Discrete: L exp(k N·x) = Σ w (cosh(k N·ξ) − 1) exp(k N·x).
                    let rate = match spec.dispersion {
                        Dispersion::Local => diffusivity * k * k,
                        Dispersion::Discrete => lattice.real_symbol(k, &n),
                    };
                    Mode {
                        wave_vector: std::array::from_fn(|c| Complex::new(k * n[c], 0.0)),
                        rate: Complex::new(rate, 0.0),
                        polarization: None,
                    }
                }
                ScalarFarField::Wave {
                    speed_squared,
                    damping,
                } => {
                    let symbol = match spec.dispersion {
                        Dispersion::Local => speed_squared * k * k,
                        Dispersion::Discrete => lattice.symbol(k, &n),
                    };
                    // ω̃ = √(S − d²), the principal root (non-oscillating below d², harmless).
                    let omega = Complex::new(symbol - damping * damping, 0.0).sqrt();
                    Mode {
                        wave_vector: std::array::from_fn(|c| Complex::new(0.0, k * n[c])),
                        rate: Complex::new(-damping, 0.0) - Complex::new(0.0, 1.0) * omega,
                        polarization: None,
                    }
                }
            };
            modes.push(mode);
        }
    }
    // The rest states: k = 0 has s = 0 and, damped, s = −2d ((4.53) with ω̃ = ±i d). No
    // outgoing mode reproduces them exactly, and a layer whose weights do not sum to one makes
    // a uniform offset (the 2D wave's slowly decaying tail) grow (docs/validation.md).
    if spec.rest_modes {
        let rest = |s: f64| Mode {
            wave_vector: [Complex::new(0.0, 0.0); D],
            rate: Complex::new(s, 0.0),
            polarization: None,
        };
        modes.push(rest(0.0));
        if let ScalarFarField::Wave { damping, .. } = far
            && damping > 0.0
        {
            modes.push(rest(-2.0 * damping));
        }
    }
    modes
}

/// The cloud of absorbing node `i`: itself, then the family members within d∞ (behind it in
/// the backward cone (4.86) if `spec.cone`), thinned to every 2^thin-th lattice offset.
fn cloud<const D: usize>(
    i: u32,
    normal: &[f64; D],
    positions: &[[f64; D]],
    families: &Families,
    spec: &AbsorbingSpec,
    spacing: f64,
    thin: u32,
) -> Vec<u32> {
    let x = positions[i as usize];
    let stride = 1i64 << thin;
    let mut out = vec![i];
    let row = families.offsets[i as usize]..families.offsets[i as usize + 1];
    for e in row {
        if families.length(i as usize, e) > spec.cloud_radius * (1.0 + 1e-9) {
            continue;
        }
        let j = families.neighbors[e];
        let rel: [f64; D] = std::array::from_fn(|k| positions[j as usize][k] - x[k]);
        let r = families.length(i as usize, e);
        let ahead: f64 = rel.iter().zip(normal).map(|(a, b)| a * b).sum();
        if spec.cone && -ahead <= r * spec.spread.sin() + 1e-12 * r {
            continue;
        }
        let on_stride = rel
            .iter()
            .all(|v| ((v / spacing).round() as i64).rem_euclid(stride) == 0);
        if on_stride {
            out.push(j);
        }
    }
    out
}

/// The fitted layer of a scalar scene: modes and clouds per node, one SVD per fitted row;
/// with `spec.thinning`, a node whose ‖V‖ or cond(M) exceeds its limit gets its cloud thinned
/// (density halved along the axes, up to 3 times; thesis Fig. 4.23).
#[allow(clippy::too_many_arguments)]
pub fn fit_scalar_layer<const D: usize>(
    spec: &AbsorbingSpec,
    nodes: &[(u32, [f64; D])],
    positions: &[[f64; D]],
    families: &Families,
    lattice: &ScalarLattice<D>,
    far: ScalarFarField,
    spacing: f64,
    dt: f64,
) -> AbsorbingLayer {
    let levels = match far {
        ScalarFarField::Diffusion { .. } => Levels::One,
        ScalarFarField::Wave { .. } => Levels::Two,
    };
    let clouds = Clouds {
        spec,
        positions,
        families,
        spacing,
    };
    clouds.fit(nodes, levels, dt, |n| scalar_modes(n, spec, lattice, far))
}

/// The fitted layer of linearized 2D bond-based PD (thesis §4.3.3): per (φ_l, k_m) an outgoing
/// pressure and shear mode (seed-thesis-ch4-5 erratum 14: both, so 2 n_φ n_k columns), fitted
/// on two levels for u and u̇ ((4.162)–(4.166)).
#[allow(clippy::too_many_arguments)]
pub fn fit_bond_layer<const D: usize>(
    spec: &AbsorbingSpec,
    nodes: &[(u32, [f64; D])],
    positions: &[[f64; D]],
    families: &Families,
    far: &BondFarField,
    spacing: f64,
    dt: f64,
) -> AbsorbingLayer {
    let clouds = Clouds {
        spec,
        positions,
        families,
        spacing,
    };
    clouds.fit(nodes, Levels::Two, dt, |n| {
        bond_modes(&[n[0], n[1]], spec, far)
            .into_iter()
            .map(|m| Mode {
                wave_vector: std::array::from_fn(|k| m.wave_vector[k]),
                rate: m.rate,
                polarization: m.polarization.map(|g| std::array::from_fn(|k| g[k])),
            })
            .collect()
    })
}

/// The far field of linearized 2D bond-based PD: its lattice, density and the local wave
/// speeds (4.110) for `dispersion = "local"`.
#[derive(Debug, Clone)]
pub struct BondFarField {
    pub lattice: BondLattice,
    pub density: f64,
    /// (c_P, c_S) of the local limit.
    pub speeds: (f64, f64),
}

/// The outgoing P and S modes of one absorbing node: ψ = γ exp(i(k N·x̄ − ω t̄)), ‖γ‖ = 2
/// (4.103), ω and γ from the discrete acoustic matrix (4.144)–(4.151) (erratum 7) or the local
/// limit (4.110).
pub fn bond_modes(normal: &[f64; 2], spec: &AbsorbingSpec, far: &BondFarField) -> Vec<Mode<2>> {
    let mut modes = Vec::new();
    for n in directions(normal, spec, true) {
        for &k in &wave_numbers(spec, true) {
            let waves = match spec.dispersion {
                Dispersion::Discrete => far.lattice.waves(k, &n, far.density),
                Dispersion::Local => dispersion::BondWaves {
                    pressure: (far.speeds.0 * k.abs(), n),
                    shear: (far.speeds.1 * k.abs(), [-n[1], n[0]]),
                },
            };
            for (omega, gamma) in [waves.pressure, waves.shear] {
                modes.push(Mode {
                    wave_vector: [Complex::new(0.0, k * n[0]), Complex::new(0.0, k * n[1])],
                    rate: Complex::new(0.0, -omega),
                    polarization: Some([2.0 * gamma[0], 2.0 * gamma[1]]),
                });
            }
        }
    }
    // The rest states (k = 0): the two rigid translations, u = γ, u̇ = 0 (as the scalar rest
    // mode; not in the thesis).
    if spec.rest_modes {
        for gamma in [[2.0, 0.0], [0.0, 2.0]] {
            modes.push(Mode {
                wave_vector: [Complex::new(0.0, 0.0); 2],
                rate: Complex::new(0.0, 0.0),
                polarization: Some(gamma),
            });
        }
    }
    modes
}

/// What the clouds of a layer are taken from.
pub(crate) struct Clouds<'a, const D: usize> {
    pub spec: &'a AbsorbingSpec,
    pub positions: &'a [[f64; D]],
    pub families: &'a Families,
    pub spacing: f64,
}

impl<const D: usize> Clouds<'_, D> {
    /// The cloud of absorbing node `i` with outward normal `normal`, thinned `thin` times.
    pub fn of(&self, i: u32, normal: &[f64; D], thin: u32) -> Vec<u32> {
        cloud(
            i,
            normal,
            self.positions,
            self.families,
            self.spec,
            self.spacing,
            thin,
        )
    }

    /// Fits the modes `modes(normal)` of every node; with `spec.thinning`, a node whose ‖V‖
    /// or cond(M) exceeds its limit gets its cloud thinned (density halved along the axes, up
    /// to 3 times; thesis Fig. 4.23).
    fn fit(
        &self,
        nodes: &[(u32, [f64; D])],
        levels: Levels,
        dt: f64,
        modes: impl Fn(&[f64; D]) -> Vec<Mode<D>>,
    ) -> AbsorbingLayer {
        let spec = self.spec;
        let mut thin = vec![0u32; nodes.len()];
        let specs = |thin: &[u32]| -> Vec<CloudSpec<D>> {
            nodes
                .iter()
                .zip(thin)
                .map(|((i, n), &t)| CloudSpec {
                    node: *i,
                    modes: modes(n),
                    cloud: self.of(*i, n, t),
                })
                .collect()
        };
        let fit = |thin: &[u32]| {
            AbsorbingLayer::fit(
                self.positions,
                &specs(thin),
                levels,
                dt,
                Pseudoinverse {
                    cutoff: spec.cutoff,
                    tikhonov: spec.tikhonov,
                },
            )
        };
        let mut layer = fit(&thin);
        if !spec.thinning {
            return layer;
        }
        for _ in 0..3 {
            let mut changed = false;
            for (t, r) in thin.iter_mut().zip(&layer.reports) {
                if (r.norm > spec.max_norm || r.condition > spec.max_condition) && r.cloud > 2 {
                    *t += 1;
                    changed = true;
                }
            }
            if !changed {
                break;
            }
            layer = fit(&thin);
        }
        layer
    }
}
