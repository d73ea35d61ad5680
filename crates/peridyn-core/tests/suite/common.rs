#![allow(dead_code)]
//! Helpers shared by the integration tests (the application crate's suite includes this file too).

use peridyn_core::scene::Scene;

/// The `;`-separated preset overrides in environment variable `name` (none if unset or empty):
/// the exploration harnesses' `SET`.
pub fn env_overrides(name: &str) -> Vec<String> {
    std::env::var(name)
        .map(|s| {
            s.split(';')
                .filter(|s| !s.is_empty())
                .map(String::from)
                .collect()
        })
        .unwrap_or_default()
}

/// A scene from inline preset text.
pub fn scene(text: &str) -> Scene {
    Scene::from_text("test.toml", text, None).unwrap_or_else(|e| panic!("{e}"))
}

/// A block scene of `n` spacings per side in `dim` dimensions with horizon factor `m`;
/// `extra` lines go into the `[discretization]` table.
pub fn block(dim: usize, n: usize, m: f64, plane: &str, extra: &str) -> Scene {
    let max = vec![format!("{}", n as f64 * 1e-3); dim].join(", ");
    let min = vec!["0.0"; dim].join(", ");
    scene(&format!(
        r#"
name = "block"
dimension = {dim}
[geometry]
box = {{ min = [{min}], max = [{max}] }}
[discretization]
spacing = 1e-3
horizon = "{m} dx"
{extra}
[material]
density = 1000.0
youngs_modulus = 1e9
plane = "{plane}"
[time]
dt = "0.5 stable"
end = "10 steps"
"#
    ))
}
