//! Scenes: TOML presets (schema, units, variants) validated into a plain `Scene` in SI units.

mod absorbing;
pub mod nernst_planck;
mod state_based;
pub use state_based::{
    OpeningSpec, SplitRule, StateBasedSpec, check_split_damage, check_split_strain,
};
pub mod builtin;
pub mod collocation;
pub mod error;
pub mod geometry;
pub mod reference;
pub mod schema;
pub mod units;
mod validate;
pub use crate::model::diffusion::second_moment;

use std::path::Path;

pub use error::SceneError;
pub use geometry::Solid;
pub use reference::Reference;
pub use schema::{BondWeights, CheckSet, CrackEnds, FamilyRadius, Physics, Preset, SchemeKind};

use crate::model::pmb::{Influence, PmbConstants};

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
    pub nernst_planck: Option<nernst_planck::NernstPlanckSpec>,
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
    pub energy_circles: Vec<EnergyCircleSpec>,
    /// Scalar-field probes: (name, point).
    pub probes: Vec<(String, Vec<f64>)>,
    pub damage_counts: Vec<DamageCountSpec>,
}

#[derive(Debug, Clone, PartialEq)]
pub struct MaterialSpec {
    pub density: f64,
    /// Stiffness, failure, influence and plane as given: the law (`model::pmb::PmbLaw`)
    /// derives c and s0 from them.
    pub constants: PmbConstants,
}

#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DiffusionSpec {
    /// κ (κ_liq for corrosion).
    pub diffusivity: f64,
    pub exponent: f64,
    pub influence: Influence,
    /// Corrosion only.
    pub corrosion: Option<CorrosionSpec>,
}

#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CorrosionSpec {
    /// κ_int of solid–liquid bonds.
    pub interface_diffusivity: f64,
    /// C_sat.
    pub saturation: f64,
}

/// χ where a preset does not set it (the thesis's switching margin, seed-thesis-ch2-3 §8.3).
pub const DEFAULT_CHI: f64 = 0.95;

/// The one check of the switching margin χ of (3.80), wherever it is set (preset, command,
/// running simulation): it must lie in (0, 1].
pub fn check_chi(chi: f64) -> Result<f64, String> {
    if chi.is_finite() && chi > 0.0 && chi <= 1.0 {
        Ok(chi)
    } else {
        Err(format!("χ must be in (0, 1], got {chi}"))
    }
}

#[derive(Debug, Clone, Copy, PartialEq)]
pub struct HybridSpec {
    pub adaptive: bool,
    /// Initial Ω_s band width (m).
    pub band: f64,
    pub chi: f64,
    pub check: CheckSet,
    pub check_every: u64,
    /// κ of the interface damping (`adapt::interface`): 0 turns it off.
    pub interface_damping: f64,
    /// Half-width of its band on each side of the Ω_s/Ω_w interface (m).
    pub interface_band: f64,
}

/// Two grid levels, the fine one `ratio` times finer (thesis §3.4–3.5).
#[derive(Debug, Clone)]
pub struct MultigridSpec {
    pub ratio: usize,
    pub refinement: Refinement,
    /// The coarse level's scheme (the fine level always runs the standard scheme).
    pub coarse: CoarseScheme,
    /// How the levels' fluxes through fictitious nodes are accounted (nernst-planck).
    pub coupling: Coupling,
}

/// The accounting of the fluxes between the two levels of a predefined-region multi-grid.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Deserialize)]
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

/// The scheme on the coarse level of a multi-adaptive scene (thesis §3.5): "adaptive, standard"
/// or "adaptive, hybrid" (WLS-2 collocation on the coarse active nodes over the given rule).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub enum CoarseScheme {
    #[default]
    Standard,
    Wls(collocation::Collocation),
}

/// Where the fine level is active.
#[derive(Debug, Clone)]
pub enum Refinement {
    /// A predefined, fixed fine region (diffusion and corrosion, thesis §3.4).
    Region(Solid),
    /// The multi-adaptive switch (dynamic fracture, thesis §3.5): refined at the start within
    /// `band` of boundaries and pre-cracks, then around every coarse bond reaching χ·s0.
    Adaptive {
        band: f64,
        chi: f64,
        transfer: Transfer,
    },
}

/// The scalar wave (2.37)–(2.40): ü = L u − 2 d u̇, L the PD operator with c_s calibrated to
/// the local wave speed χ (thesis (4.47), (4.87)).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct WaveSpec {
    /// χ (m/s).
    pub speed: f64,
    /// d (1/s).
    pub damping: f64,
}

/// A Gaussian u0 = A exp(−a ‖x − x0‖²) added to the initial scalar field (thesis (4.96),
/// (4.97); the diffusion pulse of §4.1.4).
#[derive(Debug, Clone, PartialEq)]
pub struct Pulse {
    pub center: Vec<f64>,
    pub amplitude: f64,
    /// a (1/m²).
    pub decay: f64,
    /// Zero beyond this distance from the centre (m).
    pub radius: f64,
    /// A displacement pulse's direction (dynamics); `None` for scalar fields.
    pub direction: Option<PulseDirection>,
}

#[derive(Debug, Clone, PartialEq)]
pub enum PulseDirection {
    /// Along e_r = (x − x0)/‖x − x0‖ (zero at the centre; thesis (4.168)).
    Radial,
    /// Along a fixed unit vector.
    Fixed(Vec<f64>),
}

impl Pulse {
    pub fn value(&self, x: &[f64]) -> f64 {
        let r2: f64 = x
            .iter()
            .zip(&self.center)
            .map(|(a, b)| (a - b) * (a - b))
            .sum();
        if r2 > self.radius * self.radius {
            return 0.0;
        }
        self.amplitude * (-self.decay * r2).exp()
    }

    /// A displacement pulse's value at `x` (component k into `out[k]`, added).
    pub fn add_displacement(&self, x: &[f64], out: &mut [f64]) {
        let size = self.value(x);
        match &self.direction {
            Some(PulseDirection::Fixed(e)) => {
                for (o, e) in out.iter_mut().zip(e) {
                    *o += size * e;
                }
            }
            Some(PulseDirection::Radial) | None => {
                let rel: Vec<f64> = x.iter().zip(&self.center).map(|(a, b)| a - b).collect();
                let r = rel.iter().map(|v| v * v).sum::<f64>().sqrt();
                if r > 0.0 {
                    for (o, v) in out.iter_mut().zip(&rel) {
                        *o += size * v / r;
                    }
                }
            }
        }
    }
}

/// How an absorbing layer sets its nodes.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum AbsorbingMethod {
    /// The minimum-norm fit of outgoing far-field modes (thesis §4.1–4.3).
    #[default]
    Modes,
    /// The conventional first-order boundary u̇ + χ ∂_n u + d u = 0 (4.75) in every layer
    /// node (waves and bond-based PD; the baseline of the acceptance).
    FirstOrder,
}

/// Which wave numbers the far-field modes take (seed-thesis-ch4-5 §3.2, erratum 6).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum WaveNumberSet {
    /// Waves: k ∈ (0, Δk] (outgoing only; (4.154)); diffusion: k ∈ Δk·[−1, 0) (4.25).
    #[default]
    Positive,
    /// Waves: k equally spaced in [−Δk, Δk] as printed in (4.56) (did not absorb in the note's
    /// check; kept as an option).
    Symmetric,
}

/// The frequencies of the far-field modes.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Dispersion {
    /// The near field's own lattice quadrature (4.85), (4.95) ("Proposed-A").
    Discrete,
    /// The local limit ω̃² = χ²k² − d² (4.39) or ω̄ = D k² (4.10) ("Proposed-B").
    Local,
}

/// An absorbing layer at the truncation of an unbounded domain (thesis Chapter 4;
/// seed-thesis-ch4-5 §1.3 for the knobs and their defaults).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AbsorbingSpec {
    pub method: AbsorbingMethod,
    /// Nodes nearer the truncation than this are absorbing (m).
    pub width: f64,
    /// d∞, the cloud's radius (m).
    pub cloud_radius: f64,
    /// n_k per direction.
    pub wave_numbers: usize,
    /// n_φ.
    pub directions: usize,
    /// Δk (1/m).
    pub max_wave_number: f64,
    /// Δφ (rad): the waves' directions lie in θ_n + [−Δφ, Δφ]; also the backward cone's margin.
    pub spread: f64,
    pub wave_number_set: WaveNumberSet,
    pub dispersion: Dispersion,
    /// Relative SVD cut-off of the pseudo-inverse (seed-thesis-ch4-5 §3.7).
    pub cutoff: f64,
    /// λ of Tikhonov's filter factors σ/(σ² + (λ σ_max)²) in the pseudo-inverse (0: none, the
    /// thesis; see `absorb::Pseudoinverse`).
    pub tikhonov: f64,
    /// Clouds only behind the node (backward cone (4.86)).
    pub cone: bool,
    /// ‖V‖_max and cond(M) limits: `check` flags nodes above them; with `thinning` their clouds
    /// are thinned (density halved along the axes, Fig. 4.23) until they hold.
    pub max_norm: f64,
    pub max_condition: f64,
    pub thinning: bool,
    /// ε of the layer's selective filter (0: none, the thesis): after each overwrite an absorbing
    /// node's value becomes (1 − ε) u_a + ε · the mean of its lattice neighbours (not in the
    /// thesis; see `sim::far_field::Filter`).
    pub filter: f64,
    /// κ of a damped band of near-field nodes inside the layer (0: none, the thesis; not in the
    /// thesis): after every step v ← v − r L D L v there, r = κ ω_max Δt, as at the hybrid's
    /// interface (`adapt::interface`). It takes O(r (kΔx)⁴) per step from a smooth wave and O(r)
    /// from the lattice-scale waves that no fitted mode carries.
    pub damping: f64,
    /// The damped band's width (m); it starts two lattice hops inside the layer.
    pub damping_band: f64,
    /// Adds the far field's rest states to every node's modes: u = const (s = 0) and, for a
    /// damped wave, u = e^{−2dt} (s = −2d), the k → 0 limits of (4.53) (not in the thesis;
    /// see `absorb::scalar_modes`).
    pub rest_modes: bool,
}

/// How fine nodes take their values from the coarse level in the multi-adaptive scheme.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Transfer {
    /// Inverse-distance weights of the 2ᵈ nearest coarse nodes, (3.85)–(3.88) (the thesis).
    #[default]
    Idw,
    /// Tensor-product linear weights of the 2ᵈ coarse nodes around the fine node (linear
    /// fields reproduced exactly; extrapolated at the body's edge).
    Multilinear,
}

#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SchemeSpec {
    pub kind: SchemeKind,
    /// WLS collocation rule (auxiliary grid δ/k_aux, or orbits); for the standard scheme the
    /// unused grid factor 0.
    pub collocation: collocation::Collocation,
}

#[derive(Debug, Clone)]
pub enum CrackGeometry {
    Point(f64),
    Segment([f64; 2], [f64; 2], CrackEnds),
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
    /// The scalar field is held at the reference solution.
    Reference,
    /// The scalar field is held at `value[0]`.
    Value,
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
    /// The layer was added outside the body's face (the solid is already extended).
    pub outside: bool,
}

impl BoundarySpec {
    /// Whether node position `x` lies in the layer; `lo`, `hi` are the solid's bounds.
    pub fn contains(&self, x: &[f64], lo: &[f64], hi: &[f64], eps: f64) -> bool {
        let in_face = self.face.is_none_or(|(a, upper, t)| {
            if upper {
                x[a] >= hi[a] - t - eps
            } else {
                x[a] <= lo[a] + t + eps
            }
        });
        in_face && self.region.as_ref().is_none_or(|r| r.contains(x, eps))
    }
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

/// Kinetic plus strain energy within a circle (sphere) of the reference configuration.
#[derive(Debug, Clone)]
pub struct EnergyCircleSpec {
    pub name: String,
    pub center: Vec<f64>,
    pub radius: f64,
}

/// Nodes of a region whose damage reaches a threshold.
#[derive(Debug, Clone)]
pub struct DamageCountSpec {
    pub name: String,
    pub region: Solid,
    pub threshold: f64,
}

impl Scene {
    /// An error about one of this scene's fields, located in its preset text.
    pub fn error(&self, field: &str, message: impl Into<String>) -> SceneError {
        SceneError {
            file: self.source.clone(),
            field: field.to_string(),
            line: error::locate_field(&self.preset_text, field),
            message: message.into(),
        }
    }

    /// Loads a preset by built-in name or file path.
    pub fn load(name_or_path: &str, variant: Option<&str>) -> Result<Scene, SceneError> {
        Scene::load_with(name_or_path, variant, &[])
    }

    /// Loads a preset and applies `key.path=value` overrides after the variant (values in TOML
    /// syntax; a bare word is taken as a string), e.g. `discretization.scheme=wls-2`.
    pub fn load_with(
        name_or_path: &str,
        variant: Option<&str>,
        overrides: &[String],
    ) -> Result<Scene, SceneError> {
        let (file, text) = Scene::read(name_or_path)?;
        let table = override_table(&file, overrides)?;
        let mut scene = Scene::from_text_with(&file, &text, variant, &table)?;
        scene.overrides = overrides.to_vec();
        Ok(scene)
    }

    /// The preset text of a built-in name or a file, and the name to report it under.
    pub fn read(name_or_path: &str) -> Result<(String, String), SceneError> {
        if let Some(text) = builtin::text(name_or_path) {
            return Ok((format!("builtin:{name_or_path}"), text.to_string()));
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
        Ok((name_or_path.to_string(), text))
    }

    /// Parses and validates preset text; `file` names it in errors.
    pub fn from_text(file: &str, text: &str, variant: Option<&str>) -> Result<Scene, SceneError> {
        Scene::from_text_with(file, text, variant, &toml::Table::new())
    }

    /// As `from_text`, with `overrides` merged after the variant.
    pub fn from_text_with(
        file: &str,
        text: &str,
        variant: Option<&str>,
        overrides: &toml::Table,
    ) -> Result<Scene, SceneError> {
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
        let preset = if variant.is_none() && overrides.is_empty() {
            base
        } else {
            let ctx = ErrorContext {
                variant,
                ..base_ctx.clone()
            };
            let mut merged: toml::Table = text.parse().map_err(|e| toml_error(e, &ctx))?;
            merged.remove("variants");
            if let Some(v) = variant {
                for table in variant_chain(&base.variants, v, &ctx)? {
                    merge_tables(&mut merged, &table);
                }
            }
            merge_tables(&mut merged, overrides);
            toml::Value::Table(merged)
                .try_into()
                .map_err(|e: toml::de::Error| {
                    if overrides.is_empty() {
                        toml_error(e, &ctx)
                    } else {
                        override_error(file, overrides, e)
                    }
                })?
        };
        let ctx = ErrorContext {
            file,
            text,
            variant,
        };
        validate::validate(&preset, &ctx, text, variant)
    }
}

/// `a.b=value` strings as a nested table; values in TOML syntax, bare words as strings.
pub fn override_table(file: &str, overrides: &[String]) -> Result<toml::Table, SceneError> {
    let mut table = toml::Table::new();
    for o in overrides {
        let bad = |message: String| SceneError {
            file: file.to_string(),
            field: o.split('=').next().unwrap_or_default().trim().to_string(),
            line: None,
            message,
        };
        let Some((key, value)) = o.split_once('=') else {
            return Err(bad(format!(
                "override `{o}`: write KEY=VALUE, e.g. discretization.scheme=wls-2"
            )));
        };
        let value = value.trim();
        let parsed = format!("v = {value}")
            .parse::<toml::Table>()
            .ok()
            .and_then(|mut t| t.remove("v"))
            .unwrap_or_else(|| toml::Value::String(value.to_string()));
        let keys: Vec<&str> = key.trim().split('.').collect();
        if keys.iter().any(|k| k.is_empty()) {
            return Err(bad(format!("override `{o}`: empty key segment")));
        }
        let mut node = toml::Value::Table(table.clone());
        let mut cursor = &mut node;
        for k in &keys[..keys.len() - 1] {
            let t = cursor
                .as_table_mut()
                .ok_or_else(|| bad(format!("override `{o}`: `{k}` is not a table")))?;
            cursor = t
                .entry(k.to_string())
                .or_insert_with(|| toml::Value::Table(toml::Table::new()));
        }
        cursor
            .as_table_mut()
            .ok_or_else(|| bad(format!("override `{o}`: not a table")))?
            .insert(keys[keys.len() - 1].to_string(), parsed);
        if let toml::Value::Table(t) = node {
            table = t;
        }
    }
    Ok(table)
}

fn override_error(file: &str, overrides: &toml::Table, e: toml::de::Error) -> SceneError {
    SceneError {
        file: file.to_string(),
        field: String::new(),
        line: None,
        message: format!("{} (with overrides {overrides})", e.message().trim()),
    }
}

/// The tables a variant overlays, outermost first: a variant with `extends = "other"` is
/// `other`'s overlay followed by its own (the `extends` key itself dropped); an unknown name or
/// a cycle is an error naming the variant.
fn variant_chain(
    variants: &std::collections::BTreeMap<String, toml::Table>,
    name: &str,
    ctx: &ErrorContext,
) -> Result<Vec<toml::Table>, SceneError> {
    let mut chain: Vec<toml::Table> = Vec::new();
    let mut seen: Vec<String> = Vec::new();
    let mut current = name.to_string();
    loop {
        if seen.contains(&current) {
            seen.push(current);
            return Err(ctx.error(
                &format!("variants.{name}.extends"),
                format!(
                    "the variants extend each other in a cycle: {}",
                    seen.join(" → ")
                ),
            ));
        }
        let field = match seen.last() {
            None => "variants".to_string(),
            Some(child) => format!("variants.{child}.extends"),
        };
        let table = variants.get(&current).ok_or_else(|| {
            let known: Vec<&str> = variants.keys().map(String::as_str).collect();
            ctx.error(
                &field,
                format!(
                    "no variant `{current}`; this preset has: {}",
                    known.join(", ")
                ),
            )
        })?;
        let mut own = table.clone();
        let parent = own.remove("extends");
        chain.push(own);
        seen.push(current);
        current = match parent {
            None => break,
            Some(toml::Value::String(p)) => p,
            Some(other) => {
                return Err(ctx.error(
                    &format!("{}.extends", field_of(&seen)),
                    format!("write the name of another variant as a string, not {other}"),
                ));
            }
        };
    }
    chain.reverse();
    Ok(chain)
}

fn field_of(seen: &[String]) -> String {
    format!("variants.{}", seen.last().map_or("", String::as_str))
}

/// Overlays a variant (or `--set` overrides) on the base table: tables merge key by key,
/// other values replace; `key = false` over a table removes it (a variant without the base's
/// `[multigrid]`, say).
fn merge_tables(base: &mut toml::Table, overrides: &toml::Table) {
    for (key, value) in overrides {
        match (base.get_mut(key), value) {
            (Some(toml::Value::Table(b)), toml::Value::Table(o)) => merge_tables(b, o),
            (Some(toml::Value::Table(_)), toml::Value::Boolean(false)) => {
                base.remove(key);
            }
            _ => {
                base.insert(key.clone(), value.clone());
            }
        }
    }
}
