//! The semi-implicit step of the NNPP system (thesis §3.1.2, (3.11)–(3.21); seed-thesis-ch2-3
//! §2.3, in the order the note infers): the Poisson solve for φ with C^n, then per species
//! (Jacobi style: the other species and the reactions' other factors at t^n) the modified
//! Newton iteration (3.16)–(3.17) with λ = 1 and the Jacobian built once per step and frozen.
//! With rate laws linear in the implicit species the residual is linear, so one iteration is
//! exact up to the linear solve; the loop runs until the relative residual is below the
//! tolerance or the iteration cap is reached (reported either way). On a multi-grid with the
//! conservative coupling each species' residual holds the balance of its cross-level exchange
//! (`discretization::CrossBonds`) and its Jacobian the balance's rank-one term.

use crate::discretization::{CrossBonds, Families, Interpolation};
use crate::model::corrosion::Phase;
use crate::scheme::nnpp::{
    FamilySystem, ImplicitStep, LinearSource, NnppFields, NnppOperator, Unknowns,
};
use crate::sparse::{LinearMethod, LinearSolver, RankOne, SparseError};

/// What one semi-implicit step reports.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct StepReport {
    /// ‖K_φ φ − b_φ‖/‖b_φ‖ of the Poisson solve.
    pub poisson_residual: f64,
    /// Per species: the Newton residual ‖F(C^{n+1,m})‖/‖F(C^{n+1,0})‖ at the last iterate.
    pub newton_residual: Vec<f64>,
    /// Per species: the largest relative residual of its linear solves.
    pub linear_residual: Vec<f64>,
    /// Per species: Newton iterations taken.
    pub iterations: Vec<usize>,
    /// BiCGSTAB iterations of the Poisson solve (0 for the LU).
    pub poisson_iterations: usize,
    /// Per species: BiCGSTAB iterations summed over its Newton iterations (0 for the LU).
    pub linear_iterations: Vec<usize>,
    /// Per species, with the conservative coupling: the mass (Σ C V) the balance of the
    /// cross-level exchange moved in the step, D Δt (what the interpolated coupling would
    /// have created or lost); empty without it.
    pub balanced: Vec<f64>,
}

/// The two systems and their factorizations, kept across steps.
pub struct SemiImplicit {
    species: FamilySystem,
    poisson: FamilySystem,
    species_solver: LinearSolver,
    poisson_solver: LinearSolver,
    /// Solid nodes when the Poisson pattern was built (it is rebuilt when a phase changes).
    poisson_solid: usize,
    held: Vec<bool>,
    constraints: Interpolation,
    /// Iterations of the last Poisson solve (BiCGSTAB; 0 for the LU).
    pub poisson_iterations: usize,
    pub tolerance: f64,
    pub max_iterations: usize,
    residual: Vec<f64>,
    old: Vec<f64>,
    /// The cross-listed nodes' exchanges at the iterate.
    exchange: Vec<f64>,
    /// The balance's rank-one Jacobian term, and a buffer over the unknowns for its v.
    balance: RankOne,
    dense: Vec<f64>,
}

impl SemiImplicit {
    /// `held`: nodes whose species and φ are known (Dirichlet); `constraints`: nodes whose
    /// values interpolate others' (a multi-grid's fictitious nodes; empty on one grid).
    pub fn new(
        families: &Families,
        held: Vec<bool>,
        phase: &[Phase],
        constraints: Interpolation,
        method: LinearMethod,
    ) -> SemiImplicit {
        let species = FamilySystem::new(
            families,
            Unknowns::of(held.iter().map(|h| !h)),
            &constraints,
        );
        let poisson = Self::poisson_pattern(families, &held, phase, &constraints);
        let n = species.unknowns.len();
        SemiImplicit {
            species,
            poisson,
            species_solver: LinearSolver::new(method),
            poisson_solver: LinearSolver::new(method),
            poisson_solid: phase.iter().filter(|p| p.is_solid()).count(),
            held,
            constraints,
            poisson_iterations: 0,
            tolerance: 1e-10,
            max_iterations: 4,
            residual: vec![0.0; n],
            old: Vec::new(),
            exchange: Vec::new(),
            balance: RankOne::default(),
            dense: Vec::new(),
        }
    }

    fn poisson_pattern(
        families: &Families,
        held: &[bool],
        phase: &[Phase],
        constraints: &Interpolation,
    ) -> FamilySystem {
        FamilySystem::new(
            families,
            Unknowns::of(held.iter().zip(phase).map(|(h, p)| !h && !p.is_solid())),
            constraints,
        )
    }

    /// Entries of the species and the Poisson matrices (the cost of one product each).
    pub fn entries(&self) -> (usize, usize) {
        (
            self.species.matrix.values.len(),
            self.poisson.matrix.values.len(),
        )
    }

    /// Solves the Poisson equation for φ with the fields' concentrations (φ = 0 in the
    /// solid, held values kept); `extra` adds to the right side per node. Returns the
    /// relative residual.
    pub fn solve_potential(
        &mut self,
        op: &NnppOperator,
        f: &mut NnppFields,
        extra: &[f64],
    ) -> Result<f64, SparseError> {
        let solid = f.phase.iter().filter(|p| p.is_solid()).count();
        if solid != self.poisson_solid {
            self.poisson =
                Self::poisson_pattern(op.families, &self.held, &f.phase, &self.constraints);
            self.poisson_solver.reset();
            self.poisson_solid = solid;
        }
        for (p, phase) in f.potential.iter_mut().zip(&f.phase) {
            if phase.is_solid() {
                *p = 0.0;
            }
        }
        let mut rhs = vec![0.0; self.poisson.unknowns.len()];
        op.poisson_system(&mut self.poisson, f, extra, &mut rhs);
        let residual = self.poisson_solver.solve(&self.poisson.matrix, &mut rhs)?;
        self.poisson_iterations = self.poisson_solver.iterations;
        for (&i, &v) in self.poisson.unknowns.nodes.iter().zip(&rhs) {
            f.potential[i as usize] = v;
        }
        Ok(residual)
    }

    /// One implicit step of every species with φ as it is in `f` (solve it first);
    /// `sources[k]` is species k's linearized reaction per node, evaluated from the old state.
    pub fn step_species(
        &mut self,
        op: &NnppOperator,
        f: &mut NnppFields,
        dt: f64,
        sources: &[Vec<LinearSource>],
        report: &mut StepReport,
    ) -> Result<(), SparseError> {
        report.newton_residual.clear();
        report.linear_residual.clear();
        report.iterations.clear();
        report.linear_iterations.clear();
        report.balanced.clear();
        report.poisson_iterations = self.poisson_iterations;
        for (k, source) in sources.iter().enumerate() {
            self.old.clone_from(&f.concentration[k]);
            op.species_jacobian(&mut self.species, k, f, dt, source);
            let unknowns = &self.species.unknowns;
            let system = &self.species;
            let step = ImplicitStep {
                old: &self.old,
                dt,
                sources: source,
            };
            // The conservative balance: the rate −a_i D(C)/V_i on the receiving nodes, D
            // linear in C, so the exact Jacobian gains u vᵀ (u = a/V, v = ∂D/∂C).
            let update = op.cross.map(|cross| {
                let balance = &mut self.balance;
                op.cross_derivative(cross, k, f, unknowns, &mut self.dense, &mut balance.v);
                balance.u.clear();
                balance.u.extend(
                    cross
                        .nodes
                        .iter()
                        .zip(&cross.share)
                        .zip(&cross.volumes)
                        .filter(|((_, a), _)| **a > 0.0)
                        .map(|((&i, a), v)| (unknowns.index[i as usize] as usize, a / v)),
                );
                &*balance
            });
            let mut defect = 0.0;
            let mut residual = |f: &NnppFields, out: &mut Vec<f64>, exchange: &mut Vec<f64>| {
                op.species_residual(system, k, f, &step, out);
                if let Some(cross) = op.cross {
                    exchange.resize(cross.len(), 0.0);
                    op.cross_exchange(cross, k, f, exchange);
                    defect = exchange.iter().sum::<f64>();
                    for ((&i, v), a) in cross.nodes.iter().zip(&cross.volumes).zip(&cross.share) {
                        out[unknowns.index[i as usize] as usize] += a * defect / v;
                    }
                }
            };
            residual(f, &mut self.residual, &mut self.exchange);
            let initial = norm(&self.residual);
            let (mut relative, mut linear, mut iterations) = (0.0_f64, 0.0_f64, 0);
            let mut linear_iterations = 0;
            while iterations < self.max_iterations {
                let mut delta: Vec<f64> = self.residual.iter().map(|r| -r).collect();
                let r = self
                    .species_solver
                    .solve_with(&self.species.matrix, update, &mut delta)?;
                linear = linear.max(r);
                linear_iterations += self.species_solver.iterations;
                let c = &mut f.concentration[k];
                for (&i, d) in unknowns.nodes.iter().zip(&delta) {
                    c[i as usize] += d;
                }
                iterations += 1;
                residual(f, &mut self.residual, &mut self.exchange);
                relative = if initial > 0.0 {
                    norm(&self.residual) / initial
                } else {
                    0.0
                };
                if relative <= self.tolerance {
                    break;
                }
            }
            report.newton_residual.push(relative);
            report.linear_residual.push(linear);
            report.iterations.push(iterations);
            report.linear_iterations.push(linear_iterations);
            if op.cross.is_some() {
                report.balanced.push(defect * dt);
            }
        }
        Ok(())
    }

    /// Explicit Euler of every species with the same φ and sources (for comparison and the
    /// stability tests): C^{n+1} = C^n + Δt (rate + R(C^n)), the cross-level exchange
    /// balanced at C^n with the conservative coupling.
    pub fn explicit_species(
        &self,
        op: &NnppOperator,
        f: &mut NnppFields,
        dt: f64,
        sources: &[Vec<LinearSource>],
    ) {
        let unknowns = &self.species.unknowns;
        let updates: Vec<Vec<f64>> = (0..sources.len())
            .map(|k| {
                unknowns
                    .nodes
                    .iter()
                    .map(|&i| {
                        let i = i as usize;
                        let c = f.concentration[k][i];
                        c + dt
                            * (op.species_rate(k, i, f) + sources[k][i][0] + sources[k][i][1] * c)
                    })
                    .collect()
            })
            .collect();
        let corrections: Vec<Vec<f64>> = match op.cross {
            Some(cross) => (0..sources.len())
                .map(|k| {
                    let mut g = vec![0.0; cross.len()];
                    op.cross_exchange(cross, k, f, &mut g);
                    let defect: f64 = g.iter().sum();
                    cross.share.iter().map(|a| -a * defect).collect()
                })
                .collect(),
            None => Vec::new(),
        };
        for (k, update) in updates.into_iter().enumerate() {
            let c = &mut f.concentration[k];
            for (&i, v) in unknowns.nodes.iter().zip(update) {
                c[i as usize] = v;
            }
            if let (Some(cross), Some(g)) = (op.cross, corrections.get(k)) {
                apply_corrections(cross, g, dt, c);
            }
            self.constraints.transfer(c);
        }
    }
}

/// C_i += Δt g_i / V_i on the cross-listed nodes (g: the balance's corrections −a_i D,
/// mass per unit time).
fn apply_corrections(cross: &CrossBonds, corrections: &[f64], dt: f64, c: &mut [f64]) {
    for ((&i, v), g) in cross.nodes.iter().zip(&cross.volumes).zip(corrections) {
        c[i as usize] += dt * g / v;
    }
}

fn norm(v: &[f64]) -> f64 {
    v.iter().map(|x| x * x).sum::<f64>().sqrt()
}
