//! 2D transient PD diffusion with a manufactured solution (seed-004 Example 2, thesis §3.2.6),
//! through the `diffusion-2d-manufactured` preset: (−0.5, 0.5)², 40 × 40 nodes, κ = 1, q = 2,
//! ω0, Dirichlet layer of width δ, forward Euler with Δt = 1e-5 to T = 0.1.

use peridyn::report::{self, SweepSpec};
use peridyn::runner::{self, NullSink};
use peridyn::scene::reference::{pd_of_quartic, quartic};
use peridyn::scene::{Scene, SchemeKind};
use peridyn::sim;
use peridyn::sim::DiffusionSimulation;
use peridyn::solver::SimError;

const PRESET: &str = "diffusion-2d-manufactured";

/// WLS-4 spans the quartic: its interior operator reproduces L[P] to round-off on both grids.
#[test]
fn wls4_reproduces_the_quartic_operator() {
    for variant in [None, Some("perturbed")] {
        let scene =
            Scene::load_with(PRESET, variant, &["discretization.scheme=wls-4".into()]).unwrap();
        let sim = DiffusionSimulation::<2>::new(&scene).unwrap();
        let p: Vec<f64> = sim.positions().iter().map(|x| quartic(x)).collect();
        let mut out = vec![f64::NAN; p.len()];
        sim.operator().apply(&p, &mut out);
        for &i in &sim.operator().rows {
            let x = &sim.positions()[i as usize];
            let exact = pd_of_quartic(x, scene.horizon);
            assert!(
                (out[i as usize] - exact).abs() < 1e-9,
                "{variant:?}: node {i}"
            );
        }
    }
}

/// Relative change of the final-time error between the uniform and the perturbed grid: at
/// δ = 5Δx the standard scheme's is ≥ 3× the WLS schemes' (thesis: 38.63 % vs 6.53 % and
/// 7.09 %). δ = 4Δx is reported, not asserted (WLS-2's change is close to the standard's).
#[test]
fn grid_sensitivity_standard_vs_wls() {
    let schemes = [SchemeKind::Standard, SchemeKind::Wls2, SchemeKind::Wls4];
    let errors = |variant: &str| -> Vec<f64> {
        let spec = SweepSpec {
            preset: PRESET.into(),
            variant: (variant != "base").then(|| variant.into()),
            set: Vec::new(),
            axes: Vec::new(),
            schemes: schemes.to_vec(),
        };
        report::run(&spec, &mut |_| {})
            .unwrap()
            .iter()
            .map(|r| {
                assert!(r.failure.is_none(), "{r:?}");
                r.error.unwrap()
            })
            .collect()
    };
    let mut changes = Vec::new();
    for (uniform, perturbed) in [("base", "perturbed"), ("m4", "m4-perturbed")] {
        let u = errors(uniform);
        let p = errors(perturbed);
        let change: Vec<f64> = u.iter().zip(&p).map(|(u, p)| (p - u).abs() / u).collect();
        for k in 0..3 {
            eprintln!(
                "{uniform:>5} {:<8}: uniform {:.3e}, perturbed {:.3e}, change {:.2} %",
                schemes[k].name(),
                u[k],
                p[k],
                100.0 * change[k]
            );
        }
        changes.push(change);
    }
    let m5 = &changes[0];
    assert!(m5[0] >= 3.0 * m5[1], "{m5:?}");
    assert!(m5[0] >= 3.0 * m5[2], "{m5:?}");
}

fn run_to_end(variant: &str, set: &[&str]) -> (Option<SimError>, u64) {
    let set: Vec<String> = set.iter().map(|s| s.to_string()).collect();
    let scene = Scene::load_with(PRESET, Some(variant), &set).unwrap();
    let mut sim = sim::build(&scene).unwrap();
    let stop = Default::default();
    let summary = runner::run(sim.as_mut(), &mut NullSink, &stop, None, &mut |_, _| {});
    (summary.error, summary.steps)
}

/// Forward Euler at 0.9× the power-iterated bound stays bounded for 10⁴ steps on the
/// perturbed grid; at 1.2× (variant `unstable`) it is detected and stopped with a message.
#[test]
fn forward_euler_bound_for_the_wls_operator() {
    let (error, steps) = run_to_end("perturbed", &["time.dt=\"0.9 stable\""]);
    assert!(error.is_none(), "0.9× must stay bounded: {error:?}");
    assert_eq!(steps, 10_000);
    let (error, steps) = run_to_end("unstable", &[]);
    let message = error.expect("1.2× must be stopped").to_string();
    assert!(steps < 10_000);
    assert!(message.contains("forward Euler diverged"), "{message}");
    assert!(message.contains("1.20×"), "{message}");
}

/// WLS-4's error on the uniform grid is forward Euler's: halving Δt (same T = 0.1) halves it,
/// while WLS-2's, dominated by its spatial error (it misses the 7πδ⁴/16 term), barely moves.
#[test]
fn wls4_error_is_time_stepping_error() {
    let error = |scheme: &str, dt: &str, steps: &str| -> f64 {
        let set = [
            format!("discretization.scheme={scheme}"),
            format!("time.dt={dt}"),
            format!("time.end=\"{steps} steps\""),
        ];
        let scene = Scene::load_with(PRESET, None, &set).unwrap();
        let mut sim = sim::build(&scene).unwrap();
        let summary = runner::run(
            sim.as_mut(),
            &mut NullSink,
            &Default::default(),
            None,
            &mut |_, _| {},
        );
        summary.relative_error.unwrap()
    };
    let wls4 = error("wls-4", "1e-5", "10000") / error("wls-4", "5e-6", "20000");
    let wls2 = error("wls-2", "1e-5", "10000") / error("wls-2", "5e-6", "20000");
    eprintln!("error ratio Δt → Δt/2: WLS-4 {wls4:.3}, WLS-2 {wls2:.3}");
    assert!((wls4 - 2.0).abs() < 0.1, "{wls4}");
    assert!((wls2 - 1.0).abs() < 0.2, "{wls2}");
}

/// Issue 14 item 2: the wide orbit stencil of the hybrid's Ω_w (the `medium-fast` set: orbits
/// (1,1), (2,1), (3,0) with weight exponent 6) keeps the manufactured solution's operator error
/// within 1.5× of the papers' δ/3 grid rule. WLS-2 on the quartic P of this preset against the
/// analytic nonlocal operator L[P] (thesis (3.78)): the largest error over the interior rows,
/// relative to the largest |L[P]|, on the uniform and the perturbed grid, at δ = 5Δx and 4Δx
/// (Kalthoff–Winkler's m). The orbits are defined in 2D only, so there is no 1D counterpart.
#[test]
fn orbit_stencil_keeps_the_manufactured_operator_error() {
    use peridyn::discretization::{Families, family};
    use peridyn::model::pmb::Influence;
    use peridyn::scheme::wls::{self, Basis, Collocation};
    for variant in [None, Some("perturbed"), Some("m4"), Some("m4-perturbed")] {
        let scene = Scene::load(PRESET, variant).unwrap();
        let sim = DiffusionSimulation::<2>::new(&scene).unwrap();
        let positions = sim.positions();
        let rows = sim.operator().rows.clone();
        let radius = family::search_radius(scene.family_radius, scene.horizon, scene.spacing);
        let families = Families::build(positions, radius);
        let basis = Basis::new(2, 2);
        // κ = 1, q = 2, ω = 1: the preset's kernel.
        let l = wls::diffusion_l(&basis, 1.0, 2.0, scene.horizon, Influence::Constant);
        let p: Vec<f64> = positions.iter().map(|x| quartic(x)).collect();
        // Orbit offsets are in lattice spacings.
        let orbits = Collocation::orbits(scene.spacing, &[[1, 1], [2, 1], [3, 0]], 6.0).unwrap();
        let error = |rule: Collocation| {
            let op = wls::diffusion_operator(
                &rows,
                positions,
                &families,
                &basis,
                &l,
                scene.horizon,
                rule,
            )
            .unwrap();
            let mut out = vec![0.0; p.len()];
            op.apply(&p, &mut out);
            let (mut worst, mut size) = (0.0f64, 0.0f64);
            for &i in &rows {
                let exact = pd_of_quartic(&positions[i as usize], scene.horizon);
                worst = worst.max((out[i as usize] - exact).abs());
                size = size.max(exact.abs());
            }
            worst / size
        };
        let (grid, wide) = (error(Collocation::grid(3)), error(orbits));
        eprintln!(
            "{variant:?}: WLS-2 operator error, δ/3 grid {grid:.3e}, orbits {wide:.3e} ({:.2}×)",
            wide / grid
        );
        assert!(
            wide <= 1.5 * grid,
            "{variant:?}: orbits {wide:e} against grid {grid:e}"
        );
    }
}
