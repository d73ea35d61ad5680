//! Scenes: TOML presets (schema, units, variants) validated into a plain `Scene` in SI units.

pub mod builtin;
pub mod error;
pub mod geometry;
pub mod schema;
pub mod units;
mod validate;

use std::path::Path;

pub use error::SceneError;
pub use geometry::Solid;
pub use schema::{FamilyRadius, Influence, Plane, Preset};

use error::{ErrorContext, line_of};

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
    pub dim: usize,
    pub solid: Solid,
    pub spacing: f64,
    pub horizon: f64,
    pub perturbation: f64,
    pub seed: u64,
    pub family_radius: FamilyRadius,
    pub volume_correction: bool,
    pub material: MaterialSpec,
    pub precracks: Vec<CrackGeometry>,
    pub boundary: Vec<BoundarySpec>,
    pub initial_velocity: Vec<InitialVelocity>,
    pub time: TimeSpec,
    pub output_every: Option<u64>,
    pub crack_angles: Vec<CrackAngleSpec>,
}

#[derive(Debug, Clone, PartialEq)]
pub struct MaterialSpec {
    pub density: f64,
    pub micromodulus: f64,
    /// None: no failure.
    pub critical_stretch: Option<f64>,
    pub influence: Influence,
    pub plane: Plane,
    pub youngs_modulus: Option<f64>,
}

#[derive(Debug, Clone)]
pub enum CrackGeometry {
    Point(f64),
    Segment([f64; 2], [f64; 2]),
    Patch {
        origin: [f64; 3],
        edge_a: [f64; 3],
        edge_b: [f64; 3],
    },
}

#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Condition {
    Velocity,
    Displacement,
    BodyForce,
}

#[derive(Debug, Clone)]
pub struct BoundarySpec {
    pub name: String,
    pub region: Option<Solid>,
    /// (axis, upper side, thickness)
    pub face: Option<(usize, bool, f64)>,
    pub condition: Condition,
    pub value: Vec<f64>,
    pub axes: Vec<usize>,
}

#[derive(Debug, Clone)]
pub enum InitialVelocity {
    Uniform(Vec<f64>),
    Ramp {
        component: usize,
        axis: usize,
        from: f64,
        to: f64,
    },
    Sine {
        component: usize,
        axis: usize,
        amplitude: f64,
        modes: f64,
    },
}

#[derive(Debug, Clone, Copy, PartialEq)]
pub enum StepSize {
    Absolute(f64),
    FractionOfStable(f64),
}

#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Duration {
    End(f64),
    Steps(u64),
}

#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TimeSpec {
    pub step: StepSize,
    pub duration: Duration,
    pub allow_unstable: bool,
}

#[derive(Debug, Clone)]
pub struct CrackAngleSpec {
    pub name: String,
    pub tip: Vec<f64>,
    pub direction: Vec<f64>,
    pub threshold: f64,
    pub region: Solid,
}

impl Scene {
    /// Loads a preset by built-in name or file path.
    pub fn load(name_or_path: &str, variant: Option<&str>) -> Result<Scene, SceneError> {
        if let Some(text) = builtin::text(name_or_path) {
            return Scene::from_text(&format!("builtin:{name_or_path}"), text, variant);
        }
        let path = Path::new(name_or_path);
        let text = std::fs::read_to_string(path).map_err(|e| SceneError {
            file: name_or_path.to_string(),
            field: String::new(),
            line: None,
            message: if path.exists() {
                format!("cannot read: {e}")
            } else {
                format!(
                    "no such preset file or built-in preset (built-ins: {})",
                    builtin::names().join(", ")
                )
            },
        })?;
        Scene::from_text(name_or_path, &text, variant)
    }

    /// Parses and validates preset text; `file` names it in errors.
    pub fn from_text(file: &str, text: &str, variant: Option<&str>) -> Result<Scene, SceneError> {
        let base_ctx = ErrorContext {
            file,
            text,
            variant: None,
        };
        let toml_error = |e: toml::de::Error, ctx: &ErrorContext| SceneError {
            file: file.to_string(),
            field: String::new(),
            line: e.span().map(|s| line_of(text, s.start)),
            message: match ctx.variant {
                Some(v) => format!("{} (variant `{v}`)", e.message().trim()),
                None => e.message().trim().to_string(),
            },
        };
        let base: Preset = toml::from_str(text).map_err(|e| toml_error(e, &base_ctx))?;
        let preset = match variant {
            None => base,
            Some(v) => {
                let ctx = ErrorContext {
                    variant: Some(v),
                    ..base_ctx.clone()
                };
                let overrides = base.variants.get(v).ok_or_else(|| {
                    let known: Vec<&str> = base.variants.keys().map(String::as_str).collect();
                    ctx.error(
                        "variants",
                        format!("no variant `{v}`; this preset has: {}", known.join(", ")),
                    )
                })?;
                let mut merged: toml::Table = text.parse().map_err(|e| toml_error(e, &ctx))?;
                merged.remove("variants");
                merge_tables(&mut merged, overrides);
                toml::Value::Table(merged)
                    .try_into()
                    .map_err(|e: toml::de::Error| toml_error(e, &ctx))?
            }
        };
        let ctx = ErrorContext {
            file,
            text,
            variant,
        };
        validate::validate(&preset, &ctx, text, variant)
    }
}

/// Deep merge: tables merge key by key, anything else is replaced.
fn merge_tables(base: &mut toml::Table, overrides: &toml::Table) {
    for (key, value) in overrides {
        match (base.get_mut(key), value) {
            (Some(toml::Value::Table(b)), toml::Value::Table(o)) => merge_tables(b, o),
            _ => {
                base.insert(key.clone(), value.clone());
            }
        }
    }
}
