//! The least-measure scan of `BondView::least` on 2D scenes, written with AVX-512
//! intrinsics: 8 bonds per iteration, each neighbour's reference and current position read
//! with one 2-lane load apiece and transposed into x and y vectors (`simd::gather8`). The
//! compiled 8-lane build spends about twice the instructions: a bounds check per lane and
//! array, and scalar lane assembly.
//!
//! r² and l² are formed as `bond_squares` forms them and the minimum is exact, so the result
//! is the portable scan's bit for bit (`least_margin_is_the_rows_minimum_in_every_build`).

use std::arch::x86_64::*;

use super::{Measure, bond_squares, lesser};
use crate::simd::{gather8, lanes};

const LANES: usize = 8;

/// The least of f l² − r² (`NEGATED_RATIO` false, f = `factor`) or of −r²/l² (true) over
/// the bonds (i, j), j in `neighbors`; `reference` and `positions` hold 2 doubles per node.
///
/// Safety: AVX-512 F/VL are available (`simd::avx512_f_vl()`).
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
        // SAFETY: the features are enabled here and the indices were checked above.
        let ([x, y], [u, v]) = unsafe {
            (
                gather8::<2>(reference, chunk),
                gather8::<2>(positions, chunk),
            )
        };
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
    let measure = if NEGATED_RATIO {
        Measure::NegatedSquaredRatio
    } else {
        Measure::Margin(factor)
    };
    let (reference, positions) = (reference.as_chunks::<2>().0, positions.as_chunks::<2>().0);
    tail.iter().fold(
        lanes(least).into_iter().fold(f64::INFINITY, lesser),
        |a, &j| {
            let (r2, l2) = bond_squares(i, j as usize, reference, positions);
            lesser(a, measure.of(r2, l2))
        },
    )
}
