//! The gather loop of `Standard::forces`: f_i = Σ_j μ ω c s β V_j e_ij, (2.33) in the sum
//! (3.1), per node over its CSR row, written once over the lanes of `simd`.
//!
//! A row's bonds go N at a time (N = the lane count) through `Law::bonds`, a broken bond
//! weighing 0; each lane keeps its own partial sums, added in lane order at the row's end;
//! the remainder then goes one bond at a time through the same `Law::bonds` with one lane,
//! added to those sums in bond order. Node ranges are split recursively over rayon tasks
//! (no allocation) so each task owns its rows of the node terms and of the bond states; one
//! monomorphized loop per (influence, β, energy, volumes) combination, so no branch on them
//! inside.

use crate::discretization::{Families, Quadrature};
use crate::model::pmb::{Influence, PmbLaw};
use crate::scheme::RowMask;
use crate::simd::{LaneLoop, Lanes, Portable, Simd};

use super::terms::NodeTerms;

/// Nodes per task of the force loop.
const ROWS_PER_TASK: usize = 512;

/// The bond weight ω(‖ξ‖) c β(‖ξ‖) of (2.33) in the sum (3.1), without the volume: the
/// influence ω (constant, or linear 1 − ‖ξ‖/δ) and the partial-volume factor β (3.2) chosen
/// by the const parameters, so each combination is its own branch-free function.
#[derive(Debug, Clone, Copy)]
pub(super) struct BondWeight {
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

    /// ω c β on N bond lengths `l`.
    #[inline(always)]
    fn lanes<L: Lanes, const LINEAR: bool, const BETA: bool>(&self, l: L) -> L {
        let (zero, one) = (L::zero(), L::splat(1.0));
        let w = if LINEAR {
            L::splat(self.c) * (one - l / L::splat(self.horizon)).max(zero)
        } else {
            L::splat(self.c)
        };
        if BETA {
            w * ((L::splat(self.reach) - l) * L::splat(self.inv_dx))
                .max(zero)
                .min(one)
        } else {
            w
        }
    }
}

/// The node volumes of the force loop.
pub(super) trait NodeVolumes: Copy + Sync {
    /// V_j of the neighbours `nodes[..N]`.
    ///
    /// # Safety
    /// Every index is a node (`check`ed).
    unsafe fn lanes<L: Lanes>(&self, nodes: &[u32]) -> L;
    /// V'_j of the damage weights (`Standard::damage_weights`).
    fn damage(&self, j: usize) -> f64;
    /// Panics unless there is a volume for each of `node_count` nodes.
    fn check(&self, node_count: usize);
}

/// One volume for every node: no gather, and V'_j = 1.
#[derive(Debug, Clone, Copy)]
pub(super) struct Uniform(pub f64);

impl NodeVolumes for Uniform {
    #[inline(always)]
    unsafe fn lanes<L: Lanes>(&self, _nodes: &[u32]) -> L {
        L::splat(self.0)
    }

    #[inline(always)]
    fn damage(&self, _j: usize) -> f64 {
        1.0
    }

    fn check(&self, _node_count: usize) {}
}

/// A volume per node, V'_j = V_j.
#[derive(Debug, Clone, Copy)]
pub(super) struct PerNode<'a>(pub &'a [f64]);

impl NodeVolumes for PerNode<'_> {
    #[inline(always)]
    unsafe fn lanes<L: Lanes>(&self, nodes: &[u32]) -> L {
        // SAFETY: the caller guarantees the indices, and `check` that each has a volume.
        let [v] = unsafe { L::gather::<1>(self.0, nodes) };
        v
    }

    #[inline(always)]
    fn damage(&self, j: usize) -> f64 {
        self.0[j]
    }

    fn check(&self, node_count: usize) {
        assert_eq!(self.0.len(), node_count);
    }
}

/// What bonds break and weigh by: the weight (its influence linear or constant, with or
/// without β), the volumes, the critical stretch s0, and the quadrature whose β weighs a
/// broken bond in the damage.
#[derive(Clone, Copy)]
pub(super) struct Law<'a, V> {
    weight: BondWeight,
    linear: bool,
    beta: bool,
    volumes: V,
    s0: f64,
    quadrature: &'a Quadrature,
}

impl<'a, V: NodeVolumes> Law<'a, V> {
    pub(super) fn of(law: &PmbLaw, quadrature: &'a Quadrature, volumes: V) -> Self {
        Law {
            weight: BondWeight::of(law, quadrature),
            linear: law.influence == Influence::Linear,
            beta: quadrature.volume_correction,
            volumes,
            s0: law.critical_stretch,
            quadrature,
        }
    }
}

/// A block of consecutive rows of the force loop: node `first` on, those the mask does not
/// skip.
#[derive(Clone, Copy)]
pub(super) struct Rows<'a, const D: usize, M> {
    pub positions: &'a [[f64; D]],
    pub families: &'a Families,
    pub first: usize,
    pub skip: Option<&'a [M]>,
}

impl<'a, const D: usize, M: RowMask> Rows<'a, D, M> {
    /// Every row of `families` (at `positions`) but those `skip` skips.
    pub(super) fn all(
        positions: &'a [[f64; D]],
        families: &'a Families,
        skip: Option<&'a [M]>,
    ) -> Self {
        assert_eq!(positions.len(), families.node_count());
        Rows {
            positions,
            families,
            first: 0,
            skip,
        }
    }

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

/// The force loop over `rows` on `simd`'s lanes. Without `energy` the strain-energy
/// densities are left as they are. Returns the directed bonds broken.
pub(super) fn pmb_forces<const D: usize, M: RowMask, V: NodeVolumes>(
    simd: Simd,
    rows: Rows<D, M>,
    law: Law<V>,
    intact: &mut [u8],
    terms: &mut [NodeTerms<D>],
    energy: bool,
) -> u64 {
    assert_eq!(intact.len(), rows.families.bond_count());
    assert_eq!(terms.len(), rows.families.node_count() - rows.first);
    law.volumes.check(rows.positions.len());
    macro_rules! run {
        ($linear:literal, $beta:literal, $energy:literal) => {
            split_rows(
                rows.families,
                rows.first,
                terms,
                intact,
                &|first, terms, state| {
                    simd.run(RowsLoop::<D, M, V, $linear, $beta, $energy> {
                        rows: Rows { first, ..rows },
                        law: &law,
                        terms,
                        state,
                    })
                },
            )
        };
    }
    match (law.linear, law.beta, energy) {
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

/// One task's rows of the force loop, for `Simd::run`.
struct RowsLoop<
    'a,
    'b,
    const D: usize,
    M,
    V,
    const LINEAR: bool,
    const BETA: bool,
    const ENERGY: bool,
> {
    rows: Rows<'a, D, M>,
    law: &'b Law<'a, V>,
    terms: &'b mut [NodeTerms<D>],
    state: &'b mut [u8],
}

impl<
    const D: usize,
    M: RowMask,
    V: NodeVolumes,
    const LINEAR: bool,
    const BETA: bool,
    const ENERGY: bool,
> LaneLoop for RowsLoop<'_, '_, D, M, V, LINEAR, BETA, ENERGY>
{
    type Output = u64;

    #[inline(always)]
    fn run<L: Lanes>(self) -> u64 {
        let Self {
            rows,
            law,
            terms,
            state,
        } = self;
        let positions = rows.positions.as_flattened();
        let mut broken = 0;
        for (i, t_i, st) in rows.each_row(terms, state) {
            let families = rows.families;
            let (neighbors, lengths) = (
                &families.neighbors[families.range(i)],
                families.row_lengths(i),
            );
            // Every neighbour is a node (checked once per row: the gathers do not check).
            let last = neighbors.iter().copied().max().unwrap_or(0) as usize;
            assert!(neighbors.is_empty() || last < rows.positions.len());
            let y_i = rows.positions[i];
            let blocked = neighbors.len() / L::N * L::N;
            let mut sums = RowSums::<L, D>::default();
            for ((nodes, ln), st) in neighbors[..blocked]
                .chunks_exact(L::N)
                .zip(lengths[..blocked].chunks_exact(L::N))
                .zip(st[..blocked].chunks_exact_mut(L::N))
            {
                // SAFETY: the indices were checked above.
                unsafe {
                    law.bonds::<L, D, LINEAR, BETA, ENERGY>(
                        y_i, positions, nodes, ln, st, &mut sums,
                    )
                };
            }
            let mut row = sums.in_lane_order();
            for b in blocked..neighbors.len() {
                // A broken bond of the remainder is skipped (in a block it weighs 0).
                if st[b] != 0 {
                    let one = b..b + 1;
                    // SAFETY: the index was checked above.
                    unsafe {
                        law.bonds::<Portable<1>, D, LINEAR, BETA, ENERGY>(
                            y_i,
                            positions,
                            &neighbors[one.clone()],
                            &lengths[one.clone()],
                            &mut st[one],
                            &mut row,
                        )
                    };
                }
            }
            t_i.force = row.force.map(|f| f.0[0]);
            if ENERGY {
                t_i.energy_density = 0.25 * row.energy.0[0];
            }
            t_i.broken_weight += row.lost;
            broken += row.broken;
        }
        broken
    }
}

/// What a row's bonds add up, per lane where they are vectors.
struct RowSums<L, const D: usize> {
    /// Force density.
    force: [L; D],
    /// 4·W_i.
    energy: L,
    /// Bonds broken now.
    broken: u64,
    /// Σ β V'_j over the bonds broken now.
    lost: f64,
}

impl<L: Lanes, const D: usize> Default for RowSums<L, D> {
    fn default() -> Self {
        RowSums {
            force: [L::zero(); D],
            energy: L::zero(),
            broken: 0,
            lost: 0.0,
        }
    }
}

impl<L: Lanes, const D: usize> RowSums<L, D> {
    /// The lanes' partial sums added in lane order, as one lane.
    #[inline(always)]
    fn in_lane_order(self) -> RowSums<Portable<1>, D> {
        RowSums {
            force: self.force.map(|f| Portable([f.sum()])),
            energy: Portable([self.energy.sum()]),
            broken: self.broken,
            lost: self.lost,
        }
    }
}

impl<V: NodeVolumes> Law<'_, V> {
    /// The PMB bond force (2.33) of node i (at `y_i`) on the N bonds to `nodes`, of reference
    /// lengths `lengths` and states `states`, added to `sums`: a bond whose stretch reaches
    /// s0, or is NaN, breaks (its state set to 0, its β V'_j added to the damage numerator),
    /// and a broken bond adds 0. `positions` holds D values per node.
    ///
    /// # Safety
    /// Every index in `nodes` is a node of `positions` and of the volumes.
    #[inline(always)]
    unsafe fn bonds<
        L: Lanes,
        const D: usize,
        const LINEAR: bool,
        const BETA: bool,
        const ENERGY: bool,
    >(
        &self,
        y_i: [f64; D],
        positions: &[f64],
        nodes: &[u32],
        lengths: &[f64],
        states: &mut [u8],
        sums: &mut RowSums<L, D>,
    ) {
        // SAFETY: the caller guarantees the indices.
        let (y, v) = unsafe {
            (
                L::gather::<D>(positions, nodes),
                self.volumes.lanes::<L>(nodes),
            )
        };
        let d: [L; D] = std::array::from_fn(|k| y[k] - L::splat(y_i[k]));
        // ‖y_j − y_i‖², the axes added in order.
        let mut r2 = d[0] * d[0];
        for d_k in &d[1..] {
            r2 = r2 + *d_k * *d_k;
        }
        let r = r2.sqrt();
        let ln = L::load(lengths);
        let extension = r - ln;
        let alive = L::nonzero(states);
        let keep = L::and(alive, extension.lt(L::splat(self.s0) * ln));
        // ω c β V_j · s · (y_j − y_i)/‖y_j − y_i‖ with s = extension / length.
        let scale =
            (self.weight.lanes::<L, LINEAR, BETA>(ln) * v * extension / (ln * r)).zero_unless(keep);
        if ENERGY {
            // Strain energy w β V_j = ½ ω c s² ‖ξ‖ β V_j (2.27), with the force.
            sums.energy = sums.energy + scale * extension * r;
        }
        let kept = L::bits(keep);
        if L::bits(alive) != kept {
            sums.broken += self.break_lanes(states, kept, lengths, nodes, &mut sums.lost);
        }
        for (f, d_k) in sums.force.iter_mut().zip(&d) {
            *f = *f + scale * *d_k;
        }
    }

    /// Marks the lanes whose bond broke in this pass (intact before, bit clear in `kept`),
    /// adds their β V'_j to `lost` one by one (the damage numerator) and returns how many
    /// broke.
    #[inline(never)]
    fn break_lanes(
        &self,
        states: &mut [u8],
        kept: u32,
        lengths: &[f64],
        nodes: &[u32],
        lost: &mut f64,
    ) -> u64 {
        let mut broken = 0;
        for (l, state) in states.iter_mut().enumerate() {
            if *state != 0 && kept & (1 << l) == 0 {
                *state = 0;
                broken += 1;
                *lost += self.quadrature.beta(lengths[l]) * self.volumes.damage(nodes[l] as usize);
            }
        }
        broken
    }
}

/// Runs `kernel(first row, its terms, its bond states)` on blocks of at most
/// `ROWS_PER_TASK` rows, split in halves over rayon tasks; returns the sum of its counts.
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
    use super::super::{NodeTerms, Standard, intact_bonds};
    use super::Rows;
    use crate::discretization::grid::Lattice;
    use crate::discretization::{Families, Quadrature};
    use crate::model::pmb::{Influence, PmbLaw};
    use crate::scene::Solid;
    use crate::simd::Simd;

    /// A perturbed lattice at spacing `dx` (horizon 3 dx) and its current positions; node
    /// volumes other than 1 that differ per node, so that a wrong operand order or a wrong
    /// gather shows.
    struct Body<const D: usize> {
        reference: Vec<[f64; D]>,
        positions: Vec<[f64; D]>,
        families: Families,
        volumes: Vec<f64>,
        dx: f64,
    }

    impl<const D: usize> Body<D> {
        fn new(side: f64, seed: u64, dx: f64, deform: impl Fn([f64; D]) -> [f64; D]) -> Self {
            let solid = Solid::Box {
                min: vec![0.0; D],
                max: vec![side; D],
            };
            let lattice = Lattice::<D>::build(&solid, 1.0, [-0.2, 0.2], seed);
            let reference: Vec<[f64; D]> = lattice
                .positions
                .iter()
                .map(|x| x.map(|c| c * dx))
                .collect();
            let positions = reference.iter().map(|&x| deform(x)).collect();
            let families = Families::build(&reference, 3.0 * dx);
            let volumes = (0..reference.len())
                .map(|i| dx.powi(D as i32) * (1.0 + 0.1 * (0.37 * i as f64).sin()))
                .collect();
            Body {
                reference,
                positions,
                families,
                volumes,
                dx,
            }
        }
    }

    /// One choice of law and call.
    #[derive(Debug, Clone, Copy)]
    struct Case {
        influence: Influence,
        volume_correction: bool,
        uniform: bool,
        energy: bool,
        masked: bool,
    }

    impl Case {
        fn all() -> impl Iterator<Item = Case> {
            let flags = [false, true];
            [Influence::Constant, Influence::Linear]
                .into_iter()
                .flat_map(move |influence| flags.map(move |b| (influence, b)))
                .flat_map(move |(influence, volume_correction)| {
                    flags.map(move |uniform| (influence, volume_correction, uniform))
                })
                .flat_map(move |(influence, volume_correction, uniform)| {
                    // Energy with every row, and without the energy on masked rows.
                    flags.map(move |energy| Case {
                        influence,
                        volume_correction,
                        uniform,
                        energy,
                        masked: !energy,
                    })
                })
        }
    }

    /// A force-loop call's bonds broken, bond states and node terms, the floats as bits.
    type Outcome = (u64, Vec<u8>, Vec<u64>);

    /// What the loop must leave alone (skipped rows; energies not asked for) starts here.
    const UNTOUCHED: f64 = 7.25;

    /// Runs `forces` (a force loop filling fresh bond states and node terms, returning the
    /// bonds broken) for `case` on `body`.
    fn outcome<const D: usize>(
        body: &Body<D>,
        case: Case,
        forces: impl FnOnce(&Standard<D>, Rows<D, u8>, &mut [u8], &mut [NodeTerms<D>]) -> u64,
    ) -> Outcome {
        let dx = body.dx;
        let law = PmbLaw {
            micromodulus: 3.7,
            critical_stretch: 0.012,
            influence: case.influence,
            horizon: 3.0 * dx,
        };
        let quadrature = Quadrature {
            spacing: dx,
            horizon: 3.0 * dx,
            volume_correction: case.volume_correction,
        };
        let scheme = Standard {
            reference: &body.reference,
            volumes: &body.volumes,
            uniform_volume: case.uniform.then_some(0.9 * dx.powi(D as i32)),
            families: &body.families,
            law: &law,
            quadrature: &quadrature,
        };
        let n = body.reference.len();
        let skip: Vec<u8> = (0..n)
            .map(|i| u8::from(case.masked && i % 3 == 1))
            .collect();
        let mut intact = intact_bonds(body.families.bond_count());
        let mut terms = vec![
            NodeTerms {
                force: [UNTOUCHED; D],
                energy_density: UNTOUCHED,
                broken_weight: 0.5,
            };
            n
        ];
        let rows = Rows::all(&body.positions, &body.families, Some(&skip));
        let broken = forces(&scheme, rows, &mut intact, &mut terms);
        let bits = terms
            .iter()
            .flat_map(|t| {
                t.force
                    .into_iter()
                    .chain([t.energy_density, t.broken_weight])
            })
            .map(f64::to_bits)
            .collect();
        (broken, intact, bits)
    }

    /// The force loop as plain scalar code, bond by bond, in the order of the `lanes`-lane
    /// loop: of a row's n bonds the first ⌊n/N⌋·N go to lane b mod N, the lanes' sums are
    /// added in lane order, then the other bonds one by one. The weight is `BondWeight`'s
    /// formula: ω c β with β = ((δ + Δx/2 − ‖ξ‖)/Δx) clamped, the division as a product by
    /// 1/Δx.
    fn scalar_loop<const D: usize>(
        lanes: usize,
        scheme: &Standard<D>,
        rows: Rows<D, u8>,
        energy: bool,
        intact: &mut [u8],
        terms: &mut [NodeTerms<D>],
    ) -> u64 {
        let (law, quadrature, families) = (scheme.law, scheme.quadrature, scheme.families);
        let positions = rows.positions;
        let weight = |l: f64| {
            let w = match law.influence {
                Influence::Constant => law.micromodulus,
                Influence::Linear => law.micromodulus * (1.0 - l / law.horizon).max(0.0),
            };
            let x =
                (quadrature.horizon + 0.5 * quadrature.spacing - l) * (1.0 / quadrature.spacing);
            if quadrature.volume_correction {
                w * x.clamp(0.0, 1.0)
            } else {
                w
            }
        };
        let volume = |j: usize| scheme.uniform_volume.unwrap_or(scheme.volumes[j]);
        let damage_volume = |j: usize| scheme.uniform_volume.map_or(scheme.volumes[j], |_| 1.0);
        let mut broken = 0;
        for (i, t) in terms.iter_mut().enumerate() {
            if rows.skip.is_some_and(|skip| skip[i] != 0) {
                continue;
            }
            let mut lost = 0.0;
            // Bond b: whether it stays intact, its force factor s (0 where not), y_j − y_i,
            // extension and ‖y_j − y_i‖.
            let mut bond = |b: usize| {
                let (j, l) = (families.neighbors[b] as usize, families.length(i, b));
                let d: [f64; D] = std::array::from_fn(|a| positions[j][a] - positions[i][a]);
                let r = d[1..].iter().fold(d[0] * d[0], |r2, x| r2 + x * x).sqrt();
                let extension = r - l;
                let alive = intact[b] != 0;
                let kept = alive && extension < law.critical_stretch * l;
                if alive && !kept {
                    intact[b] = 0;
                    broken += 1;
                    lost += quadrature.beta(l) * damage_volume(j);
                }
                let s = if kept {
                    weight(l) * volume(j) * extension / (l * r)
                } else {
                    0.0
                };
                (kept, s, d, extension, r)
            };
            let bonds: Vec<usize> = families.range(i).collect();
            let blocked = bonds.len() / lanes * lanes;
            let mut lane_sums = vec![([0.0; D], 0.0); lanes];
            for (k, &b) in bonds[..blocked].iter().enumerate() {
                let (_, s, d, extension, r) = bond(b);
                let (f, w) = &mut lane_sums[k % lanes];
                for a in 0..D {
                    f[a] += s * d[a];
                }
                *w += s * extension * r;
            }
            let mut force: [f64; D] =
                std::array::from_fn(|a| lane_sums.iter().map(|s| s.0[a]).sum());
            let mut w: f64 = lane_sums.iter().map(|s| s.1).sum();
            for &b in &bonds[blocked..] {
                // The remainder as the loop before the lanes abstraction took it: broken
                // bonds and bonds that break now add nothing.
                let (kept, s, d, extension, r) = bond(b);
                if kept {
                    for a in 0..D {
                        force[a] += s * d[a];
                    }
                    w += s * extension * r;
                }
            }
            t.force = force;
            if energy {
                t.energy_density = 0.25 * w;
            }
            t.broken_weight += lost;
        }
        broken
    }

    /// Every lane implementation this CPU runs (the portable ones at 4 and 8 lanes always,
    /// AVX2 and AVX-512 where present) gives the bits of the plain scalar loop in its lane
    /// count's order: both influences, with and without β, uniform and per-node volumes,
    /// with and without the energy sum, masked rows, in 1D, 2D and 3D, with bonds breaking.
    #[test]
    fn every_lane_implementation_gives_the_scalar_loops_bits() {
        let cube = Body::<3>::new(9.0, 17, 0.7, |x| {
            [
                x[0] * (1.0 + 0.003 * x[1]),
                x[1] - 0.001 * x[2] * x[2],
                x[2],
            ]
        });
        assert_every_implementation_matches(&cube);
        let plane = Body::<2>::new(17.0, 23, 0.7, |x| {
            [x[0] * (1.0 + 0.002 * x[1]), x[1] - 0.0008 * x[0] * x[0]]
        });
        assert_every_implementation_matches(&plane);
        let line = Body::<1>::new(300.0, 29, 0.7, |x| [x[0] * (1.0 + 4e-5 * x[0])]);
        assert_every_implementation_matches(&line);
    }

    fn assert_every_implementation_matches<const D: usize>(body: &Body<D>) {
        let supported = Simd::supported();
        assert!(supported.contains(&Simd::Portable) && supported.contains(&Simd::Portable8));
        let mut compared = 0;
        for case in Case::all() {
            let scalar = |lanes: usize| {
                outcome(body, case, |scheme, rows, intact, terms| {
                    scalar_loop(lanes, scheme, rows, case.energy, intact, terms)
                })
            };
            let expected = [scalar(4), scalar(8)];
            let bonds = body.families.bond_count() as u64;
            assert!(expected[0].0 > 0 && expected[0].0 < bonds / 2, "{case:?}");
            for &simd in &supported {
                let got = outcome(body, case, |scheme, rows, intact, terms| {
                    scheme.forces_on(simd, rows, intact, terms, case.energy)
                });
                let want = &expected[usize::from(simd.lanes() == 8)];
                assert!(
                    got == *want,
                    "{simd:?} against the scalar loop, {case:?}, D = {D}"
                );
                compared += 1;
            }
        }
        assert_eq!(compared, 16 * supported.len());
    }

    /// 4 and 8 lanes break the same bonds and give forces and energies equal to rounding
    /// (the partial sums of ~120 bonds added in another order: a few ulps of the largest
    /// bond term, far below 1e-12 of the largest force), and 1 and 2 threads the same bits.
    #[test]
    fn lane_counts_agree_to_rounding_and_threads_to_the_bit() {
        let body = Body::<3>::new(12.0, 5, 1.0, |x| {
            [x[0] * (1.0 + 0.001 * x[1]), x[1], x[2] + 1e-3 * x[0]]
        });
        let case = Case {
            influence: Influence::Constant,
            volume_correction: true,
            uniform: true,
            energy: true,
            masked: false,
        };
        let run = |simd: Simd, threads: usize| {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap();
            pool.install(|| {
                outcome(&body, case, |scheme, rows, intact, terms| {
                    scheme.forces_on(simd, rows, intact, terms, true)
                })
            })
        };
        let (four, eight) = (run(Simd::Portable, 1), run(Simd::Portable8, 1));
        assert_eq!(run(Simd::selected(), 2), run(Simd::selected(), 1));
        assert!(four.0 > 0);
        assert_eq!((four.0, &four.1), (eight.0, &eight.1));
        let values = |o: &Outcome| o.2.iter().map(|&b| f64::from_bits(b)).collect::<Vec<_>>();
        let (a, b) = (values(&four), values(&eight));
        let largest = a.iter().fold(0.0f64, |m, x| m.max(x.abs()));
        for (x, y) in a.iter().zip(&b) {
            assert!((x - y).abs() <= 1e-12 * largest, "{x} against {y}");
        }
        assert_ne!(a, b, "the orders differ somewhere");
    }
}
