//! The TOML preset schema. Every table rejects unknown fields; quantities accept SI numbers or
//! strings with units (see `units`).

use std::collections::BTreeMap;

use serde::Deserialize;

use super::geometry::{Point, Shape};
use super::units::{Measure, Quantity};

#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Preset {
    pub name: String,
    #[serde(default)]
    pub description: String,
    /// Spatial dimension: 1, 2 or 3.
    pub dimension: usize,
    pub geometry: Shape,
    pub discretization: Discretization,
    pub material: Material,
    #[serde(default)]
    pub precracks: Vec<Precrack>,
    #[serde(default)]
    pub boundary: Vec<BoundaryLayer>,
    #[serde(default)]
    pub initial: Initial,
    pub time: TimeSpec,
    #[serde(default)]
    pub output: Output,
    #[serde(default)]
    pub metrics: MetricsSpec,
    /// Named overrides merged onto this file, e.g. `[variants.small]`.
    #[serde(default)]
    pub variants: BTreeMap<String, toml::Table>,
}

#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Discretization {
    /// Lattice spacing Δx.
    pub spacing: Quantity,
    /// Horizon δ, absolute ("2 mm") or as m = δ/Δx ("4 dx").
    pub horizon: Measure,
    /// Random node offsets, uniform in ±perturbation·Δx per component.
    #[serde(default)]
    pub perturbation: f64,
    #[serde(default = "default_seed")]
    pub seed: u64,
    #[serde(default)]
    pub family_radius: FamilyRadius,
    /// β partial-volume factor (3.2).
    #[serde(default = "yes")]
    pub volume_correction: bool,
    #[serde(default)]
    pub scheme: SchemeKind,
}

fn default_seed() -> u64 {
    1
}

fn yes() -> bool {
    true
}

#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum FamilyRadius {
    /// ‖ξ‖ ≤ δ (the thesis's counts).
    #[default]
    Horizon,
    /// ‖ξ‖ < δ + Δx/2 (Peridigm style, the whole β band).
    HorizonPlusHalfSpacing,
}

#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum SchemeKind {
    #[default]
    Standard,
}

#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum ModelKind {
    /// Prototype microelastic brittle bond-based material (GPBM), (2.27)–(2.34).
    #[default]
    Pmb,
}

#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Influence {
    /// ω0 = 1 (2.12).
    #[default]
    Constant,
    /// ω1 = 1 − r/δ (2.13).
    Linear,
}

#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Plane {
    /// Plane stress, ν = 1/3.
    Stress,
    /// Plane strain, ν = 1/4.
    #[default]
    Strain,
}

#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Material {
    #[serde(default)]
    pub model: ModelKind,
    pub density: Quantity,
    /// Young's modulus E (gives the micromodulus c by the tables of §1.3).
    pub youngs_modulus: Option<Quantity>,
    /// Micromodulus c, overriding the one derived from E.
    pub micromodulus: Option<Quantity>,
    /// Fracture energy G0 (gives the critical stretch s0).
    pub fracture_energy: Option<Quantity>,
    /// Critical stretch s0, overriding the one derived from G0.
    pub critical_stretch: Option<f64>,
    #[serde(default)]
    pub influence: Influence,
    /// 2D only: plane stress or plane strain.
    #[serde(default)]
    pub plane: Plane,
}

#[derive(Debug, Clone, Deserialize)]
#[serde(rename_all = "snake_case", deny_unknown_fields)]
pub enum Precrack {
    /// 1D: a cut at one coordinate.
    Point { at: Quantity },
    /// 2D: a line segment.
    Segment { from: Point, to: Point },
    /// 3D: the parallelogram origin + a·edge_a + b·edge_b, a, b ∈ [0, 1].
    Patch {
        origin: Point,
        edge_a: Point,
        edge_b: Point,
    },
}

/// A layer of nodes that carries a boundary condition. The nodes are those inside `region`
/// (if given) and within `thickness` of the bounding-box `face` (if given).
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BoundaryLayer {
    #[serde(default)]
    pub name: String,
    pub region: Option<Shape>,
    /// "x-", "x+", "y-", "y+", "z-" or "z+".
    pub face: Option<String>,
    pub thickness: Option<Quantity>,
    /// Held velocity (m/s) on the listed `axes`.
    pub velocity: Option<Point>,
    /// Held displacement (m) on the listed `axes`.
    pub displacement: Option<Point>,
    /// Body-force density (N/m³) added in the layer.
    pub body_force: Option<Point>,
    /// Which components are held, e.g. "x" or "xy"; all by default.
    pub axes: Option<String>,
}

#[derive(Debug, Clone, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Initial {
    #[serde(default)]
    pub velocity: Vec<VelocityField>,
}

/// Initial velocity contributions, summed.
#[derive(Debug, Clone, Deserialize)]
#[serde(rename_all = "snake_case", deny_unknown_fields)]
pub enum VelocityField {
    Uniform {
        value: Point,
    },
    /// Component `component` varies linearly along `axis` from `from` at the body's lower bound
    /// to `to` at its upper bound.
    Ramp {
        component: String,
        axis: String,
        from: Quantity,
        to: Quantity,
    },
    /// v_component = amplitude · sin(π · modes · (x_axis − lower) / extent).
    Sine {
        component: String,
        axis: String,
        amplitude: Quantity,
        #[serde(default = "one")]
        modes: f64,
    },
}

fn one() -> f64 {
    1.0
}

#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TimeSpec {
    /// Time step, absolute ("2 ns") or a fraction of the stable bound (3.8) ("0.5 stable").
    pub dt: Measure,
    /// Duration, as an end time ("87 us") or a number of steps ("2000 steps").
    pub end: Measure,
    /// Permit Δt above the stable bound (the run is still stopped if it blows up).
    #[serde(default)]
    pub allow_unstable: bool,
}

#[derive(Debug, Clone, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Output {
    /// Log a frame every this many steps (default: about 100 frames per run).
    pub every: Option<u64>,
}

#[derive(Debug, Clone, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MetricsSpec {
    #[serde(default)]
    pub crack_angle: Vec<CrackAngleSpec>,
}

/// Angle of a crack grown from a pre-crack tip: a least-squares line through the damaged nodes
/// (φ ≥ threshold) connected to the tip inside `region`, against `direction`.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CrackAngleSpec {
    pub name: String,
    pub tip: Point,
    pub direction: Point,
    #[serde(default = "default_threshold")]
    pub threshold: f64,
    pub region: Shape,
}

fn default_threshold() -> f64 {
    0.35
}
