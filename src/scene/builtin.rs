//! Presets compiled into the binary, so the tool runs with no files around.

const PRESETS: &[(&str, &str)] = &[
    (
        "kalthoff-winkler",
        include_str!("../../presets/kalthoff-winkler.toml"),
    ),
    (
        "pmb-block-3d",
        include_str!("../../presets/pmb-block-3d.toml"),
    ),
    (
        "vibrating-plate",
        include_str!("../../presets/vibrating-plate.toml"),
    ),
];

/// The default scene of `peridyn` with no arguments.
pub const DEFAULT: (&str, &str) = ("kalthoff-winkler", "small");

pub fn text(name: &str) -> Option<&'static str> {
    PRESETS.iter().find(|(n, _)| *n == name).map(|(_, t)| *t)
}

pub fn names() -> Vec<&'static str> {
    PRESETS.iter().map(|(n, _)| *n).collect()
}
