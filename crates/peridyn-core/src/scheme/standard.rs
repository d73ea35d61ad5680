//! Standard meshfree particle scheme (thesis §3.1, (3.1) with the nonlinear bond force (2.33)):
//! a sum over all family nodes weighted by the partial-volume factor β (3.2).
//!
//! The force loop (`force`) is a per-node gather over CSR rows, parallel over blocks of
//! nodes; each task owns its rows of the force array and of the bond states. It and the
//! linearized operator's rows (`linearized`) are written once over the lanes of `simd`.

use rayon::prelude::*;

use crate::discretization::{Families, Quadrature, RowValues};
use crate::model::diffusion::DiffusionKernel;
use crate::model::pmb::{PmbLaw, influence};
use crate::scheme::{RowMask, ScalarOperator};
use crate::simd::Simd;

mod force;
mod linearized;
mod terms;

use force::{Law, PerNode, Rows, Uniform, pmb_forces};
use linearized::{LinearizedRow, RowLoop};
pub use terms::NodeTerms;

/// The standard scheme over one discretization: what every bond sum needs, borrowed from the
/// simulation that owns it.
#[derive(Debug, Clone, Copy)]
pub struct Standard<'a, const D: usize> {
    pub reference: &'a [[f64; D]],
    pub volumes: &'a [f64],
    /// Set when all node volumes are equal (saves a gather per bond).
    pub uniform_volume: Option<f64>,
    pub families: &'a Families,
    pub law: &'a PmbLaw,
    pub quadrature: &'a Quadrature,
}

impl<const D: usize> Standard<'_, D> {
    /// V'_j of the damage weights: 1 where all volumes are equal, V_j otherwise.
    fn damage_volume(&self, j: usize) -> f64 {
        if self.uniform_volume.is_some() {
            1.0
        } else {
            self.volumes[j]
        }
    }

    /// Per node, (Σ β V'_j over all bonds, Σ β V'_j over broken bonds): the damage
    /// denominator and the numerator `forces` keeps up to date.
    pub fn damage_weights(&self, intact: &[u8]) -> (Vec<f64>, Vec<f64>) {
        (0..self.families.node_count())
            .into_par_iter()
            .map(|i| self.row_damage_weights(i, intact))
            .unzip()
    }

    /// Node i's (Σ β V'_j over all bonds, Σ β V'_j over broken bonds).
    pub fn row_damage_weights(&self, i: usize, intact: &[u8]) -> (f64, f64) {
        let families = self.families;
        let (mut all, mut lost) = (0.0, 0.0);
        for b in families.range(i) {
            let j = families.neighbors[b] as usize;
            let w = self.quadrature.beta(families.length(i, b)) * self.damage_volume(j);
            all += w;
            if intact[b] == 0 {
                lost += w;
            }
        }
        (all, lost)
    }

    /// Force density on every node (N/m³) at `positions`, breaking bonds whose stretch
    /// reaches s0, and each node's strain-energy density over the bonds still intact.
    /// Returns the number of directed bonds broken in this call.
    pub fn forces(
        &self,
        positions: &[[f64; D]],
        intact: &mut [u8],
        terms: &mut [NodeTerms<D>],
    ) -> u64 {
        self.forces_masked::<u8>(positions, intact, terms, None, true)
    }

    /// As `forces`, skipping the rows whose mask entry is `skipped` (the hybrid scheme's Ω_w
    /// nodes, seed-thesis-ch2-3 §5): their terms are left as they are and their bonds are
    /// never evaluated. Without `energy` the strain-energy densities are left as they are (a
    /// step no frame reads skips that sum).
    pub fn forces_masked<M: RowMask>(
        &self,
        positions: &[[f64; D]],
        intact: &mut [u8],
        terms: &mut [NodeTerms<D>],
        skip: Option<&[M]>,
        energy: bool,
    ) -> u64 {
        let rows = Rows::all(positions, self.families, skip);
        self.forces_on(Simd::selected(), rows, intact, terms, energy)
    }

    /// The force loop on `rows` on the lanes of `simd`.
    fn forces_on<M: RowMask>(
        &self,
        simd: Simd,
        rows: Rows<D, M>,
        intact: &mut [u8],
        terms: &mut [NodeTerms<D>],
        energy: bool,
    ) -> u64 {
        let (law, quadrature) = (self.law, self.quadrature);
        // One volume for every node saves a gather per bond.
        match self.uniform_volume {
            Some(v) => {
                let law = Law::of(law, quadrature, Uniform(v));
                pmb_forces(simd, rows, law, intact, terms, energy)
            }
            None => {
                let law = Law::of(law, quadrature, PerNode(self.volumes));
                pmb_forces(simd, rows, law, intact, terms, energy)
            }
        }
    }

    /// Σ_j ‖C(ξ)‖ β V_j of the stable-step bound (3.8), with ‖C‖ = ω c/‖ξ‖, per node.
    pub fn stiffness_sums(&self) -> Vec<f64> {
        let (families, law) = (self.families, self.law);
        (0..families.node_count())
            .into_par_iter()
            .map(|i| {
                families
                    .range(i)
                    .map(|b| {
                        let l = families.length(i, b);
                        let j = families.neighbors[b] as usize;
                        influence(law.influence, l, law.horizon) * law.micromodulus / l
                            * self.quadrature.beta(l)
                            * self.volumes[j]
                    })
                    .sum()
            })
            .collect()
    }

    /// Damage φ_i = 1 − Σ μ β V_j / Σ β V_j, (2.36) discretized, in one pass over the bonds.
    pub fn damage(&self, intact: &[u8]) -> Vec<f64> {
        let (all, lost) = self.damage_weights(intact);
        all.iter()
            .zip(&lost)
            .map(|(&a, &l)| if a > 0.0 { l / a } else { 0.0 })
            .collect()
    }

    /// Strain-energy density of node i, W_i = ½ Σ_j w_ij β V_j over intact bonds,
    /// (2.26)–(2.27).
    pub fn energy_density(&self, i: usize, positions: &[[f64; D]], intact: &[u8]) -> f64 {
        let families = self.families;
        let mut w = 0.0;
        for b in families.range(i) {
            if intact[b] == 0 {
                continue;
            }
            let j = families.neighbors[b] as usize;
            let l = families.length(i, b);
            let r = (0..D)
                .map(|k| (positions[j][k] - positions[i][k]).powi(2))
                .sum::<f64>()
                .sqrt();
            w += self.law.bond_energy((r - l) / l, l) * self.quadrature.beta(l) * self.volumes[j];
        }
        0.5 * w
    }

    /// Total strain energy Σ_i W_i V_i.
    pub fn strain_energy(&self, positions: &[[f64; D]], intact: &[u8]) -> f64 {
        (0..self.families.node_count())
            .into_par_iter()
            .map(|i| self.energy_density(i, positions, intact) * self.volumes[i])
            .sum()
    }

    /// The coefficients c ω β V_j / (ρ ‖ξ‖³) of the linearized operator of (3.1) per unit mass
    /// (see [`Self::apply_linearized`]), computed once for the many applications of a
    /// stable-step estimate. With one volume for every node they depend on the bond's length
    /// alone and are stored once per distinct row, as the lengths are (on the Kalthoff–Winkler
    /// paper grid a few distinct rows instead of 500 MB, and each application streams 5 bytes
    /// per bond instead of 13); else one per bond.
    pub fn linearized(&self, density: f64) -> Linearized {
        match self.uniform_volume {
            Some(v) => Linearized::PerLength(
                self.families
                    .map_lengths(|l| self.linearized_coefficient(density, l, v)),
            ),
            None => Linearized::PerBond(self.linearized_coefficients(density)),
        }
    }

    /// One bond's c ω β V_j / (ρ ‖ξ‖³), ‖ξ‖ = `l`, V_j = `volume` (the coefficient of
    /// [`Self::linearized`]; a function of the length alone).
    pub fn linearized_coefficient(&self, density: f64, l: f64, volume: f64) -> f64 {
        let law = self.law;
        law.micromodulus / density
            * influence(law.influence, l, law.horizon)
            * self.quadrature.beta(l)
            * volume
            / (l * l * l)
    }

    /// Per-bond coefficients c ω β V_j / (ρ ‖ξ‖³) of the linearized operator of (3.1) per
    /// unit mass, one per bond whatever the volumes (the multi-grid's levels share one bond
    /// list and take each level's coefficients on its own bonds).
    pub fn linearized_coefficients(&self, density: f64) -> Vec<f64> {
        let families = self.families;
        (0..families.node_count())
            .into_par_iter()
            .with_min_len(64)
            .flat_map_iter(|i| {
                families
                    .row_lengths(i)
                    .iter()
                    .zip(&families.neighbors[families.range(i)])
            })
            .map(|(&l, &j)| self.linearized_coefficient(density, l, self.volumes[j as usize]))
            .collect()
    }

    /// The linearized operator of (3.1) per unit mass, applied to a displacement field:
    /// out_i = (1/ρ) Σ_j ω c (ξ⊗ξ/‖ξ‖³) (u_i − u_j) β V_j over intact bonds (the stiffness
    /// the stable-step bound needs; positive semi-definite in the mass inner product), with
    /// the `coefficients` of [`Self::linearized`].
    pub fn apply_linearized(
        &self,
        coefficients: &Linearized,
        intact: &[u8],
        u: &[[f64; D]],
        out: &mut [[f64; D]],
    ) {
        self.apply_linearized_masked(coefficients, intact, u, out, |_| false);
    }

    /// [`Self::apply_linearized`] on the rows not `skip`ped (others left untouched): the
    /// standard part of a hybrid operator.
    pub fn apply_linearized_masked(
        &self,
        coefficients: &Linearized,
        intact: &[u8],
        u: &[[f64; D]],
        out: &mut [[f64; D]],
        skip: impl Fn(usize) -> bool + Sync,
    ) {
        let (families, reference) = (self.families, self.reference);
        // Four lanes whatever the CPU: these sums decide the stable step, and stay as they
        // were measured.
        let simd = Simd::selected().four_lanes();
        out.par_iter_mut()
            .enumerate()
            .with_min_len(256)
            .filter(|(i, _)| !skip(*i))
            .for_each(|(i, o)| {
                let range = families.range(i);
                let row = LinearizedRow {
                    i,
                    neighbors: &families.neighbors[range.clone()],
                    states: &intact[range.clone()],
                    coefficients: match coefficients {
                        Linearized::PerBond(c) => &c[range],
                        Linearized::PerLength(c) => families.row_values(c, i),
                    },
                };
                *o = simd.run(RowLoop {
                    row: &row,
                    reference,
                    u,
                });
            });
    }
}

/// The linearized operator's coefficients ([`Standard::linearized`]).
pub enum Linearized {
    /// One per bond.
    PerBond(Vec<f64>),
    /// A function of the bond's length, one copy per distinct row.
    PerLength(RowValues),
}

/// The standard diffusion operator (3.4), Ċ_i = Σ_j κ ω (C_j − C_i)/‖ξ‖^q β V_j, as sparse rows
/// (the node itself first, with minus the sum of the others) for the nodes of `rows`.
pub fn diffusion_operator<const D: usize>(
    rows: &[u32],
    volumes: &[f64],
    families: &Families,
    quadrature: &Quadrature,
    kernel: &DiffusionKernel,
) -> ScalarOperator {
    let blocks = rows
        .par_iter()
        .map(|&i| {
            let range = families.range(i as usize);
            let mut columns = Vec::with_capacity(range.len() + 1);
            let mut weights = Vec::with_capacity(range.len() + 1);
            columns.push(i);
            weights.push(0.0);
            for b in range {
                let j = families.neighbors[b];
                let l = families.length(i as usize, b);
                let w = kernel.weight(l) * quadrature.beta(l) * volumes[j as usize];
                columns.push(j);
                weights.push(w);
                weights[0] -= w;
            }
            (columns, weights)
        })
        .collect();
    ScalarOperator::from_rows(rows, blocks)
}

/// Bond state μ: 1 intact, 0 broken (2.34). One byte per directed bond.
pub fn intact_bonds(count: usize) -> Vec<u8> {
    vec![1; count]
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::discretization::grid::Lattice;
    use crate::integrate::lattice_symbol::{LatticeSymbol, on_lattice};
    use crate::model::pmb::Influence;
    use crate::scene::Solid;

    /// A unit-spaced cube lattice of side `side`, perturbed by up to 0.2 spacings (seeded),
    /// with families of horizon 3.
    fn perturbed_cube(side: f64, seed: u64) -> (Lattice<3>, Families) {
        let cube = Solid::Box {
            min: vec![0.0; 3],
            max: vec![side; 3],
        };
        let lattice = Lattice::<3>::build(&cube, 1.0, [-0.2, 0.2], seed);
        let families = Families::build(&lattice.positions, 3.0);
        (lattice, families)
    }

    /// On a lattice with a cut, the symbol's bound (from above) and Lanczos on the operator
    /// itself (from below) bracket λ_max, 3 % apart at most (Lanczos's former margin was 2 %);
    /// a perturbed cloud is not a lattice.
    #[test]
    fn the_lattice_symbol_bounds_the_operator_from_above() {
        let (spacing, side) = (0.7, 30usize);
        let positions: Vec<[f64; 2]> = (0..side * side)
            .map(|k| [(k % side) as f64 * spacing, (k / side) as f64 * spacing])
            .collect();
        let horizon = 3.0 * spacing;
        let families = Families::build(&positions, horizon);
        let volume = spacing * spacing;
        let volumes = vec![volume; positions.len()];
        let law = PmbLaw {
            micromodulus: 2.5,
            critical_stretch: 0.5,
            influence: Influence::Linear,
            horizon,
        };
        let quadrature = Quadrature {
            spacing,
            horizon,
            volume_correction: true,
        };
        let scheme = Standard {
            reference: &positions,
            volumes: &volumes,
            uniform_volume: Some(volume),
            families: &families,
            law: &law,
            quadrature: &quadrature,
        };
        // A cut between rows 14 and 15 over the left half, both directions of each bond.
        let line = 14.5 * spacing;
        let mut intact = intact_bonds(families.bond_count());
        for i in 0..positions.len() {
            for b in families.range(i) {
                let j = families.neighbors[b] as usize;
                let left = positions[i][0].max(positions[j][0]) < 15.0 * spacing;
                if left && (positions[i][1] < line) != (positions[j][1] < line) {
                    intact[b] = 0;
                }
            }
        }
        let density = 7.8;
        assert!(on_lattice(&positions, spacing));
        let bound = LatticeSymbol::<2>::of_bonds(spacing, families.longest(), |l| {
            scheme.linearized_coefficient(density, l, volume)
        })
        .expect("a lattice")
        .max_eigenvalue_bound(1e-3, 1_000_000)
        .expect("settles");
        let coefficients = scheme.linearized(density);
        let masses = vec![volume * density; positions.len()];
        let lanczos = crate::integrate::stability::max_eigenvalue::<2>(
            positions.len(),
            &masses,
            200,
            |u, out| scheme.apply_linearized(&coefficients, &intact, u, out),
        );
        assert!(
            lanczos <= bound && bound <= 1.03 * lanczos,
            "{lanczos} against {bound}"
        );
        let mut moved = positions.clone();
        moved[17][1] += 0.01 * spacing;
        assert!(!on_lattice(&moved, spacing));
    }

    /// With one volume for every node the coefficients are kept per distinct row
    /// (`Linearized::PerLength`), and the operator gives the per-bond form's bits: a 2D lattice
    /// with β partial volumes, a linear influence and broken bonds; the interior rows share one
    /// copy in the store.
    #[test]
    fn row_shared_linearized_coefficients_give_the_per_bond_operator() {
        let spacing = 0.7;
        let positions: Vec<[f64; 2]> = (0..400)
            .map(|k| [(k / 20) as f64 * spacing, (k % 20) as f64 * spacing])
            .collect();
        let families = Families::build(&positions, 3.0 * spacing);
        let volumes = vec![spacing * spacing; positions.len()];
        let law = PmbLaw {
            micromodulus: 2.5,
            critical_stretch: 0.5,
            influence: Influence::Linear,
            horizon: 3.0 * spacing,
        };
        let quadrature = Quadrature {
            spacing,
            horizon: 3.0 * spacing,
            volume_correction: true,
        };
        let scheme = Standard {
            reference: &positions,
            volumes: &volumes,
            uniform_volume: Some(spacing * spacing),
            families: &families,
            law: &law,
            quadrature: &quadrature,
        };
        let intact: Vec<u8> = (0..families.bond_count())
            .map(|b| u8::from(b % 5 != 0))
            .collect();
        let u: Vec<[f64; 2]> = positions
            .iter()
            .map(|x| [(0.9 * x[1]).sin(), (0.4 * x[0] - 0.2 * x[1]).cos()])
            .collect();
        let shared = scheme.linearized(7.8);
        let Linearized::PerLength(rows) = &shared else {
            panic!("uniform volumes keep the coefficients per row")
        };
        // The 14 × 14 nodes three or more spacings from every edge have one row between them.
        let interior = families.range(10 * 20 + 10).len();
        assert!(rows.memory_bytes() <= 8 * (families.bond_count() - 195 * interior));
        let per_bond = Linearized::PerBond(scheme.linearized_coefficients(7.8));
        let (mut a, mut b) = (vec![[0.0; 2]; 400], vec![[0.0; 2]; 400]);
        scheme.apply_linearized(&shared, &intact, &u, &mut a);
        scheme.apply_linearized(&per_bond, &intact, &u, &mut b);
        assert!(a.iter().any(|o| o[0] != 0.0));
        assert_eq!(a, b);
    }

    /// The linearized operator is the force loop's derivative: −ρ L u = f(X + u) for a small
    /// displacement u, with broken bonds skipped by both; and its rows equal a plain
    /// bond-by-bond sum to rounding. The tolerance comes from the neglected terms: they are
    /// O(|u_j − u_i|/‖ξ‖) relative to a bond's linear term, at most about 1e-6 here (|u| ≤
    /// 6.4·10⁻⁷ on a unit lattice), so 1e-5 of the largest force leaves a factor 10.
    #[test]
    fn linearized_operator_is_the_force_loops_derivative() {
        let (lattice, families) = perturbed_cube(8.0, 11);
        let law = PmbLaw {
            micromodulus: 2.5,
            critical_stretch: 0.5,
            influence: Influence::Linear,
            horizon: 3.0,
        };
        let quadrature = Quadrature {
            spacing: 1.0,
            horizon: 3.0,
            volume_correction: true,
        };
        let scheme = Standard {
            reference: &lattice.positions,
            volumes: &lattice.volumes,
            uniform_volume: None,
            families: &families,
            law: &law,
            quadrature: &quadrature,
        };
        let density = 3.0;
        // Every seventh bond broken (in both directions' rows alike: only the row's own
        // state matters to either loop).
        let intact: Vec<u8> = (0..families.bond_count())
            .map(|b| u8::from(b % 7 != 0))
            .collect();
        let amplitude = 1e-7;
        let u: Vec<[f64; 3]> = lattice
            .positions
            .iter()
            .map(|x| {
                [
                    amplitude * (0.7 * x[1]).sin(),
                    amplitude * (0.3 * x[0] + 0.5 * x[2]).cos(),
                    amplitude * 0.1 * x[0] * x[1],
                ]
            })
            .collect();
        let coefficients = scheme.linearized_coefficients(density);
        let mut linear = vec![[0.0; 3]; lattice.len()];
        let per_bond = Linearized::PerBond(coefficients.clone());
        scheme.apply_linearized(&per_bond, &intact, &u, &mut linear);
        let positions: Vec<[f64; 3]> = lattice
            .positions
            .iter()
            .zip(&u)
            .map(|(x, u)| std::array::from_fn(|k| x[k] + u[k]))
            .collect();
        let mut state = intact.clone();
        let mut terms = vec![NodeTerms::default(); lattice.len()];
        assert_eq!(scheme.forces(&positions, &mut state, &mut terms), 0);
        let largest = terms
            .iter()
            .flat_map(|t| t.force.map(f64::abs))
            .fold(0.0, f64::max);
        assert!(largest > 0.0);
        for (i, t) in terms.iter().enumerate() {
            // The plain sum, one bond after another.
            let mut plain = [0.0; 3];
            for b in families.range(i) {
                let j = families.neighbors[b] as usize;
                let xi: [f64; 3] =
                    std::array::from_fn(|k| lattice.positions[j][k] - lattice.positions[i][k]);
                let proj: f64 = (0..3).map(|k| xi[k] * (u[i][k] - u[j][k])).sum();
                for k in 0..3 {
                    plain[k] += coefficients[b] * f64::from(intact[b]) * proj * xi[k];
                }
            }
            for k in 0..3 {
                assert!((-density * linear[i][k] - t.force[k]).abs() <= 1e-5 * largest);
                assert!((linear[i][k] - plain[k]).abs() <= 1e-12 * largest / density);
            }
        }
    }
}
