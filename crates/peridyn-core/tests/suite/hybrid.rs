//! The hybrid configuration (thesis §3.3, seed-thesis-ch2-3 §5): one grid, Ω_s standard (PMB with
//! failure) and Ω_w WLS-2 (linearized), Ω_s grown where bonds reach χ·s0.

use peridyn_core::adapt::hybrid::Hybrid;
use peridyn_core::adapt::masks::SchemeClass;
use peridyn_core::runner::{self, NullSink};
use peridyn_core::scene::Scene;
use peridyn_core::sim::DynamicSimulation;
use peridyn_core::solver::Stepper;

fn load(preset: &str, variant: &str, set: &[&str]) -> Scene {
    let set: Vec<String> = set.iter().map(|s| s.to_string()).collect();
    Scene::load_with(preset, Some(variant), &set).unwrap_or_else(|e| panic!("{e}"))
}

/// With Ω_s = everything (a band wider than the plate) and χ = 1, the hybrid code path gives
/// the standard scheme's result bit for bit.
#[test]
fn all_standard_hybrid_is_bit_identical_to_the_standard_scheme() {
    let common = ["time.dt=\"50 ns\"", "time.end=\"120 steps\""];
    let mut standard =
        DynamicSimulation::<2>::new(&load("kalthoff-winkler", "small", &common)).unwrap();
    let mut with_hybrid = DynamicSimulation::<2>::new(&load(
        "kalthoff-winkler",
        "small-hybrid",
        &[
            common[0],
            common[1],
            "hybrid.band=\"1 m\"",
            "hybrid.chi=1.0",
        ],
    ))
    .unwrap();
    assert_eq!(with_hybrid.hybrid().unwrap().standard_fraction(), 1.0);
    for _ in 0..120 {
        standard.step().unwrap();
        with_hybrid.step().unwrap();
    }
    assert!(standard.broken_bonds() > 0, "cracks started");
    assert_eq!(standard.broken_bonds(), with_hybrid.broken_bonds());
    assert_eq!(standard.positions(), with_hybrid.positions(), "bit for bit");
    assert_eq!(standard.velocities(), with_hybrid.velocities());
}

/// With Ω_w = everything and no failure, the hybrid code path is velocity-Verlet on the WLS
/// operator: ρ ü = K u, compared with the same integration done by hand.
#[test]
fn all_wls_hybrid_is_the_wls_scheme() {
    let scene = load(
        "vibrating-plate",
        "small",
        &[
            "discretization.scheme=\"hybrid-fixed\"",
            "time.dt=\"20 ns\"",
        ],
    );
    let mut sim = DynamicSimulation::<2>::new(&scene).unwrap();
    let n = sim.reference().len();
    let everything_wls = vec![SchemeClass::Wls; n];
    let spec = scene.hybrid.unwrap();
    let h = Hybrid::new(
        spec,
        everything_wls,
        sim.reference(),
        sim.families(),
        &sim.law,
        3,
    )
    .unwrap();
    // The reference: the same operator, integrated here.
    let op = peridyn_core::scheme::wls::elasticity_operator(
        &(0..n as u32).collect::<Vec<_>>(),
        sim.reference(),
        sim.families(),
        &peridyn_core::scheme::wls::Basis::new(2, 2),
        &peridyn_core::scheme::wls::bond_l(
            &peridyn_core::scheme::wls::Basis::new(2, 2),
            sim.law.micromodulus,
            sim.law.horizon,
            sim.law.influence,
        ),
        sim.law.horizon,
        3,
    )
    .unwrap();
    sim.set_hybrid(h);
    sim.refresh_forces();
    let rho = scene.material.as_ref().unwrap().density;
    let dt = sim.clock().dt();
    let reference = sim.reference().to_vec();
    let mut y = sim.positions().to_vec();
    let mut v = sim.velocities().to_vec();
    let accel = |y: &[[f64; 2]]| -> Vec<[f64; 2]> {
        let u: Vec<[f64; 2]> = y
            .iter()
            .zip(&reference)
            .map(|(p, x)| [p[0] - x[0], p[1] - x[1]])
            .collect();
        let mut f = vec![[0.0; 2]; n];
        op.apply_rows(&u, &mut f);
        f.iter().map(|f| [f[0] / rho, f[1] / rho]).collect()
    };
    let mut a = accel(&y);
    for _ in 0..200 {
        sim.step().unwrap();
        for i in 0..n {
            for k in 0..2 {
                v[i][k] += 0.5 * dt * a[i][k];
                y[i][k] += dt * v[i][k];
            }
        }
        a = accel(&y);
        for i in 0..n {
            for k in 0..2 {
                v[i][k] += 0.5 * dt * a[i][k];
            }
        }
    }
    // The reference sums K u row by row; the hybrid over translation runs (another order).
    // u is dominated by the rigid drift of the plate (0.3 m/s), which K u cancels to about
    // six digits, so the two roundings part at ~1e-9 of the speed after 200 steps; a wrong
    // block or column would differ at O(1).
    let scale = v.iter().flatten().fold(0.0f64, |m, x| m.max(x.abs()));
    for i in 0..n {
        for k in 0..2 {
            assert!(
                (sim.velocities()[i][k] - v[i][k]).abs() <= 1e-7 * scale,
                "node {i}"
            );
            assert!((sim.positions()[i][k] - y[i][k]).abs() <= 1e-12);
        }
    }
    assert_eq!(sim.broken_bonds(), 0);
}

/// Runs a hybrid KW scene step by step, checking the invariant (no bond broken with an Ω_w
/// end) after every step and that Ω_s only grows; returns (simulation, Ω_s fractions).
fn run_checked(scene: &Scene) -> (DynamicSimulation<2>, Vec<f64>) {
    let mut sim = DynamicSimulation::<2>::new(scene).unwrap();
    let mut fractions = vec![sim.hybrid().unwrap().standard_fraction()];
    for _ in 0..sim.clock().total_steps() {
        sim.step().unwrap();
        assert_eq!(
            sim.enforce_hybrid_invariant(),
            0,
            "damage reached Ω_w at step {}",
            sim.steps_done()
        );
        let f = sim.hybrid().unwrap().standard_fraction();
        assert!(f >= *fractions.last().unwrap(), "Ω_s only grows");
        fractions.push(f);
    }
    (sim, fractions)
}

/// A Kalthoff–Winkler `medium` hybrid variant against all standard on the same grid and Δt:
/// crack angles within 2° and in 60–72°, damage fields agree (fewer than 2 % of nodes differ
/// by > 0.3), Ω_s grows monotonically from within 1.5 points of the thesis's 9.72 % to within
/// 1.5 points of its 14.70 %; no bond ever breaks in Ω_w. Returns the standard run.
fn matches_the_standard_scheme(variant: &str) -> DynamicSimulation<2> {
    let hybrid_scene = load("kalthoff-winkler", variant, &[]);
    let (mut h, fractions) = run_checked(&hybrid_scene);
    // The same grid and time step, all standard.
    let dt = format!("time.dt={}", h.clock().dt());
    let mut s = DynamicSimulation::<2>::new(&load("kalthoff-winkler", "medium", &[&dt])).unwrap();
    let stop = Default::default();
    runner::run(&mut s, &mut NullSink, &stop, None, &mut |_, _| {});
    assert_eq!(s.steps_done(), h.steps_done());
    let (initial, last) = (fractions[0], *fractions.last().unwrap());
    eprintln!(
        "Ω_s {:.2} % → {:.2} %, broken bonds {} (hybrid) vs {} (standard)",
        100.0 * initial,
        100.0 * last,
        h.broken_bonds(),
        s.broken_bonds()
    );
    assert!(last > initial, "Ω_s followed the cracks");
    // The thesis (seed-thesis-ch2-3 §8.3): Ω_s 9.72 % initially, 14.70 % at the end; within
    // ±1.5 points (issue 14 item 6; the grid is the scaled m = 4 one, not the thesis's m = 8).
    assert!((initial - 0.0972).abs() <= 0.015, "initial Ω_s {initial}");
    assert!((last - 0.1470).abs() <= 0.015, "final Ω_s {last}");
    for ((name, a), (_, b)) in h.crack_angles().iter().zip(s.crack_angles()) {
        let (a, b) = (a.unwrap(), b.unwrap());
        eprintln!("{name}: hybrid {a:.1}°, standard {b:.1}°");
        // Within 2° of each other and in 60–72° (issue 14 item 6: a band around the
        // experiment's ≈ 70° that the PD runs of the papers fall in).
        assert!((a - b).abs() <= 2.0, "{name}: {a} vs {b}");
        assert!((60.0..=72.0).contains(&a), "{name}: hybrid {a}");
        assert!((60.0..=72.0).contains(&b), "{name}: standard {b}");
    }
    let (dh, ds) = (h.damage(), s.damage());
    let differ = dh
        .iter()
        .zip(&ds)
        .filter(|(a, b)| (*a - *b).abs() > 0.3)
        .count();
    let share = differ as f64 / dh.len() as f64;
    eprintln!(
        "nodes whose damage differs by > 0.3: {:.3} %",
        100.0 * share
    );
    assert!(share < 0.02);
    // Damage only in Ω_s.
    let mask = h.hybrid().unwrap().mask().to_vec();
    assert!(
        dh.iter()
            .zip(&mask)
            .all(|(d, &m)| m == SchemeClass::Standard || *d == 0.0)
    );
    let _ = h.frame();
    s
}

/// `medium-hybrid` (the papers' δ/3 stencil) matches the standard scheme; no bond ever breaks
/// in Ω_w, also with χ raised to 0.99.
#[test]
fn kalthoff_winkler_medium_hybrid_matches_the_standard_scheme() {
    let s = matches_the_standard_scheme("medium-hybrid");

    // χ = 0.99 on the same scene: every broken bond still inside Ω_s (checked after every
    // step by `run_checked`), the cracks still pull Ω_s along and keep their angles. (Ω_s
    // need not end smaller than at χ = 0.95: the switched regions change the crack path a
    // little; measured 14.27 % against 14.24 %.)
    let (high, fractions) = run_checked(&load(
        "kalthoff-winkler",
        "medium-hybrid",
        &["hybrid.chi=0.99"],
    ));
    let high_last = *fractions.last().unwrap();
    eprintln!(
        "χ = 0.99: Ω_s {:.2} % → {:.2} %, broken bonds {}",
        100.0 * fractions[0],
        100.0 * high_last,
        high.broken_bonds()
    );
    assert!(high.broken_bonds() > 0, "the cracks ran");
    assert!(high_last > fractions[0], "Ω_s followed the cracks");
    assert_eq!(high.hybrid_violations(), 0);
    assert!(high_last < 0.4);
    for ((name, a), (_, b)) in high.crack_angles().iter().zip(s.crack_angles()) {
        let (a, b) = (a.unwrap(), b.unwrap());
        eprintln!("χ = 0.99, {name}: hybrid {a:.1}°, standard {b:.1}°");
        assert!((a - b).abs() <= 3.0, "χ = 0.99, {name}: {a} vs {b}");
    }
}

/// `medium-fast` (the m = 4 orbit stencil) matches the standard scheme in the same terms. Its
/// coupling grows modes at the interface (`undamped_soft_stencil_couplings_grow`); without the
/// interface damping Ω_s ends at 21.4 % and this fails.
#[test]
fn kalthoff_winkler_medium_fast_matches_the_standard_scheme() {
    matches_the_standard_scheme("medium-fast");
}

/// Lowering χ enlarges Ω_s; χ = 0.99 still keeps damage out of Ω_w (every bond of Ω_w is
/// checked every step, so a bond is switched before it can break); χ changes live.
#[test]
fn chi_controls_the_size_of_omega_s() {
    let fraction = |chi: &str| -> f64 {
        let scene = load(
            "kalthoff-winkler",
            "small-hybrid",
            &[&format!("hybrid.chi={chi}")],
        );
        let (sim, _) = run_checked(&scene);
        sim.hybrid().unwrap().standard_fraction()
    };
    let (low, default, high) = (fraction("0.8"), fraction("0.95"), fraction("0.99"));
    eprintln!("Ω_s at the end: χ = 0.8 {low:.4}, 0.95 {default:.4}, 0.99 {high:.4}");
    assert!(low > default && low > high, "lowering χ enlarges Ω_s");

    let scene = load("kalthoff-winkler", "small-hybrid", &[]);
    let mut sim = DynamicSimulation::<2>::new(&scene).unwrap();
    let half = sim.clock().total_steps() / 2;
    for _ in 0..half {
        sim.step().unwrap();
    }
    let before = sim.hybrid().unwrap().standard_fraction();
    assert!(sim.hybrid_mut().unwrap().set_chi(1.5).is_err());
    sim.hybrid_mut().unwrap().set_chi(0.3).unwrap();
    sim.step().unwrap();
    let after = sim.hybrid().unwrap().standard_fraction();
    assert!(
        after > before,
        "χ = 0.3 switches more at once: {before} → {after}"
    );
    let frame = sim.frame();
    assert_eq!(frame.scalar("hybrid/chi"), Some(0.3));
    assert!(
        frame
            .events
            .iter()
            .any(|e| e.contains("switched to the standard scheme"))
    );
    assert_eq!(frame.classes[0].name, "scheme");
}

/// The `near` check policy (Ω_w nodes within 2δ of Ω_s, kept up to date incrementally as Ω_s
/// grows) also keeps every broken bond inside Ω_s, checked after every step.
#[test]
fn near_check_policy_keeps_damage_in_omega_s() {
    let scene = load(
        "kalthoff-winkler",
        "small-hybrid",
        &["hybrid.check=\"near\""],
    );
    let (sim, fractions) = run_checked(&scene);
    assert!(sim.broken_bonds() > 0);
    assert!(fractions.last().unwrap() > &fractions[0]);
    let h = sim.hybrid().unwrap();
    let wls = h.mask().iter().filter(|&&m| m == SchemeClass::Wls).count();
    assert!(h.check_nodes().len() < wls);
}

/// The `collocation` policy (collocation bonds of the near nodes only) is cheaper and not
/// safe: a crack can reach Ω_w. The invariant check (run here every step, in recordings at
/// every frame) finds it, switches those neighbourhoods with a warning event and counts it.
#[test]
fn collocation_check_policy_repairs_damage_that_reached_omega_w() {
    let scene = load(
        "kalthoff-winkler",
        "small-hybrid",
        &["hybrid.check=\"collocation\""],
    );
    let mut sim = DynamicSimulation::<2>::new(&scene).unwrap();
    let mut found = 0;
    for _ in 0..sim.clock().total_steps() {
        sim.step().unwrap();
        found += sim.enforce_hybrid_invariant();
    }
    let frame = sim.frame();
    eprintln!("violations {found}");
    assert!(
        found > 0,
        "this scene makes the collocation policy miss a bond"
    );
    assert_eq!(frame.scalar("hybrid/violations"), Some(found as f64));
    assert!(
        frame
            .events
            .iter()
            .any(|e| e.contains("damage reached Ω_w")),
        "{:?}",
        frame.events
    );
    assert_eq!(sim.enforce_hybrid_invariant(), 0, "all repaired");
}

/// The motion-bound filter of the switching check is exact: with it (the default: the cell
/// bound and the lattice-path bound, epochs keeping quiet nodes' slacks), with the cell bound
/// alone, and without any (every check visits every bond), the Ω_s mask is the same after
/// every step, for the `all` and `near` policies; the filter does skip most checks' work, and
/// the lattice-path bound needs fewer epochs than the cell bound alone.
#[test]
fn motion_filtered_check_switches_exactly_like_the_exhaustive_check() {
    for check in ["all", "near"] {
        let scene = load(
            "kalthoff-winkler",
            "small-hybrid",
            &[&format!("hybrid.check=\"{check}\"")],
        );
        let mut filtered = DynamicSimulation::<2>::new(&scene).unwrap();
        let mut cells_only = DynamicSimulation::<2>::new(&scene).unwrap();
        let mut exhaustive = DynamicSimulation::<2>::new(&scene).unwrap();
        assert!(filtered.hybrid().unwrap().uses_lattice_paths());
        cells_only.hybrid_mut().unwrap().drop_lattice_paths();
        exhaustive.hybrid_mut().unwrap().exhaustive = true;
        for step in 0..filtered.clock().total_steps() {
            for sim in [&mut filtered, &mut cells_only, &mut exhaustive] {
                sim.step().unwrap();
            }
            let e = exhaustive.hybrid().unwrap().mask();
            for (name, sim) in [("both bounds", &filtered), ("cell bound", &cells_only)] {
                assert!(
                    sim.hybrid().unwrap().mask() == e,
                    "{check}, {name}: masks differ after step {}",
                    step + 1
                );
            }
        }
        let h = filtered.hybrid().unwrap();
        let c = cells_only.hybrid().unwrap();
        let e = exhaustive.hybrid().unwrap();
        eprintln!(
            "{check}: {} full and {} filtered checks ({} full with the cell bound alone); bonds \
             visited {} ({} with the cell bound, {} exhaustive); {} slacks kept by epochs; Ω_s \
             {:.4}",
            h.full_checks,
            h.filtered_checks,
            c.full_checks,
            h.checked_bonds,
            c.checked_bonds,
            e.checked_bonds,
            h.reused_slacks,
            h.standard_fraction()
        );
        // Epochs kept quiet nodes' slacks (less the motion bound), and the masks above still
        // matched the exhaustive check's after every step.
        assert!(h.reused_slacks > 0);
        assert_eq!(e.reused_slacks, 0);
        assert!(h.standard_fraction() > h.initial_standard_fraction());
        assert!(h.filtered_checks > h.full_checks);
        assert!(h.checked_bonds < e.checked_bonds / 2);
        assert!(h.full_checks < c.full_checks);
        assert_eq!(filtered.broken_bonds(), exhaustive.broken_bonds());
        assert_eq!(cells_only.broken_bonds(), exhaustive.broken_bonds());
    }
}

/// The orbit stencils of the `*-fast` variants keep the hybrid's stable step at ≥ 0.6× the
/// standard scheme's on the same grid (issue 14 item 6): m = 4 (`small-fast` against `small`)
/// and m = 8 (the same variants at spacing 0.5 mm, the m = 8 orbits of `paper-fast`). The
/// papers' δ/3 auxiliary grid gives 0.375× at m = 4 (docs/validation.md), which this would catch.
#[test]
fn orbit_stencils_keep_the_stable_step_near_the_standard_schemes() {
    let ratio = |set: &[&str], orbits: Option<&str>| {
        let mut hybrid_set = set.to_vec();
        if let Some(o) = orbits {
            hybrid_set.push(o);
        }
        let hybrid =
            DynamicSimulation::<2>::new(&load("kalthoff-winkler", "small-fast", &hybrid_set))
                .unwrap()
                .info()
                .stable_dt;
        let standard = DynamicSimulation::<2>::new(&load("kalthoff-winkler", "small", set))
            .unwrap()
            .info()
            .stable_dt;
        hybrid / standard
    };
    let m4 = ratio(&[], None);
    let m8 = ratio(
        &["discretization.spacing=\"0.5 mm\""],
        Some("hybrid.collocation_orbits=[[3, 3], [4, 1], [4, 2]]"),
    );
    eprintln!("stable step, hybrid / standard: m = 4 {m4:.3}, m = 8 {m8:.3}");
    assert!(m4 >= 0.6, "m = 4: {m4}");
    assert!(m8 >= 0.6, "m = 8: {m8}");
}

/// The stencil fields of the `*-fast` variants are checked like every preset value: each
/// refusal names the field and the allowed range; a stencil too small for WLS-2's fit is
/// refused when the operator is built, naming `hybrid.collocation_orbits` (the field that chose
/// the set), not the auxiliary grid.
#[test]
fn bad_stencil_fields_are_refused_with_the_field_and_range() {
    let refused = |set: &[&str]| {
        let set: Vec<String> = set.iter().map(|s| s.to_string()).collect();
        Scene::load_with("kalthoff-winkler", Some("small-fast"), &set)
            .err()
            .unwrap_or_else(|| panic!("`{set:?}` was accepted"))
            .to_string()
    };
    for (set, field, phrase) in [
        ("hybrid.fit_weight=-1.0", "hybrid.fit_weight", "[0, 64]"),
        (
            "hybrid.collocation_orbits=[[1, 1, 2]]",
            "hybrid.collocation_orbits",
            "0 ≤ a, b ≤ 64",
        ),
        (
            "hybrid.collocation_orbits=[[0, 0]]",
            "hybrid.collocation_orbits",
            "(0, 0)",
        ),
        (
            "hybrid.collocation_factor=3",
            "hybrid.collocation_orbits",
            "not both",
        ),
    ] {
        let message = refused(&[set]);
        assert!(
            message.contains(field) && message.contains(phrase),
            "{set}: {message}"
        );
    }
    // Four nodes at (±1, 0), (0, ±1) and the node itself: fewer than WLS-2's six monomials.
    let scene = load(
        "kalthoff-winkler",
        "small-fast",
        &["hybrid.collocation_orbits=[[1, 0]]"],
    );
    let fit = DynamicSimulation::<2>::new(&scene)
        .err()
        .expect("a 5-node stencil cannot fit WLS-2")
        .to_string();
    assert!(fit.contains("hybrid.collocation_orbits"), "{fit}");
}

/// Energy (kinetic + PD strain, `energy/total`) of a free Kalthoff–Winkler plate (no impact)
/// set ringing by a smooth pulse in Ω_w (u_x = 1 µm · exp(−r²/25 mm²)), with the Ω_s band
/// fixed, at 1 µs and at `ends` (µs). (The PD strain energy of a field in Ω_w is not what the
/// WLS rows conserve, so the hybrid's value differs from the standard scheme's by ≈ 10 % from
/// the start; an instability shows as orders of magnitude.)
fn free_plate_energies(variant: &str, extra: &[&str], ends: &[f64]) -> Vec<f64> {
    let mut set = vec![
        "discretization.scheme=\"hybrid-fixed\"",
        "boundary=[]",
        "initial.pulse=[{center=[\"70 mm\",\"50 mm\"], amplitude=\"1e-6 m\", decay=4e4, \
         radius=\"20 mm\", direction=[1.0, 0.0]}]",
        "time.end=\"500 us\"",
    ];
    set.extend_from_slice(extra);
    let mut sim = DynamicSimulation::<2>::new(&load("kalthoff-winkler", variant, &set)).unwrap();
    let mut out = Vec::new();
    for &t in std::iter::once(&1.0).chain(ends) {
        while sim.run().clock.time() < t * 1e-6 && !sim.run().clock.done() {
            sim.step().unwrap();
        }
        out.push(sim.frame().scalar("energy/total").unwrap());
    }
    out
}

/// The papers' coupling is not pairwise antisymmetric (seed-004 §4.3: "monitor energy"); its
/// stiffness has complex eigenvalues whose modes grow at the interface. With the interface
/// damping (`adapt::interface`, the default) a free plate's energy never rises more than 2 %
/// above its value at 1 µs over 500 µs (≈ 25 crossings of the plate), and the damping takes
/// less than 15 % of it in 160 µs, for the papers' δ/3 stencil at m = 4 (`medium-hybrid`) and
/// at m = 8 (δ = 4 mm on the same grid) and for the m = 4 orbit stencil (`medium-fast`).
#[test]
fn damped_hybrid_couplings_keep_a_free_plates_energy_bounded() {
    let runs: Vec<_> = [
        ("medium-hybrid", &[][..]),
        ("medium-hybrid", &["discretization.horizon=\"4 mm\""][..]),
        ("medium-fast", &[][..]),
    ]
    .into_iter()
    .map(|(variant, extra)| {
        let e = free_plate_energies(variant, extra, &[160.0, 500.0]);
        eprintln!("{variant} {extra:?}, free plate: energy at 1 / 160 / 500 µs {e:.4?} J");
        (variant, e)
    })
    .collect();
    for (variant, e) in runs {
        assert!(e.iter().all(|&x| x <= 1.02 * e[0]), "{variant}: {e:?}");
        assert!(
            e[1] >= 0.85 * e[0],
            "{variant}: the damping took too much: {e:?}"
        );
    }
}

/// Why the damping exists: without it (κ = 0, the papers' coupling) the same free plate with
/// the m = 4 orbit stencil gains energy exponentially (measured ×2.5 at 160 µs and ×2.6·10⁵ at
/// 500 µs, whatever Δt), and with the δ/3 stencil at m = 8 (×15 at 160 µs). Should a coupling
/// change make them stable, this fails and the damping may go.
#[test]
fn undamped_soft_stencil_couplings_grow() {
    for (variant, extra) in [
        ("medium-fast", &["hybrid.interface_damping=0"][..]),
        (
            "medium-hybrid",
            &[
                "hybrid.interface_damping=0",
                "discretization.horizon=\"4 mm\"",
            ][..],
        ),
    ] {
        let e = free_plate_energies(variant, extra, &[160.0]);
        eprintln!("{variant} {extra:?}, free plate: energy at 1 / 160 µs {e:.4?} J");
        assert!(e[1] > 2.0 * e[0], "{variant}: {e:?}");
    }
}
