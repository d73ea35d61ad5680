//! Bi-material corrosion (thesis §2.3.3 / §3.4.1; seed-thesis-ch2-3 §1.6): bond classes by phase,
//! irreversible solid → liquid change below C_sat; `corrosion-1d`.

use peridyn_core::scene::Scene;
use peridyn_core::sim;
use peridyn_core::solver::Stepper;

/// Steps a scene to its end, returning (time, mass Σ C V, volume loss, solid nodes) each step.
fn history(variant: Option<&str>) -> Vec<(f64, f64, f64, f64)> {
    let scene = Scene::load("corrosion-1d", variant).unwrap();
    let mut sim = sim::build(&scene).unwrap();
    let mut rows = Vec::new();
    let mut record = |sim: &mut Box<dyn Stepper>| {
        let f = sim.frame();
        let get = |k: &str| f.scalar(k).unwrap();
        rows.push((
            f.time,
            get("field/integral"),
            get("corrosion/volume_loss"),
            get("corrosion/solid_nodes"),
        ));
    };
    record(&mut sim);
    for _ in 0..sim.info().total_steps {
        sim.step().unwrap();
        record(&mut sim);
    }
    rows
}

/// No-flux ends: total mass Σ C V is conserved to 1e-10 relative; the solid only shrinks.
#[test]
fn mass_is_conserved_and_the_solid_shrinks_monotonically() {
    for variant in [None, Some("fine")] {
        let h = history(variant);
        let m0 = h[0].1;
        let drift = h.iter().map(|r| (r.1 - m0).abs()).fold(0.0, f64::max) / m0;
        eprintln!(
            "{variant:?}: mass drift {drift:.2e}, final volume loss {:.4}",
            h.last().unwrap().2
        );
        assert!(drift < 1e-10, "{drift}");
        assert!(h.windows(2).all(|w| w[1].3 <= w[0].3 && w[1].2 >= w[0].2));
        assert!(h.last().unwrap().2 > 0.5, "the bar dissolves");
        assert_eq!(h[0].2, 0.0);
    }
}

fn time_to(variant: Option<&str>, loss: f64) -> f64 {
    history(variant)
        .iter()
        .find(|r| r.2 >= loss)
        .map(|r| r.0)
        .unwrap_or(f64::INFINITY)
}

/// The thesis (Fig. 3.23): the coarse model's solid vanishes earlier than the fine one's. That
/// holds for the original scheme (β = 1), whose coarse grid (m = 2) overestimates the second
/// moment by (m + 1)/m = 1.5; with β (3.2) the quadrature is exact at integer m and the coarse
/// front runs later instead (each coarse node is a larger chunk of solid).
#[test]
fn coarse_grid_against_fine() {
    let original = (
        time_to(Some("no-beta"), 0.999),
        time_to(Some("fine-no-beta"), 0.999),
    );
    let with_beta = (time_to(None, 0.999), time_to(Some("fine"), 0.999));
    eprintln!("solid gone (coarse, fine): β = 1 {original:?}, β {with_beta:?}");
    assert!(original.0 < original.1, "{original:?}");
    assert!(with_beta.0 > with_beta.1, "{with_beta:?}");
    assert!(with_beta.1.is_finite());
}

/// Steps `corrosion-3d` (variant, overrides) to its end; returns the frames' scalars every
/// `every` steps: (time, volume loss, solid nodes, Ω_s fraction, violations).
fn corrosion_3d(variant: Option<&str>, set: &[&str], every: u64) -> Vec<(f64, f64, f64, f64, f64)> {
    let set: Vec<String> = set.iter().map(|s| s.to_string()).collect();
    let scene = Scene::load_with("corrosion-3d", variant, &set).unwrap();
    let mut sim = sim::build(&scene).unwrap();
    let mut rows = Vec::new();
    for step in 0..=sim.info().total_steps {
        if step > 0 {
            sim.step().unwrap();
        }
        if step % every == 0 {
            let f = sim.frame();
            let get = |k: &str| f.scalar(k).unwrap_or(f64::NAN);
            rows.push((
                f.time,
                get("corrosion/volume_loss"),
                get("corrosion/solid_nodes"),
                get("hybrid/omega_s_fraction"),
                get("hybrid/violations"),
            ));
        }
    }
    rows
}

/// `corrosion-3d` (small: Δx = 0.15 mm, m = 4, Δt = 1 s, 3000 s): the fixed hybrid's relative volume
/// loss follows the all-standard run within 2 % of the initial solid volume at every output
/// time, while the solid dissolves past half its volume; no node of Ω_w is ever solid; the C = 0
/// layer drains mass; the solid only shrinks; Ω_s stays fixed.
#[test]
fn corrosion_3d_hybrid_volume_loss_follows_the_standard_scheme() {
    let hybrid = corrosion_3d(Some("small"), &[], 100);
    let standard = corrosion_3d(Some("small-standard"), &[], 100);
    let worst = largest_difference(&hybrid, &standard);
    let (last_h, last_s) = (hybrid.last().unwrap(), standard.last().unwrap());
    eprintln!(
        "largest volume-loss difference {worst:.4}; final {:.4} (hybrid) vs {:.4} (standard); Ω_s {:.2} %",
        last_h.1,
        last_s.1,
        100.0 * last_h.3
    );
    assert!(worst < 0.02, "{worst}");
    assert!(
        last_s.1 > 0.45,
        "the specimen loses about half its volume: {}",
        last_s.1
    );
    assert!(
        hybrid.iter().all(|r| r.4 == 0.0),
        "a node of Ω_w turned solid"
    );
    assert!(
        hybrid
            .iter()
            .all(|r| r.3 == hybrid[0].3 && r.3 > 0.0 && r.3 < 0.5)
    );
    for run in [&hybrid, &standard] {
        assert!(run.windows(2).all(|w| w[1].2 <= w[0].2 && w[1].1 >= w[0].1));
    }
}

fn largest_difference(
    hybrid: &[(f64, f64, f64, f64, f64)],
    standard: &[(f64, f64, f64, f64, f64)],
) -> f64 {
    assert_eq!(hybrid.len(), standard.len());
    hybrid
        .iter()
        .zip(standard)
        .map(|(h, s)| (h.1 - s.1).abs())
        .fold(0.0, f64::max)
}

/// The full scaled scene (195 k nodes, m = 6) at Δt = 1 s to 3000 s: minutes, so run on demand
/// (`cargo test --release --test corrosion -- --ignored`); the figure is in docs/validation.md.
#[test]
#[ignore]
fn corrosion_3d_full_size_hybrid_volume_loss_follows_the_standard_scheme() {
    let set = ["time.dt=\"1 s\"", "time.end=\"3000 s\""];
    let hybrid = corrosion_3d(None, &set, 100);
    let standard = corrosion_3d(Some("standard"), &set, 100);
    let worst = largest_difference(&hybrid, &standard);
    eprintln!(
        "largest volume-loss difference {worst:.4}; final {:.4} (hybrid) vs {:.4} (standard)",
        hybrid.last().unwrap().1,
        standard.last().unwrap().1
    );
    assert!(worst < 0.02, "{worst}");
}

/// The papers' m = 6 in CI (issue 14 item 6): `ci-m6` keeps the full scene's Δx = 0.1 mm,
/// δ = 0.6 mm (925-node families, 123 WLS collocation nodes) and specimen in a smaller sphere
/// (radius 3.0 mm), Ω_s the liquid within 2δ of the solid (39 % of the nodes, near the paper's
/// 35 %; the preset says why not 1.2δ). The fixed hybrid's relative volume loss follows the
/// all-standard run within 2 % of the initial solid volume at every output time (the criterion
/// of the other corrosion-3d checks), while the specimen loses a substantial part of its
/// volume; no node of Ω_w is ever solid; Ω_w is most of the sphere. 54 s for both runs here.
#[test]
fn corrosion_3d_m6_hybrid_volume_loss_follows_the_standard_scheme() {
    let hybrid = corrosion_3d(Some("ci-m6"), &[], 10);
    let standard = corrosion_3d(Some("ci-m6-standard"), &[], 10);
    let worst = largest_difference(&hybrid, &standard);
    let (last_h, last_s) = (hybrid.last().unwrap(), standard.last().unwrap());
    eprintln!(
        "m = 6: largest volume-loss difference {worst:.4}; final {:.4} (hybrid) vs {:.4} (standard); Ω_s {:.2} %",
        last_h.1,
        last_s.1,
        100.0 * last_h.3
    );
    assert!(worst < 0.02, "{worst}");
    assert!(last_s.1 > 0.3, "the specimen dissolves: {}", last_s.1);
    assert!(
        last_h.3 > 0.3 && last_h.3 < 0.45,
        "Ω_s near the paper's 35 %: {}",
        last_h.3
    );
    assert!(
        hybrid.iter().all(|r| r.4 == 0.0),
        "a node of Ω_w turned solid"
    );
}

/// With no held layer, the 3D bi-material scheme conserves mass (no-flux surface) to 1e-10.
#[test]
fn corrosion_3d_standard_conserves_mass_without_a_sink() {
    let set: Vec<String> = [
        "time.dt=\"5 s\"",
        "time.end=\"20000 s\"",
        "boundary=[]",
        "discretization.spacing=\"0.3 mm\"",
    ]
    .iter()
    .map(|s| s.to_string())
    .collect();
    let scene = Scene::load_with("corrosion-3d", Some("small-standard"), &set).unwrap();
    let mut sim = sim::build(&scene).unwrap();
    let mass = |sim: &mut Box<dyn Stepper>| sim.frame().scalar("field/integral").unwrap();
    let (m0, loss0) = (mass(&mut sim), 0.0);
    for _ in 0..sim.info().total_steps {
        sim.step().unwrap();
    }
    let f = sim.frame();
    let drift = (f.scalar("field/integral").unwrap() - m0).abs() / m0;
    let loss = f.scalar("corrosion/volume_loss").unwrap();
    eprintln!("mass drift {drift:.2e}, volume loss {loss:.4}");
    assert!(drift < 1e-10, "{drift}");
    assert!(loss > loss0, "some solid dissolves");
}
