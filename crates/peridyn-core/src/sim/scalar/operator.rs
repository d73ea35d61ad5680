//! The scalar operator of a scene: its physical kernel, its assembly on the solved rows (the
//! standard scheme (3.4), WLS (seed-thesis-ch2-3 §3.4), or each level of a multi-grid scene
//! with its own quadrature), and which rows run WLS in a fixed hybrid or a WLS coarse level.

use crate::adapt::fixed;
use crate::adapt::masks::{GridClass, Phase, SchemeClass};
use crate::adapt::multigrid::MultiGrid;
use crate::discretization::{Discretization, Families, Quadrature};
use crate::model::diffusion::DiffusionKernel;
use crate::model::pmb::{Influence, PmbLaw};
use crate::scene::{CoarseScheme, Scene, SceneError};
use crate::scheme::ScalarOperator;
use crate::scheme::standard;
use crate::scheme::wls::{self, Basis, Collocation};

/// The physical kernel of the scene's scalar operator (κ_liq for corrosion).
pub fn kernel(scene: &Scene, dim: usize) -> DiffusionKernel {
    match (&scene.diffusion, &scene.material) {
        (Some(d), _) => DiffusionKernel {
            diffusivity: d.diffusivity,
            exponent: d.exponent,
            influence: d.influence,
            horizon: scene.horizon,
        },
        (None, m) => DiffusionKernel {
            diffusivity: m.as_ref().map_or(0.0, |m| {
                PmbLaw::new(&m.constants, scene.horizon, dim).micromodulus
            }),
            exponent: 1.0,
            influence: m
                .as_ref()
                .map_or(Influence::Constant, |m| m.constants.influence),
            horizon: scene.horizon,
        },
    }
}

/// Assembles the scheme's operator with `kernel` on the rows `free` (standard (3.4) or WLS
/// seed-thesis-ch2-3 §3.4).
pub fn assemble<const D: usize>(
    scene: &Scene,
    positions: &[[f64; D]],
    volumes: &[f64],
    families: &Families,
    kernel: &DiffusionKernel,
    free: &[u32],
) -> Result<ScalarOperator, String> {
    match scene.scheme.kind.wls_order() {
        // Identical cells and nominal β, also on a perturbed grid
        // (seed-004 Example 2; seed-thesis-ch2-3 §4.2).
        None => Ok(standard::diffusion_operator::<D>(
            free,
            volumes,
            families,
            &Quadrature::of_scene(scene),
            kernel,
        )),
        Some(order) => {
            let basis = Basis::new(D, order);
            let l = wls::diffusion_l(
                &basis,
                kernel.diffusivity,
                kernel.exponent,
                scene.horizon,
                kernel.influence,
            );
            wls::diffusion_operator(
                free,
                positions,
                families,
                &basis,
                &l,
                scene.horizon,
                scene.scheme.collocation,
            )
            .map_err(|e| e.to_string())
        }
    }
}

/// The operator on `rows` with `kernel`: on a multi-grid scene each level's rows with its own
/// quadrature (β of its spacing), else the scene's scheme.
pub fn operator<const D: usize>(
    scene: &Scene,
    discretization: &Discretization<D>,
    multigrid: Option<&MultiGrid<D>>,
    kernel: &DiffusionKernel,
    rows: &[u32],
) -> Result<ScalarOperator, SceneError> {
    let (positions, volumes) = (
        discretization.nodes.reference(),
        discretization.nodes.volumes(),
    );
    let families = &discretization.families;
    match multigrid {
        Some(g) => {
            let level = |fine: bool, quadrature: &Quadrature| {
                let rows: Vec<u32> = rows
                    .iter()
                    .copied()
                    .filter(|&i| g.class[i as usize].is_fine() == fine)
                    .collect();
                standard::diffusion_operator::<D>(&rows, volumes, families, quadrature, kernel)
            };
            Ok(ScalarOperator::concat(
                level(false, &g.coarse),
                level(true, &g.fine),
            ))
        }
        None => assemble(scene, positions, volumes, families, kernel, rows)
            .map_err(|m| scene.error("discretization.collocation_factor", m)),
    }
}

/// The WLS rows of a scalar scene, with the collocation rule and the preset table it came
/// from: Ω_w of the fixed corrosion hybrid (`hybrid`; `phase` the initial phases of a
/// corrosion scene), or the active coarse nodes of a multi-grid scene whose coarse level runs
/// WLS (`multigrid.coarse = "wls"`, the thesis's §3.5.2 screw: "coarse WLS elsewhere"). On the
/// multi-grid, coarse nodes within δ of the initial solid stay standard (their bonds carry the
/// phases' classes; the solid only shrinks, so a WLS row never sees one), as do held,
/// fictitious and fine nodes.
pub fn wls_mask<const D: usize>(
    scene: &Scene,
    positions: &[[f64; D]],
    phase: Option<&[Phase]>,
    multigrid: Option<&MultiGrid<D>>,
    is_held: &[bool],
) -> Option<(Vec<SchemeClass>, Collocation, &'static str)> {
    let solid = |band: f64| {
        let solid: Vec<bool> = match phase {
            Some(phase) => phase.iter().map(|p| p.is_solid()).collect(),
            None => vec![false; positions.len()],
        };
        fixed::corrosion_mask(positions, &solid, is_held, band)
    };
    match (&scene.hybrid, multigrid, scene.multigrid.as_ref()) {
        (Some(spec), None, _) if phase.is_some() => {
            Some((solid(spec.band), scene.scheme.collocation, "hybrid"))
        }
        (_, Some(g), Some(spec)) => {
            let CoarseScheme::Wls(rule) = spec.coarse else {
                return None;
            };
            let mut mask = solid(scene.horizon);
            for (m, class) in mask.iter_mut().zip(&g.class) {
                if *m == SchemeClass::Wls && *class != GridClass::CoarseActive {
                    *m = SchemeClass::Standard;
                }
            }
            Some((mask, rule, "multigrid"))
        }
        _ => None,
    }
}
