//! The least-measure scan of `BondView::least` in 2D and 3D on machines without AVX-512,
//! written with AVX2 intrinsics: 4 bonds per iteration, each neighbour's reference and
//! current position gathered by `simd::gather4` into one vector per axis. The compiled
//! 4-lane build assembles each lane with scalar loads and bounds checks.
//!
//! r² and l² are formed as `bond_squares` forms them and the minimum is exact, so the result
//! is the portable scan's bit for bit (`least_margin_is_the_rows_minimum_in_every_build`).

use std::arch::x86_64::*;

use super::{Measure, bond_squares, lesser};
use crate::simd::{gather4, lanes4};

const LANES: usize = 4;

/// The least of f l² − r² (`NEGATED_RATIO` false, f = `factor`) or of −r²/l² (true) over
/// the bonds (i, j), j in `neighbors`.
///
/// # Safety
/// AVX2 is available and `D` is 2 or 3.
#[target_feature(enable = "avx2")]
pub(super) unsafe fn least<const D: usize, const NEGATED_RATIO: bool>(
    i: usize,
    neighbors: &[u32],
    reference: &[[f64; D]],
    positions: &[[f64; D]],
    factor: f64,
) -> f64 {
    let node_count = positions.len();
    assert_eq!(reference.len(), node_count);
    // Every neighbour index is a node (checked once per row, not per lane and array).
    let last = neighbors.iter().copied().max().unwrap_or(0) as usize;
    assert!(i < node_count && (neighbors.is_empty() || last < node_count));
    let (flat_reference, flat_positions) = (reference.as_flattened(), positions.as_flattened());
    let x: [__m256d; D] = std::array::from_fn(|k| _mm256_set1_pd(reference[i][k]));
    let y: [__m256d; D] = std::array::from_fn(|k| _mm256_set1_pd(positions[i][k]));
    let f = _mm256_set1_pd(factor);
    let sign = _mm256_set1_pd(-0.0);
    let mut least = _mm256_set1_pd(f64::INFINITY);
    let chunks = neighbors.chunks_exact(LANES);
    let tail = chunks.remainder();
    for chunk in chunks {
        // SAFETY: the feature is enabled here and the indices were checked above.
        let (p, q) = unsafe {
            (
                gather4::<D>(flat_reference, chunk),
                gather4::<D>(flat_positions, chunk),
            )
        };
        let (mut l2, mut r2) = (_mm256_setzero_pd(), _mm256_setzero_pd());
        for k in 0..D {
            let (dx, dy) = (_mm256_sub_pd(p[k], x[k]), _mm256_sub_pd(q[k], y[k]));
            let (dx2, dy2) = (_mm256_mul_pd(dx, dx), _mm256_mul_pd(dy, dy));
            // 0 + d² = d² for d² ≥ 0: the first axis as `bond_squares` adds it.
            (l2, r2) = if k == 0 {
                (dx2, dy2)
            } else {
                (_mm256_add_pd(l2, dx2), _mm256_add_pd(r2, dy2))
            };
        }
        let measure = if NEGATED_RATIO {
            _mm256_xor_pd(_mm256_div_pd(r2, l2), sign)
        } else {
            _mm256_sub_pd(_mm256_mul_pd(f, l2), r2)
        };
        // `lesser`: the new value where it is below, NaN ignored.
        least = _mm256_min_pd(measure, least);
    }
    let measure = if NEGATED_RATIO {
        Measure::NegatedSquaredRatio
    } else {
        Measure::Margin(factor)
    };
    tail.iter().fold(
        lanes4(least).into_iter().fold(f64::INFINITY, lesser),
        |a, &j| {
            let (r2, l2) = bond_squares(i, j as usize, reference, positions);
            lesser(a, measure.of(r2, l2))
        },
    )
}
