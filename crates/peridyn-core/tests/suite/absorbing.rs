//! Unbounded domains (thesis Chapter 4; seed-thesis-ch4-5 §2.6, §3.7 and §6): a truncated near
//! field with absorbing layers against the same model on a domain so large that nothing comes
//! back in time (the thesis's references), node by node on the shared lattice; and against
//! the truncation without a layer (free or Neumann ends).

use std::ops::Deref;

use peridyn_core::scene::{Scene, SceneError};
use peridyn_core::sim::scalar::FieldBody;
use peridyn_core::sim::{DiffusionSimulation, WaveSimulation};
use peridyn_core::solver::Stepper;

/// A constructor of a scalar simulation of one physics.
type New<S> = fn(&Scene) -> Result<S, SceneError>;

fn scene(preset: &str, variant: Option<&str>, set: &[&str]) -> Scene {
    let set: Vec<String> = set.iter().map(|s| s.to_string()).collect();
    Scene::load_with(preset, variant, &set).unwrap()
}

/// max over Ω_N of |u − u_ref| and max over Ω_N of |u_ref|, at the checked times.
struct Comparison {
    times: Vec<f64>,
    errors: Vec<f64>,
    peaks: Vec<f64>,
    /// The near-field energy at every check.
    energies: Vec<f64>,
    /// (truncated, reference) ½ Σ u² Δxᴰ over the truncated scene's nodes at every check.
    squares: Vec<(f64, f64)>,
    /// Scenes with a probe `p`: (truncated, reference) value there at every check.
    probes: Vec<(f64, f64)>,
    /// Corrosion: (truncated, reference) relative volume loss at every check.
    volume_losses: Vec<(f64, f64)>,
    /// The run stopped with a divergence error (its error is then ∞).
    diverged: bool,
}

impl Comparison {
    /// The largest error up to time `t` over the reference's peak then.
    fn relative_at(&self, t: f64) -> f64 {
        let k = self
            .times
            .iter()
            .position(|&s| (s - t).abs() < 1e-9 * t.max(1.0))
            .expect("a checked time");
        self.errors[k] / self.peaks[k]
    }

    /// max_t |Π(t) − Π_ref(t)| / Π_ref(0) with Π = ½ Σ u² over the near field (thesis (4.35),
    /// erratum 13), taking the first check as t = 0.
    fn energy_gap(&self) -> f64 {
        let first = self.squares.first().map_or(1.0, |s| s.1);
        self.squares
            .iter()
            .fold(0.0, |a: f64, (x, y)| a.max((x - y).abs() / first))
    }

    /// The largest difference of the relative volume loss from the reference's.
    fn volume_loss_gap(&self) -> f64 {
        self.volume_losses
            .iter()
            .fold(0.0, |a: f64, (x, y)| a.max((x - y).abs()))
    }

    /// Σ (u − u_ref)² over the checks at the probe: what reflects back to it.
    fn reflected(&self) -> f64 {
        self.probes.iter().map(|(a, b)| (a - b) * (a - b)).sum()
    }

    /// The largest absolute error over the whole run.
    fn max_error(&self) -> f64 {
        self.errors.iter().fold(0.0, |a: f64, &e| a.max(e))
    }
}

/// Steps the truncated scenes and the reference together (each built by `new`), comparing
/// every `every` steps.
fn lockstep<const D: usize, S: Stepper + Deref<Target = FieldBody<D>>>(
    new: New<S>,
    truncated: &[Scene],
    reference: &Scene,
    every: u64,
) -> Vec<Comparison> {
    let mut far = new(reference).unwrap();
    let origin = far.positions()[0];
    let dx = reference.spacing;
    let key = |x: &[f64; D]| -> [i64; D] {
        std::array::from_fn(|k| ((x[k] - origin[k]) / dx).round() as i64)
    };
    let index: std::collections::HashMap<[i64; D], usize> = far
        .positions()
        .iter()
        .enumerate()
        .map(|(i, x)| (key(x), i))
        .collect();
    let mut runs: Vec<(S, Vec<usize>, Comparison)> = truncated
        .iter()
        .map(|t| {
            let near = new(t).unwrap();
            let map = near
                .positions()
                .iter()
                .map(|x| *index.get(&key(x)).expect("the lattices coincide"))
                .collect();
            assert_eq!(near.info().total_steps, far.info().total_steps);
            let c = Comparison {
                times: Vec::new(),
                errors: Vec::new(),
                peaks: Vec::new(),
                energies: Vec::new(),
                volume_losses: Vec::new(),
                probes: Vec::new(),
                squares: Vec::new(),
                diverged: false,
            };
            (near, map, c)
        })
        .collect();
    let steps = far.info().total_steps;
    for n in 1..=steps {
        far.step().unwrap();
        let check = n % every == 0 || n == steps;
        let (far_loss, far_probe) = match check {
            true => {
                let f = far.frame();
                (f.scalar("corrosion/volume_loss"), f.scalar("probe/p/value"))
            }
            false => (None, None),
        };
        for (near, map, c) in runs.iter_mut() {
            if c.diverged {
                continue;
            }
            if near.step().is_err() {
                c.diverged = true;
                c.errors.push(f64::INFINITY);
                continue;
            }
            if check {
                let (u, r) = (near.field(), far.field());
                let (mut e, mut p) = (0.0f64, 0.0f64);
                let (mut su, mut sr) = (0.0, 0.0);
                for (a, &k) in map.iter().enumerate() {
                    e = e.max((u[a] - r[k]).abs());
                    p = p.max(r[k].abs());
                    su += 0.5 * u[a] * u[a];
                    sr += 0.5 * r[k] * r[k];
                }
                c.squares.push((su, sr));
                c.times.push(near.run().clock.time());
                c.errors.push(e);
                c.peaks.push(p);
                let f = near.frame();
                c.energies
                    .push(f.scalar("energy/near_field").unwrap_or(f64::NAN));
                if let (Some(a), Some(b)) = (f.scalar("corrosion/volume_loss"), far_loss) {
                    c.volume_losses.push((a, b));
                }
                if let (Some(a), Some(b)) = (f.scalar("probe/p/value"), far_probe) {
                    c.probes.push((a, b));
                }
            }
        }
    }
    runs.into_iter().map(|(_, _, c)| c).collect()
}

/// S1: the relative error against the large domain at t = 50 and t = 250 with the layer, and
/// with Neumann ends at ±30.
#[test]
fn diffusion_leaves_the_near_field_through_the_layer() {
    let reference = scene("abc-diffusion-1d", Some("reference"), &[]);
    let runs = lockstep::<1, _>(
        DiffusionSimulation::new,
        &[
            scene("abc-diffusion-1d", None, &[]),
            scene("abc-diffusion-1d", Some("neumann"), &[]),
        ],
        &reference,
        10_000,
    );
    let (abc, neumann) = (&runs[0], &runs[1]);
    for t in [50.0, 250.0] {
        eprintln!(
            "S1 t = {t}: absorbing layer {:.3e}, Neumann {:.3e}",
            abc.relative_at(t),
            neumann.relative_at(t)
        );
    }
    assert!(abc.relative_at(50.0) <= 1e-3);
    assert!(abc.relative_at(250.0) <= 0.1);
    assert!(neumann.relative_at(50.0) > 5e-3);
    assert!(neumann.relative_at(250.0) > 0.3);
}

/// S4: the mode-count study (m = 3): the error against the large domain falls by more than
/// ten times from 3 to 4 modes and stays there (the thesis's energy error saturates at
/// n_b = 4, Figs. 4.25–4.26); n_b = 5 within 1e-2 (the note's check: 7.2e-3) against ≥ 0.5
/// with free truncated ends (0.78).
#[test]
fn wave_mode_count_saturates() {
    let reference = scene("abc-wave-1d", Some("reference"), &[]);
    let variants = ["free", "modes-1", "modes-2", "modes-3", "modes-4"];
    let mut scenes: Vec<Scene> = variants
        .iter()
        .map(|v| scene("abc-wave-1d", Some(v), &[]))
        .collect();
    scenes.push(scene("abc-wave-1d", None, &[]));
    scenes.push(scene("abc-wave-1d", None, &["absorbing.wave_numbers=8"]));
    let runs = lockstep::<1, _>(WaveSimulation::new, &scenes, &reference, 100);
    let error = |k: usize| runs[k].max_error();
    for (k, name) in [
        "free ends",
        "n_b = 1",
        "n_b = 2",
        "n_b = 3",
        "n_b = 4",
        "n_b = 5",
        "n_b = 8",
    ]
    .iter()
    .enumerate()
    {
        eprintln!(
            "S4 {name}: max |u − u_ref| = {:.3e}{}",
            error(k),
            if runs[k].diverged { " (diverged)" } else { "" }
        );
    }
    assert!(error(0) >= 0.5);
    assert!(error(5) <= 1e-2);
    assert!(error(4) <= 0.1 * error(3));
    assert!(error(5) <= error(4));
}

/// S5: the dispersive case, m = 25 (the reference domain cut to (−32, 32): a reflection from
/// its ends reaches the near field only after t = 16.4 > 15, at the local speed χ which no
/// discrete PD wave exceeds).
#[test]
fn dispersive_wave_leaves_through_the_layer() {
    let reference = scene(
        "abc-wave-1d",
        Some("m25-reference"),
        &["geometry.box.min=[-32.0]", "geometry.box.max=[32.0]"],
    );
    let runs = lockstep::<1, _>(
        WaveSimulation::new,
        &[
            scene("abc-wave-1d", Some("m25"), &[]),
            scene("abc-wave-1d", Some("m25-free"), &[]),
        ],
        &reference,
        500,
    );
    let (abc, free) = (&runs[0], &runs[1]);
    eprintln!(
        "S5: absorbing layer {:.3e}, free ends {:.3e}",
        abc.max_error(),
        free.max_error()
    );
    assert!(abc.max_error() <= 1e-2);
    assert!(free.max_error() >= 0.5);
}

/// S2 small (Δx = 0.08; the reference disc r ≤ 6, which the solute does not reach by
/// t = 0.085): the truncated run's relative volume loss stays within 2 % of the initial solid
/// volume of the reference's at every check (it does on Neumann ends too: the letters are gone
/// before the solute reaches r = 2); the near-field energy Π = ½ ∫ C² never rises, and its
/// gap ΔΠ/Π0 (4.35) to the reference's stays a third or less of the Neumann truncation's (the
/// thesis's Fig. 4.15 shows the Neumann gap growing).
#[test]
fn corrosion_volume_loss_matches_the_large_domain() {
    let reference = scene("abc-corrosion-2d", Some("small-reference"), &[]);
    let runs = lockstep::<2, _>(
        DiffusionSimulation::new,
        &[
            scene("abc-corrosion-2d", Some("small"), &[]),
            scene("abc-corrosion-2d", Some("small-neumann"), &[]),
        ],
        &reference,
        161,
    );
    let (abc, neumann) = (&runs[0], &runs[1]);
    let last = |c: &Comparison| c.volume_losses.last().copied().unwrap();
    eprintln!(
        "S2 small: volume-loss gap {:.3e} (Neumann {:.3e}); ΔΠ/Π0 {:.3e} (Neumann {:.3e}); final \
         volume loss {:?} (Neumann {:?}); max |C − C_ref| {:.3e} (Neumann {:.3e}); near-field \
         energy {:.3e} → {:.3e}",
        abc.volume_loss_gap(),
        neumann.volume_loss_gap(),
        abc.energy_gap(),
        neumann.energy_gap(),
        last(abc),
        last(neumann),
        abc.max_error(),
        neumann.max_error(),
        abc.energies[0],
        abc.energies.last().unwrap(),
    );
    assert!(abc.volume_loss_gap() <= 0.02);
    assert!(abc.energy_gap() <= neumann.energy_gap() / 3.0);
    // Monotone decay of Π = ½ ∫ C² over the near field from its peak on.
    let peak = abc
        .energies
        .iter()
        .enumerate()
        .max_by(|a, b| a.1.total_cmp(b.1))
        .unwrap()
        .0;
    assert!(
        abc.energies[peak..]
            .windows(2)
            .all(|w| w[1] <= w[0] * (1.0 + 1e-12))
    );
}

/// S7 scaled (m = 3): the pulse leaves the disc r ≤ 26; against the same model on r ≤ 40 the
/// signal reflected to the probe (20, 10), Σ (u − u_ref)² over the checks, stays below 10 % of
/// a fixed boundary's and below the first-order boundary's (4.75), the near-field energy never rises once the pulse reaches the layer
/// (t ≥ 24), and over the near field the discrete modes ("Proposed-A") stay closer to the
/// reference than the local ones ("Proposed-B"; thesis Figs. 4.31–4.32).
#[test]
fn wave_2d_leaves_the_disc_through_the_layer() {
    let reference = scene("abc-wave-2d", Some("scaled-reference"), &[]);
    let variants = [
        "scaled",
        "scaled-local",
        "scaled-fixed",
        "scaled-free",
        "scaled-first-order",
    ];
    let scenes: Vec<Scene> = variants
        .iter()
        .map(|v| scene("abc-wave-2d", Some(v), &[]))
        .collect();
    let runs = lockstep::<2, _>(WaveSimulation::new, &scenes, &reference, 10);
    for (v, c) in variants.iter().zip(&runs) {
        eprintln!(
            "S7 {v}: max |u − u_ref| = {:.3e}, reflected Σ(u − u_ref)² at the probe = {:.3e}, \
             near-field energy {:.3e} → {:.3e}{}",
            c.max_error(),
            c.reflected(),
            c.energies[0],
            c.energies.last().unwrap(),
            if c.diverged { " (diverged)" } else { "" }
        );
    }
    let (a, b, fixed, first) = (&runs[0], &runs[1], &runs[2], &runs[4]);
    assert!(!a.diverged && !b.diverged);
    assert!(a.reflected() < 0.1 * fixed.reflected());
    assert!(a.reflected() < first.reflected());
    assert!(a.max_error() < b.max_error());
    let rising = rises_after(a, 24.0);
    assert_eq!(
        rising, 0,
        "the near-field energy rose at {rising} checks after t = 24"
    );
}

/// How many checks from time `t` on see the near-field energy rise (relative 1e-12).
fn rises_after(c: &Comparison, t: f64) -> usize {
    let from = c.times.iter().position(|&s| s >= t).unwrap();
    c.energies[from..]
        .windows(2)
        .filter(|w| w[1] > w[0] * (1.0 + 1e-12))
        .count()
}

/// S8 scaled (thesis §4.2.7, Figs. 4.33–4.34; m = 3 as the thesis's δ = 0.75 at Δx = 0.25): two
/// notches reflect the pulse, so fronts meet the layer at many angles. To t = 100 against r ≤ 75: the
/// signal reflected to the probe (20, 10) stays below 10 % of a fixed boundary's and below the
/// first-order boundary's, the near-field energy never rises once the pulse reaches the layer,
/// and the larger near field (R = 42) matches the reference better at the probe than R = 26
/// (the thesis's Fig. 4.34).
#[test]
fn wave_2d_with_notches_leaves_the_disc_through_the_layer() {
    let reference = scene("abc-wave-2d", Some("notched-scaled-reference"), &[]);
    let variants = [
        "notched-scaled",
        "notched-scaled-42",
        "notched-scaled-fixed",
        "notched-scaled-first-order",
    ];
    let scenes: Vec<Scene> = variants
        .iter()
        .map(|v| scene("abc-wave-2d", Some(v), &[]))
        .collect();
    let runs = lockstep::<2, _>(WaveSimulation::new, &scenes, &reference, 10);
    for (v, c) in variants.iter().zip(&runs) {
        eprintln!(
            "S8 {v}: max |u − u_ref| = {:.3e}, reflected Σ(u − u_ref)² at the probe = {:.3e}, \
             near-field energy {:.3e} → {:.3e}{}",
            c.max_error(),
            c.reflected(),
            c.energies[0],
            c.energies.last().unwrap(),
            if c.diverged { " (diverged)" } else { "" }
        );
    }
    let (r26, r42, fixed, first) = (&runs[0], &runs[1], &runs[2], &runs[3]);
    assert!(!r26.diverged && !r42.diverged);
    assert!(r26.reflected() < 0.1 * fixed.reflected());
    assert!(r26.reflected() < first.reflected());
    assert!(r42.reflected() < r26.reflected());
    // The pulse's front (speed ≤ χ = 1) reaches each layer at t = R − δ.
    assert_eq!(
        rises_after(r26, 24.0),
        0,
        "R = 26: the near-field energy rose"
    );
    assert_eq!(
        rises_after(r42, 40.0),
        0,
        "R = 42: the near-field energy rose"
    );
}

/// The one-step map of a linear scalar simulation, column by column: each state component set
/// to 1 in turn (the rest 0), one step, the new state read back. A state is the field, and for
/// waves also u̇, u^{n−1} and u̇^{n−1} (built by `new`).
fn one_step_map<const D: usize, S: Stepper + Deref<Target = FieldBody<D>>>(
    new: New<S>,
    scene: &Scene,
) -> nalgebra::DMatrix<f64> {
    let mut sim = new(scene).unwrap();
    let n = sim.positions().len();
    let template = sim.save_state();
    let names: &[&str] = if template.has("velocity") {
        &["field", "velocity", "previous_field", "previous_velocity"]
    } else {
        &["field"]
    };
    let size = n * names.len();
    let mut map = nalgebra::DMatrix::zeros(size, size);
    for column in 0..size {
        let mut state = template.clone();
        for (k, name) in names.iter().enumerate() {
            let mut v = vec![0.0; n];
            if column / n == k {
                v[column % n] = 1.0;
            }
            state.put_f64(name, v);
        }
        sim.restore_state(&state).unwrap();
        sim.step().unwrap();
        let after = sim.save_state();
        for (k, name) in names.iter().enumerate() {
            for (i, v) in after.f64(name, n).unwrap().iter().enumerate() {
                map[(k * n + i, column)] = *v;
            }
        }
    }
    map
}

fn spectral_radius(map: nalgebra::DMatrix<f64>) -> f64 {
    map.complex_eigenvalues()
        .iter()
        .fold(0.0, |a: f64, l| a.max(l.norm()))
}

/// Stability over many steps from the one-step maps' spectral radii. S1 (the thesis: stable
/// for 4·10⁶ steps): no eigenvalue outside the unit circle, so no number of steps diverges;
/// the Neumann truncation keeps its mass (an eigenvalue 1). S4: the layer's radius is within
/// 1 + 9.5e-7, so no mode grows by more than 10 % over 10⁵ steps (the long run); it is
/// not ≤ 1 (5.5e-7 above: over 2.6·10⁶ steps the residual energy left in the near field grows
/// tenfold, measured); the n_b = 2 layer, which the note's check saw diverge, is far above.
#[test]
fn absorbing_layers_are_stable_for_any_number_of_steps() {
    let diffusion_map = |variant| {
        one_step_map::<1, _>(
            DiffusionSimulation::new,
            &scene("abc-diffusion-1d", variant, &[]),
        )
    };
    let wave_map =
        |variant| one_step_map::<1, _>(WaveSimulation::new, &scene("abc-wave-1d", variant, &[]));
    let diffusion = spectral_radius(diffusion_map(None));
    let neumann = spectral_radius(diffusion_map(Some("neumann")));
    let wave = spectral_radius(wave_map(None));
    let two = spectral_radius(wave_map(Some("modes-2")));
    eprintln!(
        "spectral radius of one step: S1 layer {diffusion:.12}, S1 Neumann {neumann:.12}, S4 n_b = 5 \
         {wave:.12}, S4 n_b = 2 {two:.6}"
    );
    assert!(diffusion < 1.0, "{diffusion}");
    assert!((neumann - 1.0).abs() < 1e-12, "{neumann}");
    assert!(wave.powi(100_000) <= 1.1, "{wave}");
    assert!(two > 1.0 + 1e-6, "{two}");
}

/// Long runs stay bounded (the 10⁵ steps): S4 to t = 100 and S7 scaled to t = 1 000
/// (100 times the time the pulse needs to leave). The near-field energy at the end is below its
/// value when the pulse has left (t = 50) and never exceeds the initial energy; S7's must
/// also keep falling: below 10⁻⁶ of its t = 50 value at the end (measured 1.9e-16 against
/// 2.1e-2: without the rest modes and the filter a lattice sawtooth grew from t ≈ 700 on and
/// passed the initial energy, docs/validation.md). ≈ 2 min in CI.
#[test]
fn long_runs_stay_bounded() {
    let check = |name: &str, energies: &[(f64, f64)]| {
        let initial = energies[0].1;
        let at_50 = energies.iter().find(|(t, _)| *t >= 50.0).unwrap().1;
        let last = energies.last().unwrap().1;
        let top = energies.iter().fold(0.0f64, |a, e| a.max(e.1));
        eprintln!(
            "{name}: energy {initial:.3e} → {at_50:.3e} (t = 50) → {last:.3e} (t = {:.0}); max {top:.3e}",
            energies.last().unwrap().0
        );
        assert!(last <= at_50 && top <= initial * (1.0 + 1e-9), "{name}");
        (at_50, last)
    };
    let s4 = scene("abc-wave-1d", None, &["time.end=\"100000 steps\""]);
    check("S4", &energy_history::<1>(&s4));
    let s7 = scene(
        "abc-wave-2d",
        Some("scaled"),
        &["time.end=\"100000 steps\""],
    );
    let (at_50, last) = check("S7 scaled", &energy_history::<2>(&s7));
    assert!(last < 1e-6 * at_50, "S7's residual energy stopped falling");
}

fn energy_history<const D: usize>(s: &Scene) -> Vec<(f64, f64)> {
    let mut sim = WaveSimulation::<D>::new(s).unwrap();
    let mut out = vec![(0.0, sim.frame().scalar("energy/near_field").unwrap())];
    let mut n = 0u64;
    while !sim.run().clock.done() {
        if sim.step().is_err() {
            out.push((f64::INFINITY, f64::INFINITY));
            break;
        }
        n += 1;
        if n.is_multiple_of(1000) {
            let f = sim.frame();
            out.push((f.time, f.scalar("energy/near_field").unwrap()));
        }
    }
    out
}

/// A wave scene's restart state carries u̇ and the previous level the layer fits on: a run
/// restored half-way ends bit for bit where the uninterrupted run ends (consistency check).
#[test]
fn a_restored_wave_run_ends_where_the_uninterrupted_one_does() {
    let s = scene("abc-wave-1d", Some("small"), &[]);
    let mut whole = WaveSimulation::<1>::new(&s).unwrap();
    let mut state = None;
    while !whole.run().clock.done() {
        whole.step().unwrap();
        if whole.run().clock.step() == 5_000 {
            state = Some(whole.save_state());
        }
    }
    let mut resumed = WaveSimulation::<1>::new(&s).unwrap();
    resumed.restore_state(&state.unwrap()).unwrap();
    while !resumed.run().clock.done() {
        resumed.step().unwrap();
    }
    assert_eq!(whole.field(), resumed.field());
    assert_eq!(whole.velocity(), resumed.velocity());
}

/// A live Δt change refits the layer's rows (they hold Δt): S4 with Δt halved at t = 12.5 still
/// ends within 1e-2 of the large domain at t = 25 (rows left at the old Δt extrapolate twice too
/// far each step).
#[test]
fn a_new_time_step_refits_the_layer() {
    let reference = {
        let mut r =
            WaveSimulation::<1>::new(&scene("abc-wave-1d", Some("reference"), &[])).unwrap();
        while !r.run().clock.done() {
            r.step().unwrap();
        }
        r
    };
    let mut s = WaveSimulation::<1>::new(&scene("abc-wave-1d", None, &[])).unwrap();
    while !s.run().clock.done() {
        if s.run().clock.step() == 12_500 {
            s.set_dt(5e-4);
        }
        s.step().unwrap();
    }
    assert!((s.run().clock.time() - 25.0).abs() < 1e-9);
    let offset = ((s.positions()[0][0] - reference.positions()[0][0]) / 0.2).round() as usize;
    let error = s.field().iter().enumerate().fold(0.0f64, |a, (i, u)| {
        a.max((u - reference.field()[i + offset]).abs())
    });
    eprintln!("S4 with Δt halved at t = 12.5: max |u − u_ref| at t = 25: {error:.3e}");
    assert!(error <= 1e-2);
}

/// Tuning aid for the 2D long-run stability: the near-field energy of `scaled` on a disc of
/// `RADIUS` (default 26) over `STEPS` steps (default 10⁵) with the options in `SET`
/// (`;`-separated), e.g. `RADIUS=10 cargo test --release -- --ignored zz_wave_2d_long`.
#[test]
#[ignore = "exploration"]
fn zz_wave_2d_long_energy() {
    let radius = std::env::var("RADIUS").unwrap_or_else(|_| "26".into());
    let steps = std::env::var("STEPS").unwrap_or_else(|_| "100000".into());
    let geometry = format!("geometry={{sphere={{center=[0.0, 0.0], radius={radius}}}}}");
    let end = format!("time.end=\"{steps} steps\"");
    let extra = crate::common::env_overrides("SET");
    let mut set: Vec<&str> = vec![geometry.as_str(), end.as_str()];
    set.extend(extra.iter().map(String::as_str));
    let s = scene("abc-wave-2d", Some("scaled"), &set);
    if std::env::var("WHERE").is_ok() {
        // Where the field is largest at the end: the nodes a growing mode lives on.
        let mut sim = WaveSimulation::<2>::new(&s).unwrap();
        while !sim.run().clock.done() && sim.step().is_ok() {}
        let u = sim.field();
        let mut order: Vec<usize> = (0..u.len()).collect();
        order.sort_by(|a, b| u[*b].abs().total_cmp(&u[*a].abs()));
        for &i in order.iter().take(12) {
            let x = sim.positions()[i];
            eprintln!(
                "node {i}: u {:.3e} at r {:.3}, angle {:.1}°",
                u[i],
                (x[0] * x[0] + x[1] * x[1]).sqrt(),
                x[1].atan2(x[0]).to_degrees()
            );
        }
        return;
    }
    let e = energy_history::<2>(&s);
    for (t, v) in e.iter().step_by((e.len() / 20).max(1)) {
        eprintln!("t {t:8.1}: {v:.3e}");
    }
    eprintln!("{extra:?}: last {:?}", e.last());
}

/// Tuning aid: the one-step map's leading growth by power iteration. `scaled` on a disc of
/// `RADIUS` starts from a random field and runs `STEPS` steps (default 20 000) with the
/// options in `SET`; prints ‖u‖₂ over all nodes, its per-step growth, and where |u| peaks.
#[test]
#[ignore = "exploration"]
fn zz_wave_2d_leading_mode() {
    let radius = std::env::var("RADIUS").unwrap_or_else(|_| "26".into());
    let steps: u64 = std::env::var("STEPS").map_or(20_000, |s| s.parse().unwrap());
    let geometry = format!("geometry={{sphere={{center=[0.0, 0.0], radius={radius}}}}}");
    let end = format!("time.end=\"{steps} steps\"");
    let extra = crate::common::env_overrides("SET");
    let mut set: Vec<&str> = vec![geometry.as_str(), end.as_str()];
    set.extend(extra.iter().map(String::as_str));
    let s = scene("abc-wave-2d", Some("scaled"), &set);
    let mut sim = WaveSimulation::<2>::new(&s).unwrap();
    let mut seed = 0x2545_f491_4f6c_dd1du64;
    let mut random: Vec<f64> = (0..sim.field().len())
        .map(|_| {
            seed ^= seed << 13;
            seed ^= seed >> 7;
            seed ^= seed << 17;
            (seed >> 11) as f64 / (1u64 << 53) as f64 - 0.5
        })
        .collect();
    sim.set_field(&mut random);
    let norm = |u: &[f64]| u.iter().map(|v| v * v).sum::<f64>().sqrt();
    let mut last = norm(sim.field());
    let every = (steps / 20).max(1);
    for n in 1..=steps {
        if sim.step().is_err() {
            eprintln!("step {n}: failed");
            return;
        }
        if n % every == 0 {
            let now = norm(sim.field());
            let u = sim.field();
            let peak = (0..u.len())
                .max_by(|a, b| u[*a].abs().total_cmp(&u[*b].abs()))
                .unwrap();
            let x = sim.positions()[peak];
            eprintln!(
                "step {n:7}: ‖u‖ {now:.3e}, growth/step {:+.3e}, peak at r {:.2}, {:.1}°",
                (now / last).ln() / every as f64,
                (x[0] * x[0] + x[1] * x[1]).sqrt(),
                x[1].atan2(x[0]).to_degrees()
            );
            last = now;
        }
    }
    if let Ok(angle) = std::env::var("RAY") {
        // The field along the ray at `RAY` degrees: the mode's wavelength and where it lives.
        let a: f64 = angle.parse::<f64>().unwrap().to_radians();
        let (c, sn) = (a.cos(), a.sin());
        let u = sim.field();
        let mut on: Vec<(f64, f64)> = sim
            .positions()
            .iter()
            .zip(u)
            .filter(|(x, _)| (x[1] * c - x[0] * sn).abs() < 0.26 && x[0] * c + x[1] * sn > 0.0)
            .map(|(x, v)| (x[0] * c + x[1] * sn, *v))
            .collect();
        on.sort_by(|a, b| a.0.total_cmp(&b.0));
        for (r, v) in on {
            eprintln!("ray r {r:7.3}: {v:+.4e}");
        }
    }
}
