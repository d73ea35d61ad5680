//! The validated scene: every part of a preset in SI units, ready to be discretized, and where
//! it came from (file, variant, overrides) so that errors found later still name the field.

use super::error::{SceneError, locate_field};
use super::geometry::Solid;
use super::nernst_planck::NernstPlanckSpec;
use super::reference::Reference;
use super::schema::{FamilyRadius, Physics};
use super::spec::{
    AbsorbingSpec, BoundarySpec, CrackAngleSpec, CrackGeometry, CrackLengthSpec, DamageCountSpec,
    DiffusionSpec, EnergyCircleSpec, HybridSpec, InitialVelocity, MaterialSpec, MultigridSpec,
    Pulse, SchemeSpec, TimeSpec, WaveSpec,
};
use super::state_based::StateBasedSpec;

/// A validated scene, in SI units, ready to be discretized.
#[derive(Debug, Clone)]
pub struct Scene {
    pub name: String,
    pub description: String,
    pub variant: Option<String>,
    /// Where the preset came from (a path, or `builtin:NAME`).
    pub source: String,
    /// The preset file's text, as given (variants included).
    pub preset_text: String,
    /// `KEY=VALUE` overrides applied after the variant (`--set`), in order.
    pub overrides: Vec<String>,
    pub dim: usize,
    pub solid: Solid,
    pub spacing: f64,
    pub horizon: f64,
    /// Node offsets per component, uniform in [lo, hi]·Δx.
    pub perturbation: [f64; 2],
    /// A lattice anchor: nodes at origin + k·Δx (None: from the body's lower bounds).
    pub origin: Option<Vec<f64>>,
    pub seed: u64,
    pub family_radius: FamilyRadius,
    pub volume_correction: bool,
    pub physics: Physics,
    pub scheme: SchemeSpec,
    /// Elastic material (dynamics and static scenes).
    pub material: Option<MaterialSpec>,
    /// Diffusion kernel (diffusion scenes).
    pub diffusion: Option<DiffusionSpec>,
    pub reference: Option<Reference>,
    /// Hybrid schemes only.
    pub hybrid: Option<HybridSpec>,
    /// Multi-grid scenes only.
    pub multigrid: Option<MultigridSpec>,
    /// Unbounded-domain scenes: the absorbing layer at the truncation.
    pub absorbing: Option<AbsorbingSpec>,
    /// OSB scenes (`material.model = "osb"`): the state-based material on a dual-horizon
    /// discretization, its refinement and integrator.
    pub state_based: Option<StateBasedSpec>,
    /// Scalar-wave scenes: χ and the damping d (the kernel is in `diffusion`).
    pub wave: Option<WaveSpec>,
    /// NNPP scenes: species, Poisson equation, kernels, manufactured reference.
    pub nernst_planck: Option<NernstPlanckSpec>,
    /// Gaussian pulses added to the initial scalar field.
    pub initial_pulses: Vec<Pulse>,
    pub precracks: Vec<CrackGeometry>,
    pub boundary: Vec<BoundarySpec>,
    pub initial_velocity: Vec<InitialVelocity>,
    /// Initial concentration regions (later entries win; 0 elsewhere).
    pub initial_concentration: Vec<(Solid, f64)>,
    pub time: TimeSpec,
    pub output_every: Option<u64>,
    pub crack_angles: Vec<CrackAngleSpec>,
    pub crack_lengths: Vec<CrackLengthSpec>,
    pub energy_circles: Vec<EnergyCircleSpec>,
    /// Scalar-field probes: (name, point).
    pub probes: Vec<(String, Vec<f64>)>,
    pub damage_counts: Vec<DamageCountSpec>,
}

impl Scene {
    /// An error about one of this scene's fields, located in its preset text.
    pub fn error(&self, field: &str, message: impl Into<String>) -> SceneError {
        SceneError {
            file: self.source.clone(),
            field: field.to_string(),
            line: locate_field(&self.preset_text, field),
            message: message.into(),
        }
    }
}
