//! What the commands print: one line on a built scene, and a run's summary.

use crate::control::driver::field_hash;
use crate::runner::RunSummary;
use crate::scene::{CoarseScheme, Physics, Scene};
use crate::solver::SimInfo;

/// A ratio to a bound, readable from 10⁻⁶ to 10.
fn ratio(r: f64) -> String {
    if r >= 0.01 {
        format!("{r:.3}")
    } else {
        format!("{r:.2e}")
    }
}

/// One line on a built scene: size, scheme, time step against its bound, steps.
pub fn describe(scene: &Scene, info: &SimInfo, steps: Option<u64>) -> String {
    let name = match &scene.variant {
        Some(v) => format!("{} [{v}]", scene.name),
        None => scene.name.clone(),
    };
    let steps = steps.unwrap_or(info.total_steps).min(info.total_steps);
    let coarse = match scene.multigrid.as_ref().map(|m| &m.coarse) {
        Some(CoarseScheme::Wls(_)) => " (coarse level WLS-2)",
        _ => "",
    };
    let stencil = format!(
        "{} scheme{coarse}, {:.1} nodes per stencil",
        scene.scheme.kind.name(),
        info.stencil
    );
    match scene.physics {
        Physics::Static => format!(
            "{name}: {}D static, {} nodes, {stencil}, {} operator entries, one global solve",
            info.dim, info.nodes, info.bonds
        ),
        Physics::Diffusion | Physics::Corrosion => format!(
            "{name}: {}D {}, {} nodes, {stencil}, Δt = {:.4e} s ({} × forward Euler's \
             bound {:.4e} s from {}), {steps} steps, a frame every {}",
            info.dim,
            if scene.physics == Physics::Corrosion {
                "corrosion"
            } else {
                "diffusion"
            },
            info.nodes,
            info.dt,
            ratio(info.dt / info.stable_dt),
            info.stable_dt,
            if info.stable_dt == info.gershgorin_dt {
                "Gershgorin discs; the step is below it, no power iteration needed"
            } else {
                "the operator's spectral radius"
            },
            info.frame_every
        ),
        Physics::NernstPlanck => format!(
            "{name}: {}D Nernst–Planck–Poisson, {} nodes, {stencil}, Δt = {:.4e} s \
             (semi-implicit Newton; explicit Euler's bound {:.4e} s), {steps} steps, a frame \
             every {}",
            info.dim, info.nodes, info.dt, info.gershgorin_dt, info.frame_every
        ),
        Physics::ScalarWave => format!(
            "{name}: {}D scalar wave, {} nodes, {stencil}, Δt = {:.4e} s ({} × velocity-Verlet's \
             bound {:.4e} s), {steps} steps, a frame every {}",
            info.dim,
            info.nodes,
            info.dt,
            ratio(info.dt / info.stable_dt),
            info.stable_dt,
            info.frame_every
        ),
        Physics::Dynamics => format!(
            "{name}: {}D, {} nodes, {} directed bonds ({:.2} GB of bond and node arrays at the \
             start), Δt = {:.4e} s ({:.2}× the stable bound {:.4e} s; (3.8) estimate {:.4e} s), \
             {steps} steps, a frame every {}",
            info.dim,
            info.nodes,
            info.bonds,
            info.bytes_per_bond * info.bonds as f64 / 1e9,
            info.dt,
            info.dt / info.stable_dt,
            info.stable_dt,
            info.gershgorin_dt,
            info.frame_every
        ),
    }
}

/// A run's summary: speed, stages, error or volume loss or broken bonds, energies, crack
/// angles, and the final time with a hash of every field of the last frame (equal hashes:
/// equal fields, bit for bit).
pub fn print_summary(s: &RunSummary) {
    println!(
        "steps: {}  frames: {}  wall: {:.2} s  steps/s: {:.1}  bond evaluations/s: {:.3e}  frame share: {:.1} %",
        s.steps,
        s.frames,
        s.wall_seconds,
        s.steps_per_second(),
        s.bond_evaluations_per_second(),
        100.0 * s.frame_seconds / s.wall_seconds.max(1e-12)
    );
    let stages: Vec<String> = s
        .stages
        .iter()
        .filter(|(_, t)| *t > 0.0)
        .map(|(n, t)| format!("{n} {t:.2} s"))
        .collect();
    println!("stages: {}", stages.join(", "));
    let last = |key: &str| s.last_frame.as_ref().and_then(|f| f.scalar(key));
    if let Some(e) = s.relative_error {
        println!("relative l2 error (3.79): {e:.6e}");
    } else if let Some(loss) = last("corrosion/volume_loss") {
        println!(
            "relative volume loss: {loss:.4}  solid nodes: {}  mass Σ C V: {:.10e}",
            last("corrosion/solid_nodes").unwrap_or(0.0),
            last("field/integral").unwrap_or(0.0)
        );
    } else {
        println!("broken bonds: {}", s.broken_bonds);
    }
    if let (Some(bonds), Some(full), Some(filtered)) = (
        last("hybrid/checked_bonds"),
        last("hybrid/full_checks"),
        last("hybrid/filtered_checks"),
    ) {
        println!(
            "switching check: {full} full (epoch) checks, {filtered} filtered, {bonds:.4e} bonds \
             checked exactly ({:.0} per check), {} slacks kept by epochs, Ω_s {:.2} %",
            bonds / (full + filtered).max(1.0),
            last("hybrid/reused_slacks").unwrap_or(0.0),
            100.0 * last("hybrid/omega_s_fraction").unwrap_or(0.0)
        );
    }
    if let (Some(coarse), Some(fine), Some(fictitious)) = (
        last("grid/coarse_active"),
        last("grid/fine_active"),
        last("grid/fictitious"),
    ) {
        println!(
            "grid levels at the end: {coarse} coarse active, {fine} fine active, {fictitious} \
             fictitious nodes"
        );
    }
    if let Some(r) = last("adr/residual") {
        println!(
            "dynamic relaxation: residual ‖F‖/‖F_ext‖ {r:.3e} after {} iterations",
            s.steps
        );
    }
    if let Some(f) = &s.last_frame {
        for key in ["energy/kinetic", "energy/strain", "energy/total"] {
            if let Some(v) = f.scalar(key) {
                println!("{key}: {v:.6e} J");
            }
        }
        // Region energies and crack lengths of the scene's `[metrics]`.
        for (key, v) in &f.scalars {
            if key.starts_with("energy/circle/") || key == "energy/near_field" {
                println!("{key}: {v:.6e} J");
            } else if key.starts_with("crack_length/") {
                println!("{key}: {:.3} mm", 1e3 * v);
            }
        }
        let hash = |values: &[f64]| field_hash(values.iter().map(|v| v.to_bits()));
        if let Some(d) = f.fields.iter().find(|f| f.name == "damage") {
            println!("final damage hash: {:016x}", hash(&d.values));
        }
        let mut hashes = vec![format!("positions {:016x}", hash(&f.positions))];
        hashes.extend(
            f.fields
                .iter()
                .map(|n| format!("{} {:016x}", n.name, hash(&n.values))),
        );
        hashes.extend(f.classes.iter().map(|c| {
            let ids = field_hash(c.ids.iter().map(|&v| v as u64));
            format!("{} {ids:016x}", c.name)
        }));
        println!(
            "final time: {:e} s  field hashes: {}",
            f.time,
            hashes.join(", ")
        );
    }
    for (name, angle) in &s.crack_angles {
        match angle {
            Some(a) => println!("crack angle {name}: {a:.1}°"),
            None => println!("crack angle {name}: no crack found"),
        }
    }
}
