//! S11 (thesis §4.3.6): DRAFT

use peridyn_core::scene::Scene;
use peridyn_core::sim::DynamicSimulation;
use peridyn_core::solver::Stepper;

/// Tuning aid: `VARIANTS=small,small-reference SET='a=1;b=2' EVERY=20` runs each variant and
/// prints time, crack length and angle, near-field energy and broken bonds every EVERY steps.
#[test]
#[ignore = "exploration"]
fn zz_half_space_series() {
    let variants = std::env::var("VARIANTS").unwrap_or_else(|_| "small".into());
    let every: u64 = std::env::var("EVERY").map_or(20, |s| s.parse().unwrap());
    let set = crate::common::env_overrides("SET");
    let preset = std::env::var("PRESET").unwrap_or_else(|_| "half-space-impact".into());
    for v in variants.split(',') {
        let s = Scene::load_with(&preset, Some(v), &set).unwrap();
        let wall = std::time::Instant::now();
        let mut sim = DynamicSimulation::<2>::new(&s).unwrap();
        eprintln!(
            "{v}: {} nodes, {} steps, setup {:.1} s",
            sim.reference().len(),
            sim.info().total_steps,
            wall.elapsed().as_secs_f64()
        );
        let mut n = 0u64;
        while !sim.run().clock.done() {
            if sim.step().is_err() {
                eprintln!("  diverged at step {n}");
                break;
            }
            n += 1;
            if n % every == 0 || sim.run().clock.done() {
                let f = sim.frame();
                let g = |k: &str| f.scalar(k).unwrap_or(f64::NAN);
                eprintln!(
                    "  t = {:6.2} µs: length {:6.2} mm, angle {:5.1}°, near {:.5e} J (layer's {:.5e}), total {:.5e}, broken {}",
                    1e6 * f.time,
                    1e3 * g("crack_length/right"),
                    g("crack_angle_deg/right"),
                    g("energy/circle/near"),
                    g("energy/near_field"),
                    g("energy/total"),
                    g("bonds/broken")
                );
            }
        }
        eprintln!("{v}: wall {:.1} s", wall.elapsed().as_secs_f64());
    }
}
