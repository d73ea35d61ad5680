//! The exact bond-stretch check shared by the switching rules of the hybrid (§3.3) and
//! multi-adaptive (§3.5) schemes: criterion (3.80) as f l² − r² ≤ 0 on squared lengths, and
//! the least margin over a node's bonds, written once over the lanes of `simd`.

use crate::discretization::Families;
use crate::simd::{LaneLoop, Lanes, Portable, Simd};

/// What a scan minimizes over a node's bonds, from r² and l² (a bond's squared current and
/// reference lengths).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Measure {
    /// f l² − r² (`critical_margin`): ≤ 0 where the bond is critical at the factor f.
    Margin(f64),
    /// −r²/l²: the least is minus the largest squared stretch ratio.
    NegatedSquaredRatio,
}

impl Measure {
    #[inline(always)]
    pub fn of(self, r2: f64, l2: f64) -> f64 {
        match self {
            Measure::Margin(factor) => critical_margin(factor, r2, l2),
            Measure::NegatedSquaredRatio => -(r2 / l2),
        }
    }
}

/// The bond data a check reads, and the lanes it runs on.
pub struct BondView<'a, const D: usize> {
    reference: &'a [[f64; D]],
    positions: &'a [[f64; D]],
    pub families: &'a Families,
    simd: Simd,
}

impl<'a, const D: usize> BondView<'a, D> {
    pub fn new(
        reference: &'a [[f64; D]],
        positions: &'a [[f64; D]],
        families: &'a Families,
    ) -> Self {
        assert_eq!(reference.len(), positions.len());
        BondView {
            reference,
            positions,
            families,
            simd: Simd::selected(),
        }
    }

    /// The least `measure` over bonds (i, j), j in `neighbors` (the same value on every
    /// lane implementation: a minimum).
    #[inline(always)]
    pub fn least(&self, i: usize, neighbors: &[u32], measure: Measure) -> f64 {
        self.least_on(self.simd, i, neighbors, measure)
    }

    /// `least` on the lanes of `simd`.
    fn least_on(&self, simd: Simd, i: usize, neighbors: &[u32], measure: Measure) -> f64 {
        let (reference, positions) = (self.reference, self.positions);
        match measure {
            Measure::Margin(factor) => simd.run(Scan::<D, false> {
                i,
                neighbors,
                reference,
                positions,
                factor,
            }),
            Measure::NegatedSquaredRatio => simd.run(Scan::<D, true> {
                i,
                neighbors,
                reference,
                positions,
                factor: 0.0,
            }),
        }
    }
}

/// The least of f l² − r² (`NEGATED_RATIO` false, f = `factor`) or of −r²/l² (true) over the
/// bonds (i, j), j in `neighbors`: N bonds at a time in N independent lanes (a min reduction
/// does not vectorize otherwise), the remainder one at a time. NaN values are ignored, as by
/// `lesser`.
struct Scan<'a, const D: usize, const NEGATED_RATIO: bool> {
    i: usize,
    neighbors: &'a [u32],
    reference: &'a [[f64; D]],
    positions: &'a [[f64; D]],
    factor: f64,
}

impl<const D: usize, const NEGATED_RATIO: bool> LaneLoop for Scan<'_, D, NEGATED_RATIO> {
    type Output = f64;

    #[inline(always)]
    fn run<L: Lanes>(self) -> f64 {
        let node_count = self.positions.len();
        // Every neighbour is a node (checked once per row: the gathers do not check).
        let last = self.neighbors.iter().copied().max().unwrap_or(0) as usize;
        assert!(self.i < node_count && (self.neighbors.is_empty() || last < node_count));
        let mut least = L::splat(f64::INFINITY);
        let chunks = self.neighbors.chunks_exact(L::N);
        let tail = chunks.remainder();
        for nodes in chunks {
            // SAFETY: the indices were checked above.
            least = unsafe { self.measure::<L>(nodes) }.min(least);
        }
        tail.chunks(1)
            .fold(least.fold(f64::INFINITY, lesser), |a, node| {
                // SAFETY: the index was checked above.
                lesser(a, unsafe { self.measure::<Portable<1>>(node) }.0[0])
            })
    }
}

impl<const D: usize, const NEGATED_RATIO: bool> Scan<'_, D, NEGATED_RATIO> {
    /// The measure of the N bonds to `nodes`, r² and l² formed as `bond_squares` forms them.
    ///
    /// # Safety
    /// Every index in `nodes` is a node.
    #[inline(always)]
    unsafe fn measure<L: Lanes>(&self, nodes: &[u32]) -> L {
        let (x, y) = (self.reference[self.i], self.positions[self.i]);
        // SAFETY: the caller guarantees the indices.
        let (p, q) = unsafe {
            (
                L::gather::<D>(self.reference.as_flattened(), nodes),
                L::gather::<D>(self.positions.as_flattened(), nodes),
            )
        };
        let (mut l2, mut r2) = (L::zero(), L::zero());
        for k in 0..D {
            let (dx, dy) = (p[k] - L::splat(x[k]), q[k] - L::splat(y[k]));
            // 0 + d² = d² for d² ≥ 0: the first axis as `bond_squares` adds it.
            (l2, r2) = if k == 0 {
                (dx * dx, dy * dy)
            } else {
                (l2 + dx * dx, r2 + dy * dy)
            };
        }
        if NEGATED_RATIO {
            -(r2 / l2)
        } else {
            L::splat(self.factor) * l2 - r2
        }
    }
}

/// min(a, v) for a non-NaN a, ignoring a NaN v; branch-free (a SIMD min).
#[inline(always)]
fn lesser(a: f64, v: f64) -> f64 {
    if v < a { v } else { a }
}

/// The bond criterion (3.80) for every check path: a bond is critical when f l² − r² ≤ 0,
/// i.e. r² ≥ (1 + χ s0)² l² (the rounded difference has the exact difference's sign).
#[inline(always)]
pub fn critical_margin(factor: f64, r2: f64, l2: f64) -> f64 {
    factor * l2 - r2
}

/// Squared current and reference lengths of bond (i, j).
#[inline(always)]
pub fn bond_squares<const D: usize>(
    i: usize,
    j: usize,
    reference: &[[f64; D]],
    positions: &[[f64; D]],
) -> (f64, f64) {
    (0..D).fold((0.0, 0.0), |(r2, l2), k| {
        let (dy, dx) = (
            positions[j][k] - positions[i][k],
            reference[j][k] - reference[i][k],
        );
        (r2 + dy * dy, l2 + dx * dx)
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::discretization::grid::Lattice;
    use crate::scene::Solid;

    /// Every lane implementation this CPU runs (portable at 4 and 8 lanes, AVX2, AVX-512)
    /// returns the portable scan's bits, the plain minimum over the row, for both measures,
    /// in 1D, 2D and 3D, on rows whose lengths are not multiples of the lane count.
    #[test]
    fn least_margin_is_the_rows_minimum_on_every_implementation() {
        let (reference, positions) = deformed::<3>(7.0, 3, |x| {
            [
                x[0] * (1.0 + 0.01 * x[1].sin()),
                x[1],
                x[2] + 1e-3 * x[0] * x[0],
            ]
        });
        assert_rows_minimum(&reference, &positions, 2.6);
        let (reference, positions) = deformed::<2>(15.0, 5, |x| {
            [x[0] * (1.0 + 0.01 * x[1].sin()), x[1] + 1e-3 * x[0] * x[0]]
        });
        assert_rows_minimum(&reference, &positions, 4.3);
        let (reference, positions) =
            deformed::<1>(80.0, 7, |x| [x[0] * (1.0 + 0.01 * (0.3 * x[0]).sin())]);
        assert_rows_minimum(&reference, &positions, 4.3);
    }

    /// A unit lattice on a cube of side `side`, perturbed (seeded), and its image under
    /// `deform`.
    fn deformed<const D: usize>(
        side: f64,
        seed: u64,
        deform: impl Fn([f64; D]) -> [f64; D],
    ) -> (Vec<[f64; D]>, Vec<[f64; D]>) {
        let solid = Solid::Box {
            min: vec![0.0; D],
            max: vec![side; D],
        };
        let reference = Lattice::<D>::build(&solid, 1.0, [-0.2, 0.2], seed).positions;
        let positions = reference.iter().map(|&x| deform(x)).collect();
        (reference, positions)
    }

    fn assert_rows_minimum<const D: usize>(
        reference: &[[f64; D]],
        positions: &[[f64; D]],
        horizon: f64,
    ) {
        let families = Families::build(reference, horizon);
        let view = BondView::new(reference, positions, &families);
        let supported = Simd::supported();
        assert!(supported.contains(&Simd::Portable) && supported.contains(&Simd::Portable8));
        let mut unaligned = 0;
        for measure in [
            Measure::Margin(1.0 + 0.5 * 0.01),
            Measure::NegatedSquaredRatio,
        ] {
            for i in 0..reference.len() {
                let row = &families.neighbors[families.range(i)];
                unaligned += usize::from(!row.len().is_multiple_of(8));
                let plain = row
                    .iter()
                    .map(|&j| {
                        let (r2, l2) = bond_squares(i, j as usize, reference, positions);
                        measure.of(r2, l2)
                    })
                    .fold(f64::INFINITY, f64::min);
                let portable = view.least_on(Simd::Portable, i, row, measure);
                assert_eq!(portable, plain);
                assert_eq!(view.least(i, row, measure).to_bits(), portable.to_bits());
                for &simd in &supported {
                    let least = view.least_on(simd, i, row, measure);
                    assert_eq!(least.to_bits(), portable.to_bits(), "{simd:?}, row {i}");
                }
            }
        }
        assert!(unaligned > 0);
    }
}
