//! The multi-adaptive scheme for dynamic fracture (thesis §3.5.1; seed-thesis-ch2-3 §7, §8.7):
//! `kalthoff-winkler-multigrid --variant small` (Δx⁺ = 1 mm, Δx⁻ = 0.5 mm, δ = 4 mm) against its
//! uniform fine and coarse references, each at 0.7 of its own stable step. The fine level must
//! follow the cracks (fine active count growing, coarse falling, no coarse bond broken), the
//! active cells must tile the body (mass exact), the locally updated node roles must equal a
//! classification from scratch, and the physics must match the uniform fine run (crack
//! angles, the energy in the 10 mm circle at the upper tip, the thesis's Fig. 3.35).

use peridyn::discretization::{Families, family};
use peridyn::scene::Scene;
use peridyn::scheme::standard::{NodeTerms, Standard};
use peridyn::sim::{self, DynamicSimulation};
use peridyn::solver::Stepper;

const PRESET: &str = "kalthoff-winkler-multigrid";

/// The preset's scene ("" for its base, the scaled run), a frame every other step (the
/// series of runs with different steps are compared by interpolating in time: a dense
/// cadence keeps that interpolation out of the comparison). `variant|key=value|…` adds
/// overrides.
fn scene(variant: &str) -> Scene {
    let mut parts = variant.split('|');
    let name = parts.next().unwrap_or_default();
    let mut set = vec!["output.every=2".to_string()];
    set.extend(parts.map(str::to_string));
    Scene::load_with(PRESET, (!name.is_empty()).then_some(name), &set).unwrap()
}

/// One frame's time and scalars.
struct Sample {
    time: f64,
    scalars: Vec<(String, f64)>,
}

impl Sample {
    fn get(&self, name: &str) -> Option<f64> {
        self.scalars
            .iter()
            .find(|(n, _)| n == name)
            .map(|(_, v)| *v)
    }
}

/// Every frame of a run to its end (at the preset's cadence, and the last step).
fn samples(stepper: &mut dyn Stepper) -> Vec<Sample> {
    let every = stepper.info().frame_every.max(1);
    let take = |s: &mut dyn Stepper| {
        let f = s.frame();
        Sample {
            time: f.time,
            scalars: f.scalars,
        }
    };
    let mut out = vec![take(stepper)];
    let total = stepper.info().total_steps;
    while stepper.steps_done() < total {
        stepper.step().unwrap();
        if stepper.steps_done().is_multiple_of(every) || stepper.steps_done() == total {
            out.push(take(stepper));
        }
    }
    out
}

fn series(samples: &[Sample], name: &str) -> Vec<f64> {
    samples.iter().map(|f| f.get(name).unwrap()).collect()
}

/// The last crack angle a run reported under `name`.
fn last_angle(samples: &[Sample], name: &str) -> f64 {
    samples
        .iter()
        .rev()
        .find_map(|f| f.get(&format!("crack_angle_deg/{name}")))
        .unwrap_or_else(|| panic!("no {name} crack"))
}

/// A series linearly interpolated at time `t`.
fn at(samples: &[Sample], name: &str, t: f64) -> f64 {
    let k = samples
        .partition_point(|s| s.time < t)
        .clamp(1, samples.len() - 1);
    let (a, b) = (&samples[k - 1], &samples[k]);
    let w = ((t - a.time) / (b.time - a.time)).clamp(0.0, 1.0);
    a.get(name).unwrap() * (1.0 - w) + b.get(name).unwrap() * w
}

/// Runs a multi-adaptive variant and asserts what holds for it alone (the fine level follows
/// the cracks, no coarse bond breaks, roles and tiling exact); returns its frames.
fn multi_adaptive_run(variant: &str) -> Vec<Sample> {
    let mut multi = DynamicSimulation::<2>::new(&scene(variant)).unwrap();
    let body = |sim: &DynamicSimulation<2>| -> f64 {
        let g = sim.multigrid().unwrap();
        g.active_volumes(sim.volumes()).iter().sum()
    };
    let area = body(&multi);
    let run = samples(&mut multi);
    assert_the_fine_level_is_where_it_is_used(&multi);
    let g = multi.multigrid().unwrap();
    let classes_agree = g.classes_from_scratch(multi.families()) == g.class;
    let tiling = (body(&multi) / area - 1.0).abs();
    let fine_active = series(&run, "grid/fine_active");
    let coarse_active = series(&run, "grid/coarse_active");
    let coarse_broken = series(&run, "grid/coarse_broken");
    let last = run.len() - 1;
    eprintln!(
        "{variant}: fine active {} → {}, coarse active {} → {}, {} frames",
        fine_active[0],
        fine_active[last],
        coarse_active[0],
        coarse_active[last],
        run.len()
    );
    assert!(
        fine_active.windows(2).all(|w| w[1] >= w[0]),
        "{fine_active:?}"
    );
    assert!(
        coarse_active.windows(2).all(|w| w[1] <= w[0]),
        "{coarse_active:?}"
    );
    assert!(fine_active[last] > 1.2 * fine_active[0], "{fine_active:?}");
    assert!(coarse_broken.iter().all(|&b| b == 0.0), "{coarse_broken:?}");
    assert!(
        classes_agree,
        "locally updated roles differ from a classification from scratch"
    );
    // The cells of active nodes tile the body: Σ V over active nodes never changes (to the
    // round-off of a sum of n terms, n ε).
    let n = multi.volumes().len() as f64;
    assert!(tiling < n * f64::EPSILON, "{tiling:e}");
    run
}

/// The fine level holds only the nodes in use: every fine node that is not active lies in the
/// family of an active fine node (within one horizon of a refined cell), and the level holds
/// fewer nodes than the whole fine lattice.
fn assert_the_fine_level_is_where_it_is_used(sim: &DynamicSimulation<2>) {
    let g = sim.multigrid().unwrap();
    let families = sim.families();
    let mut in_a_family = vec![false; g.class.len()];
    for (i, _) in g.fine_nodes().filter(|&(i, _)| g.class[i].is_active()) {
        for b in families.range(i) {
            in_a_family[families.neighbors[b] as usize] = true;
        }
    }
    let fine: Vec<usize> = g.fine_nodes().map(|(i, _)| i).collect();
    let stray = fine
        .iter()
        .filter(|&&i| !g.class[i].is_active() && !in_a_family[i])
        .count();
    assert_eq!(
        stray, 0,
        "fine nodes farther than one horizon from a refined cell"
    );
    let lattice = g.fine_lattice().len();
    eprintln!(
        "fine level: {} nodes of the lattice's {lattice}",
        fine.len()
    );
    assert!(fine.len() < lattice, "{} of {lattice}", fine.len());
}

/// Runs the multi-adaptive variants against their uniform fine and coarse references and
/// asserts what the thesis's §3.5.1 shows (see the module comment); prints every figure.
fn compare(multi_variants: &[&str], fine_variant: &str, coarse_variant: &str, strict: bool) {
    let fine = samples(sim::build(&scene(fine_variant)).unwrap().as_mut());
    let coarse = samples(sim::build(&scene(coarse_variant)).unwrap().as_mut());
    let energy = "energy/circle/upper_tip";
    let peak = series(&fine, energy).into_iter().fold(0.0, f64::max);
    // The largest difference from the uniform fine run's tip-circle energy, relative to its
    // peak, and when (each run has its own step: the fine series is interpolated).
    let worst = |samples: &[Sample]| {
        samples
            .iter()
            .map(|s| {
                let d = (s.get(energy).unwrap() - at(&fine, energy, s.time)).abs() / peak;
                (d, s.time)
            })
            .fold((0.0, 0.0), |a, b| if b.0 > a.0 { b } else { a })
    };
    let worst_coarse = worst(&coarse);
    let far = "damage/count/far_edge";
    eprintln!(
        "uniform fine: tip-circle energy peak {peak:.4e} J/m; uniform coarse differs by up to \
         {:.2} % of it (at {:.1} µs); damaged nodes near the far edge: fine {}, coarse {}",
        100.0 * worst_coarse.0,
        1e6 * worst_coarse.1,
        fine[fine.len() - 1].get(far).unwrap(),
        coarse[coarse.len() - 1].get(far).unwrap()
    );
    let mut over = Vec::new();
    for variant in multi_variants {
        let run = multi_adaptive_run(variant);
        for name in ["upper", "lower"] {
            let (m, f, c) = (
                last_angle(&run, name),
                last_angle(&fine, name),
                last_angle(&coarse, name),
            );
            eprintln!(
                "{variant}: {name} crack angle {m:.2}°, uniform fine {f:.2}°, uniform coarse {c:.2}°"
            );
            assert!((m - f).abs() <= 3.0, "{variant} {name}: {m} vs {f}");
        }
        // The energy in the 10 mm circle at the upper tip within 5 % of the uniform fine
        // run's peak at every frame.
        let worst_multi = worst(&run);
        eprintln!(
            "{variant}: tip-circle energy within {:.2} % of the fine peak (worst at {:.1} µs); \
             damaged nodes near the far edge {}",
            100.0 * worst_multi.0,
            1e6 * worst_multi.1,
            run[run.len() - 1].get(far).unwrap()
        );
        // The issue's target is 5 % of the peak (the scaled test asserts it); the adaptive
        // run must at least be closer to the uniform fine run than the uniform coarse run is.
        assert!(
            worst_multi.0 < worst_coarse.0,
            "{variant}: {worst_multi:?} vs {worst_coarse:?}"
        );
        if strict && worst_multi.0 > 0.05 {
            over.push(format!("{variant}: {worst_multi:?}"));
        }
    }
    assert!(
        over.is_empty(),
        "tip-circle energy beyond 5 % of the peak: {over:?}"
    );
}

#[test]
fn small_multi_adaptive_runs_follow_the_crack_and_match_the_uniform_fine_run() {
    compare(
        &["small", "small-hybrid", "small-hybrid-fast"],
        "small-fine",
        "small-coarse",
        false,
    );
}

/// The scaled runs of the preset (Δx⁺ = 2/3 mm, Δx⁻ = 1/3 mm), with the issue's 5 % bound on the
/// tip-circle energy: about 2 minutes for the four runs on 2 cores;
/// `cargo test --release -- --ignored scaled`.
#[test]
#[ignore = "3 min, and fails today: tip-circle energy 6.3 % (standard), 17.1 % (hybrid, δ/3) and 16.8 % (hybrid, orbits) of the peak off (issue 16 open)"]
fn scaled_multi_adaptive_runs_follow_the_crack_and_match_the_uniform_fine_run() {
    compare(&["", "hybrid", "hybrid-fast"], "fine", "coarse", true);
}

/// A plate 40 mm square, δ = 4 mm, its fine level in a band of 2δ along the edges: under a
/// homogeneous strain the bulk of a uniform lattice carries no force; what active nodes more
/// than δ from the edges carry is the coupling's error (IDW does not reproduce a linear field
/// at fine fictitious nodes). Measured against the free edges' surface-effect force.
fn interface_force_ratio(coarse_mm: f64) -> f64 {
    let text = format!(
        r#"
name = "patch"
dimension = 2
[geometry]
box = {{ min = ["0 mm", "0 mm"], max = ["40 mm", "40 mm"] }}
[discretization]
spacing = "{coarse_mm} mm"
horizon = "4 mm"
family_radius = "horizon"
volume_correction = true
[multigrid]
ratio = 2
band = "2 horizon"
[material]
model = "pmb"
density = "8000 kg/m^3"
youngs_modulus = "190 GPa"
fracture_energy = "1e9 J/m^2"
plane = "strain"
[time]
dt = "0.5 stable"
end = "10 steps"
"#
    );
    let scene = crate::common::scene(&text);
    let mut sim = DynamicSimulation::<2>::new(&scene).unwrap();
    // Rigid translation first: every active node force-free to round-off.
    let reference = sim.reference().to_vec();
    for (y, x) in sim.positions_mut().iter_mut().zip(&reference) {
        *y = [x[0] + 1e-4, x[1] - 2e-4];
    }
    sim.refresh_forces();
    let active: Vec<bool> = {
        let g = sim.multigrid().unwrap();
        g.class.iter().map(|c| c.is_active()).collect()
    };
    let force = |sim: &DynamicSimulation<2>, i: usize| {
        let f = sim.force_density()[i];
        (f[0] * f[0] + f[1] * f[1]).sqrt()
    };
    let strain = 1e-4;
    let translation_max = (0..reference.len())
        .filter(|&i| active[i])
        .map(|i| force(&sim, i))
        .fold(0.0, f64::max);
    for (y, x) in sim.positions_mut().iter_mut().zip(&reference) {
        *y = [x[0] * (1.0 + strain), x[1] * (1.0 + 0.5 * strain)];
    }
    sim.refresh_forces();
    let forces = sim.force_density();
    let magnitude = |i: usize| (forces[i][0].powi(2) + forces[i][1].powi(2)).sqrt();
    let edge_distance = |x: &[f64; 2]| x[0].min(x[1]).min(0.04 - x[0]).min(0.04 - x[1]);
    let (mut edge, mut interface) = (0.0f64, 0.0f64);
    for i in (0..reference.len()).filter(|&i| active[i]) {
        if edge_distance(&reference[i]) < 0.004 {
            edge = edge.max(magnitude(i));
        } else {
            interface = interface.max(magnitude(i));
        }
    }
    // Relative to the free-edge force of a unit strain: the stretch of a translated bond is
    // round-off of positions ~ 0.04 m over bonds ~ 1 mm, ~ 1e-14, not zero.
    let unit_strain_force = edge / strain;
    assert!(
        translation_max <= 1e-12 * unit_strain_force,
        "rigid translation: {translation_max:e} against {unit_strain_force:e}"
    );
    eprintln!(
        "rigid translation: largest active-node force {:.2e} of the unit-strain edge force",
        translation_max / unit_strain_force
    );
    interface / edge
}

#[test]
fn patch_tests_across_the_level_interface() {
    let coarse = interface_force_ratio(1.0);
    let fine = interface_force_ratio(0.5);
    eprintln!(
        "homogeneous strain: largest interface force / free-edge force {coarse:.3e} \
         (Δx⁺ = 1 mm), {fine:.3e} (Δx⁺ = 0.5 mm)"
    );
    assert!(fine < coarse, "{fine:e} vs {coarse:e}");
}

/// A recording of the scaled run (the preset's base, ≈ 20 s) read back: the `nodes/grid`
/// classes of the last frame match the logged counts, inactive nodes are not drawn, and point
/// counts change between frames.
#[test]
fn the_recording_shows_the_fine_level_following_the_crack() {
    use peridyn::adapt::masks::GridClass;
    use peridyn::readback;
    let dir = std::env::temp_dir().join(format!("peridyn-multiadaptive-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("kw-multigrid-scaled.rrd");
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_peridyn"))
        .args(["record", PRESET, "-q", "-o"])
        .arg(&path)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let rec = readback::read(&path).unwrap();
    let grid = rec
        .entity("/nodes/grid")
        .expect("the grid classes are logged");
    let (&last, ids) = grid.classes.iter().next_back().unwrap();
    let count = |c: GridClass| ids.iter().filter(|&&k| k == c.id()).count() as f64;
    let metric = |name: &str| {
        rec.entity(&format!("/metrics/grid/{name}"))
            .unwrap()
            .scalars[&last]
    };
    assert_eq!(count(GridClass::FineActive), metric("fine_active"));
    assert_eq!(count(GridClass::CoarseActive), metric("coarse_active"));
    assert_eq!(
        count(GridClass::FineFictitious) + count(GridClass::CoarseFictitious),
        metric("fictitious")
    );
    assert!(
        ids.iter().all(|&k| k <= GridClass::FineFictitious.id()),
        "inactive drawn"
    );
    let counts: Vec<usize> = grid.points.values().copied().collect();
    assert!(counts.windows(2).any(|w| w[0] != w[1]), "{counts:?}");
    assert!(
        rec.entity("/log/events")
            .unwrap()
            .texts
            .iter()
            .any(|t| t.contains("coarse cells refined")),
        "switch events logged"
    );
    std::fs::remove_dir_all(&dir).ok();
}

/// The scaled run with the initial fine band twice the thesis's (`wide-band`, 2 δ) meets the
/// issue's 5 % bound on the tip-circle energy (measured 3.74 %); with χ = 0.8 instead of 0.95
/// (a measurement for planning) it does not (5.38 %), which the second run reports only.
#[test]
#[ignore = "3 min: the scaled runs with a wider band and a lower χ (issue 16)"]
fn scaled_wide_band_run_meets_the_energy_bound() {
    compare(&["wide-band"], "fine", "coarse", true);
    compare(&["|multigrid.chi=0.8"], "fine", "coarse", false);
}

/// A WLS coarse level takes issue 14's orbit stencils (`multigrid.collocation_orbits`,
/// `multigrid.fit_weight`); bad fields are refused naming the `multigrid` field and its range,
/// and a stencil too small for WLS-2 names it when the level is built.
#[test]
fn bad_coarse_stencil_fields_are_refused_with_the_field_and_range() {
    let refused = |variant: &str, set: &str| {
        Scene::load_with(PRESET, Some(variant), &[set.to_string()])
            .err()
            .unwrap_or_else(|| panic!("`{variant}` with `{set}` was accepted"))
            .to_string()
    };
    for (variant, set, field, phrase) in [
        (
            "small",
            "multigrid.collocation_orbits=[[1, 1]]",
            "multigrid.collocation_orbits",
            "coarse = \"wls\"",
        ),
        (
            "small",
            "multigrid.fit_weight=6.0",
            "multigrid.fit_weight",
            "coarse = \"wls\"",
        ),
        (
            "small-hybrid",
            "multigrid.collocation_orbits=[[1, 1]]",
            "multigrid.collocation_orbits",
            "not both",
        ),
        (
            "small-hybrid-fast",
            "multigrid.fit_weight=65.0",
            "multigrid.fit_weight",
            "[0, 64]",
        ),
        (
            "small-hybrid-fast",
            "multigrid.collocation_orbits=[[0, 0]]",
            "multigrid.collocation_orbits",
            "(0, 0)",
        ),
    ] {
        let message = refused(variant, set);
        assert!(
            message.contains(field) && message.contains(phrase),
            "{variant} {set}: {message}"
        );
    }
    let scene = Scene::load_with(
        PRESET,
        Some("small-hybrid-fast"),
        &["multigrid.collocation_orbits=[[1, 0]]".to_string()],
    )
    .unwrap();
    let fit = DynamicSimulation::<2>::new(&scene)
        .err()
        .expect("a 5-node stencil cannot fit WLS-2")
        .to_string();
    assert!(fit.contains("multigrid.collocation_orbits"), "{fit}");
}

/// The scaled runs with every family the whole β band (`full-band*`: both schemes then carry
/// the PD continuum's stiffness, see the preset) meet the issue's 5 % bound on the tip-circle
/// energy, the "adaptive, hybrid" run with the orbit stencil and a 1.25 δ initial band (measured
/// 2.74 % standard, 2.31 % hybrid; uniform coarse 2.79 %).
#[test]
#[ignore = "1 min: the four scaled runs with the whole β band (passes: 3.10 % and 1.72 % on 2026-12-07)"]
fn scaled_full_band_runs_meet_the_energy_bound() {
    compare(
        &["full-band", "full-band-hybrid"],
        "full-band-fine",
        "full-band-coarse",
        true,
    );
}

/// Cells refined mid-run give the forces of a fine level built whole: after 120 steps of
/// `small` (cells refined by the switch), every active fine node's family is its family in
/// `Families::build` over the whole fine lattice (the same neighbours in the same order, the
/// same lengths bit for bit), and the standard scheme over that whole level, at the run's
/// positions and bond states, gives every active fine node the run's force to 1e-12 of the
/// largest.
#[test]
fn refining_mid_run_gives_the_forces_of_a_level_built_whole() {
    let scene = scene("small");
    let mut sim = DynamicSimulation::<2>::new(&scene).unwrap();
    for _ in 0..120 {
        sim.step().unwrap();
    }
    let g = sim.multigrid().unwrap();
    assert!(g.refined_by_switch > 0, "no cell refined by the switch yet");
    let lattice = g.fine_lattice();
    let radius = family::search_radius(scene.family_radius, scene.horizon, g.fine.spacing);
    let whole = Families::build(lattice, radius);
    let mut key_of = vec![u32::MAX; g.class.len()];
    let mut positions = lattice.to_vec();
    for (i, k) in g.fine_nodes() {
        key_of[i] = k;
        positions[k as usize] = sim.positions()[i];
    }
    let families = sim.families();
    let mut intact = vec![1u8; whole.bond_count()];
    let mut skip = vec![1u8; lattice.len()];
    let active: Vec<(usize, u32)> = g
        .fine_nodes()
        .filter(|&(i, _)| g.class[i].is_active())
        .collect();
    for &(i, k) in &active {
        let k = k as usize;
        skip[k] = 0;
        let row: Vec<u32> = families.neighbors[families.range(i)]
            .iter()
            .map(|&j| key_of[j as usize])
            .collect();
        assert_eq!(row, whole.neighbors[whole.range(k)], "family of node {i}");
        let bits = |l: &[f64]| l.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
        assert_eq!(bits(families.row_lengths(i)), bits(whole.row_lengths(k)));
        for (bw, bl) in whole.range(k).zip(families.range(i)) {
            intact[bw] = sim.intact[bl];
        }
    }
    let volume = g.fine.spacing.powi(2);
    let volumes = vec![volume; lattice.len()];
    let level = Standard {
        reference: lattice,
        volumes: &volumes,
        uniform_volume: Some(volume),
        families: &whole,
        law: &sim.law,
        quadrature: &g.fine,
    };
    let mut terms = vec![NodeTerms::default(); lattice.len()];
    level.forces_masked(&positions, &mut intact, &mut terms, Some(&skip), false);
    let run = sim.force_density();
    let norm = |f: [f64; 2]| (f[0] * f[0] + f[1] * f[1]).sqrt();
    let largest = active
        .iter()
        .map(|&(i, _)| norm(run[i]))
        .fold(0.0, f64::max);
    let worst = active
        .iter()
        .map(|&(i, k)| {
            let w = terms[k as usize].force;
            norm([run[i][0] - w[0], run[i][1] - w[1]])
        })
        .fold(0.0, f64::max);
    eprintln!(
        "{} active fine nodes: largest force difference {:.2e} of the largest force",
        active.len(),
        worst / largest
    );
    assert!(
        largest > 0.0 && worst <= 1e-12 * largest,
        "{worst:e} of {largest:e}"
    );
}

/// The stable step's bound from the levels' lattice symbols covers the coupled operator: the
/// spectral radius (Arnoldi) of the linearized operator per unit mass with the fictitious
/// nodes interpolated from the other level lies below the bound, and within 3 % of it, at
/// the start and after the switch has refined cells.
#[test]
fn the_levels_symbol_bound_covers_the_coupled_operator() {
    let mut sim = DynamicSimulation::<2>::new(&scene("small")).unwrap();
    let check = |sim: &DynamicSimulation<2>, when: &str| {
        let (bound, radius) = sim.multigrid_stability().unwrap();
        eprintln!(
            "{when}: coupled radius {radius:.6e}, bound {bound:.6e} ({:.4})",
            radius / bound
        );
        assert!(
            radius <= bound && bound <= 1.03 * radius,
            "{when}: {radius:e} against {bound:e}"
        );
    };
    check(&sim, "start");
    for _ in 0..150 {
        sim.step().unwrap();
    }
    assert!(sim.multigrid().unwrap().refined_by_switch > 0);
    check(&sim, "after 150 steps");
}

/// The fine level built where it is used gives the fields of the level built whole: at one
/// Δt (3.3e-7 s: the stable step's estimate changed with it), the final-field hashes of the
/// build that made the whole fine level up front (2026-12-07, before the change).
#[test]
fn the_fine_level_built_on_demand_leaves_the_fields_unchanged() {
    let cases = [
        (
            "small",
            "positions a09c9cc65846b7bc, damage 231a8e7453edfc09, velocity 5157fd6636b88c67, \
             grid 8159fcae21bad347",
        ),
        (
            "small-hybrid",
            "positions e49462b6c7d1e12b, damage 679fa2a1fe37dfd9, velocity a3e49dc4e9b1ab47, \
             grid fff22dadf2d06be6",
        ),
    ];
    for (variant, hashes) in cases {
        let out = crate::common::temp("multiadaptive", &format!("{variant}.rrd"));
        let run = crate::common::peridyn(&[
            "record",
            PRESET,
            "--variant",
            variant,
            "--set",
            "time.dt=\"3.3e-7 s\"",
            "-q",
            "-o",
            out.to_str().unwrap(),
        ]);
        let stdout = String::from_utf8_lossy(&run.stdout);
        assert!(
            run.status.success(),
            "{}",
            String::from_utf8_lossy(&run.stderr)
        );
        assert!(stdout.contains(hashes), "{variant}: {stdout}");
    }
}
