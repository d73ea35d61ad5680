//! Cost per node-step of the WLS scheme against the standard scheme at equal m (seed-004
//! §2.7: n_c d² flops per node against ≈ 2 × family × (sqrt + 10) flops): 2D m = 12 (49
//! collocation nodes against a 441-node family) and 3D m = 6 (123 against 925), for
//! elasticity (standard: the PMB force loop with bond states; WLS: precomputed D × D blocks)
//! and for diffusion (both as precomputed sparse rows).

use std::fmt::Write as _;
use std::time::Instant;

use crate::discretization::Quadrature;
use crate::discretization::family::Families;
use crate::discretization::grid::Lattice;
use crate::model::diffusion::DiffusionKernel;
use crate::model::pmb::{Influence, Plane};
use crate::model::pmb::{PmbLaw, micromodulus};
use crate::scene::Solid;
use crate::scheme::standard::{self, NodeTerms, Standard};
use crate::scheme::wls::{self, Basis};

/// Seconds per call of `f`, repeated for at least `budget` seconds (and 3 calls).
fn seconds_per_call(budget: f64, mut f: impl FnMut()) -> f64 {
    f();
    let start = Instant::now();
    let mut calls = 0u32;
    while calls < 3 || start.elapsed().as_secs_f64() < budget {
        f();
        calls += 1;
    }
    start.elapsed().as_secs_f64() / f64::from(calls)
}

struct Case {
    dim: usize,
    m: usize,
    k_aux: usize,
    side: usize,
}

/// Rows whose horizon ball lies inside the box (full families and collocation sets).
fn interior<const D: usize>(lattice: &Lattice<D>, side: f64, horizon: f64) -> Vec<u32> {
    (0..lattice.len() as u32)
        .filter(|&i| {
            lattice.positions[i as usize]
                .iter()
                .all(|&x| x >= horizon - 1e-9 && x <= side - horizon + 1e-9)
        })
        .collect()
}

fn measure<const D: usize>(case: &Case, budget: f64, out: &mut String) -> Result<(), String> {
    let side = case.side as f64;
    let solid = Solid::Box {
        min: vec![0.0; D],
        max: vec![side; D],
    };
    let lattice = Lattice::<D>::build(&solid, 1.0, [0.0; 2], 1);
    let horizon = case.m as f64;
    let families = Families::build(&lattice.positions, horizon * (1.0 + 1e-9));
    let rows = interior(&lattice, side, horizon);
    let quadrature = Quadrature {
        spacing: 1.0,
        horizon,
        volume_correction: true,
    };
    let c = micromodulus(1.0, horizon, D, Plane::Strain, Influence::Constant);
    let law = PmbLaw {
        micromodulus: c,
        critical_stretch: f64::INFINITY,
        influence: Influence::Constant,
        horizon,
    };
    let scheme = Standard {
        reference: &lattice.positions,
        volumes: &lattice.volumes,
        uniform_volume: Some(1.0),
        families: &families,
        law: &law,
        quadrature: &quadrature,
    };
    let displaced: Vec<[f64; D]> = lattice
        .positions
        .iter()
        .map(|x| std::array::from_fn(|k| x[k] * (1.0 + 1e-4 * (k + 1) as f64)))
        .collect();
    let mut intact = standard::intact_bonds(families.bond_count());
    let mut terms = vec![NodeTerms::<D>::default(); lattice.len()];
    // The loop runs over every node; boundary nodes have smaller families, so the cost is
    // scaled to a node with a full family: time per bond × its bonds.
    let full_family = rows
        .first()
        .map_or(0, |&i| families.range(i as usize).len());
    let standard_elastic = seconds_per_call(budget, || {
        scheme.forces(&displaced, &mut intact, &mut terms);
    }) / families.bond_count() as f64
        * full_family as f64;
    let family = full_family as f64 + 1.0;

    let basis = Basis::new(D, 2);
    let started = Instant::now();
    let l = wls::bond_l(&basis, c, horizon, Influence::Constant);
    let op = wls::elasticity_operator(
        &rows,
        &lattice.positions,
        &families,
        &basis,
        &l,
        horizon,
        wls::Collocation::grid(case.k_aux),
    )
    .map_err(|e| e.to_string())?;
    let assembly = started.elapsed().as_secs_f64() / rows.len() as f64;
    let collocation = op.columns.len() as f64 / rows.len() as f64;
    let displacement: Vec<[f64; D]> = displaced
        .iter()
        .zip(&lattice.positions)
        .map(|(y, x)| std::array::from_fn(|k| y[k] - x[k]))
        .collect();
    let mut force = vec![[0.0; D]; rows.len()];
    let wls_elastic =
        seconds_per_call(budget, || op.apply_rows(&displacement, &mut force)) / rows.len() as f64;

    let kernel = DiffusionKernel {
        diffusivity: 1.0,
        exponent: 2.0,
        influence: Influence::Constant,
        horizon,
    };
    let standard_op =
        standard::diffusion_operator::<D>(&rows, &lattice.volumes, &families, &quadrature, &kernel);
    let l_c = wls::diffusion_l(&basis, 1.0, 2.0, horizon, Influence::Constant);
    let wls_op = wls::diffusion_operator(
        &rows,
        &lattice.positions,
        &families,
        &basis,
        &l_c,
        horizon,
        wls::Collocation::grid(case.k_aux),
    )
    .map_err(|e| e.to_string())?;
    let field: Vec<f64> = lattice.positions.iter().map(|x| x[0] * x[0]).collect();
    let mut rate = vec![0.0; rows.len()];
    let standard_diffusion =
        seconds_per_call(budget, || standard_op.apply_rows(&field, &mut rate)) / rows.len() as f64;
    let wls_diffusion =
        seconds_per_call(budget, || wls_op.apply_rows(&field, &mut rate)) / rows.len() as f64;

    let ns = 1e9;
    let _ = writeln!(
        out,
        "| {}D, m = {} | elasticity | {:.0} | {:.0} | {:.1} | {:.1} | {:.2}× | {:.1} |",
        case.dim,
        case.m,
        family,
        collocation,
        standard_elastic * ns,
        wls_elastic * ns,
        standard_elastic / wls_elastic,
        assembly * 1e6
    );
    let _ = writeln!(
        out,
        "| {}D, m = {} | diffusion | {:.0} | {:.0} | {:.1} | {:.1} | {:.2}× | |",
        case.dim,
        case.m,
        standard_op.columns.len() as f64 / rows.len() as f64,
        wls_op.columns.len() as f64 / rows.len() as f64,
        standard_diffusion * ns,
        wls_diffusion * ns,
        standard_diffusion / wls_diffusion
    );
    Ok(())
}

/// The Markdown table of per-node-step costs; `budget` seconds of timing per entry.
pub fn report(budget: f64) -> Result<String, String> {
    let threads = rayon::current_num_threads();
    let mut out = format!(
        "## WLS against standard at equal m ({threads} threads)\n\n\
         Per node and step, for nodes with full neighbourhoods on a uniform lattice. Elasticity: \
         the standard scheme's PMB force loop (bond states, stretch, square root) against the \
         WLS blocks K_ij (D × D); diffusion: both as precomputed sparse rows.\n\n\
         | case | operator | standard stencil | WLS stencil | standard (ns/node-step) | \
         WLS (ns/node-step) | speed-up | WLS assembly (µs/node, once) |\n\
         |---|---|---:|---:|---:|---:|---:|---:|\n"
    );
    measure::<2>(
        &Case {
            dim: 2,
            m: 12,
            k_aux: 4,
            side: 96,
        },
        budget,
        &mut out,
    )?;
    measure::<3>(
        &Case {
            dim: 3,
            m: 6,
            k_aux: 3,
            side: 24,
        },
        budget,
        &mut out,
    )?;
    Ok(out)
}
