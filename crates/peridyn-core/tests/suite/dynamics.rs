//! Time integration: energy and momentum conservation, blow-up detection, bond failure.

use crate::common;

use std::sync::Arc;
use std::sync::atomic::AtomicBool;

use peridyn_core::frame::Frame;
use peridyn_core::runner::{self, FrameSink};
use peridyn_core::scene::Scene;
use peridyn_core::sim::{self, DynamicSimulation};
use peridyn_core::solver::{SimError, Stepper};

#[derive(Default)]
struct Collect(Vec<Frame>, Vec<String>);

impl FrameSink for Collect {
    fn send(&mut self, frame: Frame) {
        self.0.push(frame);
    }
    fn message(&mut self, _level: &str, text: &str) {
        self.1.push(text.to_string());
    }
}

fn run_to_end(scene: &Scene) -> (runner::RunSummary, Collect) {
    let mut sim = sim::build(scene).unwrap();
    let mut sink = Collect::default();
    let stop = Arc::new(AtomicBool::new(false));
    let summary = runner::run(sim.as_mut(), &mut sink, &stop, None, &mut |_, _| {});
    (summary, sink)
}

#[test]
fn free_plate_conserves_energy_and_momentum() {
    let scene = Scene::load("vibrating-plate", None).unwrap();
    let (summary, sink) = run_to_end(&scene);
    assert!(summary.error.is_none());
    assert_eq!(summary.steps, 2000);
    assert!((summary.info.dt / summary.info.stable_dt - 0.5).abs() < 1e-12);
    let e0 = sink.0[0].scalar("energy/total").unwrap();
    let mass_speed: f64 = {
        let sim = DynamicSimulation::<2>::new(&scene).unwrap();
        sim.velocities()
            .iter()
            .map(|v| (v[0] * v[0] + v[1] * v[1]).sqrt() * 2700.0 * 0.25e-6)
            .sum()
    };
    let p0 = [
        sink.0[0].scalar("momentum/x").unwrap(),
        sink.0[0].scalar("momentum/y").unwrap(),
    ];
    let mut worst = 0.0f64;
    for f in &sink.0 {
        let e = f.scalar("energy/total").unwrap();
        worst = worst.max((e / e0 - 1.0).abs());
        for (k, name) in ["momentum/x", "momentum/y"].iter().enumerate() {
            let p = f.scalar(name).unwrap();
            assert!(
                (p - p0[k]).abs() <= 1e-12 * mass_speed,
                "{name} drifted from {} to {p} at step {}",
                p0[k],
                f.step
            );
        }
    }
    let strain = sink
        .0
        .iter()
        .map(|f| f.scalar("energy/strain").unwrap())
        .fold(0.0, f64::max);
    assert!(
        strain > 0.1 * e0,
        "the plate must actually vibrate (max strain energy {strain:e})"
    );
    assert!(
        worst < 1e-3,
        "total energy varied by {:.3e} relative",
        worst
    );
}

#[test]
fn unstable_step_is_detected_and_stopped_before_non_finite_frames() {
    let text = Scene::load("vibrating-plate", None)
        .unwrap()
        .preset_text
        .replace(
            "dt = \"0.5 stable\"\nend = \"2000 steps\"",
            "dt = \"1.5 stable\"\nend = \"2000 steps\"\nallow_unstable = true",
        );
    let scene = Scene::from_text("unstable.toml", &text, None).unwrap();
    let (summary, sink) = run_to_end(&scene);
    match &summary.error {
        Some(SimError::Unstable { dt, stable_dt, .. }) => {
            assert!((dt / stable_dt - 1.5).abs() < 1e-9)
        }
        other => panic!("expected an instability, got {other:?}"),
    }
    assert!(summary.steps < 2000);
    assert!(
        sink.1.iter().any(|m| m.contains("instability")),
        "{:?}",
        sink.1
    );
    for f in &sink.0 {
        assert!(f.positions.iter().all(|v| v.is_finite()));
        assert!(
            f.fields
                .iter()
                .all(|fl| fl.values.iter().all(|v| v.is_finite()))
        );
        assert!(f.scalars.iter().all(|(_, v)| v.is_finite()));
    }
}

#[test]
fn dt_above_the_bound_needs_allow_unstable() {
    let text = Scene::load("vibrating-plate", None)
        .unwrap()
        .preset_text
        .replace("dt = \"0.5 stable\"", "dt = \"1.5 stable\"");
    let err = Scene::from_text("fast.toml", &text, None).unwrap_err();
    assert_eq!(err.field, "time.dt");
    assert!(err.message.contains("allow_unstable"), "{err}");
    // An absolute Δt is checked against (3.8) once the families exist.
    let text = Scene::load("vibrating-plate", None)
        .unwrap()
        .preset_text
        .replace("dt = \"0.5 stable\"", "dt = \"1 ms\"");
    let scene = Scene::from_text("fast.toml", &text, None).unwrap();
    let err = sim::build(&scene)
        .err()
        .expect("Δt above the bound is refused");
    assert_eq!(err.field, "time.dt");
    assert!(err.line.is_some());
    assert!(err.to_string().contains("fast.toml"), "{err}");
}

/// Two nodes joined by one bond (1D, m = 1): stretch it past s0, then bring it back.
#[test]
fn broken_bond_stays_broken_after_unloading() {
    let scene = common::scene(
        r#"
name = "pair"
dimension = 1
[geometry]
box = { min = [0.0], max = [1e-3] }
[discretization]
spacing = 1e-3
horizon = "1 dx"
[material]
density = 1000.0
youngs_modulus = 1e9
critical_stretch = 0.01
[time]
dt = "0.5 stable"
end = "1 steps"
"#,
    );
    let mut sim = DynamicSimulation::<1>::new(&scene).unwrap();
    assert_eq!(sim.families().bond_count(), 2);
    sim.positions_mut()[1][0] = 1e-3 * (1.0 + 0.009);
    sim.refresh_forces();
    assert!(sim.force_density()[0][0] > 0.0, "below s0 the bond pulls");
    assert_eq!(sim.broken_bonds(), 0);
    sim.positions_mut()[1][0] = 1e-3 * (1.0 + 0.011);
    sim.refresh_forces();
    assert_eq!(sim.broken_bonds(), 2, "both directed bonds break");
    assert_eq!(sim.force_density()[0][0], 0.0);
    sim.positions_mut()[1][0] = 1e-3;
    sim.refresh_forces();
    assert_eq!(sim.force_density()[0][0], 0.0, "no healing after unloading");
    sim.positions_mut()[1][0] = 1e-3 * 0.9;
    sim.refresh_forces();
    assert_eq!(
        sim.force_density()[0][0],
        0.0,
        "no force in compression either"
    );
    assert!(sim.intact.iter().all(|&b| b == 0));
    assert_eq!(sim.damage(), vec![1.0, 1.0]);
}

/// A centre node with the bonds on one side of a line through it cut has damage 0.5: the
/// family is symmetric, so the cut half carries half of Σ β V.
#[test]
fn damage_of_half_cut_family_is_one_half() {
    let scene = common::block(2, 20, 4.0, "strain", "");
    let mut sim = DynamicSimulation::<2>::new(&scene).unwrap();
    let c = (0..sim.reference().len())
        .find(|&i| sim.reference()[i] == [10e-3, 10e-3])
        .unwrap();
    let x = sim.reference()[c];
    let mut cut_weight = 0.0;
    for b in sim.families().range(c) {
        let j = sim.families().neighbors[b] as usize;
        let dx = sim.reference()[j][0] - x[0];
        let dy = sim.reference()[j][1] - x[1];
        // Upper half-plane, plus half of the horizontal axis.
        if dy > 0.0 || (dy == 0.0 && dx > 0.0) {
            sim.intact[b] = 0;
            cut_weight += 1.0;
        }
    }
    assert!(cut_weight > 0.0);
    let phi = sim.damage_from_bonds()[c];
    assert!((phi - 0.5).abs() < 1e-12, "damage {phi}");
}

/// The damage the force loop keeps up to date equals a fresh pass over the bond states,
/// pre-cracks included.
#[test]
fn incremental_damage_matches_a_pass_over_the_bonds() {
    let scene = Scene::load("kalthoff-winkler", Some("small")).unwrap();
    let mut sim = DynamicSimulation::<2>::new(&scene).unwrap();
    let check = |sim: &DynamicSimulation<2>| {
        let (a, b) = (sim.damage(), sim.damage_from_bonds());
        let worst = a
            .iter()
            .zip(&b)
            .map(|(x, y)| (x - y).abs())
            .fold(0.0, f64::max);
        assert!(worst < 1e-12, "worst difference {worst:e}");
        b.iter().filter(|&&d| d > 0.0).count()
    };
    let precracked = check(&sim);
    assert!(precracked > 0);
    for _ in 0..200 {
        sim.step().unwrap();
    }
    assert!(sim.broken_bonds() > 0);
    assert!(check(&sim) > precracked);
}
