//! Presets compiled into the binary, so the tool runs with no files around.

const PRESETS: &[(&str, &str)] = &[
    (
        "abc-bond-2d",
        include_str!("../../../../presets/abc-bond-2d.toml"),
    ),
    (
        "abc-corrosion-2d",
        include_str!("../../../../presets/abc-corrosion-2d.toml"),
    ),
    (
        "abc-diffusion-1d",
        include_str!("../../../../presets/abc-diffusion-1d.toml"),
    ),
    (
        "abc-wave-1d",
        include_str!("../../../../presets/abc-wave-1d.toml"),
    ),
    (
        "abc-wave-2d",
        include_str!("../../../../presets/abc-wave-2d.toml"),
    ),
    (
        "branching",
        include_str!("../../../../presets/branching.toml"),
    ),
    (
        "corrosion-1d",
        include_str!("../../../../presets/corrosion-1d.toml"),
    ),
    (
        "corrosion-3d",
        include_str!("../../../../presets/corrosion-3d.toml"),
    ),
    (
        "crack-opening",
        include_str!("../../../../presets/crack-opening.toml"),
    ),
    (
        "diffusion-2d-manufactured",
        include_str!("../../../../presets/diffusion-2d-manufactured.toml"),
    ),
    (
        "half-space-impact",
        include_str!("../../../../presets/half-space-impact.toml"),
    ),
    (
        "kalthoff-winkler",
        include_str!("../../../../presets/kalthoff-winkler.toml"),
    ),
    (
        "kalthoff-winkler-dh",
        include_str!("../../../../presets/kalthoff-winkler-dh.toml"),
    ),
    (
        "kalthoff-winkler-multigrid",
        include_str!("../../../../presets/kalthoff-winkler-multigrid.toml"),
    ),
    (
        "pmb-block-3d",
        include_str!("../../../../presets/pmb-block-3d.toml"),
    ),
    (
        "plate-with-hole",
        include_str!("../../../../presets/plate-with-hole.toml"),
    ),
    (
        "nnpp-1d-manufactured",
        include_str!("../../../../presets/nnpp-1d-manufactured.toml"),
    ),
    (
        "nnpp-screw",
        include_str!("../../../../presets/nnpp-screw.toml"),
    ),
    (
        "screw-3d",
        include_str!("../../../../presets/screw-3d.toml"),
    ),
    (
        "static-1d-manufactured",
        include_str!("../../../../presets/static-1d-manufactured.toml"),
    ),
    (
        "vibrating-plate",
        include_str!("../../../../presets/vibrating-plate.toml"),
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
