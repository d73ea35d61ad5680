//! Lanes as one AVX2 register of 4 doubles, masks as all-ones or all-zeros lanes.

use std::arch::x86_64::*;

use super::lanes::{node_values, vector_lanes};
use super::{LaneLoop, Lanes};

/// 4 lanes in an AVX register. A value exists only inside `run`, where AVX2 is available:
/// every method's intrinsic relies on that (see `vector_lanes`).
#[derive(Clone, Copy)]
pub(super) struct Avx2(__m256d);

vector_lanes!(@operators Avx2, _mm256_add_pd, _mm256_sub_pd, _mm256_mul_pd, _mm256_div_pd, _mm256_xor_pd);

/// `body` over `Avx2` lanes, compiled for AVX2 (no FMA: nothing is contracted).
///
/// # Safety
/// AVX2 is available (`Simd::Avx2.runs_here()`).
#[target_feature(enable = "avx2")]
pub(super) fn run<K: LaneLoop>(body: K) -> K::Output {
    body.run::<Avx2>()
}

/// The 2 values of nodes `nodes[a]` and `nodes[b]` as [a₀ a₁ b₀ b₁] (2D positions).
///
/// # Safety
/// AVX is available; both are nodes of `values`.
#[inline(always)]
pub(super) unsafe fn two_nodes(values: &[f64], nodes: &[u32], a: usize, b: usize) -> __m256d {
    // SAFETY: the caller guarantees the indices and the instruction set.
    unsafe {
        _mm256_insertf128_pd::<1>(
            _mm256_castpd128_pd256(_mm_loadu_pd(node_values::<2>(values, nodes, a))),
            _mm_loadu_pd(node_values::<2>(values, nodes, b)),
        )
    }
}

impl Lanes for Avx2 {
    const N: usize = 4;
    type Mask = __m256d;

    vector_lanes! {
        Avx2, _mm256_set1_pd, _mm256_loadu_pd, _mm256_storeu_pd,
        _mm256_sqrt_pd, _mm256_max_pd, _mm256_min_pd
    }

    /// One 2-lane load per node, 2 inserts and 2 unpacks.
    #[inline(always)]
    unsafe fn gather2(values: &[f64], nodes: &[u32]) -> [Self; 2] {
        // SAFETY: the caller guarantees the indices; AVX2 as for the operators.
        unsafe {
            // [x0 y0 x2 y2] and [x1 y1 x3 y3]
            let (even, odd) = (
                two_nodes(values, nodes, 0, 2),
                two_nodes(values, nodes, 1, 3),
            );
            [
                Avx2(_mm256_unpacklo_pd(even, odd)),
                Avx2(_mm256_unpackhi_pd(even, odd)),
            ]
        }
    }

    /// One masked 3-lane load per node (the fourth lane never read), 4 unpacks and 3 lane
    /// permutes.
    #[inline(always)]
    unsafe fn gather3(values: &[f64], nodes: &[u32]) -> [Self; 3] {
        // SAFETY: the caller guarantees the indices; lane 4 of each load is masked off
        // (fault-suppressed, never read); AVX2 as for the operators.
        unsafe {
            let first_three = _mm256_set_epi64x(0, -1, -1, -1);
            // A macro, not a closure: an intrinsic inlines only into code compiled for
            // AVX2, which a closure here is not.
            macro_rules! node {
                ($l:expr) => {
                    _mm256_maskload_pd(node_values::<3>(values, nodes, $l), first_three)
                };
            }
            // t_l = [x_l y_l z_l 0]
            let (t0, t1, t2, t3) = (node!(0), node!(1), node!(2), node!(3));
            // [x0 x1 z0 z1], [y0 y1 0 0], [x2 x3 z2 z3], [y2 y3 0 0]
            let (lo01, hi01) = (_mm256_unpacklo_pd(t0, t1), _mm256_unpackhi_pd(t0, t1));
            let (lo23, hi23) = (_mm256_unpacklo_pd(t2, t3), _mm256_unpackhi_pd(t2, t3));
            [
                Avx2(_mm256_permute2f128_pd::<0x20>(lo01, lo23)),
                Avx2(_mm256_permute2f128_pd::<0x20>(hi01, hi23)),
                Avx2(_mm256_permute2f128_pd::<0x31>(lo01, lo23)),
            ]
        }
    }

    #[inline(always)]
    fn lt(self, other: Self) -> __m256d {
        // SAFETY: AVX2 as for the operators.
        unsafe { _mm256_cmp_pd::<_CMP_LT_OQ>(self.0, other.0) }
    }

    #[inline(always)]
    fn and(a: __m256d, b: __m256d) -> __m256d {
        // SAFETY: AVX2 as for the operators.
        unsafe { _mm256_and_pd(a, b) }
    }

    #[inline(always)]
    fn zero_unless(self, keep: __m256d) -> Self {
        // SAFETY: AVX2 as for the operators.
        unsafe { Avx2(_mm256_and_pd(keep, self.0)) }
    }

    /// The 4 bytes read as one word, widened to 64-bit lanes and compared with 0.
    #[inline(always)]
    fn nonzero(bytes: &[u8]) -> __m256d {
        let word = u32::from_le_bytes([bytes[0], bytes[1], bytes[2], bytes[3]]);
        // SAFETY: AVX2 as for the operators.
        unsafe {
            let states = _mm256_cvtepu8_epi64(_mm_cvtsi32_si128(word as i32));
            let dead = _mm256_cmpeq_epi64(states, _mm256_setzero_si256());
            _mm256_castsi256_pd(_mm256_xor_si256(dead, _mm256_set1_epi64x(-1)))
        }
    }

    #[inline(always)]
    fn bits(mask: __m256d) -> u32 {
        // SAFETY: AVX2 as for the operators.
        unsafe { _mm256_movemask_pd(mask) as u32 }
    }
}
