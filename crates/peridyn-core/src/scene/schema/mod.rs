//! The TOML preset schema. Every table rejects unknown fields; quantities accept SI numbers or
//! strings with units (see `units`).

use std::collections::BTreeMap;

use serde::Deserialize;

mod absorbing;
mod nernst_planck;

pub use absorbing::{
    AbsorbingMethod, AbsorbingTable, Dispersion, PulseDirectionTable, PulseTable, WaveNumberSet,
};
pub use nernst_planck::{
    ButlerVolmerTable, ManufacturedTable, NernstPlanckTable, ReactionsTable, SpeciesTable,
};

use super::checks::DEFAULT_CHI;
use super::geometry::{Point, Shape};
use super::units::{Measure, Quantity, Relative};
use crate::model::pmb::{Influence, Plane};

#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Preset {
    pub name: String,
    #[serde(default)]
    pub description: String,
    /// Spatial dimension: 1, 2 or 3.
    pub dimension: usize,
    /// What is solved: elastodynamics (default), a static linear solve, or diffusion.
    #[serde(default)]
    pub physics: Physics,
    pub geometry: Shape,
    pub discretization: Discretization,
    pub material: Material,
    #[serde(default)]
    pub precracks: Vec<Precrack>,
    #[serde(default)]
    pub boundary: Vec<BoundaryLayer>,
    #[serde(default)]
    pub initial: Initial,
    /// Required except for static scenes (one solve).
    pub time: Option<TimeSpec>,
    #[serde(default)]
    pub output: Output,
    #[serde(default)]
    pub metrics: MetricsSpec,
    /// Hybrid schemes: the initial Ω_s band, the switching margin χ and the check policy.
    #[serde(default)]
    pub hybrid: HybridTable,
    /// Multi-grid: a fine region refined `ratio` times (diffusion and corrosion scenes).
    pub multigrid: Option<MultigridTable>,
    /// An absorbing layer at the truncation (unbounded domains, thesis Chapter 4).
    #[serde(default)]
    pub absorbing: Option<AbsorbingTable>,
    /// OSB: adaptive particle splitting (zeng2024 Sect. 3).
    pub refinement: Option<RefinementTable>,
    /// A manufactured solution: gives the body force or source, the values held in
    /// `hold_reference` layers, and the error norm (3.79) reported in frames.
    pub reference: Option<ReferenceSpec>,
    /// NNPP scenes: the species, the Poisson equation and the kernels.
    pub nernst_planck: Option<NernstPlanckTable>,
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
    /// Random node offsets per component, as fractions of Δx: `0.2` means uniform in
    /// ±0.2 Δx, `[0.0, 0.35]` uniform in [0, 0.35 Δx] (the thesis's perturbed grid).
    #[serde(default)]
    pub perturbation: Perturbation,
    /// Anchors the lattice: nodes at origin + k·Δx (default: the body's lower bounds), so
    /// that two scenes can share their nodes (a uniform reference on a multi-grid scene's
    /// fine level).
    #[serde(default)]
    pub origin: Option<Point>,
    #[serde(default = "default_seed")]
    pub seed: u64,
    #[serde(default)]
    pub family_radius: FamilyRadius,
    /// β partial-volume factor (3.2).
    #[serde(default = "yes")]
    pub volume_correction: bool,
    #[serde(default)]
    pub scheme: SchemeKind,
    /// OSB only: the bonds' quadrature weights, "moments" (default: moment-matched volumes,
    /// see `scheme::dual_horizon`) or "volume" (plain V_j, the paper without its surface
    /// correction).
    #[serde(default)]
    pub bond_weights: Option<BondWeights>,
    /// WLS only: the auxiliary grid has spacing δ / collocation_factor (k_aux). Default: the
    /// papers' choice for the basis order and dimension (collocation sets of 5/11/13 in 1D,
    /// 29/49 in 2D, 123 in 3D).
    pub collocation_factor: Option<usize>,
}

/// Two grid levels (thesis §3.4–3.5): coarse cells are split into `ratio`ᵈ fine cells where
/// refined; `discretization.spacing` is the coarse spacing Δx⁺. Diffusion and corrosion refine
/// a predefined `region`; dynamics refines a `band` around boundaries and pre-cracks at the
/// start and then wherever a coarse bond reaches χ·s0 (the multi-adaptive switch).
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MultigridTable {
    /// The grid ratio Δx⁺/Δx⁻, a whole number.
    pub ratio: usize,
    /// The fine region Ω⁻ (diffusion, corrosion).
    #[serde(default)]
    pub region: Option<Shape>,
    /// Dynamics: the initial Ω⁻, coarse cells within this distance of a boundary or pre-crack
    /// ("1 horizon", "4 mm"; default "1 horizon").
    #[serde(default)]
    pub band: Option<Measure>,
    /// Dynamics: the switching margin χ of (3.80) on coarse bonds (default 0.95, the thesis's σ).
    #[serde(default)]
    pub chi: Option<f64>,
    /// Dynamics: "idw" (default, the thesis's (3.85)–(3.88)) or "multilinear" for the values
    /// fine nodes take from the coarse level.
    #[serde(default)]
    pub transfer: Option<Transfer>,
    /// Dynamics: the coarse level's scheme, "standard" (default, "adaptive, standard") or
    /// "wls" (WLS-2 collocation, the thesis's "adaptive, hybrid").
    #[serde(default)]
    pub coarse: Option<CoarseKind>,
    /// With `coarse = "wls"`: the auxiliary grid δ/collocation_factor (default 4, the thesis's
    /// δ/4: 49 collocation nodes at m⁺ = 12 in 2D; 3 in 3D, 123 nodes).
    #[serde(default)]
    pub collocation_factor: Option<usize>,
    /// With `coarse = "wls"`, 2D only, instead of the auxiliary grid: the collocation targets
    /// as whole orbits [a, b] of coarse-lattice offsets (±a, ±b), (±b, ±a)
    /// (docs/validation.md's stencils).
    #[serde(default)]
    pub collocation_orbits: Option<Vec<Vec<u32>>>,
    /// With `coarse = "wls"`: exponent a of the fit weight exp(−a d²/r̄²) (the papers' 16).
    #[serde(default)]
    pub fit_weight: Option<f64>,
    /// Nernst-planck: "interpolated" (default, the thesis's (3.89)–(3.90)) or "conservative"
    /// (the levels' exchange balanced, the coarse level taking the fine level's view of it).
    #[serde(default)]
    pub coupling: Option<Coupling>,
}

/// The `multigrid.coarse` scheme names.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum CoarseKind {
    Standard,
    Wls,
}

/// How fine nodes take their values from the coarse level in the multi-adaptive scheme.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Transfer {
    /// Inverse-distance weights of the 2ᵈ nearest coarse nodes, (3.85)–(3.88) (the thesis).
    #[default]
    Idw,
    /// Tensor-product linear weights of the 2ᵈ coarse nodes around the fine node (linear
    /// fields reproduced exactly; extrapolated at the body's edge).
    Multilinear,
}

/// The accounting of the fluxes between the two levels of a predefined-region multi-grid.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Coupling {
    /// The thesis's (3.89)–(3.90): each level's active nodes see the other level through
    /// their fictitious nodes; consistent on both sides, not conservative (IDW is not).
    #[default]
    Interpolated,
    /// Conservative: the same fictitious values and bonds, and the levels' exchange D (the
    /// interpolated coupling's conservation defect) taken back from the coarse nodes that
    /// exchange, inside the implicit systems (`discretization::CrossBonds`): the coarse level
    /// takes the fine level's view of the exchange. Σ C V over the active nodes is conserved up
    /// to the solves' residuals, at some accuracy next to the level interface.
    Conservative,
}

#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct HybridTable {
    /// Width of the initial Ω_s band around boundaries and pre-cracks ("1.2 horizon", "3 mm").
    #[serde(default = "default_band")]
    pub band: Measure,
    /// Switching margin χ of (3.80): a bond is critical when its stretch reaches χ·s0.
    #[serde(default = "default_chi")]
    pub chi: f64,
    /// Which Ω_w bonds are checked: "all" (every family bond of every Ω_w node), "near"
    /// (Ω_w nodes within 2δ of Ω_s) or "collocation" (their collocation bonds only).
    #[serde(default)]
    pub check: CheckSet,
    /// Check every this many steps.
    #[serde(default = "default_every")]
    pub check_every: u64,
    /// WLS auxiliary-grid factor k_aux in Ω_w (default: 29 collocation nodes in 2D, 123 in 3D).
    pub collocation_factor: Option<usize>,
    /// 2D only, instead of the auxiliary grid: the Ω_w collocation targets as whole orbits
    /// [a, b] of lattice offsets (±a, ±b), (±b, ±a) in lattice spacings.
    pub collocation_orbits: Option<Vec<Vec<u32>>>,
    /// Exponent a of the Ω_w fit weight exp(−a d²/r̄²) (the papers' (3.26): 16).
    pub fit_weight: Option<f64>,
    /// κ of the velocity exchange between lattice neighbours near the Ω_s/Ω_w interface, as a
    /// share of the top lattice frequency (0 … 0.02; 0: off, the papers' coupling).
    pub interface_damping: Option<f64>,
    /// Half-width of the damped band on each side of the interface ("0.5 horizon", "1 mm").
    #[serde(default = "default_interface_band")]
    pub interface_band: Measure,
}

impl Default for HybridTable {
    fn default() -> Self {
        HybridTable {
            band: default_band(),
            chi: default_chi(),
            check: CheckSet::default(),
            check_every: default_every(),
            collocation_factor: None,
            collocation_orbits: None,
            fit_weight: None,
            interface_damping: None,
            interface_band: default_interface_band(),
        }
    }
}

fn default_interface_band() -> Measure {
    Measure::Relative(0.5, Relative::Horizon)
}

fn default_band() -> Measure {
    Measure::Relative(1.2, Relative::Horizon)
}

fn default_chi() -> f64 {
    DEFAULT_CHI
}

fn default_every() -> u64 {
    1
}

#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum CheckSet {
    /// Every family bond of every Ω_w node.
    #[default]
    All,
    /// Every family bond of the Ω_w nodes within 2δ of Ω_s.
    Near,
    /// Only the collocation bonds of the Ω_w nodes within 2δ of Ω_s (cheapest; damage that
    /// slips past is caught at the next frame and switched with a warning).
    Collocation,
}

#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
#[serde(untagged)]
pub enum Perturbation {
    Symmetric(f64),
    Range([f64; 2]),
}

impl Default for Perturbation {
    fn default() -> Self {
        Perturbation::Symmetric(0.0)
    }
}

#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Physics {
    /// Elastodynamics with velocity-Verlet.
    #[default]
    Dynamics,
    /// Static linear elasticity, one global solve (1D).
    Static,
    /// Transient PD diffusion with forward Euler (3.4)/(3.10).
    Diffusion,
    /// Bi-material corrosion (2.48)–(2.49), (2.79): diffusion with bond classes by phase and
    /// an irreversible solid → liquid change below the saturation concentration.
    Corrosion,
    /// The scalar wave (2.37)–(2.40) with damped velocity-Verlet (4.62).
    ScalarWave,
    /// The nonlocal Nernst–Planck–Poisson system (2.63)–(2.64): several species and a
    /// potential, the semi-implicit Newton step of §3.1.2.
    NernstPlanck,
}

/// Manufactured solutions of seed-004 Examples 1–2 (thesis §3.2.5–3.2.6).
#[derive(Debug, Clone, Deserialize)]
#[serde(tag = "solution", rename_all = "kebab-case", deny_unknown_fields)]
pub enum ReferenceSpec {
    /// 1D static: u = sin(x / length). The body force balances either the PD operator
    /// (`operator = "nonlocal"`, (3.74) with γ, seed-thesis-ch2-3 erratum 4) or its local limit
    /// E u'' (`"local"`, the δ-convergence problem (3.75)–(3.76)).
    #[serde(rename = "sine-1d")]
    Sine1d {
        #[serde(default = "ten")]
        length: Quantity,
        #[serde(default)]
        operator: ReferenceOperator,
    },
    /// 2D diffusion: C = sin(ω t) (x²y² + x³y + x⁴ + xy³ + y⁴) with ω = `frequency`, and the
    /// source (3.78) for q = 2, ω0.
    #[serde(rename = "quartic-2d")]
    Quartic2d {
        #[serde(default = "five")]
        frequency: f64,
    },
}

fn ten() -> Quantity {
    Quantity(10.0)
}

fn five() -> f64 {
    5.0
}

#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum ReferenceOperator {
    #[default]
    Nonlocal,
    Local,
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
    /// Meshfree particle sums with β partial volumes (3.1)/(3.4).
    #[default]
    Standard,
    /// WLS collocation with a C² basis (thesis §3.2; seed-thesis-ch2-3 §3).
    #[serde(rename = "wls-2")]
    Wls2,
    #[serde(rename = "wls-4")]
    Wls4,
    #[serde(rename = "wls-6")]
    Wls6,
    /// Ω_s (standard, nonlinear) in a fixed band around boundaries and pre-cracks, Ω_w (WLS-2,
    /// linearized) elsewhere (thesis §3.3; seed-thesis-ch2-3 §5).
    HybridFixed,
    /// As `hybrid-fixed`, and Ω_s grows where bonds reach χ·s0 (3.80).
    HybridAdaptive,
}

impl SchemeKind {
    pub const ALL: [SchemeKind; 6] = [
        SchemeKind::Standard,
        SchemeKind::Wls2,
        SchemeKind::Wls4,
        SchemeKind::Wls6,
        SchemeKind::HybridFixed,
        SchemeKind::HybridAdaptive,
    ];

    pub fn name(self) -> &'static str {
        match self {
            SchemeKind::Standard => "standard",
            SchemeKind::Wls2 => "wls-2",
            SchemeKind::Wls4 => "wls-4",
            SchemeKind::Wls6 => "wls-6",
            SchemeKind::HybridFixed => "hybrid-fixed",
            SchemeKind::HybridAdaptive => "hybrid-adaptive",
        }
    }

    pub fn is_hybrid(self) -> bool {
        matches!(self, SchemeKind::HybridFixed | SchemeKind::HybridAdaptive)
    }

    /// The WLS basis order k, None for the standard scheme.
    pub fn wls_order(self) -> Option<usize> {
        match self {
            SchemeKind::Standard => None,
            SchemeKind::Wls2 => Some(2),
            SchemeKind::Wls4 => Some(4),
            SchemeKind::Wls6 => Some(6),
            SchemeKind::HybridFixed | SchemeKind::HybridAdaptive => None,
        }
    }
}

#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum ModelKind {
    /// Prototype microelastic brittle bond-based material (GPBM), (2.27)–(2.34).
    #[default]
    Pmb,
    /// Ordinary state-based PD, Madenci–Oterkus form, on a dual-horizon discretization
    /// (zeng2024 (3)–(14)); 2D dynamics only.
    Osb,
}

#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Material {
    #[serde(default)]
    pub model: ModelKind,
    /// Mass density ρ (dynamics only).
    pub density: Option<Quantity>,
    /// Young's modulus E (gives the micromodulus c by the tables of seed-thesis-ch2-3 §1.3).
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
    /// Diffusion only: κ of the kernel κ ω / ‖ξ‖^q (2.42).
    pub diffusivity: Option<Quantity>,
    /// Diffusion only: the kernel exponent q (seed-thesis-ch2-3 erratum 7).
    pub kernel_exponent: Option<f64>,
    /// Corrosion: κ_int of solid–liquid bonds ("micro-dissolvability"); `diffusivity` is κ_liq
    /// of liquid–liquid bonds; solid–solid bonds carry no flux.
    pub interface_diffusivity: Option<Quantity>,
    /// Corrosion: C_sat; a solid node whose concentration drops below it turns liquid.
    pub saturation: Option<Quantity>,
    /// OSB: Poisson's ratio ν (the bond-based law fixes it; the state-based law takes it).
    pub poisson_ratio: Option<f64>,
    /// OSB, 2D: the out-of-plane thickness h (volumes Δ²·h; default 1 m, energies per metre).
    pub thickness: Option<Quantity>,
    /// Scalar waves: χ (m/s).
    pub wave_speed: Option<Quantity>,
    /// Scalar waves: d (1/s).
    pub damping: Option<Quantity>,
}

#[derive(Debug, Clone, Deserialize)]
#[serde(rename_all = "snake_case", deny_unknown_fields)]
pub enum Precrack {
    /// 1D: a cut at one coordinate.
    Point { at: Quantity },
    /// 2D: a line segment. `ends`: whether a bond through an end point crosses it.
    Segment {
        from: Point,
        to: Point,
        #[serde(default)]
        ends: CrackEnds,
    },
    /// 3D: the parallelogram origin + a·edge_a + b·edge_b, a, b ∈ [0, 1].
    Patch {
        origin: Point,
        edge_a: Point,
        edge_b: Point,
    },
}

/// Whether a 2D pre-crack's end points belong to it. On a lattice, whole pairs of bonds pass
/// through a tip placed on a symmetry point (a whole millimetre between cell-centred nodes).
/// `closed` cuts them and `open` leaves them intact, "through" decided with a tolerance of
/// 10⁻⁹ of the bond length. `rounded` (the default) cuts a bond through an end point when the
/// rounded cross product is exactly 0: the rounding of the coordinates decides, so a tip and
/// its mirror image may differ (kept as the default because the Kalthoff–Winkler presets'
/// validated crack angles were measured with it: on `medium` the lower crack's angle moves by
/// up to 4° with the few bonds through its tip; docs/validation.md).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum CrackEnds {
    #[default]
    Rounded,
    Closed,
    Open,
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
    /// "2 mm", "3 dx" or "1 horizon".
    pub thickness: Option<Measure>,
    /// The layer lies outside the body's `face` (the body is extended by `thickness`), as the
    /// Dirichlet collars of seed-thesis-ch2-3 §4.1 (thesis §3.2.5). Needs a box geometry.
    #[serde(default)]
    pub outside: bool,
    /// Diffusion and static scenes: the field is held at the reference solution.
    #[serde(default)]
    pub hold_reference: bool,
    /// Diffusion and corrosion scenes: the field is held at this value (a Dirichlet layer, e.g.
    /// C = 0 in the δ-layer at an electrolyte's outer surface).
    pub hold_value: Option<Quantity>,
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
    /// Diffusion and corrosion: concentration set in regions (later entries win; 0 elsewhere).
    #[serde(default)]
    pub concentration: Vec<ConcentrationRegion>,
    /// Scalar fields: Gaussian pulses A exp(−a ‖x − x0‖²), summed.
    #[serde(default)]
    pub pulse: Vec<PulseTable>,
}

#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ConcentrationRegion {
    pub region: Shape,
    pub value: Quantity,
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
    /// Time step, absolute ("2 ns") or a fraction of the stable bound (3.8) ("0.5 stable");
    /// not used by dynamic relaxation (its pseudo step is 1).
    pub dt: Option<Measure>,
    /// "verlet" (default) or "adr": adaptive dynamic relaxation to the static solution
    /// (OSB scenes; `end` is then the iteration cap, "N steps").
    #[serde(default)]
    pub integrator: Option<IntegratorKind>,
    /// ADR: the run stops when ‖F_int + F_ext‖ / ‖F_ext‖ falls below this (default 1e-6).
    pub tolerance: Option<f64>,
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
    #[serde(default)]
    pub crack_length: Vec<CrackLengthTable>,
    #[serde(default)]
    pub energy_circle: Vec<EnergyCircleSpec>,
    #[serde(default)]
    pub damage_count: Vec<DamageCountSpec>,
    /// Scalar fields: the value and energy density at the node nearest `point`, logged as
    /// `probe/<name>/{value,energy_density}` (a pulse passing, then what reflects).
    #[serde(default)]
    pub probe: Vec<ProbeTable>,
    /// OSB: the crack opening at a crack mouth, logged as `opening/<name>` (m).
    #[serde(default)]
    pub opening: Vec<OpeningTable>,
}

/// The opening of a crack at its mouth: the displacement along `axis` of the upper face minus
/// that of the lower face (upper and lower along `axis`), each face's taken from its particle
/// nearest `mouth` (within one cell of the crack line) and the next one of the same row,
/// extrapolated linearly to the mouth (the particles sit half a cell and more inside the edge).
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct OpeningTable {
    pub name: String,
    pub mouth: Point,
    /// The axis normal to the crack faces (default 1, y).
    #[serde(default = "y_axis")]
    pub axis: usize,
}

fn y_axis() -> usize {
    1
}

/// `[refinement]`: when particles split (zeng2024 (15)–(16)) and how deep.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RefinementTable {
    /// φ_c of (15) (default 0.4, the paper's).
    pub damage: Option<f64>,
    /// α of (16) (default 0.5, the paper's).
    pub strain_factor: Option<f64>,
    /// Split generations (default 1, the paper's examples).
    pub levels: Option<u8>,
    /// δ_child / δ_parent in [0.5, 1] (default 0.5, the paper's; its Table 3 also runs 1.0).
    pub horizon_ratio: Option<f64>,
    /// Particles inside split before the run (all `levels`), beside the criteria's splits: a
    /// predefined refined region (not in the paper; a diagnosis and a user's choice).
    pub region: Option<Shape>,
    /// false: the refinement is read but never applied (the coarse reference keeps the rest of
    /// the preset).
    #[serde(default = "yes_refine")]
    pub enabled: bool,
}

fn yes_refine() -> bool {
    true
}

/// The time integrator of an OSB scene.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum IntegratorKind {
    Verlet,
    Adr,
}

#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ProbeTable {
    pub name: String,
    pub point: Point,
}

/// Kinetic plus strain energy of the (active) nodes within `radius` of `center`, logged as
/// `energy/circle/<name>` (the thesis's Fig. 3.35 measure).
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct EnergyCircleSpec {
    pub name: String,
    pub center: Point,
    pub radius: Quantity,
}

/// The number of nodes in `region` whose damage reaches `threshold`, logged as
/// `damage/count/<name>` (e.g. a secondary crack on the far edge).
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DamageCountSpec {
    pub name: String,
    pub region: Shape,
    #[serde(default = "default_threshold")]
    pub threshold: f64,
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

/// Length of a crack grown from a pre-crack tip: how far the damaged nodes (φ ≥ threshold)
/// connected to the tip inside `region` reach from the tip along their least-squares line,
/// logged as `crack_length/<name>` (m).
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CrackLengthTable {
    pub name: String,
    pub tip: Point,
    #[serde(default = "default_threshold")]
    pub threshold: f64,
    pub region: Shape,
}

fn default_threshold() -> f64 {
    0.35
}

/// How each OSB bond's share of the horizon integral is weighted (`scheme::dual_horizon`).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum BondWeights {
    /// ω = V_j (zeng2024 (2) without a surface correction).
    Volume,
    /// Moment-matched V_j (see `scheme::dual_horizon`).
    #[default]
    Moments,
}
