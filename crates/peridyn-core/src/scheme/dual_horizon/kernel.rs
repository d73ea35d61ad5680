//! The direct bonds' loop of the force pass (zeng2024 (5), (9)–(13)) written once over the
//! project's lanes (`crate::simd`): a particle's row H_k is taken N bonds at a time, the
//! neighbours' positions gathered, and each bond's kinematics, break test, θ term, force and
//! distortional energy computed lane by lane with the scalar code's IEEE operations in its
//! order. The row sums (θ_k, Σ F_kj, the distortion energy, the lost volume) are then added
//! lane after lane in bond order, so every lane count (1, 4 or 8) gives the bits of the one-bond
//! loop: the results do not depend on the CPU. A broken bond's lane adds +0, which leaves a
//! sum started at +0 unchanged (a sum of finite terms started at +0 is never −0).
//!
//! The bonds' columns are struct-of-arrays in row order (neighbour, μ, |ξ|, ω_θ, ω_b), the
//! constants per particle (its own horizon δ_k; the bond formulas are `OsbHorizon`'s). The
//! first loop's kinematics are kept on the stack for the second where a row has at most 128
//! bonds; a longer row's second loop computes them again.

use crate::model::osb::OsbHorizon;
use crate::simd::{LaneLoop, Lanes};

use super::{Body, ParticleTerms, RowSlots};

/// Particles per task of the force pass.
pub(super) const ROWS_PER_TASK: usize = 128;

/// One task's particles `first..first + terms.len()` of the direct bonds' loop, for
/// `Simd::run`: breaks, θ_k, the direct forces (stored at their reaction slots), the energy
/// density and the row's part of the lost volume. Returns the bonds broken now.
pub(super) struct RowPass<'a> {
    pub first: usize,
    pub terms: &'a mut [ParticleTerms],
    pub body: &'a Body<'a>,
    /// Deformed positions, two values per particle.
    pub positions: &'a [f64],
    pub starts: &'a [usize],
    pub ends: &'a [usize],
    pub neighbors: &'a [u32],
    pub lengths: &'a [f64],
    pub weight_theta: &'a [f64],
    pub weight_distortion: &'a [f64],
    pub reaction_slot: &'a [u32],
    pub criteria: &'a [f64],
    pub intact: &'a RowSlots<u8>,
    pub reactions: &'a RowSlots<[f64; 2]>,
}

impl LaneLoop for RowPass<'_> {
    type Output = u64;

    #[inline(always)]
    fn run<L: Lanes>(self) -> u64 {
        let reference = self.body.reference.as_flattened();
        let particles = self.body.reference.len();
        assert_eq!(self.positions.len(), reference.len());
        let mut broken = 0;
        let mut kept = KeptKinematics::default();
        for (offset, t) in self.terms.iter_mut().enumerate() {
            let k = self.first + offset;
            let row = self.starts[k]..self.ends[k];
            let count = row.len();
            let blocked = count / L::N * L::N;
            // The columns up to the end of the row's last block where they reach that far:
            // the last block (fewer than N bonds) then reads its columns in place, the lanes
            // past the row masked by its states (copied, zero past the row); at the columns'
            // end it is copied into a padded block.
            let reach = (row.start + count.div_ceil(L::N) * L::N).min(self.neighbors.len());
            let columns = row.start..reach;
            let neighbors = &self.neighbors[columns.clone()];
            // Every neighbour is a particle (checked once per row: the gathers do not check).
            assert!(neighbors.iter().all(|&j| (j as usize) < particles));
            let bonds = Row {
                reference,
                positions: self.positions,
                x_k: self.body.reference[k],
                y_k: [self.positions[2 * k], self.positions[2 * k + 1]],
                neighbors,
                lengths: &self.lengths[columns.clone()],
                weight_theta: &self.weight_theta[columns.clone()],
                weight_distortion: &self.weight_distortion[columns],
                constants: &self.body.constants[k],
                first: 0,
                count,
            };
            // SAFETY: row k's slots belong to row k alone (rows are disjoint, `RowSlots`),
            // and this task is the only one visiting row k.
            let states = unsafe { self.intact.slice_mut(row.clone()) };
            let padded;
            let (tail, tail_at) = if reach - row.start >= blocked + L::N || count == blocked {
                (&bonds, blocked)
            } else {
                padded = Padded::of(&bonds, blocked, k as u32);
                (&bonds.over(&padded, blocked), 0)
            };
            let mut tail_states = [0; 8];
            for (tail, state) in tail_states.iter_mut().zip(&states[blocked..]) {
                *tail = *state;
            }
            let tail_states = &mut tail_states[..L::N];
            let mut theta = 0.0;
            // The first loop's kinematics kept for the second where the row fits.
            let mut keep = (count + 8 <= KEPT).then_some(&mut kept);
            // SAFETY (the gathers of both loops): the neighbours were checked above, the
            // padding is particle k.
            for at in (0..blocked).step_by(L::N) {
                let states = &mut states[at..at + L::N];
                broken += unsafe { bonds.dilatation::<L>(at, states, &mut theta, &mut keep) };
            }
            if count > blocked {
                broken +=
                    unsafe { tail.dilatation::<L>(tail_at, tail_states, &mut theta, &mut keep) };
                states[blocked..].copy_from_slice(&tail_states[..count - blocked]);
            }
            let gated = self.criteria.get(k).is_some_and(|g| g.is_finite());
            let mut sums = ForceSums {
                volume: self.body.volumes[k],
                theta,
                lost: gated.then_some(0.0),
                ..ForceSums::default()
            };
            let slots = &self.reaction_slot[row];
            // SAFETY: the reaction slots of row k's bonds are written by this task alone (each
            // slot's entry in the dual lists belongs to one bond).
            let mut react =
                |b: usize, f: [f64; 2]| unsafe { self.reactions.write(slots[b] as usize, f) };
            let volumes = self.body.volumes;
            let kept = keep.as_deref();
            for at in (0..blocked).step_by(L::N) {
                let states = &states[at..at + L::N];
                unsafe { bonds.forces::<L>(at, states, volumes, kept, &mut sums, &mut react) };
            }
            if count > blocked {
                let states = &*tail_states;
                unsafe { tail.forces::<L>(tail_at, states, volumes, kept, &mut sums, &mut react) };
            }
            t.dilatation = theta;
            t.force = sums.force;
            t.energy_density = bonds.constants.a * theta * theta + sums.distortion;
            // The row's part of the lost volume (15), finished by the reactions' pass.
            t.damage = sums.lost.unwrap_or(0.0);
        }
        broken
    }
}

/// Bonds per row (padding included) whose kinematics the first loop keeps for the second;
/// a longer row's second loop computes them again.
const KEPT: usize = 136;

/// A row's kinematics in bond order: η (two columns), 1/|η|, stretch, cosine, 1/|ξ|.
struct KeptKinematics {
    columns: [[f64; KEPT]; 6],
}

impl Default for KeptKinematics {
    fn default() -> KeptKinematics {
        KeptKinematics {
            columns: [[0.0; KEPT]; 6],
        }
    }
}

impl KeptKinematics {
    #[inline(always)]
    fn store<L: Lanes>(&mut self, at: usize, k: &Kinematics<L>) {
        let [eta_x, eta_y, inverse_l, stretch, cosine, inverse_l0] = &mut self.columns;
        k.eta[0].store(&mut eta_x[at..]);
        k.eta[1].store(&mut eta_y[at..]);
        k.inverse_l.store(&mut inverse_l[at..]);
        k.stretch.store(&mut stretch[at..]);
        k.cosine.store(&mut cosine[at..]);
        k.inverse_l0.store(&mut inverse_l0[at..]);
    }

    #[inline(always)]
    fn load<L: Lanes>(&self, at: usize) -> Kinematics<L> {
        let [eta_x, eta_y, inverse_l, stretch, cosine, inverse_l0] = &self.columns;
        Kinematics {
            eta: [L::load(&eta_x[at..]), L::load(&eta_y[at..])],
            inverse_l: L::load(&inverse_l[at..]),
            stretch: L::load(&stretch[at..]),
            cosine: L::load(&cosine[at..]),
            inverse_l0: L::load(&inverse_l0[at..]),
        }
    }
}

/// What the force loop sums over a row, in bond order.
#[derive(Default)]
struct ForceSums {
    /// V_k.
    volume: f64,
    /// θ_k of the row (read).
    theta: f64,
    force: [f64; 2],
    /// Σ b δ s² |ξ| ω_b.
    distortion: f64,
    /// Σ V_j over the row's broken bonds, where the particle's damage is wanted.
    lost: Option<f64>,
}

/// One particle's row: its bonds' columns and the positions they read.
struct Row<'a> {
    reference: &'a [f64],
    positions: &'a [f64],
    x_k: [f64; 2],
    y_k: [f64; 2],
    neighbors: &'a [u32],
    lengths: &'a [f64],
    weight_theta: &'a [f64],
    weight_distortion: &'a [f64],
    constants: &'a OsbHorizon,
    /// Where these columns start in the particle's row (the padded block: its first bond).
    first: usize,
    /// Bonds in these columns (the padded block: before the padding).
    count: usize,
}

/// A row's bonds from `first` on (fewer than 8) in blocks of 8 with padding: the particle
/// itself as the neighbour, |ξ| = 1, weights 0 and μ = 0, so the lane loops treat the padding
/// as broken bonds (they add +0 and break nothing).
struct Padded {
    neighbors: [u32; 8],
    lengths: [f64; 8],
    weight_theta: [f64; 8],
    weight_distortion: [f64; 8],
    count: usize,
}

impl Padded {
    fn of(row: &Row, first: usize, particle: u32) -> Padded {
        let pad = |column: &[f64], with: f64| {
            let mut block = [with; 8];
            block[..row.count - first].copy_from_slice(&column[first..row.count]);
            block
        };
        let mut neighbors = [particle; 8];
        neighbors[..row.count - first].copy_from_slice(&row.neighbors[first..row.count]);
        Padded {
            neighbors,
            lengths: pad(row.lengths, 1.0),
            weight_theta: pad(row.weight_theta, 0.0),
            weight_distortion: pad(row.weight_distortion, 0.0),
            count: row.count - first,
        }
    }
}

/// Bonds `at..at + N` of a row, as lanes.
struct Kinematics<L> {
    /// η = y_j − y_k.
    eta: [L; 2],
    /// 1/|η|.
    inverse_l: L,
    stretch: L,
    /// ξ·η / (|ξ| |η|).
    cosine: L,
    /// 1/|ξ|.
    inverse_l0: L,
}

impl Row<'_> {
    /// The padded block `padded` of this row (its bonds from `first` on) as a row.
    fn over<'b>(&self, padded: &'b Padded, first: usize) -> Row<'b>
    where
        Self: 'b,
    {
        Row {
            neighbors: &padded.neighbors,
            lengths: &padded.lengths,
            weight_theta: &padded.weight_theta,
            weight_distortion: &padded.weight_distortion,
            first,
            count: padded.count,
            ..*self
        }
    }

    /// Bonds `at..at + N`'s kinematics (gathers of both positions, one square root and one
    /// division per bond).
    ///
    /// # Safety
    /// The row's neighbours are particles of `reference` and `positions`.
    #[inline(always)]
    unsafe fn kinematics<L: Lanes>(&self, at: usize) -> Kinematics<L> {
        let nodes = &self.neighbors[at..at + L::N];
        // SAFETY: the caller guarantees the indices.
        let (x_j, y_j) = unsafe {
            (
                L::gather2(self.reference, nodes),
                L::gather2(self.positions, nodes),
            )
        };
        let xi: [L; 2] = std::array::from_fn(|i| x_j[i] - L::splat(self.x_k[i]));
        let eta: [L; 2] = std::array::from_fn(|i| y_j[i] - L::splat(self.y_k[i]));
        let l = (eta[0] * eta[0] + eta[1] * eta[1]).sqrt();
        let l0 = L::load(&self.lengths[at..]);
        let inverse = L::splat(1.0) / (l * l0);
        let (inverse_l, inverse_l0) = (l0 * inverse, l * inverse);
        Kinematics {
            eta,
            inverse_l,
            stretch: (l - l0) * inverse_l0,
            cosine: (xi[0] * eta[0] + xi[1] * eta[1]) * inverse,
            inverse_l0,
        }
    }

    /// The first loop on bonds `at..at + N`: every intact bond whose stretch reaches s_c
    /// breaks (irreversible, μ = 0 in `states`, the block's N states), the others add their θ term d δ Λ s ω_θ (5)
    /// to `theta` in bond order. Returns the bonds broken now.
    ///
    /// # Safety
    /// As `kinematics`.
    #[inline(always)]
    unsafe fn dilatation<L: Lanes>(
        &self,
        at: usize,
        states: &mut [u8],
        theta: &mut f64,
        keep: &mut Option<&mut KeptKinematics>,
    ) -> u64 {
        let c = &self.constants;
        // SAFETY: as the caller's.
        let k = unsafe { self.kinematics::<L>(at) };
        if let Some(kept) = keep {
            kept.store(self.first + at, &k);
        }
        let intact = L::nonzero(states);
        let keep = L::and(intact, k.stretch.lt(L::splat(c.critical_stretch)));
        let (intact, kept) = (L::bits(intact), L::bits(keep));
        let mut broken = 0;
        if intact != kept {
            for (l, state) in states.iter_mut().enumerate() {
                if (intact & !kept) >> l & 1 == 1 {
                    *state = 0;
                    broken += 1;
                }
            }
        }
        let term = c.dilatation_term(k.cosine, k.stretch, L::load(&self.weight_theta[at..]));
        *theta = term.zero_unless(keep).fold(*theta, |sum, x| sum + x);
        broken
    }

    /// The second loop on bonds `at..at + N`: each intact bond's force F_kj (9)–(13), which
    /// depends on k's state only, handed to `react` (zero for a broken bond), and the row's
    /// sums in bond order: Σ F_kj, the distortional energy (4) and, where it is wanted, the
    /// lost volume Σ V_j of the broken bonds.
    ///
    /// # Safety
    /// As `kinematics`.
    #[inline(always)]
    unsafe fn forces<L: Lanes>(
        &self,
        at: usize,
        states: &[u8],
        volumes: &[f64],
        kept: Option<&KeptKinematics>,
        sums: &mut ForceSums,
        react: &mut impl FnMut(usize, [f64; 2]),
    ) {
        let c = &self.constants;
        let k = match kept {
            Some(kept) => kept.load(self.first + at),
            // SAFETY: as the caller's.
            None => unsafe { self.kinematics::<L>(at) },
        };
        let live = L::nonzero(states);
        let (weight_theta, weight_distortion, l0) = (
            L::load(&self.weight_theta[at..]),
            L::load(&self.weight_distortion[at..]),
            L::load(&self.lengths[at..]),
        );
        let scalar = c.bond_scalar(
            L::splat(sums.theta),
            k.cosine,
            k.stretch,
            k.inverse_l0,
            weight_theta,
            weight_distortion,
        ) * L::splat(sums.volume)
            * k.inverse_l;
        let mut f = [[0.0; 8]; 2];
        (scalar * k.eta[0]).zero_unless(live).store(&mut f[0]);
        (scalar * k.eta[1]).zero_unless(live).store(&mut f[1]);
        let energy = c.distortion_energy(k.stretch, l0, weight_distortion);
        sums.distortion = energy
            .zero_unless(live)
            .fold(sums.distortion, |sum, x| sum + x);
        let lanes = L::N.min(self.count - at);
        for (l, (&x, &y)) in f[0][..lanes].iter().zip(&f[1][..lanes]).enumerate() {
            sums.force[0] += x;
            sums.force[1] += y;
            react(self.first + at + l, [x, y]);
        }
        if let Some(lost) = &mut sums.lost {
            let live = L::bits(live);
            for l in 0..lanes {
                if live >> l & 1 == 0 {
                    *lost += volumes[self.neighbors[at + l] as usize];
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::super::{BondWeights, DualBonds};
    use super::*;
    use crate::discretization::buckets::Buckets;
    use crate::model::osb::OsbMaterial;
    use crate::model::pmb::Plane;
    use crate::simd::{Portable, Simd};

    /// The force pass on every lane implementation this CPU runs gives the one-bond loop's
    /// bits: forces, θ, energy densities, damage, strains, bond states and reactions, over two
    /// passes (bonds broken in the first are skipped in the second). Two horizons meet
    /// (δ = 3.015 and 7.3 spacings: rows of 28 and of about 165 bonds, longer than the rows
    /// whose kinematics are kept), every row length mod 8 occurs, a third of the particles
    /// cannot split and the rest have their damage and strains computed.
    #[test]
    fn every_lane_count_gives_the_one_bond_loops_bits() {
        let material = OsbMaterial {
            youngs_modulus: 1.0,
            poisson_ratio: 0.25,
            plane: Plane::Stress,
            thickness: 1.0,
            // s_c ≈ 0.009 at δ = 3.015, 0.006 at 7.3: the perturbation breaks some bonds.
            fracture_energy: Some(2e-4),
        };
        let n = 26;
        let x: Vec<[f64; 2]> = (0..n * n)
            .map(|k| [(k % n) as f64, (k / n) as f64])
            .collect();
        let volumes = vec![1.0; x.len()];
        let constants: Vec<_> = x
            .iter()
            .map(|p| material.at(if p[0] < 13.0 { 3.015 } else { 7.3 }))
            .collect();
        let body = Body {
            reference: &x,
            volumes: &volumes,
            constants: &constants,
            thickness: 1.0,
        };
        let mut seed = 0x9e37_79b9_7f4a_7c15_u64;
        let mut noise = move || {
            seed = seed.wrapping_mul(6_364_136_223_846_793_005).wrapping_add(1);
            (seed >> 11) as f64 / (1u64 << 53) as f64 - 0.5
        };
        let positions: Vec<[f64; 2]> = x
            .iter()
            .map(|p| [p[0] * 1.004 + 0.03 * noise(), p[1] + 0.03 * noise()])
            .collect();
        let mut bonds = DualBonds::build(&body, &Buckets::new(&x, 7.4, 0.0), BondWeights::Volume);
        bonds.criteria = (0..x.len())
            .map(|k| if k % 3 == 0 { f64::INFINITY } else { 0.0 })
            .collect();
        let lengths: std::collections::BTreeSet<usize> =
            (0..x.len()).map(|k| bonds.range(k).len() % 8).collect();
        assert_eq!(lengths.len(), 8, "row lengths mod 8: {lengths:?}");
        assert!((0..x.len()).any(|k| bonds.range(k).len() + 8 > KEPT));
        let passes = |bonds: &mut DualBonds, simd: Option<Simd>| {
            let mut out = Vec::new();
            for _ in 0..2 {
                let mut terms = vec![ParticleTerms::default(); x.len()];
                let broken =
                    bonds.evaluate_with(&body, &positions, &mut terms, |rows| match simd {
                        Some(simd) => simd.run(rows),
                        None => rows.run::<Portable<1>>(),
                    });
                out.push(broken.to_string());
                out.extend(terms.iter().map(|t| {
                    let values = [t.force[0], t.force[1], t.dilatation, t.energy_density];
                    let more = [t.damage, t.strains[0], t.strains[1]];
                    format!(
                        "{:x?}",
                        values
                            .iter()
                            .chain(&more)
                            .map(|v| v.to_bits())
                            .collect::<Vec<_>>()
                    )
                }));
            }
            out.push(format!("{:?}", bonds.intact));
            out.push(format!(
                "{:x?}",
                bonds
                    .reactions
                    .iter()
                    .map(|f| f.map(f64::to_bits))
                    .collect::<Vec<_>>()
            ));
            out
        };
        let one_lane = passes(&mut bonds.clone(), None);
        let broken: u64 = one_lane[0].parse().unwrap();
        let total = bonds.bond_count() as u64;
        assert!(
            broken > total / 50 && broken < total / 2,
            "{broken} of {total} broke"
        );
        for simd in Simd::supported() {
            let lanes = passes(&mut bonds.clone(), Some(simd));
            let first = lanes.iter().zip(&one_lane).position(|(a, b)| a != b);
            assert_eq!(
                first,
                None,
                "{}: first difference at entry {first:?}",
                simd.name()
            );
        }
    }
}
