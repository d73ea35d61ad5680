//! AVX-512 building blocks shared by the hand-written kernels (`scheme::standard`'s force
//! loop, `adapt::bonds`' switching scan): the coordinates of 8 nodes, stored 2 or 3 doubles
//! per node, as one vector per axis.

#[cfg(target_arch = "x86_64")]
use std::arch::x86_64::*;

/// AVX-512 F and VL: the switching scan's builds (compiled and hand-written).
#[cfg(target_arch = "x86_64")]
pub fn avx512_f_vl() -> bool {
    std::arch::is_x86_feature_detected!("avx512f")
        && std::arch::is_x86_feature_detected!("avx512vl")
}

/// AVX-512 F, VL and DQ: the compiled 8-lane force loop.
#[cfg(target_arch = "x86_64")]
pub fn avx512_f_vl_dq() -> bool {
    avx512_f_vl() && std::arch::is_x86_feature_detected!("avx512dq")
}

/// AVX-512 F, VL, DQ and BW: the hand-written force kernel (BW for the byte test that reads
/// 8 bond states at once).
#[cfg(target_arch = "x86_64")]
pub fn avx512_kernels_available() -> bool {
    avx512_f_vl_dq() && std::arch::is_x86_feature_detected!("avx512bw")
}

/// The coordinates of nodes `nodes[..8]` of `values` (`D` = 2 or 3 doubles per node) as `D`
/// vectors, lane l holding node `nodes[l]`. 2D: one 2-lane load per node, 3 inserts and
/// 2 permutes per 8 nodes; 3D: one masked 3-lane load per node (the fourth lane never
/// read), 4 inserts, 4 unpacks and 3 permutes.
///
/// # Safety
/// AVX-512 F/VL are available, and every index in `nodes[..8]` is a node of `values`.
#[cfg(target_arch = "x86_64")]
#[inline]
#[target_feature(enable = "avx512f,avx512vl")]
pub unsafe fn gather8<const D: usize>(values: &[f64], nodes: &[u32]) -> [__m512d; D] {
    let p = values.as_ptr();
    let mut out = [_mm512_setzero_pd(); D];
    if D == 2 {
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
        out[0] = _mm512_permutex2var_pd(low, _mm512_set_epi64(14, 12, 10, 8, 6, 4, 2, 0), high);
        out[1] = _mm512_permutex2var_pd(low, _mm512_set_epi64(15, 13, 11, 9, 7, 5, 3, 1), high);
    } else {
        assert_eq!(D, 3);
        macro_rules! pair {
            ($a:expr, $b:expr) => {
                // SAFETY: the caller guarantees the indices; lane 4 of each load is masked
                // off (fault-suppressed, never read).
                unsafe {
                    _mm512_insertf64x4::<1>(
                        _mm512_castpd256_pd512(_mm256_maskz_loadu_pd(
                            0b0111,
                            p.add(3 * nodes[$a] as usize),
                        )),
                        _mm256_maskz_loadu_pd(0b0111, p.add(3 * nodes[$b] as usize)),
                    )
                }
            };
        }
        // t_l = [x_l y_l z_l 0 | x_{l+4} y_{l+4} z_{l+4} 0]
        let (t0, t1, t2, t3) = (pair!(0, 4), pair!(1, 5), pair!(2, 6), pair!(3, 7));
        // Per 128-bit lane: [x0 x1][z0 z1][x4 x5][z4 z5] and [y0 y1][0 0][y4 y5][0 0].
        let (lo01, hi01) = (_mm512_unpacklo_pd(t0, t1), _mm512_unpackhi_pd(t0, t1));
        let (lo23, hi23) = (_mm512_unpacklo_pd(t2, t3), _mm512_unpackhi_pd(t2, t3));
        let firsts = _mm512_set_epi64(13, 12, 5, 4, 9, 8, 1, 0);
        let seconds = _mm512_set_epi64(15, 14, 7, 6, 11, 10, 3, 2);
        out[0] = _mm512_permutex2var_pd(lo01, firsts, lo23);
        out[1] = _mm512_permutex2var_pd(hi01, firsts, hi23);
        out[2] = _mm512_permutex2var_pd(lo01, seconds, lo23);
    }
    out
}

/// The lanes' sum in lane order, as a portable loop's `iter().sum()` over its lane array.
///
/// # Safety
/// AVX-512 F is available (a safe call from code compiled with it).
#[cfg(target_arch = "x86_64")]
#[inline]
#[target_feature(enable = "avx512f")]
pub fn lanes_sum(v: __m512d) -> f64 {
    lanes(v).iter().sum()
}

/// The 8 lanes as an array.
///
/// # Safety
/// AVX-512 F is available (a safe call from code compiled with it).
#[cfg(target_arch = "x86_64")]
#[inline]
#[target_feature(enable = "avx512f")]
pub fn lanes(v: __m512d) -> [f64; 8] {
    let mut out = [0.0; 8];
    // SAFETY: 8 doubles into an array of 8.
    unsafe { _mm512_storeu_pd(out.as_mut_ptr(), v) };
    out
}

/// AVX2: the 4-lane hand-written kernels (`scheme::standard`'s force loop,
/// `adapt::bonds`' switching scan) on machines without AVX-512.
#[cfg(target_arch = "x86_64")]
pub fn avx2() -> bool {
    std::arch::is_x86_feature_detected!("avx2")
}

/// The coordinates of nodes `nodes[..4]` of `values` (`D` = 2 or 3 doubles per node) as `D`
/// 4-lane vectors, lane l holding node `nodes[l]`: `gather8` for AVX2. 2D: one 2-lane load
/// per node, 2 inserts and 2 unpacks; 3D: one masked 3-lane load per node (the fourth lane
/// never read), 4 unpacks and 3 lane permutes.
///
/// # Safety
/// AVX2 is available, and every index in `nodes[..4]` is a node of `values`.
#[cfg(target_arch = "x86_64")]
#[inline]
#[target_feature(enable = "avx2")]
pub unsafe fn gather4<const D: usize>(values: &[f64], nodes: &[u32]) -> [__m256d; D] {
    let p = values.as_ptr();
    let mut out = [_mm256_setzero_pd(); D];
    if D == 2 {
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
        // [x0 y0 x2 y2] and [x1 y1 x3 y3]
        let (even, odd) = (two!(0, 2), two!(1, 3));
        out[0] = _mm256_unpacklo_pd(even, odd);
        out[1] = _mm256_unpackhi_pd(even, odd);
    } else {
        assert_eq!(D, 3);
        let first_three = _mm256_set_epi64x(0, -1, -1, -1);
        macro_rules! one {
            ($a:expr) => {
                // SAFETY: the caller guarantees the index; lane 4 is masked off
                // (fault-suppressed, never read).
                unsafe { _mm256_maskload_pd(p.add(3 * nodes[$a] as usize), first_three) }
            };
        }
        // t_l = [x_l y_l z_l 0]
        let (t0, t1, t2, t3) = (one!(0), one!(1), one!(2), one!(3));
        // [x0 x1 z0 z1], [y0 y1 0 0], [x2 x3 z2 z3], [y2 y3 0 0]
        let (lo01, hi01) = (_mm256_unpacklo_pd(t0, t1), _mm256_unpackhi_pd(t0, t1));
        let (lo23, hi23) = (_mm256_unpacklo_pd(t2, t3), _mm256_unpackhi_pd(t2, t3));
        out[0] = _mm256_permute2f128_pd::<0x20>(lo01, lo23);
        out[1] = _mm256_permute2f128_pd::<0x20>(hi01, hi23);
        out[2] = _mm256_permute2f128_pd::<0x31>(lo01, lo23);
    }
    out
}

/// The 4 lanes as an array.
///
/// # Safety
/// AVX is available (a safe call from code compiled with it).
#[cfg(target_arch = "x86_64")]
#[inline]
#[target_feature(enable = "avx")]
pub fn lanes4(v: __m256d) -> [f64; 4] {
    let mut out = [0.0; 4];
    // SAFETY: 4 doubles into an array of 4.
    unsafe { _mm256_storeu_pd(out.as_mut_ptr(), v) };
    out
}
