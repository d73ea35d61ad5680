//! The gather loop of `Standard::forces` in 2D and 3D written with AVX2 intrinsics, for
//! machines without AVX-512 and scenes whose nodes all have one volume (every lattice scene):
//! 4 bonds per iteration, each neighbour's position read with one (masked) load and the
//! 4 positions transposed into one vector per axis (`simd::gather4`). The compiled 4-lane
//! build (`rows_avx2`, still used with per-node volumes) assembles each lane with scalar
//! loads and bounds checks.
//!
//! Every lane does the portable loop's operations in its order (no FMA), so the result is
//! the portable 4-lane loop's bit for bit (`force_loop_is_bit_identical_across_builds_and_threads`,
//! `hand_written_kernel_matches_the_portable_loop_for_every_law`).

use std::arch::x86_64::*;

use super::{
    BondWeight, HandKernel, LANES, LinearizedRow, NodeTerms, Rows, break_lanes, linearized_tail,
    pmb_tail,
};
use crate::scheme::RowMask;
use crate::simd::{gather4, lanes4};

/// The AVX2 kernel.
pub(super) struct Avx2;

impl HandKernel for Avx2 {
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
        // SAFETY: the caller guarantees AVX2 and D ∈ {2, 3}.
        unsafe { rows_simd::<D, LINEAR, BETA, ENERGY, M>(rows, terms, state, weight, volume) }
    }
}

/// One task's rows. `D` must be 2 or 3: positions are read as a flat array of D per node.
#[target_feature(enable = "avx2")]
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
    let s0 = _mm256_set1_pd(rows.s0);
    let v = _mm256_set1_pd(volume);
    let zero = _mm256_setzero_si256();
    let mut broken = 0u64;
    for (i, t_i, st) in rows.each_row(terms, state) {
        let neighbors = &families.neighbors[families.range(i)];
        let lengths = families.row_lengths(i);
        let y_i = rows.positions[i];
        let blocked = neighbors.len() / LANES * LANES;
        // Every neighbour index is a node of this scene (checked once per row, not per lane).
        let last = neighbors.iter().copied().max().unwrap_or(0) as usize;
        assert!(neighbors.is_empty() || last < node_count);
        let y: [__m256d; D] = std::array::from_fn(|k| _mm256_set1_pd(y_i[k]));
        let mut acc_lanes = [_mm256_setzero_pd(); D];
        let mut w_lanes = _mm256_setzero_pd();
        let mut lost = 0.0;
        for block in (0..blocked).step_by(LANES) {
            // SAFETY: the feature is enabled here and every index was checked above.
            let p = unsafe { gather4::<D>(positions, &neighbors[block..]) };
            let d: [__m256d; D] = std::array::from_fn(|k| _mm256_sub_pd(p[k], y[k]));
            // ‖y_j − y_i‖² summed over the axes in order, as `lane_offsets` does.
            let mut r2 = _mm256_mul_pd(d[0], d[0]);
            for d_k in &d[1..] {
                r2 = _mm256_add_pd(r2, _mm256_mul_pd(*d_k, *d_k));
            }
            let r = _mm256_sqrt_pd(r2);
            // SAFETY: `block + 4 <= blocked <= lengths.len()`.
            let ln = unsafe { _mm256_loadu_pd(lengths.as_ptr().add(block)) };
            let extension = _mm256_sub_pd(r, ln);
            let bytes = u32::from_le_bytes(
                st[block..block + LANES]
                    .try_into()
                    .expect("a block of 4 bond states"),
            );
            let states = _mm256_cvtepu8_epi64(_mm_cvtsi32_si128(bytes as i32));
            let dead = _mm256_castsi256_pd(_mm256_cmpeq_epi64(states, zero));
            let alive = !_mm256_movemask_pd(dead) & 0b1111;
            let keep = _mm256_andnot_pd(
                dead,
                _mm256_cmp_pd::<_CMP_LT_OQ>(extension, _mm256_mul_pd(s0, ln)),
            );
            // ω c β V · s · (y_j − y_i)/‖y_j − y_i‖, s = extension / length (2.33).
            let numerator = _mm256_mul_pd(
                _mm256_mul_pd(lane_weight::<LINEAR, BETA>(weight, ln), v),
                extension,
            );
            let scale = _mm256_and_pd(keep, _mm256_div_pd(numerator, _mm256_mul_pd(ln, r)));
            // Strain energy w β V_j = ½ ω c s² ‖ξ‖ β V_j (2.27), with the force.
            if ENERGY {
                w_lanes = _mm256_add_pd(w_lanes, _mm256_mul_pd(_mm256_mul_pd(scale, extension), r));
            }
            let kept = _mm256_movemask_pd(keep);
            if alive != kept {
                let keep_lanes: [bool; LANES] = std::array::from_fn(|l| kept & (1 << l) != 0);
                broken += break_lanes(
                    &mut st[block..block + LANES],
                    &keep_lanes,
                    &lengths[block..block + LANES],
                    &[1.0; LANES],
                    rows.quadrature,
                    &mut lost,
                );
            }
            for (acc, d_k) in acc_lanes.iter_mut().zip(&d) {
                *acc = _mm256_add_pd(*acc, _mm256_mul_pd(scale, *d_k));
            }
        }
        let mut acc: [f64; D] = std::array::from_fn(|k| lanes4(acc_lanes[k]).iter().sum());
        let mut w = lanes4(w_lanes).iter().sum();
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

/// `BondWeight::at` on 4 lengths, the same operations in the same order.
#[inline]
#[target_feature(enable = "avx2")]
fn lane_weight<const LINEAR: bool, const BETA: bool>(weight: &BondWeight, l: __m256d) -> __m256d {
    let zero = _mm256_setzero_pd();
    let one = _mm256_set1_pd(1.0);
    let c = _mm256_set1_pd(weight.c);
    let w = if LINEAR {
        let taper = _mm256_sub_pd(one, _mm256_div_pd(l, _mm256_set1_pd(weight.horizon)));
        _mm256_mul_pd(c, _mm256_max_pd(taper, zero))
    } else {
        c
    };
    if BETA {
        let x = _mm256_mul_pd(
            _mm256_sub_pd(_mm256_set1_pd(weight.reach), l),
            _mm256_set1_pd(weight.inv_dx),
        );
        _mm256_mul_pd(w, _mm256_min_pd(_mm256_max_pd(x, zero), one))
    } else {
        w
    }
}

/// `linearized_row::<D, 4>` (one row of `Standard::apply_linearized`) with each block's
/// reference and current positions read by `gather4`: the portable loop's operations in its
/// order, so its bits.
///
/// # Safety
/// AVX2 is available and `D` is 2 or 3.
#[target_feature(enable = "avx2")]
pub(super) unsafe fn linearized_row<const D: usize>(
    row: &LinearizedRow,
    reference: &[[f64; D]],
    u: &[[f64; D]],
) -> [f64; D] {
    let (x_i, u_i) = (reference[row.i], u[row.i]);
    let (flat_reference, flat_u) = (reference.as_flattened(), u.as_flattened());
    // Every neighbour index is a node (checked once per row, not per lane and array).
    let last = row.neighbors.iter().copied().max().unwrap_or(0) as usize;
    assert!(reference.len() == u.len() && (row.neighbors.is_empty() || last < u.len()));
    assert_eq!(row.coefficients.len(), row.neighbors.len());
    let x: [__m256d; D] = std::array::from_fn(|k| _mm256_set1_pd(x_i[k]));
    let v: [__m256d; D] = std::array::from_fn(|k| _mm256_set1_pd(u_i[k]));
    let zero = _mm256_setzero_si256();
    let blocked = row.neighbors.len() / LANES * LANES;
    let mut acc_lanes = [_mm256_setzero_pd(); D];
    for block in (0..blocked).step_by(LANES) {
        let nodes = &row.neighbors[block..];
        // SAFETY: the feature is enabled here and every index was checked above.
        let (p, q) = unsafe {
            (
                gather4::<D>(flat_reference, nodes),
                gather4::<D>(flat_u, nodes),
            )
        };
        let xi: [__m256d; D] = std::array::from_fn(|k| _mm256_sub_pd(p[k], x[k]));
        let du: [__m256d; D] = std::array::from_fn(|k| _mm256_sub_pd(v[k], q[k]));
        let mut proj = _mm256_mul_pd(xi[0], du[0]);
        for k in 1..D {
            proj = _mm256_add_pd(proj, _mm256_mul_pd(xi[k], du[k]));
        }
        let bytes = u32::from_le_bytes(
            row.states[block..block + LANES]
                .try_into()
                .expect("a block of 4 bond states"),
        );
        let states = _mm256_cvtepu8_epi64(_mm_cvtsi32_si128(bytes as i32));
        let dead = _mm256_castsi256_pd(_mm256_cmpeq_epi64(states, zero));
        // SAFETY: `block + 4 <= blocked <= coefficients.len()`.
        let c = unsafe { _mm256_loadu_pd(row.coefficients.as_ptr().add(block)) };
        let scale = _mm256_andnot_pd(dead, _mm256_mul_pd(c, proj));
        for (acc, xi_k) in acc_lanes.iter_mut().zip(&xi) {
            *acc = _mm256_add_pd(*acc, _mm256_mul_pd(scale, *xi_k));
        }
    }
    let mut acc: [f64; D] = std::array::from_fn(|k| lanes4(acc_lanes[k]).iter().sum());
    linearized_tail(row, blocked, reference, u, &mut acc);
    acc
}
