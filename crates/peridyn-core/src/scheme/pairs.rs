//! The standard PMB force loop with each bond evaluated once for both of its ends (issue 14
//! item 5): the same bond force as [`Standard::forces`] (thesis (2.33) in the sum (3.1)), added
//! to node i and, negated, to node j.
//!
//! Rows are sorted by neighbour index, so node i's *forward* bonds (j > i) are the tail of its
//! row. The nodes are cut into consecutive blocks at least as long as the largest forward index
//! span of any bond: a block's forward bonds end in the block itself or the next one. Blocks
//! 0, 2, 4, … run in parallel, each writing only to itself and its successor, then blocks
//! 1, 3, 5, …; so no two tasks ever touch the same node or bond and no atomics are needed. The
//! order in which a node's force is summed depends on the blocks only, never on the thread
//! count: results are bit-identical between 1 and 2 threads. On a lattice numbered row by row
//! (the last axis slowest) the blocks are slabs a horizon thick.

use rayon::prelude::*;

use crate::discretization::{Families, Quadrature};
use crate::scheme::standard::{BondLoop, LANES, NodeTerms, Standard, lane_offsets};

/// Fewer blocks than this and the pair loop would leave a thread idle for half the step: the
/// gather loop is used instead.
const MIN_BLOCKS: usize = 4;

/// Where each row's forward bonds start and how the nodes are cut into blocks.
#[derive(Debug, Clone, PartialEq)]
pub struct PairPlan {
    /// Per node, the first bond of its row whose neighbour has a higher index.
    forward: Vec<usize>,
    /// Block k holds the nodes `bounds[k]..bounds[k + 1]`.
    bounds: Vec<usize>,
}

impl PairPlan {
    /// The plan for `families`, or `None` where each bond cannot be evaluated once: a row not
    /// strictly sorted, a bond whose reverse is missing or has another length or state, or
    /// fewer than [`MIN_BLOCKS`] blocks.
    pub fn build(families: &Families, intact: &[u8]) -> Option<PairPlan> {
        let n = families.node_count();
        let (neighbors, offsets) = (&families.neighbors, &families.offsets);
        let forward: Vec<usize> = (0..n)
            .into_par_iter()
            .map(|i| {
                let row = &neighbors[families.range(i)];
                offsets[i] + row.partition_point(|&j| (j as usize) <= i)
            })
            .collect();
        let symmetric = (0..n).into_par_iter().all(|i| {
            let row = &neighbors[families.range(i)];
            let sorted = row.windows(2).all(|w| w[0] < w[1]) && !row.contains(&(i as u32));
            sorted
                && (forward[i]..offsets[i + 1]).all(|b| {
                    let j = neighbors[b] as usize;
                    reverse_bond(neighbors, offsets[j], forward[j], i).is_some_and(|r| {
                        families.length(j, r) == families.length(i, b) && intact[r] == intact[b]
                    })
                })
        });
        // Every backward bond is some forward bond's reverse when the two counts agree.
        let forward_count: usize = (0..n).map(|i| offsets[i + 1] - forward[i]).sum();
        if !symmetric || 2 * forward_count != families.bond_count() {
            return None;
        }
        let span = (0..n)
            .filter(|&i| forward[i] < offsets[i + 1])
            .map(|i| neighbors[offsets[i + 1] - 1] as usize - i)
            .max()
            .unwrap_or(0);
        let length = span.max(1);
        let mut bounds: Vec<usize> = (0..n).step_by(length).collect();
        bounds.push(n);
        (bounds.len() > MIN_BLOCKS).then_some(PairPlan { forward, bounds })
    }

    pub fn block_count(&self) -> usize {
        self.bounds.len() - 1
    }

    /// Bytes held by the plan.
    pub fn memory_bytes(&self) -> usize {
        std::mem::size_of_val(self.forward.as_slice())
            + std::mem::size_of_val(self.bounds.as_slice())
    }
}

fn avx2_detected() -> bool {
    #[cfg(target_arch = "x86_64")]
    return std::arch::is_x86_feature_detected!("avx2");
    #[allow(unreachable_code)]
    false
}

/// The bond j→i among node j's backward bonds `start..end` (sorted), if any.
#[inline]
fn reverse_bond(neighbors: &[u32], start: usize, end: usize, i: usize) -> Option<usize> {
    neighbors[start..end]
        .binary_search(&(i as u32))
        .ok()
        .map(|k| start + k)
}

impl<const D: usize> Standard<'_, D> {
    /// [`Standard::forces`] with each bond evaluated once for both ends, by `plan` (built for
    /// these families). The same bond forces, energies and breaks; each node's sums are taken
    /// in another order, so results agree with `forces` to rounding.
    pub fn forces_by_pairs(
        &self,
        plan: &PairPlan,
        positions: &[[f64; D]],
        intact: &mut [u8],
        terms: &mut [NodeTerms<D>],
    ) -> u64 {
        let families = self.families;
        assert_eq!(positions.len(), families.node_count());
        assert_eq!(intact.len(), families.bond_count());
        assert_eq!(plan.forward.len(), families.node_count());
        self.with_bond_law(PairLoop {
            plan,
            positions,
            families,
            quadrature: self.quadrature,
            s0: self.law.critical_stretch,
            avx2: cfg!(target_arch = "x86_64") && avx2_detected(),
            intact,
            terms,
        })
    }
}

struct PairLoop<'a, const D: usize> {
    plan: &'a PairPlan,
    positions: &'a [[f64; D]],
    families: &'a Families,
    quadrature: &'a Quadrature,
    s0: f64,
    /// Run the AVX2 build (only where the CPU has it).
    avx2: bool,
    intact: &'a mut [u8],
    terms: &'a mut [NodeTerms<D>],
}

/// What one block's task reads: the loop's inputs and the bond law.
struct BlockInputs<'a, const D: usize, W, V> {
    plan: &'a PairPlan,
    positions: &'a [[f64; D]],
    families: &'a Families,
    quadrature: &'a Quadrature,
    s0: f64,
    weight: W,
    volume: V,
    avx2: bool,
}

/// Node terms and bond states from node `first` (and its first bond) onwards: what a task
/// may write.
struct Region<'a, const D: usize> {
    first: usize,
    first_bond: usize,
    terms: &'a mut [NodeTerms<D>],
    state: &'a mut [u8],
}

impl<'a, const D: usize> Region<'a, D> {
    /// This region cut at node `at`: (before, from `at` on).
    fn split(self, at: usize, offsets: &[usize]) -> (Region<'a, D>, Region<'a, D>) {
        let Region {
            first,
            first_bond,
            terms,
            state,
        } = self;
        let (terms_a, terms_b) = terms.split_at_mut(at - first);
        let (state_a, state_b) = state.split_at_mut(offsets[at] - first_bond);
        (
            Region {
                first,
                first_bond,
                terms: terms_a,
                state: state_a,
            },
            Region {
                first: at,
                first_bond: offsets[at],
                terms: terms_b,
                state: state_b,
            },
        )
    }
}

impl<const D: usize> BondLoop for PairLoop<'_, D> {
    fn run(self, weight: impl Fn(f64) -> f64 + Sync, volume: impl Fn(usize) -> f64 + Sync) -> u64 {
        let PairLoop {
            plan,
            positions,
            families,
            quadrature,
            s0,
            avx2,
            intact,
            terms,
        } = self;
        terms.par_iter_mut().with_min_len(4096).for_each(|t| {
            t.force = [0.0; D];
            t.energy_density = 0.0;
        });
        let inputs = BlockInputs {
            plan,
            positions,
            families,
            quadrature,
            s0,
            weight,
            volume,
            avx2,
        };
        let blocks = plan.block_count();
        let offsets = &families.offsets;
        let mut broken = 0;
        for phase in 0..2 {
            // Blocks phase, phase + 2, …, writing from the first of them to the end.
            let start = plan.bounds[phase.min(blocks)];
            let region = Region {
                first: start,
                first_bond: offsets[start],
                terms: &mut terms[start..],
                state: &mut intact[offsets[start]..],
            };
            let count = blocks.saturating_sub(phase).div_ceil(2);
            broken += run_blocks(&inputs, phase, count, region);
        }
        broken
    }
}

/// Blocks `first`, `first + 2`, … (`count` of them) in parallel, halving the list.
fn run_blocks<const D: usize, W, V>(
    inputs: &BlockInputs<D, W, V>,
    first: usize,
    count: usize,
    region: Region<D>,
) -> u64
where
    W: Fn(f64) -> f64 + Sync,
    V: Fn(usize) -> f64 + Sync,
{
    match count {
        0 => 0,
        1 => run_block(inputs, first, region),
        _ => {
            let half = count / 2;
            let middle = first + 2 * half;
            let (a, b) = region.split(inputs.plan.bounds[middle], &inputs.families.offsets);
            let (x, y) = rayon::join(
                || run_blocks(inputs, first, half, a),
                || run_blocks(inputs, middle, count - half, b),
            );
            x + y
        }
    }
}

fn run_block<const D: usize, W, V>(
    inputs: &BlockInputs<D, W, V>,
    block: usize,
    region: Region<D>,
) -> u64
where
    W: Fn(f64) -> f64,
    V: Fn(usize) -> f64,
{
    #[cfg(target_arch = "x86_64")]
    if inputs.avx2 {
        // SAFETY: `avx2` is set only where the CPU was detected to support AVX2.
        return unsafe { block_avx2(inputs, block, region) };
    }
    block_portable(inputs, block, region)
}

/// `block_portable` compiled for AVX2 (the lane loops 4-wide). No FMA is enabled, so the
/// results are bit-identical to the portable code.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx,avx2")]
fn block_avx2<const D: usize, W, V>(
    inputs: &BlockInputs<D, W, V>,
    block: usize,
    region: Region<D>,
) -> u64
where
    W: Fn(f64) -> f64,
    V: Fn(usize) -> f64,
{
    block_portable(inputs, block, region)
}

/// Every forward bond of the block's nodes: the force on both ends, ¼ of the bond's
/// w β V on each end's energy density (W_i = ½ Σ_j ½ c s² ‖ξ‖ β V_j, (2.26)–(2.27)), breaks
/// recorded in both directed states and both ends' damage numerators. Returns the directed
/// bonds broken (two per bond).
#[inline(always)]
fn block_portable<const D: usize, W, V>(
    inputs: &BlockInputs<D, W, V>,
    block: usize,
    region: Region<D>,
) -> u64
where
    W: Fn(f64) -> f64,
    V: Fn(usize) -> f64,
{
    let BlockInputs {
        plan,
        positions,
        families,
        quadrature,
        s0,
        weight,
        volume,
        ..
    } = inputs;
    let (neighbors, offsets) = (&families.neighbors, &families.offsets);
    let Region {
        first,
        first_bond,
        terms,
        state,
    } = region;
    let mut broken = 0u64;
    for i in plan.bounds[block]..plan.bounds[block + 1] {
        let y_i = positions[i];
        let v_i = volume(i);
        let bonds = plan.forward[i]..offsets[i + 1];
        // Row i's lengths, indexed by bond from the row's start.
        let row_lengths = families.row_lengths(i);
        let lengths = |b: usize| row_lengths[b - offsets[i]];
        let mut acc_lanes = [[0.0; LANES]; D];
        let mut w_lanes = [0.0; LANES];
        let mut lost = 0.0;
        let blocked = bonds.start + bonds.len() / LANES * LANES;
        for b in (bonds.start..blocked).step_by(LANES) {
            let nb: &[u32; LANES] = neighbors[b..b + LANES].try_into().expect("4 lanes");
            let ln: &[f64; LANES] = row_lengths[b - offsets[i]..b - offsets[i] + LANES]
                .try_into()
                .expect("4 lanes");
            let (d, vol, r2) = lane_offsets::<D, LANES>(y_i, nb, positions, volume);
            let st: [u8; LANES] = state[b - first_bond..b - first_bond + LANES]
                .try_into()
                .expect("4 lanes");
            let mut r = [0.0; LANES];
            for l in 0..LANES {
                r[l] = r2[l].sqrt();
            }
            let mut extension = [0.0; LANES];
            let mut keep = [false; LANES];
            for l in 0..LANES {
                extension[l] = r[l] - ln[l];
                keep[l] = (st[l] != 0) & (extension[l] < s0 * ln[l]);
            }
            let breaks = (0..LANES).any(|l| (st[l] != 0) != keep[l]);
            // g = ω c β · s / ‖y_j − y_i‖ with s = extension / length (V'_j applied below).
            // Computed for every lane and masked by bits, so the division stays 4-wide (with a
            // select the compiler sinks it into a branch per lane).
            let mut g = [0.0; LANES];
            for l in 0..LANES {
                let q = weight(ln[l]) * extension[l] / (ln[l] * r[l]);
                g[l] = f64::from_bits(q.to_bits() & (keep[l] as u64).wrapping_neg());
            }
            for l in 0..LANES {
                w_lanes[l] += g[l] * vol[l] * extension[l] * r[l];
            }
            for k in 0..D {
                for l in 0..LANES {
                    acc_lanes[k][l] += g[l] * vol[l] * d[k][l];
                }
            }
            // The other end's share, computed 4-wide before it is scattered lane by lane.
            let mut s_j = [0.0; LANES];
            let mut e_j = [0.0; LANES];
            let mut f_j = [[0.0; LANES]; D];
            for l in 0..LANES {
                s_j[l] = g[l] * v_i;
                e_j[l] = 0.25 * (s_j[l] * extension[l] * r[l]);
            }
            for k in 0..D {
                for l in 0..LANES {
                    f_j[k][l] = s_j[l] * d[k][l];
                }
            }
            for l in 0..LANES {
                let t_j = &mut terms[nb[l] as usize - first];
                for (f, f_k) in t_j.force.iter_mut().zip(&f_j) {
                    *f -= f_k[l];
                }
                t_j.energy_density += e_j[l];
            }
            if breaks {
                for l in 0..LANES {
                    if st[l] != 0 && !keep[l] {
                        let j = nb[l] as usize;
                        lost += break_bond(
                            (i, b + l, v_i),
                            (j, vol[l]),
                            ln[l],
                            quadrature,
                            &plan.forward,
                            families,
                            (first, first_bond),
                            terms,
                            state,
                        );
                        broken += 2;
                    }
                }
            }
        }
        let mut acc = [0.0; D];
        for k in 0..D {
            acc[k] = acc_lanes[k].iter().sum();
        }
        let mut w: f64 = w_lanes.iter().sum();
        for b in blocked..bonds.end {
            if state[b - first_bond] == 0 {
                continue;
            }
            let (j, length) = (neighbors[b] as usize, lengths(b));
            let y_j = positions[j];
            let mut d = [0.0; D];
            let mut r2 = 0.0;
            for k in 0..D {
                d[k] = y_j[k] - y_i[k];
                r2 += d[k] * d[k];
            }
            let r = r2.sqrt();
            let extension = r - length;
            let v_j = volume(j);
            if extension >= s0 * length {
                lost += break_bond(
                    (i, b, v_i),
                    (j, v_j),
                    length,
                    quadrature,
                    &plan.forward,
                    families,
                    (first, first_bond),
                    terms,
                    state,
                );
                broken += 2;
                continue;
            }
            let q = weight(length) * extension / (length * r);
            w += q * v_j * extension * r;
            let (s_i, s_j) = (q * v_j, q * v_i);
            let t_j = &mut terms[j - first];
            for k in 0..D {
                acc[k] += s_i * d[k];
                t_j.force[k] -= s_j * d[k];
            }
            t_j.energy_density += 0.25 * (s_j * extension * r);
        }
        let t_i = &mut terms[i - first];
        for (f, a) in t_i.force.iter_mut().zip(acc) {
            *f += a;
        }
        t_i.energy_density += 0.25 * w;
        t_i.broken_weight += lost;
    }
    broken
}

/// Marks bond b (i→j) and its reverse broken and adds β V'_i to j's damage numerator; returns
/// β V'_j, the share of i's.
#[allow(clippy::too_many_arguments)]
#[inline(never)]
fn break_bond<const D: usize>(
    (i, b, v_i): (usize, usize, f64),
    (j, v_j): (usize, f64),
    length: f64,
    quadrature: &Quadrature,
    forward: &[usize],
    families: &Families,
    (first, first_bond): (usize, usize),
    terms: &mut [NodeTerms<D>],
    state: &mut [u8],
) -> f64 {
    let beta = quadrature.beta(length);
    let reverse = reverse_bond(&families.neighbors, families.offsets[j], forward[j], i)
        .expect("a pair plan is built only for symmetric families");
    state[b - first_bond] = 0;
    state[reverse - first_bond] = 0;
    terms[j - first].broken_weight += beta * v_i;
    beta * v_j
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::discretization::grid::Lattice;
    use crate::model::pmb::{Influence, PmbLaw};
    use crate::scene::Solid;
    use crate::scheme::standard::intact_bonds;

    struct Case {
        lattice: Lattice<3>,
        families: Families,
        law: PmbLaw,
        quadrature: Quadrature,
        positions: Vec<[f64; 3]>,
    }

    /// A perturbed 13³ cube under a shear and a stretch that breaks some of its bonds.
    fn case(influence: Influence) -> Case {
        let cube = Solid::Box {
            min: vec![0.0; 3],
            max: vec![12.0; 3],
        };
        let lattice = Lattice::<3>::build(&cube, 1.0, [-0.2, 0.2], 5);
        let families = Families::build(&lattice.positions, 3.0);
        let positions = lattice
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
        Case {
            lattice,
            families,
            law: PmbLaw {
                micromodulus: 1.0,
                critical_stretch: 0.01,
                influence,
                horizon: 3.0,
            },
            quadrature: Quadrature {
                spacing: 1.0,
                horizon: 3.0,
                volume_correction: true,
            },
            positions,
        }
    }

    impl Case {
        fn scheme(&self, uniform: bool) -> Standard<'_, 3> {
            Standard {
                reference: &self.lattice.positions,
                volumes: &self.lattice.volumes,
                uniform_volume: uniform.then_some(1.0),
                families: &self.families,
                law: &self.law,
                quadrature: &self.quadrature,
            }
        }
    }

    type Outcome = (u64, Vec<u8>, Vec<NodeTerms<3>>);

    fn fresh(case: &Case) -> (Vec<u8>, Vec<NodeTerms<3>>) {
        (
            intact_bonds(case.families.bond_count()),
            vec![NodeTerms::default(); case.lattice.len()],
        )
    }

    /// 1 and 2 threads, and the AVX2 and portable builds, give the same bits, breaking
    /// included (the blocks fix every node's summation order).
    #[test]
    fn pairs_are_bit_identical_across_threads_and_builds() {
        let case = case(Influence::Linear);
        let scheme = case.scheme(false);
        let plan = PairPlan::build(&case.families, &fresh(&case).0).expect("a symmetric lattice");
        let run = |threads: usize, avx2: bool| -> Outcome {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap();
            pool.install(|| {
                let (mut intact, mut terms) = fresh(&case);
                let broken = if avx2 {
                    scheme.forces_by_pairs(&plan, &case.positions, &mut intact, &mut terms)
                } else {
                    scheme.with_bond_law(PairLoop {
                        plan: &plan,
                        positions: &case.positions,
                        families: &case.families,
                        quadrature: &case.quadrature,
                        s0: case.law.critical_stretch,
                        avx2: false,
                        intact: &mut intact,
                        terms: &mut terms,
                    })
                };
                (broken, intact, terms)
            })
        };
        let one = run(1, true);
        assert!(one.0 > 0);
        assert!(run(2, true) == one, "1 and 2 threads differ");
        assert!(run(2, false) == one, "the portable build differs");
    }

    /// The pair loop gives the gather loop's bond states and breaks exactly, its forces,
    /// energies and damage numerators to rounding; a second pass breaks nothing more.
    #[test]
    fn pairs_agree_with_the_gather_loop() {
        for (influence, uniform) in [
            (Influence::Constant, true),
            (Influence::Linear, true),
            (Influence::Constant, false),
        ] {
            let case = case(influence);
            let scheme = case.scheme(uniform);
            let (mut intact, mut terms) = fresh(&case);
            let plan = PairPlan::build(&case.families, &intact).expect("a symmetric lattice");
            assert!(plan.block_count() >= MIN_BLOCKS);
            let gathered: Outcome = {
                let (mut g_intact, mut g_terms) = fresh(&case);
                let b = scheme.forces(&case.positions, &mut g_intact, &mut g_terms);
                (b, g_intact, g_terms)
            };
            let broken = scheme.forces_by_pairs(&plan, &case.positions, &mut intact, &mut terms);
            assert!(broken > 0 && broken < case.families.bond_count() as u64);
            let differing = intact
                .iter()
                .zip(&gathered.1)
                .filter(|(a, b)| a != b)
                .count();
            assert_eq!(
                (broken, differing),
                (gathered.0, 0),
                "broken bonds, differing states"
            );
            let scale = gathered
                .2
                .iter()
                .map(|t| t.force.iter().map(|f| f.abs()).fold(0.0, f64::max))
                .fold(0.0, f64::max);
            for (p, g) in terms.iter().zip(&gathered.2) {
                for k in 0..3 {
                    assert!((p.force[k] - g.force[k]).abs() <= 1e-12 * scale);
                }
                assert!(
                    (p.energy_density - g.energy_density).abs()
                        <= 1e-12 * g.energy_density.abs().max(1e-30)
                );
                assert!((p.broken_weight - g.broken_weight).abs() <= 1e-12);
            }
            let again = scheme.forces_by_pairs(&plan, &case.positions, &mut intact, &mut terms);
            assert_eq!(again, 0);
        }
    }
}

#[cfg(test)]
mod timing {
    use super::*;
    use crate::discretization::grid::Lattice;
    use crate::model::pmb::{Influence, PmbLaw};
    use crate::scene::Solid;
    use crate::scheme::standard::intact_bonds;

    #[test]
    #[ignore]
    fn time_pairs_against_gather() {
        let side: f64 = std::env::var("SIDE").map_or(46.0, |s| s.parse().unwrap());
        let cube = Solid::Box {
            min: vec![0.0; 3],
            max: vec![side; 3],
        };
        let lattice = Lattice::<3>::build(&cube, 1.0, [0.0, 0.0], 5);
        let families = Families::build(&lattice.positions, 3.0001);
        let law = PmbLaw {
            micromodulus: 1.0,
            critical_stretch: 0.01,
            influence: Influence::Constant,
            horizon: 3.0001,
        };
        let quadrature = Quadrature {
            spacing: 1.0,
            horizon: 3.0001,
            volume_correction: true,
        };
        let positions: Vec<[f64; 3]> = lattice
            .positions
            .iter()
            .map(|x| [x[0], x[1], x[2] * (1.0 + 1e-4)])
            .collect();
        let scheme = Standard {
            reference: &lattice.positions,
            volumes: &lattice.volumes,
            uniform_volume: Some(1.0),
            families: &families,
            law: &law,
            quadrature: &quadrature,
        };
        let mut intact = intact_bonds(families.bond_count());
        let mut terms = vec![NodeTerms::default(); lattice.len()];
        let plan = PairPlan::build(&families, &intact).unwrap();
        eprintln!("blocks {}", plan.block_count());
        for _ in 0..3 {
            let t = std::time::Instant::now();
            for _ in 0..10 {
                scheme.forces(&positions, &mut intact, &mut terms);
            }
            let g = t.elapsed().as_secs_f64();
            let t = std::time::Instant::now();
            for _ in 0..10 {
                scheme.forces_by_pairs(&plan, &positions, &mut intact, &mut terms);
            }
            let p = t.elapsed().as_secs_f64();
            let bonds = 10.0 * families.bond_count() as f64;
            eprintln!("gather {:.3e}/s  pairs {:.3e}/s", bonds / g, bonds / p);
        }
    }
}
