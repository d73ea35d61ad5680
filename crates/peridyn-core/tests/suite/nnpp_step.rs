//! The semi-implicit NNPP step on one grid (issue 18's acceptance; thesis §3.1.2,
//! (3.11)–(3.21), seed-thesis-ch2-3 §2.3 with the sign erratum of (3.15)):
//! - each species' total Σ C V is conserved to 1e-12 relative with no reactions and no-flux
//!   ends, with a potential strong enough that electromigration moves the species;
//! - with linear rate laws one Newton iteration leaves a relative residual below 1e-10;
//! - the implicit step agrees with explicit Euler to first order in Δt (halving Δt halves the
//!   difference at a fixed time);
//! - at Δt = 3 h the implicit step stays bounded where explicit Euler diverges;
//! - every Poisson solve's relative residual is below 1e-10, and a linear potential between
//!   held ends is reproduced exactly (the nonlocal Laplacian's patch test).
//!
//! The line: 1D, Δx = 50 µm, δ = 3Δx, β partial volumes, Table-3.7-like diffusivities; the
//! first nodes solid (φ = 0 there, the Poisson equation's Dirichlet part).

use peridyn_core::adapt::masks::Phase;
use peridyn_core::discretization::{Families, Interpolation, Quadrature};
use peridyn_core::integrate::newton::{SemiImplicit, StepReport};
use peridyn_core::model::nernst_planck::NnppKernel;
use peridyn_core::model::pmb::Influence;
use peridyn_core::scheme::nnpp::{LinearSource, NnppBonds, NnppFields, NnppOperator, SpeciesLaw};
use peridyn_core::sparse::LinearMethod;

const NODES: usize = 101;
const SPACING: f64 = 50e-6;
const SOLID: usize = 10;
/// Chosen so that the charge of the initial fields gives a potential of tens of mV, where
/// z F Δφ / R T is of order one and electromigration matters.
const CONDUCTIVITY: f64 = 20.0;

struct Line {
    families: Families,
    bonds: NnppBonds,
    volumes: Vec<f64>,
    species: Vec<SpeciesLaw>,
}

impl Line {
    fn new() -> Line {
        let horizon = 3.0 * SPACING;
        let positions: Vec<[f64; 1]> = (0..NODES).map(|i| [i as f64 * SPACING]).collect();
        let families = Families::build(&positions, horizon + 0.5 * SPACING);
        let volumes = vec![SPACING; NODES];
        let quadrature = Quadrature {
            spacing: SPACING,
            horizon,
            volume_correction: true,
        };
        let kernel = NnppKernel::new(1, Influence::Constant, horizon, [0.0, 0.0, 0.0])
            .expect("a valid kernel");
        let bonds = NnppBonds::new(&kernel, &families, &volumes, &|_| quadrature, 298.15);
        let law = |name: &str, valence: f64, liquid: f64| SpeciesLaw {
            name: name.into(),
            valence,
            liquid,
            interface: 0.1 * liquid,
            solid: 0.01 * liquid,
        };
        Line {
            families,
            bonds,
            volumes,
            species: vec![law("cation", 2.0, 9.75e-10), law("anion", -1.0, 1.7e-9)],
        }
    }

    fn operator(&self) -> NnppOperator<'_> {
        NnppOperator {
            families: &self.families,
            bonds: &self.bonds,
            species: &self.species,
            conductivity: CONDUCTIVITY,
            concentration_unit: 1.0,
            cross: None,
        }
    }

    /// Smooth, charged initial fields; the first `SOLID` nodes solid.
    /// The semi-implicit solver of this one-grid line (sparse LU) with `held` nodes.
    fn solver(&self, held: Vec<bool>, phase: &[Phase]) -> SemiImplicit {
        SemiImplicit::new(
            &self.families,
            held,
            phase,
            Interpolation::new(),
            LinearMethod::Direct,
        )
    }

    fn fields(&self) -> NnppFields {
        let x = |i: usize| i as f64 / (NODES - 1) as f64;
        let tau = std::f64::consts::TAU;
        NnppFields {
            concentration: vec![
                (0..NODES).map(|i| 1.0 + 0.5 * (tau * x(i)).sin()).collect(),
                (0..NODES).map(|i| 2.0 + 0.6 * (tau * x(i)).cos()).collect(),
            ],
            potential: vec![0.0; NODES],
            interface_diffusivity: None,
            phase: (0..NODES)
                .map(|i| {
                    if i < SOLID {
                        Phase::Solid
                    } else {
                        Phase::Liquid
                    }
                })
                .collect(),
        }
    }

    fn totals(&self, f: &NnppFields) -> Vec<f64> {
        f.concentration
            .iter()
            .map(|c| c.iter().zip(&self.volumes).map(|(c, v)| c * v).sum())
            .collect()
    }

    /// Gershgorin bound of explicit Euler for the diffusion part: 2 / max_i Σ D g1.
    fn explicit_bound(&self, f: &NnppFields) -> f64 {
        let largest = (0..NODES)
            .flat_map(|i| {
                self.species.iter().map(move |law| {
                    self.families
                        .range(i)
                        .map(|b| {
                            let j = self.families.neighbors[b] as usize;
                            2.0 * law.diffusivity(f.phase[i], f.phase[j]) * self.bonds.diffusion[b]
                        })
                        .sum::<f64>()
                })
            })
            .fold(0.0, f64::max);
        2.0 / largest
    }
}

fn no_sources(species: usize) -> Vec<Vec<LinearSource>> {
    vec![vec![[0.0, 0.0]; NODES]; species]
}

/// One step: φ from C^n, then the species (implicit or explicit Euler). Returns the report.
fn step(
    line: &Line,
    solver: &mut SemiImplicit,
    f: &mut NnppFields,
    dt: f64,
    sources: &[Vec<LinearSource>],
    implicit: bool,
) -> StepReport {
    let op = line.operator();
    let extra = vec![0.0; NODES];
    let mut report = StepReport {
        poisson_residual: solver
            .solve_potential(&op, f, &extra)
            .expect("Poisson solve"),
        ..StepReport::default()
    };
    assert!(
        report.poisson_residual < 1e-10,
        "Poisson residual {:e}",
        report.poisson_residual
    );
    if implicit {
        solver
            .step_species(&op, f, dt, sources, &mut report)
            .expect("species solve");
    } else {
        solver.explicit_species(&op, f, dt, sources);
    }
    report
}

fn max_abs(v: &[f64]) -> f64 {
    v.iter().fold(0.0, |m, x| m.max(x.abs()))
}

#[test]
fn species_totals_are_conserved_with_electromigration() {
    let line = Line::new();
    let mut f = line.fields();
    let mut solver = line.solver(vec![false; NODES], &f.phase);
    let before = line.totals(&f);
    let dt = 10.0;
    let sources = no_sources(2);
    let mut moved = 0.0_f64;
    for _ in 0..20 {
        let old = f.concentration[1].clone();
        step(&line, &mut solver, &mut f, dt, &sources, true);
        moved = moved.max(
            old.iter()
                .zip(&f.concentration[1])
                .fold(0.0, |m, (a, b)| m.max((a - b).abs())),
        );
    }
    let potential = max_abs(&f.potential);
    assert!(
        potential > 5e-3,
        "the potential must matter (z F φ / R T of order one): max |φ| = {potential:e} V"
    );
    assert!(moved > 1e-3, "the species must move: {moved:e}");
    assert!(
        f.potential[..SOLID].iter().all(|&p| p == 0.0),
        "φ = 0 in the solid"
    );
    for (k, (a, b)) in before.iter().zip(line.totals(&f)).enumerate() {
        let drift = ((b - a) / a).abs();
        eprintln!("species {k}: Σ C V drift {drift:e}, max |φ| {potential:e} V");
        assert!(drift < 1e-12, "species {k}: Σ C V drifted by {drift:e}");
    }
}

#[test]
fn one_newton_iteration_solves_linear_rate_laws() {
    let line = Line::new();
    let mut f = line.fields();
    let mut solver = line.solver(vec![false; NODES], &f.phase);
    // A first-order consumption of the cation and a constant production of the anion.
    let sources = vec![vec![[1e-4, -2e-4]; NODES], vec![[3e-5, 0.0]; NODES]];
    for _ in 0..3 {
        let report = step(&line, &mut solver, &mut f, 600.0, &sources, true);
        for k in 0..2 {
            assert_eq!(report.iterations[k], 1, "species {k}: {report:?}");
            assert!(report.newton_residual[k] < 1e-10, "{report:?}");
            assert!(report.linear_residual[k] < 1e-10, "{report:?}");
        }
    }
}

#[test]
fn implicit_and_explicit_euler_agree_to_first_order() {
    let line = Line::new();
    let start = line.fields();
    let bound = line.explicit_bound(&start);
    let sources = vec![vec![[1e-4, -2e-4]; NODES], vec![[0.0, 0.0]; NODES]];
    let end_time = 2.0 * bound;
    let difference = |steps: usize| -> f64 {
        let dt = end_time / steps as f64;
        let run = |implicit: bool| {
            let mut f = start.clone();
            let mut solver = line.solver(vec![false; NODES], &f.phase);
            for _ in 0..steps {
                step(&line, &mut solver, &mut f, dt, &sources, implicit);
            }
            f.concentration
        };
        let (a, b) = (run(true), run(false));
        a.iter()
            .flatten()
            .zip(b.iter().flatten())
            .fold(0.0, |m, (x, y)| m.max((x - y).abs()))
    };
    let d: Vec<f64> = [20, 40, 80].into_iter().map(difference).collect();
    eprintln!("implicit - explicit at 20, 40, 80 steps: {d:?}");
    for w in d.windows(2) {
        let ratio = w[0] / w[1];
        assert!(
            (1.8..2.2).contains(&ratio),
            "halving Δt must halve the difference: {d:?}"
        );
    }
}

#[test]
fn implicit_step_is_bounded_at_three_hours_where_explicit_diverges() {
    let line = Line::new();
    let start = line.fields();
    let dt = 3.0 * 3600.0;
    assert!(
        dt > 100.0 * line.explicit_bound(&start),
        "the test needs a stiff step"
    );
    let sources = no_sources(2);
    let initial_max = start
        .concentration
        .iter()
        .map(|c| max_abs(c))
        .fold(0.0, f64::max);
    let run = |implicit: bool| {
        let mut f = start.clone();
        let mut solver = line.solver(vec![false; NODES], &f.phase);
        for _ in 0..40 {
            step(&line, &mut solver, &mut f, dt, &sources, implicit);

            if f.concentration.iter().flatten().any(|c| c.abs() > 1e12) {
                break; // diverged: the next Poisson right side would overflow
            }
        }
        f
    };
    // Bounded in the physical sense: finite, non-negative and conserving. (With the potential
    // lagged one step, the strongly coupled line settles into a period-2 cycle between two
    // bounded states at this Δt instead of a fixed point: max C 7.03 / 7.48 against 2.6 at
    // the start, with max |φ| 0.13 V; see the issue-18 notes.)
    let implicit = run(true);
    let largest = implicit
        .concentration
        .iter()
        .map(|c| max_abs(c))
        .fold(0.0, f64::max);
    let smallest = implicit
        .concentration
        .iter()
        .flatten()
        .fold(f64::INFINITY, |m, &c| m.min(c));
    assert!(
        largest.is_finite() && smallest >= 0.0,
        "implicit: C in [{smallest:e}, {largest:e}]"
    );
    for (k, (a, b)) in line
        .totals(&start)
        .iter()
        .zip(line.totals(&implicit))
        .enumerate()
    {
        let drift = ((b - a) / a).abs();
        assert!(
            drift < 1e-12,
            "species {k}: Σ C V drifted by {drift:e} at Δt = 3 h"
        );
    }
    eprintln!("Δt = 3 h: implicit max |C| {largest:e} (start {initial_max:e})");
    let explicit = run(false);
    let blown = explicit
        .concentration
        .iter()
        .map(|c| max_abs(c))
        .fold(0.0, f64::max);
    assert!(
        !blown.is_finite() || blown > 1e6 * initial_max,
        "explicit Euler should diverge at Δt = 3 h: max |C| {blown:e}"
    );
}

#[test]
fn linear_potential_between_held_ends_is_reproduced() {
    let line = Line::new();
    let layer = 3;
    let held: Vec<bool> = (0..NODES)
        .map(|i| i < layer || i >= NODES - layer)
        .collect();
    let exact = |i: usize| 0.1 - 0.25 * i as f64 * SPACING / (NODES as f64 * SPACING);
    let mut f = NnppFields {
        // Neutral: z1 C1 + z2 C2 = 0.
        concentration: vec![vec![1.0; NODES], vec![2.0; NODES]],
        potential: (0..NODES)
            .map(|i| if held[i] { exact(i) } else { 0.0 })
            .collect(),
        phase: vec![Phase::Liquid; NODES],
        interface_diffusivity: None,
    };
    let mut solver = line.solver(held, &f.phase);
    let residual = solver
        .solve_potential(&line.operator(), &mut f, &vec![0.0; NODES])
        .expect("Poisson solve");
    assert!(residual < 1e-10, "{residual:e}");
    let error = (0..NODES)
        .map(|i| (f.potential[i] - exact(i)).abs())
        .fold(0.0, f64::max);
    assert!(error < 1e-13, "linear φ error {error:e} V");
}
