//! The `[nernst_planck]` table of a preset: species, Poisson equation, kernels, solver
//! settings, reactions and a manufactured reference (`scene::nernst_planck` checks them).

use serde::Deserialize;

use crate::model::pmb::Influence;
use crate::scene::geometry::Shape;
use crate::scene::units::Quantity;

#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct NernstPlanckTable {
    /// T (K).
    pub temperature: f64,
    /// σ of the nonlocal Poisson equation (2.64) (S/m).
    pub conductivity: Quantity,
    /// q1, q2, q3 of the kernels ω/r^{n+2q} (default 0, 0, 0).
    #[serde(default)]
    pub exponents: Option<[f64; 3]>,
    #[serde(default)]
    pub influence: Influence,
    /// The region solid at the start (default: none).
    pub solid: Option<Shape>,
    /// A solid node whose C₁ drops below this turns liquid (irreversible; none: no change).
    pub saturation: Option<f64>,
    /// The Newton iteration's relative residual target (default 1e-10).
    pub tolerance: Option<f64>,
    /// Newton iterations per species and step at most (default 4).
    pub max_iterations: Option<usize>,
    pub species: Vec<SpeciesTable>,
    pub manufactured: Option<ManufacturedTable>,
    /// The amount of substance of one unit of C, for the Poisson charge F Σ z C (default
    /// "1 mol/m^3"; the screw's concentrations are normalized by C_solid = 143.1 mol/L).
    pub concentration_unit: Option<Quantity>,
    /// "direct" (sparse LU), "bicgstab" (Jacobi-preconditioned) or "auto" (the default:
    /// direct in 1D and 2D, bicgstab in 3D, where the LU's fill does not fit).
    pub linear_solver: Option<String>,
    /// BiCGSTAB's relative residual target (default 1e-12) and iteration cap (default 5000).
    pub linear_tolerance: Option<f64>,
    pub linear_iterations: Option<usize>,
    pub reactions: Option<ReactionsTable>,
}

/// The screw's reactions (3.98)–(3.103) and the Butler–Volmer interface diffusivity (3.92).
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ReactionsTable {
    /// The species of each role, by name (the metal must be the first species: the phase
    /// change reads C1).
    pub metal: String,
    pub complex: String,
    pub hydrogen: String,
    pub hydroxide: String,
    /// k1f, k1b of (3.95), k2f, k2b of (3.96) (Table 3.7's numbers, in the species' unit).
    pub forward_1: f64,
    pub backward_1: f64,
    pub forward_2: f64,
    pub backward_2: f64,
    /// J50, J60 of (3.100)–(3.101).
    pub hydrogen_current: f64,
    pub hydroxide_current: f64,
    /// α_H⁺, α_OH⁻.
    pub hydrogen_charge: f64,
    pub hydroxide_charge: f64,
    /// c_solid in J/(z F c_solid).
    pub solid_concentration: Quantity,
    pub applied_potential: Quantity,
    pub standard_potential: Quantity,
    pub butler_volmer: Option<ButlerVolmerTable>,
}

#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ButlerVolmerTable {
    /// D0 (m²/s).
    pub exchange: Quantity,
    pub anodic: f64,
    pub cathodic: f64,
}

#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SpeciesTable {
    /// Lower-case letters, digits, `_` or `-`: the entity `nodes/species/<name>`.
    pub name: String,
    pub valence: f64,
    /// D of liquid–liquid bonds (m²/s).
    pub liquid: Quantity,
    /// D of interface bonds (default: `liquid`).
    pub interface: Option<Quantity>,
    /// D of solid–solid bonds (default 0).
    pub solid: Option<Quantity>,
    /// C at the start in the liquid and in the solid (default 0).
    #[serde(default)]
    pub initial_liquid: f64,
    #[serde(default)]
    pub initial_solid: f64,
    /// C in `hold_value` layers (default: `initial_liquid`).
    pub boundary: Option<f64>,
}

/// A steady manufactured solution in 1D: C_k = A_k + B_k cos(κx), φ = P cos(κx), κ = 2π/λ,
/// with sources that make it exact for the horizon integrals.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ManufacturedTable {
    pub wavelength: Quantity,
    /// P (V).
    pub potential: Quantity,
    /// A_k per species.
    pub means: Vec<f64>,
    /// B_k per species.
    pub amplitudes: Vec<f64>,
}
