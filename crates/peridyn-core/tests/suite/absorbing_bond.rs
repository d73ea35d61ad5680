//! Unbounded domains in bond-based PD (thesis §4.3; seed-thesis-ch4-5 §4.8, S10): a radial
//! pulse leaves the disc through the absorbing layer; the truncated runs step in lock with the
//! same model on a disc so large that nothing comes back in time, node by node on the shared
//! lattice, and against a fixed boundary, the free truncation and the first-order boundary.

use peridyn_core::scene::Scene;
use peridyn_core::sim::DynamicSimulation;
use peridyn_core::solver::Stepper;

fn scene(variant: &str) -> Scene {
    Scene::load_with("abc-bond-2d", Some(variant), &[]).unwrap()
}

/// One truncated run against the reference.
#[derive(Default)]
struct Run {
    times: Vec<f64>,
    /// max over the near field of |u − u_ref| at every check.
    errors: Vec<f64>,
    /// The near-field energy (4.169) at every check.
    energies: Vec<f64>,
    /// (truncated, reference) displacement at the probe `p` at every check.
    probes: Vec<([f64; 2], [f64; 2])>,
    /// (truncated, reference) energy Σ (½ ρ |v|² + W) V over the compared nodes at every check:
    /// the reference's tells how the near field's own nodal energy behaves on an unbounded plane.
    compared_energies: Vec<(f64, f64)>,
    diverged: bool,
}

impl Run {
    /// Σ |u − u_ref|² at the probe over the checks: what reflects back to it.
    fn reflected(&self) -> f64 {
        self.probes
            .iter()
            .map(|(a, b)| (a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2))
            .sum()
    }

    fn max_error(&self) -> f64 {
        self.errors.iter().fold(0.0, |a: f64, &e| a.max(e))
    }

    /// One line of figures for the test log.
    fn report(&self, variant: &str) {
        eprintln!(
            "S10 {variant}: max |u − u_ref| = {:.3e} m, reflected Σ|u − u_ref|² at the probe = \
             {:.3e} m², near-field energy {:.3e} → {:.3e} J{}",
            self.max_error(),
            self.reflected(),
            self.energies.first().copied().unwrap_or(f64::NAN),
            self.energies.last().copied().unwrap_or(f64::NAN),
            if self.diverged { " (diverged)" } else { "" }
        );
    }
}

fn probe(f: &peridyn_core::frame::Frame) -> [f64; 2] {
    [
        f.scalar("probe/p/displacement_x").unwrap(),
        f.scalar("probe/p/displacement_y").unwrap(),
    ]
}

/// Σ over `nodes` of (½ ρ |v|² + W) V, the per-node energy of (4.169).
fn nodal_energy(sim: &DynamicSimulation<2>, nodes: impl Iterator<Item = usize>) -> f64 {
    let (v, vol, rho) = (sim.velocities(), sim.volumes(), sim.density());
    nodes
        .map(|i| (0.5 * rho * (v[i][0].powi(2) + v[i][1].powi(2)) + sim.energy_density(i)) * vol[i])
        .sum()
}

/// The checks from `from` on at which an energy series rises (relative 1e-9).
fn rises(times: &[f64], energies: impl Iterator<Item = f64>, from: usize) -> Vec<String> {
    let e: Vec<f64> = energies.collect();
    e[from..]
        .windows(2)
        .zip(&times[from + 1..])
        .filter(|(w, _)| w[1] > w[0] * (1.0 + 1e-9))
        .map(|(w, t)| format!("t = {t:.3e} s: {:.2e} → {:.2e} J", w[0], w[1]))
        .collect()
}

/// Steps `truncated` and `reference` together, comparing every `every` steps over the nodes
/// within `near` of the centre (the near field).
fn lockstep(truncated: &[Scene], reference: &Scene, every: u64, near: f64) -> Vec<Run> {
    let mut far = DynamicSimulation::<2>::new(reference).unwrap();
    let dx = reference.spacing;
    let key = |x: &[f64; 2]| [(x[0] / dx).round() as i64, (x[1] / dx).round() as i64];
    let index: std::collections::HashMap<[i64; 2], usize> = far
        .reference()
        .iter()
        .enumerate()
        .map(|(i, x)| (key(x), i))
        .collect();
    // (simulation, (near-field node, reference node) pairs, comparison)
    type Truncated = (DynamicSimulation<2>, Vec<(usize, usize)>, Run);
    let mut runs: Vec<Truncated> = truncated
        .iter()
        .map(|t| {
            let sim = DynamicSimulation::<2>::new(t).unwrap();
            assert_eq!(sim.info().total_steps, far.info().total_steps);
            assert_eq!(sim.run().clock.dt(), far.run().clock.dt());
            let map = sim
                .reference()
                .iter()
                .enumerate()
                .filter(|(_, x)| x[0].hypot(x[1]) < near)
                .map(|(a, x)| (a, index[&key(x)]))
                .collect();
            (sim, map, Run::default())
        })
        .collect();
    let steps = far.info().total_steps;
    for n in 1..=steps {
        far.step().unwrap();
        let check = n % every == 0 || n == steps;
        let far_probe = check.then(|| probe(&far.frame()));
        for (sim, map, run) in runs.iter_mut() {
            if run.diverged {
                continue;
            }
            if sim.step().is_err() {
                run.diverged = true;
                continue;
            }
            let Some(far_probe) = far_probe else { continue };
            let (u, x) = (sim.positions(), sim.reference());
            let (y, r) = (far.positions(), far.reference());
            let error = map.iter().fold(0.0f64, |e, &(a, k)| {
                let d0 = (u[a][0] - x[a][0]) - (y[k][0] - r[k][0]);
                let d1 = (u[a][1] - x[a][1]) - (y[k][1] - r[k][1]);
                e.max(d0.hypot(d1))
            });
            let far_energy = nodal_energy(&far, map.iter().map(|&(_, k)| k));
            let own_energy = nodal_energy(sim, map.iter().map(|&(a, _)| a));
            run.compared_energies.push((own_energy, far_energy));
            let f = sim.frame();
            run.times.push(f.time);
            run.errors.push(error);
            run.energies
                .push(f.scalar("energy/near_field").unwrap_or(f64::NAN));
            run.probes.push((probe(&f), far_probe));
        }
    }
    runs.into_iter().map(|(_, _, r)| r).collect()
}

/// S10 small: the radial pulse (peak 1 µm) leaves the disc r ≤ 30 mm. Against r ≤ 100 mm:
/// the signal reflected to the probe (20, 10) mm stays below 10 % of a fixed boundary's and
/// below the first-order boundary's; the fitted layer stays closer to the reference than the
/// free truncation. The rises of the near-field energy once the front has reached the layer
/// (t ≥ 5 µs: c_P = 5.17 km/s, the pulse's half-width ≈ 4 mm) are printed.
#[test]
fn bond_pulse_leaves_the_disc_through_the_layer() {
    let reference = scene("small-reference");
    let variants = [
        "small",
        "small-first-order",
        "small-fixed",
        "small-free",
        "small-local",
    ];
    let scenes: Vec<Scene> = variants.iter().map(|v| scene(v)).collect();
    let runs = lockstep(&scenes, &reference, 5, 28e-3 - 1e-9);
    for (v, r) in variants.iter().zip(&runs) {
        r.report(v);
    }
    let (modes, first, fixed, free) = (&runs[0], &runs[1], &runs[2], &runs[3]);
    assert!(!modes.diverged && !first.diverged);
    assert!(modes.reflected() < 0.1 * fixed.reflected());
    assert!(modes.reflected() < first.reflected());
    assert!(modes.max_error() < free.max_error());
    let from = modes.times.iter().position(|&t| t >= 5e-6).unwrap();
    let own = rises(&modes.times, modes.energies.iter().copied(), from);
    let compared = rises(
        &modes.times,
        modes.compared_energies.iter().map(|e| e.0),
        from,
    );
    let reference = rises(
        &modes.times,
        modes.compared_energies.iter().map(|e| e.1),
        from,
    );
    eprintln!(
        "S10 small: the compared nodes' energy rises at {compared:?}; the reference's at {reference:?}"
    );
    // Reported, not asserted: once ≈ 7 % of the energy is left (t ≈ 26 µs) the near-field
    // energy of this narrow pulse rises by 1–2 % at a few checks, and so does the reference's
    // nodal energy over the same nodes (printed beside it): in the pulse's 2D wake the energy
    // flux through the disc's edge changes sign. The monotone decay is asserted on `scaled`
    // (the thesis's pulse), where the reference's energy falls at every check.
    eprintln!("S10 small: near-field energy rises after t = 5 µs: {own:?}");
}

/// S10 `scaled` (r ≤ 50 mm, 31 417 nodes, 2 500 absorbing; the pulse of the base scene, to
/// 0.05 ms) against `scaled-reference` (r ≤ 160 mm, 321 657 nodes: nothing comes back to r ≤ 50
/// before 0.05 ms). Over the near field (r < 48 mm) the signal reflected to the probe stays
/// below 10 % of what the free truncation lets through (the bound against a reflecting
/// boundary; 4.7·10⁻⁶ with the plain fit, the preset's figure in the test log and
/// docs/validation.md) and the largest error below a tenth of the free truncation's (8.5·10⁻⁷ m).
#[test]
fn scaled_bond_layer_matches_the_large_disc() {
    let reference = scene("scaled-reference");
    let free = Scene::load_with(
        "abc-bond-2d",
        Some("scaled"),
        &["absorbing=false".to_string()],
    )
    .unwrap();
    let runs = lockstep(&[scene("scaled"), free], &reference, 2, 48e-3 - 1e-9);
    for (v, r) in ["scaled", "scaled, free"].iter().zip(&runs) {
        r.report(v);
    }
    let (layer, free) = (&runs[0], &runs[1]);
    // From when the reference's energy over r < 48 mm starts to fall: the pulse's 1 % contour
    // (r ≈ 21.5 mm) reaches r = 48 mm at (48 − 21.5) mm / c_P ≈ 5.1 µs. Before, the nodal
    // energy of the closed region wavers by ≈ 1 % as the pulse turns potential into kinetic
    // energy (Verlet keeps a shadow energy, not this one), in the reference too. It then falls
    // at every check until the 2D wake's flux turns inwards for a while (the first rise at
    // 69.8 µs; on r ≤ 300 mm to 0.1 ms it rises at 4 checks, docs/validation.md).
    let reference_series: Vec<f64> = layer.compared_energies.iter().map(|e| e.1).collect();
    let rising = |w: &[f64]| w[1] > w[0] * (1.0 + 1e-9);
    let from = reference_series
        .windows(2)
        .enumerate()
        .rfind(|&(i, w)| layer.times[i + 1] < 6e-6 && rising(w))
        .map_or(0, |(i, _)| i + 1);
    let until = reference_series[from..]
        .windows(2)
        .position(rising)
        .map_or(reference_series.len(), |i| from + i + 1);
    assert!(
        layer.times[until - 1] > 60e-6,
        "the reference's energy falls only from t = {:.3e} s to {:.3e} s",
        layer.times[from],
        layer.times[until - 1]
    );
    let window =
        |series: &mut dyn Iterator<Item = f64>| -> Vec<f64> { series.take(until).collect() };
    let mut up = [Vec::new(), Vec::new()];
    for (name, pick) in [("the layer's", 0), ("the reference's", 1)] {
        let series = window(&mut layer.compared_energies.iter().map(|e| [e.0, e.1][pick]));
        up[pick] = rises(&layer.times, series.into_iter(), from);
        eprintln!(
            "S10 scaled: {name} energy over r < 48 mm from t = {:.3e} s to {:.3e} s, checked \
             every 2 steps, rises at {:?}",
            layer.times[from],
            layer.times[until - 1],
            up[pick]
        );
    }
    let own = rises(
        &layer.times,
        window(&mut layer.energies.iter().copied()).into_iter(),
        from,
    );
    eprintln!("S10 scaled: the near-field energy (4.169) rises at {own:?}");
    let later = rises(
        &layer.times,
        layer.compared_energies.iter().map(|e| e.0),
        until - 1,
    );
    eprintln!("S10 scaled: after the reference's first rise, the layer's rises at {later:?}");
    // The "decreases monotonically after the pulse reaches the layer", for as long as
    // the unbounded plane's own energy over these nodes does. The layer meets it through its
    // damped band (docs/validation.md, "S10: a damped band inside the layer").
    assert!(up[0].is_empty() && own.is_empty());
    assert!(!layer.diverged);
    assert!(layer.max_error() < 0.1 * free.max_error());
    assert!(layer.reflected() < 0.1 * free.reflected());
}

/// Tuning aid: `SCAN='a=1,b=2;a=3' cargo test --release -- --ignored scan_bond_layers` runs the
/// `small` variant (or `VARIANT=scaled`) with each `;`-separated set of overrides against its
/// reference, comparing every `EVERY` steps (default 5), and prints the rises of the energy
/// over the compared nodes once the front has reached the layer.
#[test]
#[ignore]
fn scan_bond_layers() {
    let scan = std::env::var("SCAN").unwrap_or_default();
    let sets: Vec<Vec<String>> = scan
        .split(';')
        .map(|s| {
            s.split(',')
                .filter(|x| !x.is_empty())
                .map(String::from)
                .collect()
        })
        .collect();
    let variant = std::env::var("VARIANT").unwrap_or("small".into());
    let every: u64 = std::env::var("EVERY").map_or(5, |s| s.parse().unwrap());
    let near = if variant == "scaled" { 48e-3 } else { 28e-3 } - 1e-9;
    // `END=0.1ms` runs every scene longer; `REFERENCE='geometry.sphere.radius="300 mm"'`
    // overrides the reference (a larger disc for a longer run).
    let end: Vec<String> = std::env::var("END")
        .map(|e| vec![format!("time.end=\"{e}\"")])
        .unwrap_or_default();
    let scenes: Vec<Scene> = sets
        .iter()
        .map(|s| {
            let s: Vec<String> = s.iter().chain(&end).cloned().collect();
            Scene::load_with("abc-bond-2d", Some(&variant), &s).unwrap()
        })
        .collect();
    let mut reference_set = crate::common::env_overrides("REFERENCE");
    reference_set.extend(end);
    let reference = Scene::load_with(
        "abc-bond-2d",
        Some(&format!("{variant}-reference")),
        &reference_set,
    )
    .unwrap();
    let runs = lockstep(&scenes, &reference, every, near);
    for (s, r) in sets.iter().zip(&runs) {
        let from = r.times.iter().position(|&t| t >= 5e-6).unwrap_or(0);
        let up = rises(&r.times, r.compared_energies.iter().map(|e| e.0), from);
        let reference_up = rises(&r.times, r.compared_energies.iter().map(|e| e.1), from);
        eprintln!("the reference's rises: {reference_up:?}");
        eprintln!(
            "{s:?}: max err {:.3e}, reflected {:.3e}, energy end {:.3e}{}, {} rises: {up:?}",
            r.max_error(),
            r.reflected(),
            r.energies.last().copied().unwrap_or(f64::NAN),
            if r.diverged { " (diverged)" } else { "" },
            up.len()
        );
    }
}

/// Long runs stay bounded (the 10⁵ steps; the thesis: 100 000 steps): `small` to
/// 10⁵ steps (18 ms, 600 times the crossing time of the disc; ≈ 3 min on 2 cores). On an
/// unbounded plane nothing is left in the disc by then, so the near-field energy at the end must
/// be below 1 % of its value when the pulse has left (t = 0.03 ms), and it never exceeds the
/// initial energy (measured with the preset's λ = 5e-4, filter 0.5 and damped band: 5.9·10⁻² J
/// → 5.3·10⁻⁷ J, falling at every 10⁴ steps; with the plain pseudo-inverse alone the layer
/// diverges near 3 000 steps; docs/validation.md, "S10's long run" and "S10: a damped band").
#[test]
fn long_bond_run_stays_bounded() {
    let s = Scene::load_with(
        "abc-bond-2d",
        Some("small"),
        &["time.end=\"100000 steps\"".to_string()],
    )
    .unwrap();
    let mut sim = DynamicSimulation::<2>::new(&s).unwrap();
    let energy = |sim: &mut DynamicSimulation<2>| sim.frame().scalar("energy/near_field").unwrap();
    let initial = energy(&mut sim);
    let (mut at_pulse_gone, mut top, mut n) = (f64::NAN, initial, 0u64);
    let mut history = Vec::new();
    while !sim.run().clock.done() {
        sim.step().expect("stays stable");
        n += 1;
        if n.is_multiple_of(1000) || n == 165 {
            let e = energy(&mut sim);
            if n == 165 {
                at_pulse_gone = e;
            }
            top = top.max(e);
            history.push((sim.run().clock.time(), e));
        }
    }
    let last = history.last().unwrap().1;
    eprintln!(
        "S10 small, 1e5 steps: energy {initial:.3e} → {at_pulse_gone:.3e} J (t = 0.03 ms) → \
         {last:.3e} J (t = {:.3e} s); max {top:.3e}; every 10⁴ steps: {:?}",
        sim.run().clock.time(),
        history
            .iter()
            .step_by(10)
            .map(|(_, e)| format!("{e:.2e}"))
            .collect::<Vec<_>>()
    );
    assert!(last <= 1e-2 * at_pulse_gone && top <= initial * (1.0 + 1e-9));
}

/// Tuning aid: `SCAN='a=1;b=2' STEPS=20000 cargo test --release -- --ignored scan_bond_stability`
/// runs `small` alone with each set of overrides for STEPS steps and prints the near-field
/// energy every STEPS/10 steps, or the step it diverged at.
#[test]
#[ignore]
fn scan_bond_stability() {
    let scan = std::env::var("SCAN").unwrap_or_default();
    let steps: u64 = std::env::var("STEPS").map_or(20_000, |s| s.parse().unwrap());
    for set in scan.split(';') {
        let mut set: Vec<String> = set
            .split(',')
            .filter(|x| !x.is_empty())
            .map(String::from)
            .collect();
        set.push(format!("time.end=\"{steps} steps\""));
        let s = Scene::load_with("abc-bond-2d", Some("small"), &set).unwrap();
        let mut sim = DynamicSimulation::<2>::new(&s).unwrap();
        let mut line = Vec::new();
        for n in 1..=steps {
            if sim.step().is_err() {
                // Where the growth sits: the node with the largest |u| (radius, angle).
                let (x, y) = (sim.reference(), sim.positions());
                let top = (0..x.len())
                    .max_by(|&a, &b| {
                        let d = |i: usize| (y[i][0] - x[i][0]).hypot(y[i][1] - x[i][1]);
                        d(a).total_cmp(&d(b))
                    })
                    .unwrap();
                line.push(format!(
                    "diverged at {n}; largest |u| at r = {:.2} mm, θ = {:.1}°",
                    1e3 * x[top][0].hypot(x[top][1]),
                    x[top][1].atan2(x[top][0]).to_degrees()
                ));
                break;
            }
            if n % (steps / 10) == 0 {
                line.push(format!(
                    "{:.1e}",
                    sim.frame().scalar("energy/near_field").unwrap()
                ));
            }
        }
        eprintln!("{set:?}: {}", line.join(" "));
    }
}

/// Tuning aid: the one-step map's leading growth by power iteration on `small` (linear at these
/// amplitudes): a random displacement of 1e-9 m, `STEPS` steps (default 20 000) with the options
/// in `SET`, the state scaled back to that size every STEPS/20 steps; prints the per-step
/// growth of ‖u‖₂ and where |u| peaks.
#[test]
#[ignore = "exploration"]
fn zz_bond_leading_mode() {
    let steps: u64 = std::env::var("STEPS").map_or(20_000, |s| s.parse().unwrap());
    let mut set = crate::common::env_overrides("SET");
    set.push(format!("time.end=\"{steps} steps\""));
    let s = Scene::load_with("abc-bond-2d", Some("small"), &set).unwrap();
    let mut sim = DynamicSimulation::<2>::new(&s).unwrap();
    let x: Vec<[f64; 2]> = sim.reference().to_vec();
    let n = x.len();
    let mut seed = 0x2545_f491_4f6c_dd1du64;
    let mut state = sim.save_state();
    let position: Vec<f64> = x
        .as_flattened()
        .iter()
        .map(|p| {
            seed ^= seed << 13;
            seed ^= seed >> 7;
            seed ^= seed << 17;
            p + 1e-9 * ((seed >> 11) as f64 / (1u64 << 53) as f64 - 0.5)
        })
        .collect();
    state.put_f64("position", position);
    state.put_f64("velocity", vec![0.0; 2 * n]);
    state.put_f64("acceleration", vec![0.0; 2 * n]);
    sim.restore_state(&state).unwrap();
    let norm = |sim: &DynamicSimulation<2>| {
        sim.positions()
            .iter()
            .zip(&x)
            .map(|(y, x)| (y[0] - x[0]).powi(2) + (y[1] - x[1]).powi(2))
            .sum::<f64>()
            .sqrt()
    };
    let size = norm(&sim);
    let every = (steps / 20).max(1);
    for k in 1..=steps {
        if sim.step().is_err() {
            eprintln!("step {k}: failed");
            return;
        }
        if k % every == 0 {
            let now = norm(&sim);
            let y = sim.positions();
            let peak = (0..n)
                .max_by(|&a, &b| {
                    let d = |i: usize| (y[i][0] - x[i][0]).hypot(y[i][1] - x[i][1]);
                    d(a).total_cmp(&d(b))
                })
                .unwrap();
            eprintln!(
                "step {k:7}: growth/step {:+.3e}, peak at r {:.2} mm, {:.1}°",
                (now / size).ln() / every as f64,
                1e3 * x[peak][0].hypot(x[peak][1]),
                x[peak][1].atan2(x[peak][0]).to_degrees()
            );
            // Back to the starting size: every displacement-like entry scaled alike.
            let scale = size / now;
            let mut st = sim.save_state();
            let shrink = |v: &[f64]| v.iter().map(|a| a * scale).collect::<Vec<f64>>();
            let u: Vec<f64> = sim
                .positions()
                .as_flattened()
                .iter()
                .zip(x.as_flattened())
                .map(|(y, x)| x + (y - x) * scale)
                .collect();
            st.put_f64("position", u);
            for name in [
                "velocity",
                "acceleration",
                "absorbing/previous_displacement",
                "absorbing/previous_velocity",
            ] {
                let v = shrink(st.f64(name, 2 * n).unwrap());
                st.put_f64(name, v);
            }
            sim.restore_state(&st).unwrap();
        }
    }
    if let Ok(angle) = std::env::var("RAY") {
        // The mode along the ray at `RAY` degrees over two steps: its radial and tangential
        // displacement, and whether it flips sign from step to step.
        let a: f64 = angle.parse::<f64>().unwrap().to_radians();
        let (c, sn) = (a.cos(), a.sin());
        let before: Vec<[f64; 2]> = sim.positions().to_vec();
        sim.step().unwrap();
        let after = sim.positions();
        let mut on: Vec<(f64, usize)> = (0..n)
            .filter(|&i| {
                (x[i][1] * c - x[i][0] * sn).abs() < 0.26e-3 && x[i][0] * c + x[i][1] * sn > 20e-3
            })
            .map(|i| (x[i][0] * c + x[i][1] * sn, i))
            .collect();
        on.sort_by(|a, b| a.0.total_cmp(&b.0));
        for (r, i) in on {
            let u = |y: &[f64; 2]| {
                let (dx, dy) = (y[0] - x[i][0], y[1] - x[i][1]);
                (dx * c + dy * sn, -dx * sn + dy * c)
            };
            let (r0, t0) = u(&before[i]);
            let (r1, t1) = u(&after[i]);
            eprintln!(
                "ray r {:7.3} mm: radial {r0:+.3e} → {r1:+.3e}, tangential {t0:+.3e} → {t1:+.3e}",
                1e3 * r
            );
        }
    }
}

/// A regularization outside its range is refused before anything runs, naming the field and the
/// allowed range.
#[test]
fn a_bad_tikhonov_names_the_field() {
    let cases = [
        ("absorbing.tikhonov=1.5", "absorbing.tikhonov", "[0, 1)"),
        ("absorbing.tikhonov=-1e-3", "absorbing.tikhonov", "[0, 1)"),
        ("absorbing.damping=0.05", "absorbing.damping", "[0, 0.02]"),
        ("absorbing.damping=-0.01", "absorbing.damping", "[0, 0.02]"),
        (
            "absorbing.damping_band=\"-2 mm\"",
            "absorbing.damping_band",
            "",
        ),
    ];
    for (bad, field, range) in cases {
        let error = Scene::load_with("abc-bond-2d", Some("small"), &[bad.to_string()])
            .err()
            .unwrap_or_else(|| panic!("{bad} was accepted"))
            .to_string();
        assert!(error.contains(field) && error.contains(range), "{error}");
    }
}

/// Tuning aid: `VARIANT=scaled END=0.1ms FROM=21e-6 EVERY=5` runs one variant (`base`: the
/// preset without a variant) and prints the
/// near-field energy's rises after `FROM` seconds and the series every 10 checks.
#[test]
#[ignore = "exploration"]
fn zz_bond_energy_series() {
    let variant = std::env::var("VARIANT").unwrap_or_else(|_| "small".into());
    let from: f64 = std::env::var("FROM").map_or(5e-6, |s| s.parse().unwrap());
    let every: u64 = std::env::var("EVERY").map_or(5, |s| s.parse().unwrap());
    let mut set: Vec<String> = std::env::var("SET")
        .unwrap_or_default()
        .split(',')
        .filter(|x| !x.is_empty())
        .map(String::from)
        .collect();
    if let Ok(end) = std::env::var("END") {
        set.push(format!("time.end=\"{end}\""));
    }
    let named = (variant != "base").then_some(variant.as_str());
    let s = Scene::load_with("abc-bond-2d", named, &set).unwrap();
    let mut sim = DynamicSimulation::<2>::new(&s).unwrap();
    let (mut times, mut energies) = (Vec::new(), Vec::new());
    let mut n = 0u64;
    while !sim.run().clock.done() {
        sim.step().unwrap();
        n += 1;
        if n.is_multiple_of(every) {
            let f = sim.frame();
            times.push(f.time);
            energies.push(f.scalar("energy/near_field").unwrap());
        }
    }
    let start = times.iter().position(|&t| t >= from).unwrap_or(times.len());
    let up = rises(&times, energies.iter().copied(), start);
    eprintln!(
        "{variant} {set:?}: {} rises after {from:e} s: {up:?}",
        up.len()
    );
    for (t, e) in times.iter().zip(&energies).step_by(10) {
        eprintln!("  t = {t:.3e} s: {e:.4e} J");
    }
}
