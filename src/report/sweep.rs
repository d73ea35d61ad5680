//! What a sweep is made of: the axes it varies, what it runs, and the rows it gives (read by
//! the tables and by `plot`).

use crate::scene::SchemeKind;

/// One `--vary KEY=v1,v2,…`: a preset key and its values (TOML syntax).
#[derive(Debug, Clone, PartialEq)]
pub struct Axis {
    pub key: String,
    pub values: Vec<String>,
}

impl Axis {
    pub fn parse(text: &str) -> Result<Axis, String> {
        let (key, values) = text.split_once('=').ok_or_else(|| {
            format!("--vary `{text}`: write KEY=v1,v2,… e.g. discretization.spacing=1,0.5")
        })?;
        let values: Vec<String> = values
            .split(',')
            .map(|v| v.trim().to_string())
            .filter(|v| !v.is_empty())
            .collect();
        if key.trim().is_empty() || values.is_empty() {
            return Err(format!(
                "--vary `{text}`: needs a key and at least one value"
            ));
        }
        Ok(Axis {
            key: key.trim().to_string(),
            values,
        })
    }
}

/// What a sweep runs.
#[derive(Debug, Clone)]
pub struct SweepSpec {
    pub preset: String,
    pub variant: Option<String>,
    /// Fixed overrides applied to every run.
    pub set: Vec<String>,
    pub axes: Vec<Axis>,
    pub schemes: Vec<SchemeKind>,
}

/// One finished run of a sweep.
#[derive(Debug, Clone)]
pub struct SweepRow {
    pub scheme: SchemeKind,
    /// The value of each axis, in `SweepSpec::axes` order.
    pub values: Vec<String>,
    pub nodes: usize,
    /// Mean stencil: family (standard, node included) or collocation set (WLS).
    pub stencil: f64,
    pub steps: u64,
    /// Building the discretization and operators, and the stable-step estimate.
    pub setup_seconds: f64,
    /// Stepping (or the static solve), without I/O.
    pub run_seconds: f64,
    /// Relative ℓ² error (3.79) at the end; None if the scene has no reference.
    pub error: Option<f64>,
    /// Why the run failed, if it did (the row keeps its place in the table).
    pub failure: Option<String>,
}
