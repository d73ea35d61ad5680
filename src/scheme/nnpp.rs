//! The standard-scheme discretization of the nonlocal Nernst–Planck–Poisson system (thesis
//! (2.63)–(2.64) in the sum (3.1); the species residual (3.11), its Jacobian (3.14) and (3.15)
//! with the sign erratum of seed-thesis-ch2-3 §2.3, the Poisson system (3.18)–(3.21)).
//!
//! Per directed bond the kernel weights K ω/r^{n+2q} β V_j are precomputed once; the bond
//! diffusivities come from the bond's phase class each step ((2.78): liquid–liquid,
//! interface (exactly one end solid), solid–solid). φ is not solved in the solid: φ = 0 there
//! (caption of the thesis's Fig. 3.29), a known value to the liquid rows, as are held
//! (Dirichlet) nodes.

use rayon::prelude::*;

use crate::discretization::{Families, Quadrature};
use crate::model::corrosion::Phase;
pub use crate::model::nernst_planck::SpeciesLaw;
use crate::model::nernst_planck::{FARADAY, GAS_CONSTANT, NnppKernel};
use crate::model::pmb::influence;
use crate::sparse::SparseMatrix;

/// The precomputed bond weights of one grid, aligned with its families' CSR.
#[derive(Debug, Clone)]
pub struct NnppBonds {
    /// K1 ω/r^{n+2q1} β V_j.
    pub diffusion: Vec<f64>,
    /// K2 ω/r^{n+2q2} β V_j.
    pub migration: Vec<f64>,
    /// K3 ω/r^{n+2q3} β V_j.
    pub poisson: Vec<f64>,
    /// F/(R T), 1/V.
    pub thermal: f64,
}

impl NnppBonds {
    pub fn new(
        kernel: &NnppKernel,
        families: &Families,
        volumes: &[f64],
        quadrature: &Quadrature,
        temperature: f64,
    ) -> NnppBonds {
        let constants = kernel.constants();
        let n = kernel.dim as f64;
        let [q1, q2, q3] = kernel.exponents;
        let weights = |k: f64, q: f64| -> Vec<f64> {
            (0..families.node_count())
                .into_par_iter()
                .flat_map_iter(|i| {
                    families.range(i).map(move |b| {
                        let r = families.lengths[b];
                        let j = families.neighbors[b] as usize;
                        k * influence(kernel.influence, r, kernel.horizon) / r.powf(n + 2.0 * q)
                            * quadrature.beta(r)
                            * volumes[j]
                    })
                })
                .collect()
        };
        NnppBonds {
            diffusion: weights(constants.k1, q1),
            migration: weights(constants.k2, q2),
            poisson: weights(constants.k3, q3),
            thermal: FARADAY / (GAS_CONSTANT * temperature),
        }
    }
}

/// Which nodes are unknowns of a system, and each unknown's row.
#[derive(Debug, Clone)]
pub struct Unknowns {
    /// The node of each unknown, increasing.
    pub nodes: Vec<u32>,
    /// The unknown of each node (u32::MAX where the node's value is known).
    pub index: Vec<u32>,
}

impl Unknowns {
    pub fn of(free: impl Iterator<Item = bool>) -> Unknowns {
        let mut nodes = Vec::new();
        let index = free
            .enumerate()
            .map(|(i, f)| {
                if f {
                    nodes.push(i as u32);
                    (nodes.len() - 1) as u32
                } else {
                    u32::MAX
                }
            })
            .collect();
        Unknowns { nodes, index }
    }

    pub fn len(&self) -> usize {
        self.nodes.len()
    }

    pub fn is_empty(&self) -> bool {
        self.nodes.is_empty()
    }
}

/// A system matrix over `unknowns` with the family pattern (diagonal and unknown neighbours),
/// and for each directed bond the entry its far end fills (None: a known far end).
#[derive(Debug, Clone)]
pub struct FamilySystem {
    pub unknowns: Unknowns,
    pub matrix: SparseMatrix,
    diagonal: Vec<usize>,
    /// Per directed bond of the unknown rows, in the rows' order: the entry or usize::MAX.
    bond_entry: Vec<usize>,
    /// Start of each unknown row's bonds in `bond_entry`.
    bond_offsets: Vec<usize>,
}

impl FamilySystem {
    pub fn new(families: &Families, unknowns: Unknowns) -> FamilySystem {
        let rows: Vec<Vec<usize>> = unknowns
            .nodes
            .par_iter()
            .map(|&i| {
                let mut row = vec![unknowns.index[i as usize] as usize];
                row.extend(families.range(i as usize).filter_map(|b| {
                    let u = unknowns.index[families.neighbors[b] as usize];
                    (u != u32::MAX).then_some(u as usize)
                }));
                row
            })
            .collect();
        let matrix = SparseMatrix::with_pattern(rows);
        let mut diagonal = Vec::with_capacity(unknowns.len());
        let mut bond_entry = Vec::new();
        let mut bond_offsets = vec![0];
        for (r, &i) in unknowns.nodes.iter().enumerate() {
            diagonal.push(matrix.entry(r, r).unwrap_or(usize::MAX));
            for b in families.range(i as usize) {
                let u = unknowns.index[families.neighbors[b] as usize];
                bond_entry.push(if u == u32::MAX {
                    usize::MAX
                } else {
                    matrix.entry(r, u as usize).unwrap_or(usize::MAX)
                });
            }
            bond_offsets.push(bond_entry.len());
        }
        FamilySystem {
            unknowns,
            matrix,
            diagonal,
            bond_entry,
            bond_offsets,
        }
    }

    /// Fills the matrix row by row: `row(i, add)` calls `add(entry, value)` with `entry` the
    /// diagonal (usize::MAX) or a bond's local index in the node's family.
    fn fill(
        &mut self,
        families: &Families,
        row: impl Fn(usize, &mut dyn FnMut(Option<usize>, f64)) + Sync,
    ) {
        let FamilySystem {
            unknowns,
            matrix,
            diagonal,
            bond_entry,
            bond_offsets,
        } = self;
        matrix.values.iter_mut().for_each(|v| *v = 0.0);
        // Rows own disjoint value ranges: split them once per fill.
        let mut rest: &mut [f64] = &mut matrix.values;
        let mut slices = Vec::with_capacity(unknowns.len());
        for r in 0..unknowns.len() {
            let (head, tail) = rest.split_at_mut(matrix.offsets[r + 1] - matrix.offsets[r]);
            slices.push(head);
            rest = tail;
        }
        let offsets = &matrix.offsets;
        slices.into_par_iter().enumerate().for_each(|(r, values)| {
            let start = offsets[r];
            let i = unknowns.nodes[r] as usize;
            let first = families.offsets[i];
            let entries = &bond_entry[bond_offsets[r]..bond_offsets[r + 1]];
            row(i, &mut |bond, value| {
                let e = match bond {
                    None => diagonal[r],
                    Some(b) => entries[b - first],
                };
                if e != usize::MAX {
                    values[e - start] += value;
                }
            });
        });
    }
}

/// The fields the step reads: per species concentration C_k (SoA), the potential φ and the
/// phases.
#[derive(Debug, Clone)]
pub struct NnppFields {
    pub concentration: Vec<Vec<f64>>,
    pub potential: Vec<f64>,
    pub phase: Vec<Phase>,
}

/// A linear source linearized in the implicit species: R = r0 + r1 C_k^{n+1} per node.
pub type LinearSource = [f64; 2];

/// What the residual (3.11) of one species holds fixed over a step: C^n, Δt and the
/// linearized sources.
#[derive(Clone, Copy)]
pub struct ImplicitStep<'a> {
    pub old: &'a [f64],
    pub dt: f64,
    pub sources: &'a [LinearSource],
}

/// The discrete operator of one grid: families, bond weights, species laws, conductivity.
pub struct NnppOperator<'a> {
    pub families: &'a Families,
    pub bonds: &'a NnppBonds,
    pub species: &'a [SpeciesLaw],
    /// σ of liquid and interface bonds (the micro-conductivity of (2.64)), S/m.
    pub conductivity: f64,
}

impl NnppOperator<'_> {
    /// The nonlocal flux sum of (2.63) at node i for species k (no reaction).
    #[inline]
    pub fn species_rate(&self, k: usize, i: usize, f: &NnppFields) -> f64 {
        let law = &self.species[k];
        let c = &f.concentration[k];
        let zf = law.valence * self.bonds.thermal;
        let (ci, pi) = (c[i], f.potential[i]);
        self.families
            .range(i)
            .map(|b| {
                let j = self.families.neighbors[b] as usize;
                let d = law.diffusivity(f.phase[i], f.phase[j]);
                d * (self.bonds.diffusion[b] * (c[j] - ci)
                    + self.bonds.migration[b] * zf * (f.potential[j] - pi) * (c[j] + ci))
            })
            .sum()
    }

    /// The Jacobian of the residual (3.11) of species k, frozen at the step's φ^n and phases
    /// (3.14), (3.15) with the sign erratum: K_ii = 1/Δt + Σ D [g1 − g2 zF/RT (φ_j − φ_i)]
    /// − r1, K_ij = −D [g1 + g2 zF/RT (φ_j − φ_i)].
    pub fn species_jacobian(
        &self,
        system: &mut FamilySystem,
        k: usize,
        f: &NnppFields,
        dt: f64,
        sources: &[LinearSource],
    ) {
        let law = &self.species[k];
        let zf = law.valence * self.bonds.thermal;
        system.fill(self.families, |i, add| {
            let mut diag = 1.0 / dt - sources[i][1];
            for b in self.families.range(i) {
                let j = self.families.neighbors[b] as usize;
                let d = law.diffusivity(f.phase[i], f.phase[j]);
                let g1 = self.bonds.diffusion[b];
                let g2 = self.bonds.migration[b] * zf * (f.potential[j] - f.potential[i]);
                diag += d * (g1 - g2);
                add(Some(b), -d * (g1 + g2));
            }
            add(None, diag);
        });
    }

    /// The residual (3.11) of species k at the iterate `f.concentration[k]` on the unknown
    /// rows: (C − C^n)/Δt − Σ … − R.
    pub fn species_residual(
        &self,
        unknowns: &Unknowns,
        k: usize,
        f: &NnppFields,
        step: &ImplicitStep,
        out: &mut [f64],
    ) {
        let ImplicitStep { old, dt, sources } = *step;
        let c = &f.concentration[k];
        out.par_iter_mut().zip(&unknowns.nodes).for_each(|(o, &i)| {
            let i = i as usize;
            let reaction = sources[i][0] + sources[i][1] * c[i];
            *o = (c[i] - old[i]) / dt - self.species_rate(k, i, f) - reaction;
        });
    }

    /// The Poisson system (3.18)–(3.21) on the liquid unknown rows: K_ii = Σ g3 σ,
    /// K_ij = −g3 σ; the right side F Σ z C + `extra` plus the known far ends' g3 σ φ_j.
    pub fn poisson_system(
        &self,
        system: &mut FamilySystem,
        f: &NnppFields,
        extra: &[f64],
        rhs: &mut [f64],
    ) {
        let sigma = self.conductivity;
        system.fill(self.families, |i, add| {
            let mut diag = 0.0;
            for b in self.families.range(i) {
                let w = self.bonds.poisson[b] * sigma;
                diag += w;
                add(Some(b), -w);
            }
            add(None, diag);
        });
        let unknowns = &system.unknowns;
        rhs.par_iter_mut().zip(&unknowns.nodes).for_each(|(r, &i)| {
            let i = i as usize;
            let charge: f64 = self
                .species
                .iter()
                .zip(&f.concentration)
                .map(|(s, c)| s.valence * c[i])
                .sum();
            let known: f64 = self
                .families
                .range(i)
                .filter(|&b| unknowns.index[self.families.neighbors[b] as usize] == u32::MAX)
                .map(|b| {
                    self.bonds.poisson[b] * sigma * f.potential[self.families.neighbors[b] as usize]
                })
                .sum();
            *r = FARADAY * charge + extra[i] + known;
        });
    }
}
