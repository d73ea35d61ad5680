//! 3D bi-material corrosion of a threaded screw on two grid levels (thesis §3.5.2,
//! seed-thesis-ch2-3 §8.8): `screw-3d --variant small` (fine level in a cylinder around the
//! screw) against `small-fine` (uniform, on the fine level's nodes). The multi-grid run must
//! lose the uniform fine run's solid volume, within 3 % of the initial solid volume at every
//! frame (the bound), over the 2 days the paper compares, while the front moves.

use peridyn_core::scene::Scene;
use peridyn_core::sim;
use peridyn_core::solver::Stepper;

const PRESET: &str = "screw-3d";

/// (time, relative volume loss, solid nodes) at every frame of a run, and its node count.
fn volume_loss(variant: &str) -> (Vec<(f64, f64, f64)>, usize) {
    let scene = Scene::load(PRESET, Some(variant)).unwrap();
    let mut s = sim::build(&scene).unwrap();
    let every = s.info().frame_every.max(1);
    let total = s.info().total_steps;
    let sample = |s: &mut Box<dyn Stepper>| {
        let f = s.frame();
        (
            f.time,
            f.scalar("corrosion/volume_loss").unwrap(),
            f.scalar("corrosion/solid_nodes").unwrap(),
        )
    };
    let mut out = vec![sample(&mut s)];
    while s.steps_done() < total {
        s.step().unwrap();
        if s.steps_done().is_multiple_of(every) || s.steps_done() == total {
            out.push(sample(&mut s));
        }
    }
    (out, s.info().nodes)
}

#[test]
fn the_multi_grid_screw_loses_the_uniform_fine_runs_volume() {
    let (multi, multi_nodes) = volume_loss("small");
    let (fine, fine_nodes) = volume_loss("small-fine");
    eprintln!("nodes: multi-grid {multi_nodes}, uniform fine {fine_nodes}");
    assert_eq!(multi.len(), fine.len());
    // The same solid on the same nodes at the start (the fine level's sub-cells are the
    // uniform fine lattice, anchored Δx⁻/2 off the coarse one).
    assert_eq!(multi[0].2, fine[0].2, "solid nodes at t = 0");
    let mut worst: f64 = 0.0;
    for (m, f) in multi.iter().zip(&fine) {
        assert!(
            (m.0 - f.0).abs() < 1e-6 * f.0.max(1.0),
            "{} vs {}",
            m.0,
            f.0
        );
        eprintln!(
            "t = {:.2} d: volume loss multi-grid {:.4}, uniform fine {:.4}",
            m.0 / 86400.0,
            m.1,
            f.1
        );
        worst = worst.max((m.1 - f.1).abs());
    }
    let end = fine.last().unwrap().1;
    assert!(end > 0.05, "the front must move in the window: {end}");
    assert!(worst <= 0.03, "largest difference {worst}");
    assert!(multi_nodes < fine_nodes);
}
