//! The exact bond-stretch check shared by the switching rules of the hybrid (§3.3) and
//! multi-adaptive (§3.5) schemes: criterion (3.80) as f l² − r² ≤ 0 on squared lengths, and
//! the least margin over a node's bonds in SIMD lanes.

use crate::discretization::Families;

#[cfg(target_arch = "x86_64")]
mod avx2;
#[cfg(target_arch = "x86_64")]
mod avx512;

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

/// The bond data a check reads, and whether the CPU runs its lanes 4- or 8-wide.
pub struct BondView<'a, const D: usize> {
    reference: &'a [[f64; D]],
    positions: &'a [[f64; D]],
    pub families: &'a Families,
    #[cfg(target_arch = "x86_64")]
    avx2: bool,
    #[cfg(target_arch = "x86_64")]
    avx512: bool,
    /// The hand-written 2D kernel (`avx512::least_d2`) can run.
    #[cfg(target_arch = "x86_64")]
    kernel_2d: bool,
    /// Without it, the hand-written AVX2 kernel (`avx2::least`, 2D and 3D) can run.
    #[cfg(target_arch = "x86_64")]
    kernel_avx2: bool,
}

impl<'a, const D: usize> BondView<'a, D> {
    pub fn new(
        reference: &'a [[f64; D]],
        positions: &'a [[f64; D]],
        families: &'a Families,
    ) -> Self {
        BondView {
            reference,
            positions,
            families,
            #[cfg(target_arch = "x86_64")]
            avx2: std::arch::is_x86_feature_detected!("avx2"),
            #[cfg(target_arch = "x86_64")]
            avx512: crate::simd::avx512_f_vl(),
            #[cfg(target_arch = "x86_64")]
            kernel_2d: D == 2 && crate::simd::avx512_f_vl(),
            #[cfg(target_arch = "x86_64")]
            kernel_avx2: (D == 2 || D == 3) && crate::simd::avx2(),
        }
    }

    /// The least `measure` over bonds (i, j), j in `neighbors`: the hand-written AVX-512
    /// kernel on 2D scenes where it can run, else the hand-written AVX2 one (2D and 3D), the
    /// compiled lane builds otherwise (the same value in every build: a minimum).
    #[inline(always)]
    pub fn least(&self, i: usize, neighbors: &[u32], measure: Measure) -> f64 {
        #[cfg(target_arch = "x86_64")]
        if self.kernel_2d {
            let (reference, positions) =
                (self.reference.as_flattened(), self.positions.as_flattened());
            // SAFETY: the features were detected in `new` and D is 2.
            return unsafe {
                match measure {
                    Measure::Margin(factor) => {
                        avx512::least_d2::<false>(i, neighbors, reference, positions, factor)
                    }
                    Measure::NegatedSquaredRatio => {
                        avx512::least_d2::<true>(i, neighbors, reference, positions, 0.0)
                    }
                }
            };
        }
        #[cfg(target_arch = "x86_64")]
        if self.kernel_avx2 {
            let (reference, positions) = (self.reference, self.positions);
            // SAFETY: AVX2 was detected in `new` and D is 2 or 3.
            return unsafe {
                match measure {
                    Measure::Margin(factor) => {
                        avx2::least::<D, false>(i, neighbors, reference, positions, factor)
                    }
                    Measure::NegatedSquaredRatio => {
                        avx2::least::<D, true>(i, neighbors, reference, positions, 0.0)
                    }
                }
            };
        }
        match measure {
            Measure::Margin(factor) => {
                self.least_compiled(i, neighbors, move |r2, l2| critical_margin(factor, r2, l2))
            }
            Measure::NegatedSquaredRatio => self.least_compiled(i, neighbors, |r2, l2| -(r2 / l2)),
        }
    }

    /// The least g(r², l²) over bonds (i, j), j in `neighbors`, in the compiled lane builds.
    #[inline(always)]
    fn least_compiled(&self, i: usize, neighbors: &[u32], g: impl Fn(f64, f64) -> f64) -> f64 {
        #[cfg(target_arch = "x86_64")]
        if self.avx512 {
            // SAFETY: the CPU supports AVX-512 F/VL (detected in `new`).
            return unsafe { least_avx512(i, neighbors, self.reference, self.positions, g) };
        }
        #[cfg(target_arch = "x86_64")]
        if self.avx2 {
            // SAFETY: the CPU supports AVX2 (detected in `new`).
            return unsafe { least_avx2(i, neighbors, self.reference, self.positions, g) };
        }
        least_portable::<D, 4>(i, neighbors, self.reference, self.positions, g)
    }
}

/// A build of `least_portable` with `$lanes` lanes, compiled for `$features`.
macro_rules! least_build {
    ($(#[$doc:meta])* $name:ident, $features:literal, $lanes:literal) => {
        $(#[$doc])*
        #[cfg(target_arch = "x86_64")]
        #[target_feature(enable = $features)]
        fn $name<const D: usize>(
            i: usize,
            neighbors: &[u32],
            reference: &[[f64; D]],
            positions: &[[f64; D]],
            g: impl Fn(f64, f64) -> f64,
        ) -> f64 {
            least_portable::<D, $lanes>(i, neighbors, reference, positions, g)
        }
    };
}

least_build!(
    /// `least_portable` with 8 lanes compiled for AVX-512. A minimum does not depend on the
    /// order its values are compared in, so every build returns the same bits.
    least_avx512,
    "avx512f,avx512vl",
    8
);

least_build!(
    /// `least_portable` compiled for AVX2 (4-wide lanes, no FMA: bit-identical results).
    least_avx2,
    "avx,avx2",
    4
);

/// Minimum of g over the bonds in `LANES` independent lanes (a min reduction does not
/// vectorize otherwise); NaN values are ignored, as by `f64::min`.
#[inline(always)]
fn least_portable<const D: usize, const LANES: usize>(
    i: usize,
    neighbors: &[u32],
    reference: &[[f64; D]],
    positions: &[[f64; D]],
    g: impl Fn(f64, f64) -> f64,
) -> f64 {
    let mut lanes = [f64::INFINITY; LANES];
    let chunks = neighbors.chunks_exact(LANES);
    for &j in chunks.remainder() {
        let (r2, l2) = bond_squares(i, j as usize, reference, positions);
        lanes[0] = lesser(lanes[0], g(r2, l2));
    }
    for chunk in chunks {
        for t in 0..LANES {
            let (r2, l2) = bond_squares(i, chunk[t] as usize, reference, positions);
            lanes[t] = lesser(lanes[t], g(r2, l2));
        }
    }
    lanes.into_iter().fold(f64::INFINITY, lesser)
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

    /// Every build (portable 4 lanes, AVX2, AVX-512 8 lanes, the hand-written kernels)
    /// returns the plain minimum over the row, for both measures, in 2D and 3D, on rows whose
    /// lengths are not multiples of the lane count.
    #[test]
    fn least_margin_is_the_rows_minimum_in_every_build() {
        let cube = Solid::Box {
            min: vec![0.0; 3],
            max: vec![7.0; 3],
        };
        let lattice = Lattice::<3>::build(&cube, 1.0, [-0.2, 0.2], 3);
        let positions: Vec<[f64; 3]> = lattice
            .positions
            .iter()
            .map(|x| {
                [
                    x[0] * (1.0 + 0.01 * x[1].sin()),
                    x[1],
                    x[2] + 1e-3 * x[0] * x[0],
                ]
            })
            .collect();
        assert_rows_minimum(&lattice.positions, &positions, 2.6);
        let square = Solid::Box {
            min: vec![0.0; 2],
            max: vec![15.0; 2],
        };
        let plane = Lattice::<2>::build(&square, 1.0, [-0.2, 0.2], 5);
        let positions: Vec<[f64; 2]> = plane
            .positions
            .iter()
            .map(|x| [x[0] * (1.0 + 0.01 * x[1].sin()), x[1] + 1e-3 * x[0] * x[0]])
            .collect();
        assert_rows_minimum(&plane.positions, &positions, 4.3);
    }

    fn assert_rows_minimum<const D: usize>(
        reference: &[[f64; D]],
        positions: &[[f64; D]],
        horizon: f64,
    ) {
        let families = Families::build(reference, horizon);
        let view = BondView::new(reference, positions, &families);
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
                assert_eq!(view.least(i, row, measure), plain);
                let g = |r2, l2| measure.of(r2, l2);
                assert_eq!(view.least_compiled(i, row, g), plain);
                assert_eq!(
                    least_portable::<D, 4>(i, row, reference, positions, g),
                    plain
                );
                assert_eq!(
                    least_portable::<D, 8>(i, row, reference, positions, g),
                    plain
                );
            }
        }
        assert!(unaligned > 0);
    }
}
