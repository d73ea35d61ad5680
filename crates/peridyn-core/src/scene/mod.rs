//! Scenes: TOML presets (schema, units, variants) validated into a plain `Scene` in SI units.
//!
//! One job per file, imported one way: `schema` (the preset's tables) and the leaves (`units`,
//! `geometry`, `error`, `collocation`) first; `checks`, the checks every table shares; `spec`,
//! the validated parts; the validators of each concern (`materials`, `schemes`, `boundary`,
//! `time`, `measures`, `absorbing`, `state_based`, `nernst_planck`, `reference`); `validated`,
//! the `Scene` that holds the parts; `validate`, which runs the validators in order; `load`,
//! presets by name or file with variants and overrides. This file only declares and re-exports.

mod absorbing;
mod boundary;
pub mod builtin;
mod checks;
pub mod collocation;
pub mod error;
pub mod geometry;
mod load;
mod materials;
mod measures;
pub mod nernst_planck;
pub mod reference;
pub mod schema;
mod schemes;
mod spec;
mod state_based;
mod time;
pub mod units;
mod validate;
mod validated;

pub use crate::model::diffusion::second_moment;
pub use checks::{DEFAULT_CHI, check_chi, check_split_damage, check_split_strain};
pub use error::SceneError;
pub use geometry::Solid;
pub use load::override_table;
pub use reference::Reference;
pub use schema::{
    AbsorbingMethod, BondWeights, CheckSet, Coupling, CrackEnds, Dispersion, FamilyRadius, Physics,
    Preset, SchemeKind, Transfer, WaveNumberSet,
};
pub use spec::{
    AbsorbingSpec, BoundarySpec, CoarseScheme, Condition, CorrosionSpec, CrackAngleSpec,
    CrackGeometry, CrackLengthSpec, DamageCountSpec, DiffusionSpec, Duration, EnergyCircleSpec,
    HybridSpec, InitialVelocity, MaterialSpec, MultigridSpec, Pulse, PulseDirection, Refinement,
    SchemeSpec, StepSize, TimeSpec, WaveSpec,
};
pub use state_based::{OpeningSpec, SplitRule, StateBasedSpec};
pub use validated::Scene;
