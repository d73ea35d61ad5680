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

use crate::discretization::{CrossBonds, Families, Interpolation, Quadrature};
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
    /// `quadrature(i)`: the β rule of node i's rows (a multi-grid level's spacing).
    pub fn new(
        kernel: &NnppKernel,
        families: &Families,
        volumes: &[f64],
        quadrature: &(dyn Fn(usize) -> Quadrature + Sync),
        temperature: f64,
    ) -> NnppBonds {
        let constants = kernel.constants();
        let n = kernel.dim as f64;
        let [q1, q2, q3] = kernel.exponents;
        let weights = |k: f64, q: f64| -> Vec<f64> {
            (0..families.node_count())
                .into_par_iter()
                .flat_map_iter(|i| {
                    let quadrature = quadrature(i);
                    families.range(i).map(move |b| {
                        let r = families.length(i, b);
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
/// and for each directed bond the entry its far end fills (None: a known far end). Unknowns
/// that are targets of `constraints` (a multi-grid's fictitious nodes) get the constraint row
/// v_t − Σ w v_s = 0 (times a scale) instead of a family row.
#[derive(Debug, Clone)]
pub struct FamilySystem {
    pub unknowns: Unknowns,
    pub matrix: SparseMatrix,
    pub constraints: Interpolation,
    /// Per unknown row: its constraint row, or u32::MAX for a family row.
    constrained: Vec<u32>,
    /// The factor of the constraint rows at the last fill (residuals use it too).
    pub constraint_scale: f64,
    diagonal: Vec<usize>,
    /// Per directed bond of the family rows, in the rows' order: the entry or usize::MAX.
    bond_entry: Vec<usize>,
    /// Start of each unknown row's bonds in `bond_entry`.
    bond_offsets: Vec<usize>,
}

impl FamilySystem {
    pub fn new(families: &Families, unknowns: Unknowns, constraints: &Interpolation) -> Self {
        let row_of = constraints.row_of(unknowns.index.len());
        let constrained: Vec<u32> = unknowns.nodes.iter().map(|&i| row_of[i as usize]).collect();
        let rows: Vec<Vec<usize>> = unknowns
            .nodes
            .par_iter()
            .zip(&constrained)
            .map(|(&i, &k)| {
                let mut row = vec![unknowns.index[i as usize] as usize];
                let far: Vec<u32> = if k == u32::MAX {
                    families
                        .range(i as usize)
                        .map(|b| families.neighbors[b])
                        .collect()
                } else {
                    constraints.row(k as usize).0.to_vec()
                };
                row.extend(far.into_iter().filter_map(|j| {
                    let u = unknowns.index[j as usize];
                    (u != u32::MAX).then_some(u as usize)
                }));
                row.sort_unstable();
                row.dedup();
                row
            })
            .collect();
        let matrix = SparseMatrix::with_pattern(rows);
        let mut diagonal = Vec::with_capacity(unknowns.len());
        let mut bond_entry = Vec::new();
        let mut bond_offsets = vec![0];
        for (r, &i) in unknowns.nodes.iter().enumerate() {
            diagonal.push(matrix.entry(r, r).unwrap_or(usize::MAX));
            if constrained[r] == u32::MAX {
                for b in families.range(i as usize) {
                    let u = unknowns.index[families.neighbors[b] as usize];
                    bond_entry.push(if u == u32::MAX {
                        usize::MAX
                    } else {
                        matrix.entry(r, u as usize).unwrap_or(usize::MAX)
                    });
                }
            }
            bond_offsets.push(bond_entry.len());
        }
        FamilySystem {
            unknowns,
            matrix,
            constraints: constraints.clone(),
            constrained,
            constraint_scale: 1.0,
            diagonal,
            bond_entry,
            bond_offsets,
        }
    }

    /// The constraint row of unknown row `r`, if it has one.
    #[inline]
    pub fn constraint(&self, r: usize) -> Option<usize> {
        let k = self.constrained[r];
        (k != u32::MAX).then_some(k as usize)
    }

    /// Fills the matrix row by row: `row(i, add)` calls `add(entry, value)` with `entry` the
    /// diagonal (None) or a bond's index in the families' CSR. Constraint rows get
    /// s (1, −w …) without calling `row`, s the family rows' mean |diagonal| (kept in
    /// `constraint_scale`): rows of one magnitude keep the Jacobi-scaled system balanced.
    fn fill(
        &mut self,
        families: &Families,
        row: impl Fn(usize, &mut dyn FnMut(Option<usize>, f64)) + Sync,
    ) {
        let FamilySystem {
            unknowns,
            matrix,
            constrained,
            diagonal,
            bond_entry,
            bond_offsets,
            ..
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
            if constrained[r] != u32::MAX {
                return;
            }
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
        let (sum, count) = (0..unknowns.len())
            .filter(|&r| constrained[r] == u32::MAX && diagonal[r] != usize::MAX)
            .fold((0.0, 0usize), |(s, c), r| {
                (s + matrix.values[diagonal[r]].abs(), c + 1)
            });
        let scale = if count > 0 && sum > 0.0 {
            sum / count as f64
        } else {
            1.0
        };
        self.constraint_scale = scale;
        for r in 0..self.unknowns.len() {
            let k = self.constrained[r];
            if k == u32::MAX {
                continue;
            }
            let (sources, weights) = self.constraints.row(k as usize);
            if let Some(e) = self.matrix.entry(r, r) {
                self.matrix.values[e] += scale;
            }
            for (&s, &w) in sources.iter().zip(weights) {
                let u = self.unknowns.index[s as usize];
                if u != u32::MAX
                    && let Some(e) = self.matrix.entry(r, u as usize)
                {
                    self.matrix.values[e] -= scale * w;
                }
            }
        }
    }

    /// Σ w v over the known (not unknown) sources of constraint row `k`.
    fn known_part(&self, k: usize, values: &[f64]) -> f64 {
        let (sources, weights) = self.constraints.row(k);
        sources
            .iter()
            .zip(weights)
            .filter(|(s, _)| self.unknowns.index[**s as usize] == u32::MAX)
            .map(|(&s, w)| w * values[s as usize])
            .sum()
    }
}

/// The fields the step reads: per species concentration C_k (SoA), the potential φ and the
/// phases.
#[derive(Debug, Clone)]
pub struct NnppFields {
    pub concentration: Vec<Vec<f64>>,
    pub potential: Vec<f64>,
    pub phase: Vec<Phase>,
    /// A species whose interface bonds take a per-node diffusivity, read at the bond's solid
    /// end (the Butler–Volmer D_int(η) of (3.92)); None: every species by its law.
    pub interface_diffusivity: Option<(usize, Vec<f64>)>,
}

impl NnppFields {
    /// D_{k,ij} of bond i→j (2.78), symmetric in i and j.
    #[inline(always)]
    pub fn bond_diffusivity(&self, law: &SpeciesLaw, k: usize, i: usize, j: usize) -> f64 {
        let (a, b) = (self.phase[i], self.phase[j]);
        match &self.interface_diffusivity {
            Some((species, d)) if *species == k && a.is_solid() != b.is_solid() => {
                d[if a.is_solid() { i } else { j }]
            }
            _ => law.diffusivity(a, b),
        }
    }
}

/// A linear source linearized in the implicit species: R = r0 + r1 C_k^{n+1} per node.
pub use crate::model::nnpp_reactions::LinearSource;

/// What the residual (3.11) of one species holds fixed over a step: C^n, Δt and the
/// linearized sources.
#[derive(Clone, Copy)]
pub struct ImplicitStep<'a> {
    pub old: &'a [f64],
    pub dt: f64,
    pub sources: &'a [LinearSource],
}

/// One bond's parts of the species flux q = D [g1 (C_j − C_i) + g2 (C_j + C_i)] into i.
#[derive(Debug, Clone, Copy)]
struct BondCoefficients {
    far: usize,
    diffusivity: f64,
    /// g1.
    diffusion: f64,
    /// g2, with zF/RT (φ_j − φ_i).
    migration: f64,
}

impl BondCoefficients {
    /// (∂q/∂C_i, ∂q/∂C_j) = D (g2 − g1, g1 + g2).
    #[inline(always)]
    fn derivatives(&self) -> (f64, f64) {
        let d = self.diffusivity;
        (
            d * (self.migration - self.diffusion),
            d * (self.diffusion + self.migration),
        )
    }
}

/// The discrete operator of one grid: families, bond weights, species laws, conductivity.
pub struct NnppOperator<'a> {
    pub families: &'a Families,
    pub bonds: &'a NnppBonds,
    pub species: &'a [SpeciesLaw],
    /// σ of liquid and interface bonds (the micro-conductivity of (2.64)), S/m.
    pub conductivity: f64,
    /// mol/m³ per unit of C in the charge F Σ z C (1 when C is in mol/m³).
    pub concentration_unit: f64,
    /// The multi-grid's cross-level bonds when their exchange is balanced (the conservative
    /// coupling); None: the fluxes stand as the bonds give them.
    pub cross: Option<&'a CrossBonds>,
}

impl NnppOperator<'_> {
    /// Bond b = i→j of species k: its far end j, its diffusivity D (2.78) and its weights g1
    /// and g2 = K2-weight · zF/RT (φ_j − φ_i), so that the flux into i is
    /// q = D [g1 (C_j − C_i) + g2 (C_j + C_i)].
    #[inline(always)]
    fn bond_coefficients(&self, k: usize, b: usize, i: usize, f: &NnppFields) -> BondCoefficients {
        let law = &self.species[k];
        let j = self.families.neighbors[b] as usize;
        BondCoefficients {
            far: j,
            diffusivity: f.bond_diffusivity(law, k, i, j),
            diffusion: self.bonds.diffusion[b],
            migration: self.bonds.migration[b]
                * law.valence
                * self.bonds.thermal
                * (f.potential[j] - f.potential[i]),
        }
    }

    /// The flux of species k that bond b = i→j carries into i (2.63):
    /// D [g1 (C_j − C_i) + g2 zF/RT (φ_j − φ_i) (C_j + C_i)].
    #[inline(always)]
    fn bond_flux(&self, k: usize, b: usize, i: usize, f: &NnppFields) -> f64 {
        let c = &f.concentration[k];
        let q = self.bond_coefficients(k, b, i, f);
        let j = q.far;
        q.diffusivity * (q.diffusion * (c[j] - c[i]) + q.migration * (c[j] + c[i]))
    }

    /// The nonlocal flux sum of (2.63) at node i for species k (no reaction).
    #[inline]
    pub fn species_rate(&self, k: usize, i: usize, f: &NnppFields) -> f64 {
        self.families
            .range(i)
            .map(|b| self.bond_flux(k, b, i, f))
            .sum()
    }

    /// Each cross-listed node's exchange with the other level, V_i Σ q over its cross bonds
    /// (mass per unit time into the node), species k.
    pub fn cross_exchange(&self, cross: &CrossBonds, k: usize, f: &NnppFields, out: &mut [f64]) {
        out.par_iter_mut().enumerate().for_each(|(m, g)| {
            let i = cross.nodes[m] as usize;
            *g = cross.volumes[m]
                * cross
                    .range(m)
                    .map(|e| self.bond_flux(k, cross.bonds[e] as usize, i, f))
                    .sum::<f64>();
        });
    }

    /// ∂D/∂C of the cross exchange D = Σ_m V_m Σ_b q_b (species k, frozen φ and phases) as
    /// (unknown, value) pairs, one per unknown end of the cross bonds (`dense`: a buffer
    /// over the unknowns, left zeroed).
    pub fn cross_derivative(
        &self,
        cross: &CrossBonds,
        k: usize,
        f: &NnppFields,
        unknowns: &Unknowns,
        dense: &mut Vec<f64>,
        out: &mut Vec<(usize, f64)>,
    ) {
        dense.clear();
        dense.resize(unknowns.len(), 0.0);
        for m in 0..cross.len() {
            let i = cross.nodes[m] as usize;
            let v = cross.volumes[m];
            for e in cross.range(m) {
                let q = self.bond_coefficients(k, cross.bonds[e] as usize, i, f);
                let (near, far) = q.derivatives();
                for (node, value) in [(i, v * near), (q.far, v * far)] {
                    let u = unknowns.index[node];
                    if u != u32::MAX {
                        dense[u as usize] += value;
                    }
                }
            }
        }
        out.clear();
        out.extend(
            dense
                .iter()
                .enumerate()
                .filter(|(_, v)| **v != 0.0)
                .map(|(u, v)| (u, *v)),
        );
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
        system.fill(self.families, |i, add| {
            let mut diag = 1.0 / dt - sources[i][1];
            for b in self.families.range(i) {
                let (near, far) = self.bond_coefficients(k, b, i, f).derivatives();
                diag -= near;
                add(Some(b), -far);
            }
            add(None, diag);
        });
    }

    /// The residual (3.11) of species k at the iterate `f.concentration[k]` on the unknown
    /// rows: (C − C^n)/Δt − Σ … − R; on constraint rows s (C_t − Σ w C_s), s the scale of the
    /// last Jacobian fill.
    pub fn species_residual(
        &self,
        system: &FamilySystem,
        k: usize,
        f: &NnppFields,
        step: &ImplicitStep,
        out: &mut [f64],
    ) {
        let ImplicitStep { old, dt, sources } = *step;
        let c = &f.concentration[k];
        out.par_iter_mut()
            .zip(&system.unknowns.nodes)
            .enumerate()
            .for_each(|(r, (o, &i))| {
                let i = i as usize;
                *o = match system.constraint(r) {
                    Some(row) => {
                        system.constraint_scale * (c[i] - system.constraints.value(row, c))
                    }
                    None => {
                        let reaction = sources[i][0] + sources[i][1] * c[i];
                        (c[i] - old[i]) / dt - self.species_rate(k, i, f) - reaction
                    }
                };
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
        rhs.par_iter_mut()
            .zip(&unknowns.nodes)
            .enumerate()
            .for_each(|(row, (r, &i))| {
                if let Some(k) = system.constraint(row) {
                    *r = system.constraint_scale * system.known_part(k, &f.potential);
                    return;
                }
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
                        self.bonds.poisson[b]
                            * sigma
                            * f.potential[self.families.neighbors[b] as usize]
                    })
                    .sum();
                *r = FARADAY * self.concentration_unit * charge + extra[i] + known;
            });
    }
}
