//! Lanes as one AVX-512 register of 8 doubles, masks as the 8 bits of a `__mmask8`.

use std::arch::x86_64::*;

use super::avx2::two_nodes;
use super::lanes::{node_values, vector_lanes};
use super::{LaneLoop, Lanes};

/// 8 lanes in an AVX-512 register. A value exists only inside `run`, where AVX-512 F, VL,
/// DQ and BW are available: every method's intrinsic relies on that (see `vector_lanes`).
#[derive(Clone, Copy)]
pub(super) struct Avx512(__m512d);

vector_lanes!(@operators Avx512, _mm512_add_pd, _mm512_sub_pd, _mm512_mul_pd, _mm512_div_pd, _mm512_xor_pd);

/// `body` over `Avx512` lanes, compiled for AVX-512 (no FMA contraction).
///
/// # Safety
/// AVX-512 F, VL, DQ and BW are available (`Simd::Avx512.runs_here()`).
#[target_feature(enable = "avx512f,avx512vl,avx512dq,avx512bw")]
pub(super) fn run<K: LaneLoop>(body: K) -> K::Output {
    body.run::<Avx512>()
}

impl Lanes for Avx512 {
    const N: usize = 8;
    type Mask = __mmask8;

    vector_lanes! {
        Avx512, _mm512_set1_pd, _mm512_loadu_pd, _mm512_storeu_pd,
        _mm512_sqrt_pd, _mm512_max_pd, _mm512_min_pd
    }

    /// One 2-lane load per node, 3 inserts and 2 permutes per 8 nodes.
    #[inline(always)]
    unsafe fn gather2(values: &[f64], nodes: &[u32]) -> [Self; 2] {
        // SAFETY: the caller guarantees the indices; AVX-512 as for the operators.
        unsafe {
            // A macro, not a closure: an intrinsic inlines only into code compiled for
            // AVX-512, which a closure here is not.
            macro_rules! half {
                ($a:expr, $b:expr, $c:expr, $d:expr) => {
                    _mm512_insertf64x4::<1>(
                        _mm512_castpd256_pd512(two_nodes(values, nodes, $a, $b)),
                        two_nodes(values, nodes, $c, $d),
                    )
                };
            }
            // [x0 y0 x1 y1 x2 y2 x3 y3] and [x4 y4 … x7 y7]
            let (low, high) = (half!(0, 1, 2, 3), half!(4, 5, 6, 7));
            let evens = _mm512_set_epi64(14, 12, 10, 8, 6, 4, 2, 0);
            let odds = _mm512_set_epi64(15, 13, 11, 9, 7, 5, 3, 1);
            [
                Avx512(_mm512_permutex2var_pd(low, evens, high)),
                Avx512(_mm512_permutex2var_pd(low, odds, high)),
            ]
        }
    }

    /// One masked 3-lane load per node (the fourth lane never read), 4 inserts, 4 unpacks
    /// and 3 permutes.
    #[inline(always)]
    unsafe fn gather3(values: &[f64], nodes: &[u32]) -> [Self; 3] {
        // SAFETY: the caller guarantees the indices; lane 4 of each load is masked off
        // (fault-suppressed, never read); AVX-512 as for the operators.
        unsafe {
            // A macro, not a closure: an intrinsic inlines only into code compiled for
            // AVX-512, which a closure here is not.
            macro_rules! node {
                ($l:expr) => {
                    _mm256_maskz_loadu_pd(0b0111, node_values::<3>(values, nodes, $l))
                };
            }
            macro_rules! pair {
                ($a:expr, $b:expr) => {
                    _mm512_insertf64x4::<1>(_mm512_castpd256_pd512(node!($a)), node!($b))
                };
            }
            // t_l = [x_l y_l z_l 0 | x_{l+4} y_{l+4} z_{l+4} 0]
            let (t0, t1, t2, t3) = (pair!(0, 4), pair!(1, 5), pair!(2, 6), pair!(3, 7));
            // Per 128-bit lane: [x0 x1][z0 z1][x4 x5][z4 z5] and [y0 y1][0 0][y4 y5][0 0].
            let (lo01, hi01) = (_mm512_unpacklo_pd(t0, t1), _mm512_unpackhi_pd(t0, t1));
            let (lo23, hi23) = (_mm512_unpacklo_pd(t2, t3), _mm512_unpackhi_pd(t2, t3));
            let firsts = _mm512_set_epi64(13, 12, 5, 4, 9, 8, 1, 0);
            let seconds = _mm512_set_epi64(15, 14, 7, 6, 11, 10, 3, 2);
            [
                Avx512(_mm512_permutex2var_pd(lo01, firsts, lo23)),
                Avx512(_mm512_permutex2var_pd(hi01, firsts, hi23)),
                Avx512(_mm512_permutex2var_pd(lo01, seconds, lo23)),
            ]
        }
    }

    #[inline(always)]
    fn lt(self, other: Self) -> __mmask8 {
        // SAFETY: AVX-512 as for the operators.
        unsafe { _mm512_cmp_pd_mask::<_CMP_LT_OQ>(self.0, other.0) }
    }

    #[inline(always)]
    fn and(a: __mmask8, b: __mmask8) -> __mmask8 {
        a & b
    }

    #[inline(always)]
    fn zero_unless(self, keep: __mmask8) -> Self {
        // SAFETY: AVX-512 as for the operators.
        unsafe { Avx512(_mm512_maskz_mov_pd(keep, self.0)) }
    }

    /// The 8 bytes read as one word and tested in one instruction.
    #[inline(always)]
    fn nonzero(bytes: &[u8]) -> __mmask8 {
        let word = u64::from_le_bytes(bytes[..8].try_into().expect("8 bond states"));
        // SAFETY: AVX-512 as for the operators.
        unsafe {
            let packed = _mm_cvtsi64_si128(word as i64);
            _mm_test_epi8_mask(packed, packed) as __mmask8
        }
    }

    #[inline(always)]
    fn bits(mask: __mmask8) -> u32 {
        u32::from(mask)
    }
}
