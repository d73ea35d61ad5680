//! `physics = "nernst-planck"` and its `[nernst_planck]` table → the scene's
//! [`NernstPlanckSpec`]: the species (valence, bond diffusivities by class (2.78), initial and
//! boundary values), the Poisson equation's micro-conductivity, the kernel exponents q1–q3 of
//! (2.63)–(2.64), the phase change on C₁ and an optional manufactured reference (thesis §2.4,
//! §3.1.2; seed-thesis-ch2-3 §1.7, §2.3).
//!
//! Boundary layers: `hold_value = φ_b` holds every species at its `boundary` value and φ at
//! φ_b (Table 3.5's far field: φ = 0); `hold_reference = true` holds the manufactured values.
//! φ is not solved in the solid (φ = 0 there).

use super::checks::positive;
use super::error::{ErrorContext, SceneError};
use super::geometry::Solid;
use super::schema::{
    ManufacturedTable, NernstPlanckTable, Physics, Preset, ReactionsTable, SpeciesTable,
};
use super::units::Quantity;
use crate::model::nernst_planck::SpeciesLaw;
use crate::model::nernst_planck::{FARADAY, GAS_CONSTANT, NnppKernel};
use crate::model::nnpp_reactions::{ButlerVolmer, ReactionLaw};
use crate::model::pmb::Influence;
use crate::sparse::LinearMethod;

/// Species a scene may carry (the screw has six).
const MAX_SPECIES: usize = 12;

#[derive(Debug, Clone, PartialEq)]
pub struct SpeciesSpec {
    pub law: SpeciesLaw,
    pub initial_liquid: f64,
    pub initial_solid: f64,
    pub boundary: f64,
}

#[derive(Debug, Clone, PartialEq)]
pub struct NernstPlanckSpec {
    pub temperature: f64,
    pub conductivity: f64,
    pub kernel: NnppKernel,
    pub solid: Option<Solid>,
    pub saturation: Option<f64>,
    pub tolerance: f64,
    pub max_iterations: usize,
    pub species: Vec<SpeciesSpec>,
    pub manufactured: Option<Manufactured>,
    /// mol/m³ per unit of C.
    pub concentration_unit: f64,
    pub linear: LinearMethod,
    pub reactions: Option<ReactionLaw>,
}

/// The manufactured solution of a 1D scene with ω = 1 and q1 = q2 = q3 = −1/2, where every
/// kernel ω/r^{n+2q} is 1 and the horizon integrals of cosines are closed-form:
/// ∫_{−δ}^{δ} cos(κ(x+ξ)) − cos(κx) dξ = cos(κx) I(κ), I(κ) = 2 sin(κδ)/κ − 2δ.
#[derive(Debug, Clone, PartialEq)]
pub struct Manufactured {
    pub wavenumber: f64,
    pub potential: f64,
    pub means: Vec<f64>,
    pub amplitudes: Vec<f64>,
}

impl Manufactured {
    fn integral(&self, wavenumber: f64, horizon: f64) -> f64 {
        2.0 * (wavenumber * horizon).sin() / wavenumber - 2.0 * horizon
    }

    pub fn concentration(&self, k: usize, x: f64) -> f64 {
        self.means[k] + self.amplitudes[k] * (self.wavenumber * x).cos()
    }

    pub fn phi(&self, x: f64) -> f64 {
        self.potential * (self.wavenumber * x).cos()
    }

    /// The source of species k that makes the field steady: minus the exact horizon
    /// integral of (2.63) with the liquid diffusivity.
    pub fn species_source(&self, spec: &NernstPlanckSpec, k: usize, x: f64) -> f64 {
        let c = spec.kernel.constants();
        let delta = spec.kernel.horizon;
        let (kx, w) = (self.wavenumber * x, self.wavenumber);
        let (a, b, p) = (self.means[k], self.amplitudes[k], self.potential);
        let law = &spec.species[k].law;
        let zf = law.valence * FARADAY / (GAS_CONSTANT * spec.temperature);
        let diffusion = c.k1 * b * self.integral(w, delta) * kx.cos();
        let migration = c.k2
            * zf
            * (2.0 * a * p * self.integral(w, delta) * kx.cos()
                + 0.5 * b * p * self.integral(2.0 * w, delta) * (2.0 * kx).cos());
        -law.liquid * (diffusion + migration)
    }

    /// The Poisson source that makes φ exact: −σ K3 ∫(φ' − φ) − F Σ z C.
    pub fn poisson_source(&self, spec: &NernstPlanckSpec, x: f64) -> f64 {
        let c = spec.kernel.constants();
        let kx = self.wavenumber * x;
        let laplace = c.k3 * self.potential * self.integral(self.wavenumber, spec.kernel.horizon);
        let charge: f64 = spec
            .species
            .iter()
            .enumerate()
            .map(|(k, s)| s.law.valence * self.concentration(k, x))
            .sum();
        -spec.conductivity * laplace * kx.cos() - FARADAY * charge
    }
}

fn species(
    t: &SpeciesTable,
    ctx: &ErrorContext,
    path: &str,
    taken: &[SpeciesSpec],
) -> Result<SpeciesSpec, SceneError> {
    let name_ok = !t.name.is_empty()
        && t.name
            .chars()
            .all(|c| c.is_ascii_lowercase() || c.is_ascii_digit() || c == '_' || c == '-');
    if !name_ok {
        return Err(ctx.error(
            &format!("{path}.name"),
            format!(
                "`{}`: use lower-case letters, digits, `_` or `-` (it names nodes/species/<name>)",
                t.name
            ),
        ));
    }
    if taken.iter().any(|s| s.law.name == t.name) {
        return Err(ctx.error(
            &format!("{path}.name"),
            format!("`{}` is given twice", t.name),
        ));
    }
    if !t.valence.is_finite() {
        return Err(ctx.error(&format!("{path}.valence"), "must be finite"));
    }
    let diffusivity = |field: &str, value: Option<Quantity>, default: f64| {
        let v = value.map_or(default, Quantity::si);
        if v.is_finite() && v >= 0.0 {
            Ok(v)
        } else {
            Err(ctx.error(
                &format!("{path}.{field}"),
                format!("a diffusivity ≥ 0 in m²/s, got {v}"),
            ))
        }
    };
    let liquid = positive(ctx, &format!("{path}.liquid"), t.liquid.si())?;
    let law = SpeciesLaw {
        name: t.name.clone(),
        valence: t.valence,
        liquid,
        interface: diffusivity("interface", t.interface, liquid)?,
        solid: diffusivity("solid", t.solid, 0.0)?,
    };
    let boundary = t.boundary.unwrap_or(t.initial_liquid);
    for (field, v) in [
        ("initial_liquid", t.initial_liquid),
        ("initial_solid", t.initial_solid),
        ("boundary", boundary),
    ] {
        if !(v.is_finite() && v >= 0.0) {
            return Err(ctx.error(
                &format!("{path}.{field}"),
                format!("a concentration ≥ 0, got {v}"),
            ));
        }
    }
    Ok(SpeciesSpec {
        law,
        initial_liquid: t.initial_liquid,
        initial_solid: t.initial_solid,
        boundary,
    })
}

pub(super) fn nernst_planck(
    p: &Preset,
    ctx: &ErrorContext,
    dim: usize,
    horizon: f64,
) -> Result<Option<NernstPlanckSpec>, SceneError> {
    let table = match (&p.nernst_planck, p.physics) {
        (None, Physics::NernstPlanck) => {
            return Err(ctx.error(
                "nernst_planck",
                "physics = \"nernst-planck\" needs a [nernst_planck] table with its species",
            ));
        }
        (None, _) => return Ok(None),
        (Some(_), physics) if physics != Physics::NernstPlanck => {
            return Err(ctx.error("nernst_planck", "belongs to physics = \"nernst-planck\""));
        }
        (Some(t), _) => t,
    };
    let temperature = positive(ctx, "nernst_planck.temperature", table.temperature)?;
    let conductivity = positive(ctx, "nernst_planck.conductivity", table.conductivity.si())?;
    let exponents = table.exponents.unwrap_or([0.0; 3]);
    let kernel = NnppKernel::new(dim, table.influence, horizon, exponents)
        .map_err(|m| ctx.error("nernst_planck.exponents", m))?;
    if table.species.is_empty() || table.species.len() > MAX_SPECIES {
        return Err(ctx.error(
            "nernst_planck.species",
            format!(
                "give 1 to {MAX_SPECIES} [[nernst_planck.species]] tables, got {}",
                table.species.len()
            ),
        ));
    }
    let mut list = Vec::with_capacity(table.species.len());
    for (k, t) in table.species.iter().enumerate() {
        let s = species(t, ctx, &format!("nernst_planck.species[{k}]"), &list)?;
        list.push(s);
    }
    let solid = table
        .solid
        .as_ref()
        .map(|s| s.to_solid(dim, "nernst_planck.solid"))
        .transpose()
        .map_err(|m| ctx.from_path_message(&m))?;
    if let Some(s) = table.saturation
        && !(s.is_finite() && s >= 0.0)
    {
        return Err(ctx.error(
            "nernst_planck.saturation",
            format!("a concentration ≥ 0, got {s}"),
        ));
    }
    let tolerance = table.tolerance.unwrap_or(1e-10);
    if !(tolerance > 0.0 && tolerance < 1.0) {
        return Err(ctx.error(
            "nernst_planck.tolerance",
            format!("a relative residual in (0, 1), got {tolerance}"),
        ));
    }
    let max_iterations = table.max_iterations.unwrap_or(4);
    if !(1..=100).contains(&max_iterations) {
        return Err(ctx.error(
            "nernst_planck.max_iterations",
            format!("1 to 100 Newton iterations, got {max_iterations}"),
        ));
    }
    let manufactured = table
        .manufactured
        .as_ref()
        .map(|m| manufactured(m, ctx, dim, &kernel, list.len()))
        .transpose()?;
    let concentration_unit = match table.concentration_unit {
        Some(q) => positive(ctx, "nernst_planck.concentration_unit", q.si())?,
        None => 1.0,
    };
    let linear = linear_method(table, ctx, dim)?;
    let reactions = table
        .reactions
        .as_ref()
        .map(|r| reactions(r, ctx, &list, table.saturation))
        .transpose()?;
    Ok(Some(NernstPlanckSpec {
        temperature,
        conductivity,
        kernel,
        solid,
        saturation: table.saturation,
        tolerance,
        max_iterations,
        species: list,
        manufactured,
        concentration_unit,
        linear,
        reactions,
    }))
}

fn linear_method(
    table: &NernstPlanckTable,
    ctx: &ErrorContext,
    dim: usize,
) -> Result<LinearMethod, SceneError> {
    let tolerance = table.linear_tolerance.unwrap_or(1e-12);
    if !(tolerance > 0.0 && tolerance < 1.0) {
        return Err(ctx.error(
            "nernst_planck.linear_tolerance",
            format!("a relative residual in (0, 1), got {tolerance}"),
        ));
    }
    let max_iterations = table.linear_iterations.unwrap_or(5000);
    if !(1..=1_000_000).contains(&max_iterations) {
        return Err(ctx.error(
            "nernst_planck.linear_iterations",
            format!("1 to 1000000 BiCGSTAB iterations, got {max_iterations}"),
        ));
    }
    let iterative = LinearMethod::Iterative {
        tolerance,
        max_iterations,
    };
    match table.linear_solver.as_deref().unwrap_or("auto") {
        "direct" => Ok(LinearMethod::Direct),
        "bicgstab" => Ok(iterative),
        "auto" if dim == 3 => Ok(iterative),
        "auto" => Ok(LinearMethod::Direct),
        other => Err(ctx.error(
            "nernst_planck.linear_solver",
            format!("`{other}`: one of \"direct\", \"bicgstab\", \"auto\""),
        )),
    }
}

fn reactions(
    r: &ReactionsTable,
    ctx: &ErrorContext,
    species: &[SpeciesSpec],
    saturation: Option<f64>,
) -> Result<ReactionLaw, SceneError> {
    let field = "nernst_planck.reactions";
    let find = |role: &str, name: &str| {
        species
            .iter()
            .position(|s| s.law.name == name)
            .ok_or_else(|| {
                ctx.error(
                    &format!("{field}.{role}"),
                    format!(
                        "`{name}` is not a species (have: {})",
                        species
                            .iter()
                            .map(|s| s.law.name.as_str())
                            .collect::<Vec<_>>()
                            .join(", ")
                    ),
                )
            })
    };
    let metal = find("metal", &r.metal)?;
    if metal != 0 {
        return Err(ctx.error(
            &format!("{field}.metal"),
            "must name the first species (the phase change reads C1)",
        ));
    }
    let roles = [
        metal,
        find("complex", &r.complex)?,
        find("hydrogen", &r.hydrogen)?,
        find("hydroxide", &r.hydroxide)?,
    ];
    if (1..4).any(|a| roles[..a].contains(&roles[a])) {
        return Err(ctx.error(field, "metal, complex, hydrogen and hydroxide must differ"));
    }
    let Some(saturation) = saturation.filter(|s| *s > 0.0) else {
        return Err(ctx.error(
            "nernst_planck.saturation",
            "the reactions' overpotential (3.103) needs C_sat > 0",
        ));
    };
    for (name, v) in [
        ("forward_1", r.forward_1),
        ("backward_1", r.backward_1),
        ("forward_2", r.forward_2),
        ("backward_2", r.backward_2),
        ("hydrogen_charge", r.hydrogen_charge),
        ("hydroxide_charge", r.hydroxide_charge),
    ] {
        if !(v.is_finite() && v >= 0.0) {
            return Err(ctx.error(&format!("{field}.{name}"), format!("≥ 0, got {v}")));
        }
    }
    for (name, v) in [
        ("hydrogen_current", r.hydrogen_current),
        ("hydroxide_current", r.hydroxide_current),
    ] {
        if !v.is_finite() {
            return Err(ctx.error(&format!("{field}.{name}"), "must be finite"));
        }
    }
    for (k, role) in [(roles[2], "hydrogen"), (roles[3], "hydroxide")] {
        if species[k].law.valence == 0.0 {
            return Err(ctx.error(
                &format!("{field}.{role}"),
                "an interface current J/(z F c_solid) needs a charged species (z ≠ 0)",
            ));
        }
    }
    let butler_volmer = r
        .butler_volmer
        .as_ref()
        .map(|b| -> Result<ButlerVolmer, SceneError> {
            let exchange = positive(
                ctx,
                &format!("{field}.butler_volmer.exchange"),
                b.exchange.si(),
            )?;
            for (name, v) in [("anodic", b.anodic), ("cathodic", b.cathodic)] {
                if !(v.is_finite() && (0.0..=1.0).contains(&v)) {
                    return Err(ctx.error(
                        &format!("{field}.butler_volmer.{name}"),
                        format!("a charge-transfer coefficient in [0, 1], got {v}"),
                    ));
                }
            }
            Ok(ButlerVolmer {
                exchange,
                anodic: b.anodic,
                cathodic: b.cathodic,
            })
        })
        .transpose()?;
    Ok(ReactionLaw {
        metal,
        complex: roles[1],
        hydrogen: roles[2],
        hydroxide: roles[3],
        forward_1: r.forward_1,
        backward_1: r.backward_1,
        forward_2: r.forward_2,
        backward_2: r.backward_2,
        hydrogen_current: r.hydrogen_current,
        hydroxide_current: r.hydroxide_current,
        hydrogen_charge: r.hydrogen_charge,
        hydroxide_charge: r.hydroxide_charge,
        solid_concentration: positive(
            ctx,
            &format!("{field}.solid_concentration"),
            r.solid_concentration.si(),
        )?,
        applied_potential: r.applied_potential.si(),
        standard_potential: r.standard_potential.si(),
        saturation,
        butler_volmer,
    })
}

fn manufactured(
    m: &ManufacturedTable,
    ctx: &ErrorContext,
    dim: usize,
    kernel: &NnppKernel,
    species: usize,
) -> Result<Manufactured, SceneError> {
    let field = "nernst_planck.manufactured";
    if dim != 1 || kernel.influence != Influence::Constant || kernel.exponents != [-0.5; 3] {
        return Err(ctx.error(
            field,
            "the closed-form integrals need dimension = 1, influence = \"constant\" and \
             exponents = [-0.5, -0.5, -0.5] (the kernel ω/r^{n+2q} = 1)",
        ));
    }
    for (name, v) in [("means", &m.means), ("amplitudes", &m.amplitudes)] {
        if v.len() != species || v.iter().any(|x| !x.is_finite()) {
            return Err(ctx.error(
                &format!("{field}.{name}"),
                format!("one finite value per species ({species}), got {v:?}"),
            ));
        }
    }
    let wavelength = positive(ctx, &format!("{field}.wavelength"), m.wavelength.si())?;
    let potential = m.potential.si();
    if !potential.is_finite() {
        return Err(ctx.error(&format!("{field}.potential"), "must be finite"));
    }
    Ok(Manufactured {
        wavenumber: std::f64::consts::TAU / wavelength,
        potential,
        means: m.means.clone(),
        amplitudes: m.amplitudes.clone(),
    })
}
