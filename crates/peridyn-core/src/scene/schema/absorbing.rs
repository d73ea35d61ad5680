//! The `[absorbing]` table and `[[initial.pulse]]` tables of a preset, and the names their
//! fields take (`scene::absorbing` checks them and fills in the defaults per physics).

use serde::Deserialize;

use crate::scene::geometry::Point;
use crate::scene::units::{Measure, Quantity};

/// How an absorbing layer sets its nodes.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum AbsorbingMethod {
    /// The minimum-norm fit of outgoing far-field modes (thesis §4.1–4.3).
    #[default]
    Modes,
    /// The conventional first-order boundary u̇ + χ ∂_n u + d u = 0 (4.75) in every layer
    /// node (waves and bond-based PD; the baseline of the acceptance).
    FirstOrder,
}

/// Which wave numbers the far-field modes take (seed-thesis-ch4-5 §3.2, erratum 6).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum WaveNumberSet {
    /// Waves: k ∈ (0, Δk] (outgoing only; (4.154)); diffusion: k ∈ Δk·[−1, 0) (4.25).
    #[default]
    Positive,
    /// Waves: k equally spaced in [−Δk, Δk] as printed in (4.56) (did not absorb in the note's
    /// check; kept as an option).
    Symmetric,
}

/// The frequencies of the far-field modes.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Dispersion {
    /// The near field's own lattice quadrature (4.85), (4.95) ("Proposed-A").
    Discrete,
    /// The local limit ω̃² = χ²k² − d² (4.39) or ω̄ = D k² (4.10) ("Proposed-B").
    Local,
}

#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PulseTable {
    pub center: Point,
    #[serde(default = "unit_quantity")]
    pub amplitude: Quantity,
    /// a (1/m²).
    pub decay: Quantity,
    /// Dynamics: the displacement's direction, `"radial"` (u = A e^{−a r²} e_r, thesis
    /// (4.168)) or a vector (normalized); scalar fields take none.
    pub direction: Option<PulseDirectionTable>,
    /// The pulse is zero beyond this distance from its centre (m; (4.168)'s r ≤ 40).
    pub radius: Option<Quantity>,
}

#[derive(Debug, Clone, Deserialize)]
#[serde(untagged)]
pub enum PulseDirectionTable {
    Named(String),
    Vector(Point),
}

fn unit_quantity() -> Quantity {
    Quantity(1.0)
}

/// `[absorbing]`: the layer and the knobs of thesis §4.1.3, §4.2.3 (defaults per physics in
/// `scene::absorbing`).
#[derive(Debug, Clone, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct AbsorbingTable {
    /// "modes" (the fitted far-field modes, default) or "first-order" (the conventional
    /// boundary (4.75), the baseline).
    pub method: Option<AbsorbingMethod>,
    pub width: Option<Measure>,
    pub cloud_radius: Option<Measure>,
    pub wave_numbers: Option<usize>,
    pub directions: Option<usize>,
    /// Δk (1/m).
    pub max_wave_number: Option<f64>,
    /// Δφ (degrees).
    pub spread_degrees: Option<f64>,
    #[serde(default)]
    pub wave_number_set: WaveNumberSet,
    pub dispersion: Option<Dispersion>,
    pub cutoff: Option<f64>,
    /// λ of Tikhonov's filter factors, relative to σ_max, [0, 1) (0: none).
    pub tikhonov: Option<f64>,
    pub cone: Option<bool>,
    pub max_norm: Option<f64>,
    pub max_condition: Option<f64>,
    #[serde(default)]
    pub thinning: bool,
    /// ε of the layer's selective filter, [0, 0.5] (0: none).
    pub filter: Option<f64>,
    /// κ of the damped band inside the layer, [0, 0.02] (0: none).
    pub damping: Option<f64>,
    /// The damped band's width (default one horizon).
    pub damping_band: Option<Measure>,
    /// Fit the far field's rest states (u = const, and e^{−2dt} for damped waves) too.
    #[serde(default)]
    pub rest_modes: bool,
}
