//! The gather loop of `Standard::forces` in 2D and 3D written with AVX-512 intrinsics, for
//! scenes whose nodes all have one volume (every lattice scene): 8 bonds per iteration, each
//! neighbour's position read with one (masked) load and the 8 positions transposed into one
//! vector per axis (`simd::gather8`). The compiled 8-lane build (`rows_avx512`, still used
//! with per-node volumes) spends about twice the instructions on the same work: per-lane
//! bounds checks, 2+1 scalar loads per neighbour in 3D and the forces summed in 2-lane
//! pieces.
//!
//! Every lane does the portable loop's operations in its order (no FMA), so the result is
//! the portable 8-lane loop's bit for bit (`force_loop_is_bit_identical_across_builds_and_threads`,
//! `hand_written_kernel_matches_the_portable_loop_for_every_law`).

use std::arch::x86_64::*;

use super::{BondWeight, HandKernel, NodeTerms, Rows, WIDE_LANES, break_lanes, pmb_tail};
use crate::scheme::RowMask;
use crate::simd::{gather8, lanes_sum};

/// The AVX-512 kernel.
pub(super) struct Avx512;

impl HandKernel for Avx512 {
    unsafe fn rows<
        const D: usize,
        const LINEAR: bool,
        const BETA: bool,
        const ENERGY: bool,
        M: RowMask,
    >(
        rows: &Rows<D, M>,
        terms: &mut [NodeTerms<D>],
        state: &mut [u8],
        weight: &BondWeight,
        volume: f64,
    ) -> u64 {
        // SAFETY: the caller guarantees AVX-512 F/VL/DQ/BW and D ∈ {2, 3}.
        unsafe { rows_simd::<D, LINEAR, BETA, ENERGY, M>(rows, terms, state, weight, volume) }
    }
}

/// One task's rows. `D` must be 2 or 3: positions are read as a flat array of D per node.
#[target_feature(enable = "avx512f,avx512vl,avx512dq,avx512bw")]
unsafe fn rows_simd<
    const D: usize,
    const LINEAR: bool,
    const BETA: bool,
    const ENERGY: bool,
    M: RowMask,
>(
    rows: &Rows<D, M>,
    terms: &mut [NodeTerms<D>],
    state: &mut [u8],
    weight: &BondWeight,
    volume: f64,
) -> u64 {
    let families = rows.families;
    let positions = rows.positions.as_flattened();
    let node_count = rows.positions.len();
    let scalar_weight = |l: f64| weight.at::<LINEAR, BETA>(l) * volume;
    let unit = |_j: usize| 1.0;
    let s0 = _mm512_set1_pd(rows.s0);
    let v = _mm512_set1_pd(volume);
    let mut broken = 0u64;
    for (i, t_i, st) in rows.each_row(terms, state) {
        let neighbors = &families.neighbors[families.range(i)];
        let lengths = families.row_lengths(i);
        let y_i = rows.positions[i];
        let blocked = neighbors.len() / WIDE_LANES * WIDE_LANES;
        // Every neighbour index is a node of this scene (checked once per row, not per lane).
        let last = neighbors.iter().copied().max().unwrap_or(0) as usize;
        assert!(neighbors.is_empty() || last < node_count);
        let y: [__m512d; D] = std::array::from_fn(|k| _mm512_set1_pd(y_i[k]));
        let mut acc_lanes = [_mm512_setzero_pd(); D];
        let mut w_lanes = _mm512_setzero_pd();
        let mut lost = 0.0;
        for block in (0..blocked).step_by(WIDE_LANES) {
            // SAFETY: the features are enabled here and every index was checked above.
            let p = unsafe { gather8::<D>(positions, &neighbors[block..]) };
            let d: [__m512d; D] = std::array::from_fn(|k| _mm512_sub_pd(p[k], y[k]));
            // ‖y_j − y_i‖² summed over the axes in order, as `lane_offsets` does.
            let mut r2 = _mm512_mul_pd(d[0], d[0]);
            for d_k in &d[1..] {
                r2 = _mm512_add_pd(r2, _mm512_mul_pd(*d_k, *d_k));
            }
            let r = _mm512_sqrt_pd(r2);
            // SAFETY: `block + 8 <= blocked <= lengths.len()`.
            let ln = unsafe { _mm512_loadu_pd(lengths.as_ptr().add(block)) };
            let extension = _mm512_sub_pd(r, ln);
            let bytes = u64::from_le_bytes(
                st[block..block + WIDE_LANES]
                    .try_into()
                    .expect("a block of 8 bond states"),
            );
            let packed = _mm_cvtsi64_si128(bytes as i64);
            let alive = _mm_test_epi8_mask(packed, packed) as u8;
            let keep =
                _mm512_mask_cmp_pd_mask::<_CMP_LT_OQ>(alive, extension, _mm512_mul_pd(s0, ln));
            // ω c β V · s · (y_j − y_i)/‖y_j − y_i‖, s = extension / length (2.33).
            let numerator = _mm512_mul_pd(
                _mm512_mul_pd(lane_weight::<LINEAR, BETA>(weight, ln), v),
                extension,
            );
            let scale = _mm512_maskz_div_pd(keep, numerator, _mm512_mul_pd(ln, r));
            // Strain energy w β V_j = ½ ω c s² ‖ξ‖ β V_j (2.27), with the force.
            if ENERGY {
                w_lanes = _mm512_add_pd(w_lanes, _mm512_mul_pd(_mm512_mul_pd(scale, extension), r));
            }
            if alive != keep {
                let keep_lanes: [bool; WIDE_LANES] = std::array::from_fn(|l| keep & (1 << l) != 0);
                broken += break_lanes(
                    &mut st[block..block + WIDE_LANES],
                    &keep_lanes,
                    &lengths[block..block + WIDE_LANES],
                    &[1.0; WIDE_LANES],
                    rows.quadrature,
                    &mut lost,
                );
            }
            for (acc, d_k) in acc_lanes.iter_mut().zip(&d) {
                *acc = _mm512_add_pd(*acc, _mm512_mul_pd(scale, *d_k));
            }
        }
        let mut acc: [f64; D] = std::array::from_fn(|k| lanes_sum(acc_lanes[k]));
        let mut w = lanes_sum(w_lanes);
        pmb_tail(
            rows,
            i,
            blocked,
            st,
            &scalar_weight,
            &unit,
            (&mut acc, &mut w, &mut broken, &mut lost),
        );
        t_i.force = acc;
        if ENERGY {
            t_i.energy_density = 0.25 * w;
        }
        t_i.broken_weight += lost;
    }
    broken
}

/// `BondWeight::at` on 8 lengths, the same operations in the same order.
#[inline]
#[target_feature(enable = "avx512f,avx512vl,avx512dq,avx512bw")]
fn lane_weight<const LINEAR: bool, const BETA: bool>(weight: &BondWeight, l: __m512d) -> __m512d {
    let zero = _mm512_setzero_pd();
    let one = _mm512_set1_pd(1.0);
    let c = _mm512_set1_pd(weight.c);
    let w = if LINEAR {
        let taper = _mm512_sub_pd(one, _mm512_div_pd(l, _mm512_set1_pd(weight.horizon)));
        _mm512_mul_pd(c, _mm512_max_pd(taper, zero))
    } else {
        c
    };
    if BETA {
        let x = _mm512_mul_pd(
            _mm512_sub_pd(_mm512_set1_pd(weight.reach), l),
            _mm512_set1_pd(weight.inv_dx),
        );
        _mm512_mul_pd(w, _mm512_min_pd(_mm512_max_pd(x, zero), one))
    } else {
        w
    }
}
