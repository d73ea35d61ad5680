//! The least-measure scan of `BondView::least` on 2D scenes, written with AVX-512
//! intrinsics: 8 bonds per iteration, each neighbour's reference and current position read
//! with one 2-lane load apiece and transposed into x and y vectors (3 inserts and 2 permutes
//! per 8 neighbours and array). The compiled 8-lane build spends about twice the
//! instructions: a bounds check per lane and array, and scalar lane assembly.
//!
//! r² and l² are formed as `bond_squares` forms them and the minimum is exact, so the result
//! is the portable scan's bit for bit (`least_margin_is_the_rows_minimum_in_every_build`).

use std::arch::x86_64::*;

use super::{Measure, bond_squares, lesser};

/// AVX-512 F and VL.
pub(super) fn available() -> bool {
    std::arch::is_x86_feature_detected!("avx512f")
        && std::arch::is_x86_feature_detected!("avx512vl")
}

const LANES: usize = 8;

/// The least of f l² − r² (`NEGATED_RATIO` false, f = `factor`) or of −r²/l² (true) over
/// the bonds (i, j), j in `neighbors`; `reference` and `positions` hold 2 doubles per node.
///
/// Safety: AVX-512 F/VL are available (`available()`).
#[target_feature(enable = "avx512f,avx512vl")]
pub(super) unsafe fn least_d2<const NEGATED_RATIO: bool>(
    i: usize,
    neighbors: &[u32],
    reference: &[f64],
    positions: &[f64],
    factor: f64,
) -> f64 {
    let node_count = positions.len() / 2;
    assert_eq!(reference.len(), positions.len());
    // Every neighbour index is a node (checked once per row, not per lane and array).
    let last = neighbors.iter().copied().max().unwrap_or(0) as usize;
    assert!(i < node_count && (neighbors.is_empty() || last < node_count));
    let (ref_x, ref_y) = (
        _mm512_set1_pd(reference[2 * i]),
        _mm512_set1_pd(reference[2 * i + 1]),
    );
    let (pos_x, pos_y) = (
        _mm512_set1_pd(positions[2 * i]),
        _mm512_set1_pd(positions[2 * i + 1]),
    );
    let f = _mm512_set1_pd(factor);
    let sign = _mm512_castpd_si512(_mm512_set1_pd(-0.0));
    let mut least = _mm512_set1_pd(f64::INFINITY);
    let chunks = neighbors.chunks_exact(LANES);
    let tail = chunks.remainder();
    for chunk in chunks {
        // SAFETY: the indices were checked above.
        let ((x, y), (u, v)) = unsafe { (pairs(reference, chunk), pairs(positions, chunk)) };
        let (dx, dy) = (_mm512_sub_pd(x, ref_x), _mm512_sub_pd(y, ref_y));
        let (ex, ey) = (_mm512_sub_pd(u, pos_x), _mm512_sub_pd(v, pos_y));
        let l2 = _mm512_add_pd(_mm512_mul_pd(dx, dx), _mm512_mul_pd(dy, dy));
        let r2 = _mm512_add_pd(_mm512_mul_pd(ex, ex), _mm512_mul_pd(ey, ey));
        let measure = if NEGATED_RATIO {
            _mm512_castsi512_pd(_mm512_xor_si512(
                _mm512_castpd_si512(_mm512_div_pd(r2, l2)),
                sign,
            ))
        } else {
            _mm512_sub_pd(_mm512_mul_pd(f, l2), r2)
        };
        // `lesser`: the new value where it is below, NaN ignored.
        least = _mm512_min_pd(measure, least);
    }
    let mut lanes = [0.0; LANES];
    // SAFETY: 8 doubles into an array of 8.
    unsafe { _mm512_storeu_pd(lanes.as_mut_ptr(), least) };
    let measure = if NEGATED_RATIO {
        Measure::NegatedSquaredRatio
    } else {
        Measure::Margin(factor)
    };
    let (reference, positions) = (reference.as_chunks::<2>().0, positions.as_chunks::<2>().0);
    tail.iter()
        .fold(lanes.into_iter().fold(f64::INFINITY, lesser), |a, &j| {
            let (r2, l2) = bond_squares(i, j as usize, reference, positions);
            lesser(a, measure.of(r2, l2))
        })
}

/// The x and y coordinates of 8 nodes of a 2-per-node array as two vectors.
///
/// Safety: every index in `nodes[..8]` is a node of `values`.
#[inline]
#[target_feature(enable = "avx512f,avx512vl")]
unsafe fn pairs(values: &[f64], nodes: &[u32]) -> (__m512d, __m512d) {
    let p = values.as_ptr();
    macro_rules! two {
        ($a:expr, $b:expr) => {
            // SAFETY: the caller guarantees the indices (2 doubles per node).
            unsafe {
                _mm256_insertf128_pd::<1>(
                    _mm256_castpd128_pd256(_mm_loadu_pd(p.add(2 * nodes[$a] as usize))),
                    _mm_loadu_pd(p.add(2 * nodes[$b] as usize)),
                )
            }
        };
    }
    // [x0 y0 x1 y1 x2 y2 x3 y3] and [x4 y4 … x7 y7]
    let low = _mm512_insertf64x4::<1>(_mm512_castpd256_pd512(two!(0, 1)), two!(2, 3));
    let high = _mm512_insertf64x4::<1>(_mm512_castpd256_pd512(two!(4, 5)), two!(6, 7));
    (
        _mm512_permutex2var_pd(low, _mm512_set_epi64(14, 12, 10, 8, 6, 4, 2, 0), high),
        _mm512_permutex2var_pd(low, _mm512_set_epi64(15, 13, 11, 9, 7, 5, 3, 1), high),
    )
}
