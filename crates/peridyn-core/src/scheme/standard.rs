//! Standard meshfree particle scheme (thesis §3.1, (3.1) with the nonlinear bond force (2.33)):
//! a sum over all family nodes weighted by the partial-volume factor β (3.2).
//!
//! The force loop is a per-node gather over CSR rows, parallel over blocks of nodes; each
//! task owns its rows of the force array and of the bond states.

use rayon::prelude::*;

use crate::discretization::{Families, NodeValue, Quadrature, RowValues};
use crate::model::diffusion::DiffusionKernel;
use crate::model::pmb::Influence;
use crate::model::pmb::{PmbLaw, influence};
use crate::scheme::{RowMask, ScalarOperator};

#[cfg(target_arch = "x86_64")]
mod avx2;
#[cfg(target_arch = "x86_64")]
mod avx512;

/// What the force loop produces per node.
#[derive(Debug, Clone, Copy, PartialEq)]
#[repr(C)]
pub struct NodeTerms<const D: usize> {
    /// Force density (N/m³).
    pub force: [f64; D],
    /// Strain-energy density W_i over the intact bonds (J/m³).
    pub energy_density: f64,
    /// Σ β V'_j over the node's broken bonds, V' = 1 where all volumes are equal (the damage
    /// numerator, kept up to date as bonds break).
    pub broken_weight: f64,
}

impl<const D: usize> NodeValue for NodeTerms<D> {
    const EMPTY: Self = NodeTerms {
        force: [0.0; D],
        energy_density: 0.0,
        broken_weight: 0.0,
    };
}

impl<const D: usize> Default for NodeTerms<D> {
    fn default() -> Self {
        NodeTerms {
            force: [0.0; D],
            energy_density: 0.0,
            broken_weight: 0.0,
        }
    }
}

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
        let families = self.families;
        (0..families.node_count())
            .into_par_iter()
            .map(|i| {
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
            })
            .unzip()
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
    /// never evaluated. Without `energy` the hand-written kernel leaves the strain-energy
    /// densities as they are (a step no frame reads skips that sum); the other builds always
    /// compute them.
    pub fn forces_masked<M: RowMask>(
        &self,
        positions: &[[f64; D]],
        intact: &mut [u8],
        terms: &mut [NodeTerms<D>],
        skip: Option<&[M]>,
        energy: bool,
    ) -> u64 {
        let (families, law, quadrature) = (self.families, self.law, self.quadrature);
        assert_eq!(positions.len(), families.node_count());
        assert_eq!(intact.len(), families.bond_count());
        let rows = Rows {
            positions,
            families,
            quadrature,
            first: 0,
            s0: law.critical_stretch,
            skip,
        };
        #[cfg(target_arch = "x86_64")]
        if let Some(v) = self.uniform_volume
            && (D == 2 || D == 3)
            && let Some(kernel) = hand_kernel()
        {
            let weight = BondWeight::of(law, quadrature);
            let flags = (
                law.influence == Influence::Linear,
                quadrature.volume_correction,
                energy,
            );
            // SAFETY: `hand_kernel` detected the kernel's instruction set; D is 2 or 3.
            return unsafe {
                match kernel {
                    HandKernelSet::Avx512 => {
                        hand_forces::<avx512::Avx512, D, M>(&rows, intact, terms, weight, v, flags)
                    }
                    HandKernelSet::Avx2 => {
                        hand_forces::<avx2::Avx2, D, M>(&rows, intact, terms, weight, v, flags)
                    }
                }
            };
        }
        self.with_bond_law(GatherLoop {
            rows: &rows,
            intact,
            terms,
        })
    }

    /// Runs `bond_loop` with this scheme's bond weight ω c β (times V where all volumes are
    /// equal) and per-node volume V'_j: one monomorphized loop per (influence, β, volume)
    /// combination, so no branch on them inside.
    pub(crate) fn with_bond_law<L: BondLoop>(&self, bond_loop: L) -> u64 {
        let volumes = self.volumes;
        let weight = BondWeight::of(self.law, self.quadrature);
        macro_rules! with_volume {
            ($linear:literal, $beta:literal) => {
                match self.uniform_volume {
                    Some(v) => bond_loop.run(move |l| weight.at::<$linear, $beta>(l) * v, |_| 1.0),
                    None => bond_loop.run(move |l| weight.at::<$linear, $beta>(l), |j| volumes[j]),
                }
            };
        }
        match (self.law.influence, self.quadrature.volume_correction) {
            (Influence::Constant, true) => with_volume!(false, true),
            (Influence::Constant, false) => with_volume!(false, false),
            (Influence::Linear, true) => with_volume!(true, true),
            (Influence::Linear, false) => with_volume!(true, false),
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
        #[cfg(target_arch = "x86_64")]
        let avx2 = crate::simd::avx2();
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
                #[cfg(target_arch = "x86_64")]
                if avx2 && (D == 2 || D == 3) {
                    // SAFETY: AVX2 was detected above; D is 2 or 3.
                    *o = unsafe { avx2::linearized_row(&row, reference, u) };
                    return;
                }
                *o = linearized_row::<D, LANES>(&row, reference, u);
            });
    }
}

/// One row of [`Standard::apply_linearized`]: node i's bonds, their states and coefficients.
struct LinearizedRow<'a> {
    i: usize,
    neighbors: &'a [u32],
    states: &'a [u8],
    coefficients: &'a [f64],
}

/// Σ_j c_ij ((ξ · (u_i − u_j)) ξ over the row's intact bonds, `N` bonds together (a broken
/// bond's coefficient counts as 0), the remainder one by one. The lane loops compile to
/// SIMD arithmetic; the gathers stay scalar (`avx2::linearized_row` gives these bits at
/// 4 lanes with vector gathers).
#[inline(always)]
fn linearized_row<const D: usize, const N: usize>(
    row: &LinearizedRow,
    reference: &[[f64; D]],
    u: &[[f64; D]],
) -> [f64; D] {
    let (x_i, u_i) = (reference[row.i], u[row.i]);
    let blocked = row.neighbors.len() / N * N;
    let mut acc_lanes = [[0.0; N]; D];
    for ((nb, st), co) in row.neighbors[..blocked]
        .chunks_exact(N)
        .zip(row.states[..blocked].chunks_exact(N))
        .zip(row.coefficients[..blocked].chunks_exact(N))
    {
        let mut xi = [[0.0; N]; D];
        let mut du = [[0.0; N]; D];
        for l in 0..N {
            let j = nb[l] as usize;
            for k in 0..D {
                xi[k][l] = reference[j][k] - x_i[k];
                du[k][l] = u_i[k] - u[j][k];
            }
        }
        let mut scale = [0.0; N];
        for l in 0..N {
            let mut proj = xi[0][l] * du[0][l];
            for k in 1..D {
                proj += xi[k][l] * du[k][l];
            }
            scale[l] = if st[l] != 0 { co[l] * proj } else { 0.0 };
        }
        for k in 0..D {
            for l in 0..N {
                acc_lanes[k][l] += scale[l] * xi[k][l];
            }
        }
    }
    let mut acc = [0.0; D];
    for k in 0..D {
        acc[k] = acc_lanes[k].iter().sum();
    }
    linearized_tail(row, blocked, reference, u, &mut acc);
    acc
}

/// The row's bonds from its `first`-th on, one by one, added to `acc` (`linearized_row`'s
/// remainder after its blocks of lanes).
#[inline(always)]
fn linearized_tail<const D: usize>(
    row: &LinearizedRow,
    first: usize,
    reference: &[[f64; D]],
    u: &[[f64; D]],
    acc: &mut [f64; D],
) {
    let (x_i, u_i) = (reference[row.i], u[row.i]);
    let tail = row.neighbors[first..]
        .iter()
        .zip(&row.states[first..])
        .zip(&row.coefficients[first..]);
    for ((&j, &state), &coefficient) in tail {
        if state == 0 {
            continue;
        }
        let j = j as usize;
        let xi: [f64; D] = std::array::from_fn(|k| reference[j][k] - x_i[k]);
        let mut proj = xi[0] * (u_i[0] - u[j][0]);
        for k in 1..D {
            proj += xi[k] * (u_i[k] - u[j][k]);
        }
        let scale = coefficient * proj;
        for k in 0..D {
            acc[k] += scale * xi[k];
        }
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

/// The bond weight ω(‖ξ‖) c β(‖ξ‖) of (2.33) in the sum (3.1), without the volume: the
/// influence ω (constant, or linear 1 − ‖ξ‖/δ) and the partial-volume factor β (3.2) chosen
/// by the const parameters, so each combination is its own branch-free function.
#[derive(Debug, Clone, Copy)]
pub(crate) struct BondWeight {
    c: f64,
    horizon: f64,
    /// δ + Δx/2, where β reaches 0.
    reach: f64,
    inv_dx: f64,
}

impl BondWeight {
    fn of(law: &PmbLaw, quadrature: &Quadrature) -> BondWeight {
        BondWeight {
            c: law.micromodulus,
            horizon: law.horizon,
            reach: quadrature.horizon + 0.5 * quadrature.spacing,
            inv_dx: 1.0 / quadrature.spacing,
        }
    }

    #[inline(always)]
    fn at<const LINEAR: bool, const BETA: bool>(&self, l: f64) -> f64 {
        let w = if LINEAR {
            self.c * (1.0 - l / self.horizon).max(0.0)
        } else {
            self.c
        };
        if BETA {
            w * ((self.reach - l) * self.inv_dx).clamp(0.0, 1.0)
        } else {
            w
        }
    }
}

/// Bond state μ: 1 intact, 0 broken (2.34). One byte per directed bond.
pub fn intact_bonds(count: usize) -> Vec<u8> {
    vec![1; count]
}

/// A PMB force loop, run with the bond weight ω c β (times V where all volumes are equal)
/// and the volume V'_j of [`Standard::with_bond_law`]. Returns the directed bonds broken.
pub(crate) trait BondLoop {
    fn run(self, weight: impl Fn(f64) -> f64 + Sync, volume: impl Fn(usize) -> f64 + Sync) -> u64;
}

/// The per-node gather: every directed bond evaluated from its own row.
struct GatherLoop<'a, 'b, const D: usize, M> {
    rows: &'a Rows<'a, D, M>,
    intact: &'b mut [u8],
    terms: &'b mut [NodeTerms<D>],
}

impl<const D: usize, M: RowMask> BondLoop for GatherLoop<'_, '_, D, M> {
    fn run(self, weight: impl Fn(f64) -> f64 + Sync, volume: impl Fn(usize) -> f64 + Sync) -> u64 {
        pmb_rows(self.rows, self.intact, self.terms, weight, volume)
    }
}

/// Nodes per task of the force loop.
const ROWS_PER_TASK: usize = 512;

/// The gather loop of `Standard::forces`: f_i = Σ_j μ ω c s β V_j e_ij, (2.33) in the sum
/// (3.1). Node ranges are split recursively (no allocation) so each task owns its rows of the
/// node terms and of the bond states.
#[inline(always)]
fn pmb_rows<const D: usize, M: RowMask>(
    rows: &Rows<D, M>,
    intact: &mut [u8],
    terms: &mut [NodeTerms<D>],
    weight: impl Fn(f64) -> f64 + Sync,
    volume: impl Fn(usize) -> f64 + Sync,
) -> u64 {
    #[cfg(target_arch = "x86_64")]
    let (avx512, avx2) = (
        avx512_detected(),
        std::arch::is_x86_feature_detected!("avx2"),
    );
    let kernel = |first: usize, terms: &mut [NodeTerms<D>], state: &mut [u8]| -> u64 {
        let block = Rows { first, ..*rows };
        #[cfg(target_arch = "x86_64")]
        if avx512 {
            // SAFETY: the CPU supports AVX-512 F/VL/DQ (detected above).
            return unsafe { rows_avx512(&block, terms, state, &weight, &volume) };
        }
        #[cfg(target_arch = "x86_64")]
        if avx2 {
            // SAFETY: the CPU supports AVX2 (detected above).
            return unsafe { rows_avx2(&block, terms, state, &weight, &volume) };
        }
        rows_portable::<D, LANES, M>(&block, terms, state, &weight, &volume)
    };
    split_rows(rows.families, 0, terms, intact, &kernel)
}

/// A block of consecutive rows of the force loop.
#[derive(Clone, Copy)]
struct Rows<'a, const D: usize, M> {
    positions: &'a [[f64; D]],
    families: &'a Families,
    quadrature: &'a Quadrature,
    first: usize,
    s0: f64,
    skip: Option<&'a [M]>,
}

impl<const D: usize, M: RowMask> Rows<'_, D, M> {
    /// The block's rows the mask does not skip: (node, its terms, its bond states), `terms`
    /// and `state` being the block's.
    fn each_row<'t>(
        &self,
        terms: &'t mut [NodeTerms<D>],
        state: &'t mut [u8],
    ) -> impl Iterator<Item = (usize, &'t mut NodeTerms<D>, &'t mut [u8])> {
        let families = self.families;
        let (first, skip) = (self.first, self.skip);
        // `state` starts at the block's first bond; `consumed` is the bond `rest` starts at.
        let mut rest = state;
        let mut consumed = families.offsets[first];
        terms.iter_mut().enumerate().filter_map(move |(row, t_i)| {
            let i = first + row;
            // A skipped row (most rows of a hybrid's Ω_w) costs one mask read.
            if skip.is_some_and(|mask| mask[i].skipped()) {
                return None;
            }
            let (start, end) = (families.offsets[i], families.offsets[i + 1]);
            let (_, tail) = std::mem::take(&mut rest).split_at_mut(start - consumed);
            let (row_state, tail) = tail.split_at_mut(end - start);
            (rest, consumed) = (tail, end);
            Some((i, t_i, row_state))
        })
    }
}

/// The force loop's rows with `N` bonds evaluated together (`LANES` on the portable and AVX2
/// builds, `WIDE_LANES` on AVX-512).
#[inline(always)]
fn rows_portable<const D: usize, const N: usize, M: RowMask>(
    rows: &Rows<D, M>,
    terms: &mut [NodeTerms<D>],
    state: &mut [u8],
    weight: &impl Fn(f64) -> f64,
    volume: &impl Fn(usize) -> f64,
) -> u64 {
    let mut broken = 0u64;
    for (i, t_i, row_state) in rows.each_row(terms, state) {
        let (acc, w, newly_broken, lost) = pmb_row::<D, N, M>(rows, i, row_state, weight, volume);
        broken += newly_broken;
        t_i.force = acc;
        t_i.energy_density = 0.25 * w;
        t_i.broken_weight += lost;
    }
    broken
}

/// A build of `rows_portable` with `$lanes` bonds together, compiled for `$features`.
macro_rules! rows_build {
    ($(#[$doc:meta])* $name:ident, $features:literal, $lanes:expr) => {
        $(#[$doc])*
        #[cfg(target_arch = "x86_64")]
        #[target_feature(enable = $features)]
        fn $name<const D: usize, M: RowMask>(
            rows: &Rows<D, M>,
            terms: &mut [NodeTerms<D>],
            state: &mut [u8],
            weight: &impl Fn(f64) -> f64,
            volume: &impl Fn(usize) -> f64,
        ) -> u64 {
            rows_portable::<D, { $lanes }, M>(rows, terms, state, weight, volume)
        }
    };
}

rows_build!(
    /// `rows_portable` compiled for AVX2, where the lane loops become 4-wide. No FMA is
    /// enabled, so the results are bit-identical to the portable code.
    rows_avx2,
    "avx,avx2",
    LANES
);

rows_build!(
    /// `rows_portable` with `WIDE_LANES` bonds together, compiled for AVX-512, where the lane
    /// loops become 8-wide (one square root and one division instruction per 8 bonds). No
    /// FMA is contracted, so the results are bit-identical to the portable code at 8 lanes;
    /// against the 4-lane builds they differ in the last bits (the lanes' partial sums are
    /// added in another order), so a machine with AVX-512 and one without agree to rounding,
    /// not to the bit. Measured on a Zen 4: the force loop alone 1.16× the AVX2 build (3D,
    /// 122 bonds per node); a whole `pmb-block-3d` run, setup included, 1.18×
    /// (docs/results.md).
    rows_avx512,
    "avx512f,avx512vl,avx512dq",
    WIDE_LANES
);

/// The hand-written force kernels (2D and 3D scenes with one volume): the widest this CPU
/// runs.
#[cfg(target_arch = "x86_64")]
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum HandKernelSet {
    /// 8 lanes (`avx512`); bit-identical to the portable 8-lane loop.
    Avx512,
    /// 4 lanes (`avx2`); bit-identical to the portable 4-lane loop.
    Avx2,
}

#[cfg(target_arch = "x86_64")]
fn hand_kernel() -> Option<HandKernelSet> {
    if crate::simd::avx512_kernels_available() {
        Some(HandKernelSet::Avx512)
    } else if crate::simd::avx2() {
        Some(HandKernelSet::Avx2)
    } else {
        None
    }
}

/// A hand-written force kernel of one instruction set: one task's rows of the gather loop,
/// bond weight ω c β V by the const parameters, V = `volume` for every node.
#[cfg(target_arch = "x86_64")]
trait HandKernel {
    /// # Safety
    /// The kernel's instruction set is available and `D` is 2 or 3.
    unsafe fn rows<
        const D: usize,
        const LINEAR: bool,
        const BETA: bool,
        const ENERGY: bool,
        M: RowMask,
    >(
        rows: &Rows<D, M>,
        terms: &mut [NodeTerms<D>],
        state: &mut [u8],
        weight: &BondWeight,
        volume: f64,
    ) -> u64;
}

/// The force loop over all rows with kernel `K` (`Standard::forces_masked` on a 2D or 3D
/// scene with uniform volumes). Returns the directed bonds broken.
///
/// # Safety
/// `K`'s instruction set is available and `D` is 2 or 3.
#[cfg(target_arch = "x86_64")]
unsafe fn hand_forces<K: HandKernel, const D: usize, M: RowMask>(
    rows: &Rows<D, M>,
    intact: &mut [u8],
    terms: &mut [NodeTerms<D>],
    weight: BondWeight,
    volume: f64,
    (linear, beta, energy): (bool, bool, bool),
) -> u64 {
    macro_rules! run {
        ($linear:literal, $beta:literal, $energy:literal) => {
            split_rows(
                rows.families,
                0,
                terms,
                intact,
                &|first: usize, terms: &mut [NodeTerms<D>], state: &mut [u8]| -> u64 {
                    let block = Rows { first, ..*rows };
                    // SAFETY: the caller guarantees the instruction set and D.
                    unsafe {
                        K::rows::<D, $linear, $beta, $energy, M>(
                            &block, terms, state, &weight, volume,
                        )
                    }
                },
            )
        };
    }
    match (linear, beta, energy) {
        (false, true, true) => run!(false, true, true),
        (false, false, true) => run!(false, false, true),
        (true, true, true) => run!(true, true, true),
        (true, false, true) => run!(true, false, true),
        (false, true, false) => run!(false, true, false),
        (false, false, false) => run!(false, false, false),
        (true, true, false) => run!(true, true, false),
        (true, false, false) => run!(true, false, false),
    }
}

/// Whether the AVX-512 force loop can run here.
#[cfg(target_arch = "x86_64")]
fn avx512_detected() -> bool {
    crate::simd::avx512_f_vl_dq()
}

/// Bonds evaluated together: the lane loops below are written so the compiler turns them
/// into SIMD arithmetic (two or four square roots and divisions per instruction).
pub(crate) const LANES: usize = 4;

/// Bonds evaluated together by the AVX-512 build of the gather loop.
const WIDE_LANES: usize = 8;

/// For `N` bonds of node i (at `y_i`) to `neighbors`: the offsets y_j − y_i by component
/// and lane, V'_j, and ‖y_j − y_i‖² (the lane loops of both force loops).
#[inline(always)]
pub(crate) fn lane_offsets<const D: usize, const N: usize>(
    y_i: [f64; D],
    neighbors: &[u32],
    positions: &[[f64; D]],
    volume: &impl Fn(usize) -> f64,
) -> ([[f64; N]; D], [f64; N], [f64; N]) {
    let mut d = [[0.0; N]; D];
    let mut vol = [0.0; N];
    for l in 0..N {
        let j = neighbors[l] as usize;
        let p = positions[j];
        for k in 0..D {
            d[k][l] = p[k] - y_i[k];
        }
        vol[l] = volume(j);
    }
    let mut r2 = [0.0; N];
    for d_k in &d {
        for l in 0..N {
            r2[l] += d_k[l] * d_k[l];
        }
    }
    (d, vol, r2)
}

/// Node i's row (its bond states `state`): (force density, 4·W_i, bonds broken now). Blocks
/// of `N` bonds are evaluated branch-free (a broken bond weighs 0), the remainder one by one.
#[inline(always)]
fn pmb_row<const D: usize, const N: usize, M: RowMask>(
    rows: &Rows<D, M>,
    i: usize,
    state: &mut [u8],
    weight: &impl Fn(f64) -> f64,
    volume: &impl Fn(usize) -> f64,
) -> ([f64; D], f64, u64, f64) {
    let (y_i, positions, s0, quadrature) =
        (rows.positions[i], rows.positions, rows.s0, rows.quadrature);
    let (neighbors, lengths) = (
        &rows.families.neighbors[rows.families.range(i)],
        rows.families.row_lengths(i),
    );
    let mut lost = 0.0;
    let mut acc_lanes = [[0.0; N]; D];
    let mut w_lanes = [0.0; N];
    let mut broken = 0u64;
    let blocked = neighbors.len() / N * N;
    for ((nb, ln), st) in neighbors[..blocked]
        .chunks_exact(N)
        .zip(lengths[..blocked].chunks_exact(N))
        .zip(state[..blocked].chunks_exact_mut(N))
    {
        let (d, vol, r2) = lane_offsets::<D, N>(y_i, nb, positions, volume);
        let mut scale = [0.0; N];
        let mut breaks = false;
        let mut keep = [false; N];
        for l in 0..N {
            let r = r2[l].sqrt();
            let extension = r - ln[l];
            let alive = st[l] != 0;
            keep[l] = alive && extension < s0 * ln[l];
            breaks |= alive != keep[l];
            // ω c β V_j · s · (y_j − y_i)/‖y_j − y_i‖ with s = extension / length.
            let s = weight(ln[l]) * vol[l] * extension / (ln[l] * r);
            scale[l] = if keep[l] { s } else { 0.0 };
            // Strain energy w β V_j = ½ ω c s² ‖ξ‖ β V_j (2.27), with the force.
            w_lanes[l] += scale[l] * extension * r;
        }
        if breaks {
            broken += break_lanes(st, &keep, ln, &vol, quadrature, &mut lost);
        }
        for k in 0..D {
            for l in 0..N {
                acc_lanes[k][l] += scale[l] * d[k][l];
            }
        }
    }
    let mut acc = [0.0; D];
    for k in 0..D {
        acc[k] = acc_lanes[k].iter().sum();
    }
    let mut w: f64 = w_lanes.iter().sum();
    pmb_tail(
        rows,
        i,
        blocked,
        state,
        weight,
        volume,
        (&mut acc, &mut w, &mut broken, &mut lost),
    );
    (acc, w, broken, lost)
}

/// Marks the lanes whose bond broke in this pass (intact before, not kept), adds their
/// β V'_j to `lost` one by one (the damage numerator) and returns how many broke.
#[inline(never)]
fn break_lanes<const N: usize>(
    state: &mut [u8],
    keep: &[bool; N],
    lengths: &[f64],
    volumes: &[f64; N],
    quadrature: &Quadrature,
    lost: &mut f64,
) -> u64 {
    let mut broken = 0;
    for l in 0..N {
        if state[l] != 0 && !keep[l] {
            state[l] = 0;
            broken += 1;
            *lost += quadrature.beta(lengths[l]) * volumes[l];
        }
    }
    broken
}

/// Node i's bonds from its `first`-th on (those left after the blocks of lanes), one by one,
/// added to `sums` (force density, 4·W_i, bonds broken, Σ β V'_j lost); `state` is the row's.
#[inline(always)]
fn pmb_tail<const D: usize, M: RowMask>(
    rows: &Rows<D, M>,
    i: usize,
    first: usize,
    state: &mut [u8],
    weight: &impl Fn(f64) -> f64,
    volume: &impl Fn(usize) -> f64,
    sums: (&mut [f64; D], &mut f64, &mut u64, &mut f64),
) {
    let (acc, w, broken, lost) = sums;
    let (y_i, positions, s0, quadrature) =
        (rows.positions[i], rows.positions, rows.s0, rows.quadrature);
    let neighbors = &rows.families.neighbors[rows.families.range(i)][first..];
    let lengths = &rows.families.row_lengths(i)[first..];
    for ((&j, &length), mu) in neighbors.iter().zip(lengths).zip(&mut state[first..]) {
        if *mu == 0 {
            continue;
        }
        let j = j as usize;
        let y_j = positions[j];
        let mut d = [0.0; D];
        let mut r2 = 0.0;
        for k in 0..D {
            d[k] = y_j[k] - y_i[k];
            r2 += d[k] * d[k];
        }
        let r = r2.sqrt();
        let extension = r - length;
        if extension >= s0 * length {
            *mu = 0;
            *broken += 1;
            *lost += quadrature.beta(length) * volume(j);
            continue;
        }
        let scale = weight(length) * volume(j) * extension / (length * r);
        *w += scale * extension * r;
        for k in 0..D {
            acc[k] += scale * d[k];
        }
    }
}

fn split_rows<const D: usize, K>(
    families: &Families,
    first: usize,
    terms: &mut [NodeTerms<D>],
    state: &mut [u8],
    kernel: &K,
) -> u64
where
    K: Fn(usize, &mut [NodeTerms<D>], &mut [u8]) -> u64 + Sync,
{
    if terms.len() <= ROWS_PER_TASK {
        return kernel(first, terms, state);
    }
    let mid = terms.len() / 2;
    let (terms_a, terms_b) = terms.split_at_mut(mid);
    let cut = families.offsets[first + mid] - families.offsets[first];
    let (state_a, state_b) = state.split_at_mut(cut);
    let (a, b) = rayon::join(
        || split_rows(families, first, terms_a, state_a, kernel),
        || split_rows(families, first + mid, terms_b, state_b, kernel),
    );
    a + b
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::discretization::grid::Lattice;
    use crate::integrate::lattice_symbol::{LatticeSymbol, on_lattice};
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

    /// The AVX2 build of the force loop, the portable one and any thread count give the same
    /// bits, breaking included.
    #[test]
    fn force_loop_is_bit_identical_across_builds_and_threads() {
        let (lattice, families) = perturbed_cube(12.0, 5);
        let law = PmbLaw {
            micromodulus: 1.0,
            critical_stretch: 0.01,
            influence: Influence::Constant,
            horizon: 3.0,
        };
        let positions: Vec<[f64; 3]> = lattice
            .positions
            .iter()
            .map(|x| {
                [
                    x[0] * (1.0 + 0.012 * (x[1] / 12.0)),
                    x[1],
                    x[2] + 1e-3 * x[0],
                ]
            })
            .collect();
        let quadrature = Quadrature {
            spacing: 1.0,
            horizon: 3.0,
            volume_correction: true,
        };
        let run = |threads: usize| {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap();
            pool.install(|| {
                let mut intact = intact_bonds(families.bond_count());
                let mut terms = vec![NodeTerms::default(); lattice.len()];
                let scheme = Standard {
                    reference: &lattice.positions,
                    volumes: &lattice.volumes,
                    uniform_volume: Some(1.0),
                    families: &families,
                    law: &law,
                    quadrature: &quadrature,
                };
                let broken = scheme.forces(&positions, &mut intact, &mut terms);
                (broken, intact, terms)
            })
        };
        let (broken, intact, terms) = run(1);
        assert!(broken > 0 && broken < families.bond_count() as u64);
        assert_eq!(run(2), (broken, intact.clone(), terms.clone()));

        let rows = Rows {
            positions: &positions,
            families: &families,
            quadrature: &quadrature,
            first: 0,
            s0: law.critical_stretch,
            skip: None::<&[u8]>,
        };
        let weight = |l: f64| quadrature.beta(l);
        let volume = |_j: usize| 1.0;
        let fresh = || {
            (
                intact_bonds(families.bond_count()),
                vec![NodeTerms::default(); lattice.len()],
            )
        };
        let mut portable = fresh();
        let b1 = rows_portable::<3, LANES, u8>(
            &rows,
            &mut portable.1,
            &mut portable.0,
            &weight,
            &volume,
        );
        let mut portable_wide = fresh();
        let b8 = rows_portable::<3, WIDE_LANES, u8>(
            &rows,
            &mut portable_wide.1,
            &mut portable_wide.0,
            &weight,
            &volume,
        );
        // The solver runs 8 lanes where AVX-512 is detected, 4 elsewhere, and matches that
        // portable loop bit for bit.
        #[cfg(target_arch = "x86_64")]
        let solver_is_wide = avx512_detected();
        #[cfg(not(target_arch = "x86_64"))]
        let solver_is_wide = false;
        let (solver_lanes, other) = if solver_is_wide {
            (&portable_wide, &portable)
        } else {
            (&portable, &portable_wide)
        };
        assert_eq!(b1, broken);
        assert_eq!(b8, broken);
        assert_eq!(*solver_lanes, (intact, terms));
        // 4 against 8 lanes: the same broken bonds, forces and energies equal to rounding
        // (the partial sums of ~120 bonds added in another order: a few ulps of the largest
        // bond term, far below 1e-12 of the largest force).
        assert_eq!(other.0, solver_lanes.0);
        let largest = solver_lanes
            .1
            .iter()
            .flat_map(|t| t.force.iter().map(|f| f.abs()))
            .fold(0.0, f64::max);
        for (a, b) in other.1.iter().zip(&solver_lanes.1) {
            for k in 0..3 {
                assert!((a.force[k] - b.force[k]).abs() <= 1e-12 * largest);
            }
            assert!((a.energy_density - b.energy_density).abs() <= 1e-12 * a.energy_density.abs());
            assert_eq!(a.broken_weight, b.broken_weight);
        }
        #[cfg(target_arch = "x86_64")]
        if std::arch::is_x86_feature_detected!("avx2") {
            let mut wide = fresh();
            // SAFETY: AVX2 support was detected just above.
            let b2 = unsafe { rows_avx2(&rows, &mut wide.1, &mut wide.0, &weight, &volume) };
            assert_eq!(b2, b1);
            assert_eq!(wide, portable);
        }
        #[cfg(target_arch = "x86_64")]
        if avx512_detected() {
            let mut wide = fresh();
            // SAFETY: AVX-512 support was detected just above.
            let b2 = unsafe { rows_avx512(&rows, &mut wide.1, &mut wide.0, &weight, &volume) };
            assert_eq!(b2, b8);
            assert_eq!(wide, portable_wide);
        }
    }

    /// The hand-written kernel this CPU runs (AVX-512 or AVX2; 2D and 3D, uniform volumes)
    /// gives the portable loop's bits at its lane count (8 or 4) for every influence and
    /// partial-volume choice, with a spacing and volume other than 1 (so no product by 1
    /// hides a wrong operand order) and bonds breaking.
    #[cfg(target_arch = "x86_64")]
    #[test]
    fn hand_written_kernel_matches_the_portable_loop_for_every_law() {
        if hand_kernel().is_none() {
            return;
        }
        let dx = 0.7;
        let (lattice, _) = perturbed_cube(9.0, 17);
        let reference: Vec<[f64; 3]> = lattice
            .positions
            .iter()
            .map(|x| x.map(|c| c * dx))
            .collect();
        let positions: Vec<[f64; 3]> = reference
            .iter()
            .map(|x| {
                [
                    x[0] * (1.0 + 0.003 * x[1]),
                    x[1] - 0.001 * x[2] * x[2],
                    x[2],
                ]
            })
            .collect();
        assert_kernel_matches_portable(&reference, &positions, dx, 0.343);
        let square = Solid::Box {
            min: vec![0.0; 2],
            max: vec![17.0; 2],
        };
        let plane = Lattice::<2>::build(&square, 1.0, [-0.2, 0.2], 23);
        let reference: Vec<[f64; 2]> = plane.positions.iter().map(|x| x.map(|c| c * dx)).collect();
        let positions: Vec<[f64; 2]> = reference
            .iter()
            .map(|x| [x[0] * (1.0 + 0.002 * x[1]), x[1] - 0.0008 * x[0] * x[0]])
            .collect();
        assert_kernel_matches_portable(&reference, &positions, dx, 0.49);
    }

    #[cfg(target_arch = "x86_64")]
    fn assert_kernel_matches_portable<const D: usize>(
        reference: &[[f64; D]],
        positions: &[[f64; D]],
        dx: f64,
        v: f64,
    ) {
        let families = Families::build(reference, 3.0 * dx);
        let volumes = vec![v; reference.len()];
        let mut compared = 0;
        for influence in [Influence::Constant, Influence::Linear] {
            for volume_correction in [true, false] {
                let law = PmbLaw {
                    micromodulus: 3.7,
                    critical_stretch: 0.012,
                    influence,
                    horizon: 3.0 * dx,
                };
                let quadrature = Quadrature {
                    spacing: dx,
                    horizon: 3.0 * dx,
                    volume_correction,
                };
                let scheme = Standard {
                    reference,
                    volumes: &volumes,
                    uniform_volume: Some(v),
                    families: &families,
                    law: &law,
                    quadrature: &quadrature,
                };
                let mut kernel = (
                    intact_bonds(families.bond_count()),
                    vec![NodeTerms::default(); reference.len()],
                );
                let broken = scheme.forces(positions, &mut kernel.0, &mut kernel.1);
                assert!(
                    broken > 0 && broken < families.bond_count() as u64 / 2,
                    "{broken} of {}",
                    families.bond_count()
                );
                let rows = Rows {
                    positions,
                    families: &families,
                    quadrature: &quadrature,
                    first: 0,
                    s0: law.critical_stretch,
                    skip: None::<&[u8]>,
                };
                let weight = BondWeight::of(&law, &quadrature);
                let mut portable = (
                    intact_bonds(families.bond_count()),
                    vec![NodeTerms::default(); reference.len()],
                );
                let unit = |_j: usize| 1.0;
                let wide = hand_kernel() == Some(HandKernelSet::Avx512);
                macro_rules! portable {
                    ($linear:literal, $beta:literal) => {{
                        let weight = |l| weight.at::<$linear, $beta>(l) * v;
                        let (state, terms) = (&mut portable.0, &mut portable.1);
                        if wide {
                            rows_portable::<D, WIDE_LANES, u8>(&rows, terms, state, &weight, &unit)
                        } else {
                            rows_portable::<D, LANES, u8>(&rows, terms, state, &weight, &unit)
                        }
                    }};
                }
                let portable_broken = match (influence, volume_correction) {
                    (Influence::Constant, true) => portable!(false, true),
                    (Influence::Constant, false) => portable!(false, false),
                    (Influence::Linear, true) => portable!(true, true),
                    (Influence::Linear, false) => portable!(true, false),
                };
                assert_eq!(portable_broken, broken);
                assert_eq!(portable, kernel, "{influence:?}, β {volume_correction}");
                // Without the energy sum: the same forces and bonds, energies left alone.
                let mut quiet = (
                    intact_bonds(families.bond_count()),
                    vec![NodeTerms::default(); reference.len()],
                );
                let quiet_broken =
                    scheme.forces_masked::<u8>(positions, &mut quiet.0, &mut quiet.1, None, false);
                assert_eq!((quiet_broken, &quiet.0), (broken, &kernel.0));
                for (q, k) in quiet.1.iter().zip(&kernel.1) {
                    assert_eq!((q.force, q.broken_weight), (k.force, k.broken_weight));
                    assert_eq!(q.energy_density, 0.0);
                }
                compared += 1;
            }
        }
        assert_eq!(compared, 4);
    }

    /// The AVX2 linearized row (vector gathers) gives the portable 4-lane loop's bits, in 2D
    /// and 3D, with broken bonds and a displacement field without symmetry.
    #[cfg(target_arch = "x86_64")]
    #[test]
    fn vector_linearized_rows_match_the_portable_loop() {
        if !crate::simd::avx2() {
            return;
        }
        fn compare<const D: usize>(reference: &[[f64; D]], radius: f64) {
            let families = Families::build(reference, radius);
            let coefficients: Vec<f64> = (0..families.bond_count())
                .map(|b| 1.0 + (b % 7) as f64 * 0.37)
                .collect();
            let states: Vec<u8> = (0..families.bond_count())
                .map(|b| u8::from(b % 5 != 3))
                .collect();
            let u: Vec<[f64; D]> = (0..reference.len())
                .map(|i| std::array::from_fn(|k| ((i * (k + 3)) as f64 * 0.618).sin()))
                .collect();
            for i in 0..reference.len() {
                let range = families.range(i);
                let row = LinearizedRow {
                    i,
                    neighbors: &families.neighbors[range.clone()],
                    states: &states[range.clone()],
                    coefficients: &coefficients[range],
                };
                let portable = linearized_row::<D, LANES>(&row, reference, &u);
                // SAFETY: AVX2 was detected above; D is 2 or 3.
                let vector = unsafe { avx2::linearized_row(&row, reference, &u) };
                assert_eq!(
                    portable.map(f64::to_bits),
                    vector.map(f64::to_bits),
                    "row {i}"
                );
                assert!(portable.iter().any(|&x| x != 0.0));
            }
        }
        let (lattice, _) = perturbed_cube(7.0, 5);
        compare(&lattice.positions, 3.0);
        let square = Solid::Box {
            min: vec![0.0; 2],
            max: vec![12.0; 2],
        };
        compare(
            &Lattice::<2>::build(&square, 1.0, [-0.2, 0.2], 9).positions,
            3.0,
        );
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
