//! The 3D gather loop of `Standard::forces` written with AVX-512 intrinsics, for scenes whose
//! nodes all have one volume (every lattice scene): 8 bonds per iteration, each neighbour's
//! position read with one masked 3-lane load and the 8 positions transposed into x, y, z
//! vectors with 7 shuffles. The compiled 8-lane build (`rows_avx512`) spends about twice the
//! instructions on the same work: per-lane bounds checks, 2+1 scalar loads per neighbour and
//! the forces summed in 2-lane pieces.
//!
//! Every lane does the portable loop's operations in its order (no FMA), so the result is
//! the portable 8-lane loop's bit for bit (`force_loop_is_bit_identical_across_builds_and_threads`,
//! `hand_written_kernel_matches_the_portable_loop_for_every_law`).

use std::arch::x86_64::*;

use super::{BondWeight, NodeTerms, Rows, WIDE_LANES, break_lanes, pmb_tail, split_rows};
use crate::scheme::RowMask;

/// Whether this kernel can run here: AVX-512 F/VL/DQ as `rows_avx512`, and BW for the byte
/// test that reads 8 bond states at once.
pub(super) fn available() -> bool {
    super::avx512_detected() && std::arch::is_x86_feature_detected!("avx512bw")
}

/// The force loop over all rows (`Standard::forces_masked` on a 3D scene with uniform
/// volumes): ω c β V s e per bond with the influence and partial-volume factor of
/// `weight`, V = `volume`. Returns the directed bonds broken.
///
/// The caller checks `available()` and that `D` is 3.
pub(super) fn forces<const D: usize, M: RowMask>(
    rows: &Rows<D, M>,
    intact: &mut [u8],
    terms: &mut [NodeTerms<D>],
    weight: BondWeight,
    volume: f64,
    linear: bool,
    beta: bool,
) -> u64 {
    assert!(D == 3 && available());
    macro_rules! run {
        ($linear:literal, $beta:literal) => {
            split_rows(
                rows.families,
                0,
                terms,
                intact,
                &|first: usize, terms: &mut [NodeTerms<D>], state: &mut [u8]| -> u64 {
                    let block = Rows { first, ..*rows };
                    // SAFETY: the features were detected (asserted above) and D is 3.
                    unsafe {
                        rows_d3::<D, $linear, $beta, M>(&block, terms, state, &weight, volume)
                    }
                },
            )
        };
    }
    match (linear, beta) {
        (false, true) => run!(false, true),
        (false, false) => run!(false, false),
        (true, true) => run!(true, true),
        (true, false) => run!(true, false),
    }
}

/// One task's rows. `D` must be 3: positions are read as a flat array of 3 per node.
#[target_feature(enable = "avx512f,avx512vl,avx512dq,avx512bw")]
unsafe fn rows_d3<const D: usize, const LINEAR: bool, const BETA: bool, M: RowMask>(
    rows: &Rows<D, M>,
    terms: &mut [NodeTerms<D>],
    state: &mut [u8],
    weight: &BondWeight,
    volume: f64,
) -> u64 {
    let families = rows.families;
    let positions = rows.positions.as_flattened();
    let node_count = rows.positions.len();
    let base = families.offsets[rows.first];
    let scalar_weight = |l: f64| weight.at::<LINEAR, BETA>(l) * volume;
    let unit = |_j: usize| 1.0;
    let mut broken = 0u64;
    for (row, t_i) in terms.iter_mut().enumerate() {
        let i = rows.first + row;
        if rows.skip.is_some_and(|mask| mask[i].skipped()) {
            continue;
        }
        let range = families.range(i);
        let neighbors = &families.neighbors[range.clone()];
        let lengths = &families.lengths[range.clone()];
        let st = &mut state[range.start - base..range.end - base];
        let y_i = rows.positions[i];
        let y = [y_i[0], y_i[1], y_i[2]];
        let blocked = neighbors.len() / WIDE_LANES * WIDE_LANES;
        // Every neighbour index is a node of this scene (checked once per row, not per lane).
        let last = neighbors.iter().copied().max().unwrap_or(0) as usize;
        assert!(neighbors.is_empty() || last < node_count);
        let (mut acc, mut w, newly, mut lost) = {
            let (yx, yy, yz) = (
                _mm512_set1_pd(y[0]),
                _mm512_set1_pd(y[1]),
                _mm512_set1_pd(y[2]),
            );
            let s0 = _mm512_set1_pd(rows.s0);
            let mut acc_x = _mm512_setzero_pd();
            let mut acc_y = _mm512_setzero_pd();
            let mut acc_z = _mm512_setzero_pd();
            let mut w_lanes = _mm512_setzero_pd();
            let mut newly = 0u64;
            let mut lost = 0.0;
            for block in (0..blocked).step_by(WIDE_LANES) {
                // SAFETY: every index was checked against the node count above; the loads
                // read 3 doubles of one node (the 4th lane masked off, never touched).
                let [dx, dy, dz] = unsafe {
                    let (x, y8, z) = gather_positions(positions, &neighbors[block..]);
                    [
                        _mm512_sub_pd(x, yx),
                        _mm512_sub_pd(y8, yy),
                        _mm512_sub_pd(z, yz),
                    ]
                };
                let r2 = _mm512_add_pd(
                    _mm512_add_pd(_mm512_mul_pd(dx, dx), _mm512_mul_pd(dy, dy)),
                    _mm512_mul_pd(dz, dz),
                );
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
                    _mm512_mul_pd(
                        lane_weight::<LINEAR, BETA>(weight, ln),
                        _mm512_set1_pd(volume),
                    ),
                    extension,
                );
                let scale = _mm512_maskz_div_pd(keep, numerator, _mm512_mul_pd(ln, r));
                // Strain energy w β V_j = ½ ω c s² ‖ξ‖ β V_j (2.27), with the force.
                w_lanes = _mm512_add_pd(w_lanes, _mm512_mul_pd(_mm512_mul_pd(scale, extension), r));
                if alive != keep {
                    let keep_lanes: [bool; WIDE_LANES] =
                        std::array::from_fn(|l| keep & (1 << l) != 0);
                    newly += break_lanes(
                        &mut st[block..block + WIDE_LANES],
                        &keep_lanes,
                        &lengths[block..block + WIDE_LANES],
                        &[1.0; WIDE_LANES],
                        rows.quadrature,
                        &mut lost,
                    );
                }
                acc_x = _mm512_add_pd(acc_x, _mm512_mul_pd(scale, dx));
                acc_y = _mm512_add_pd(acc_y, _mm512_mul_pd(scale, dy));
                acc_z = _mm512_add_pd(acc_z, _mm512_mul_pd(scale, dz));
            }
            let acc = [lanes_sum(acc_x), lanes_sum(acc_y), lanes_sum(acc_z)];
            (acc, lanes_sum(w_lanes), newly, lost)
        };
        broken += newly;
        let mut acc_d = [0.0; D];
        acc_d.copy_from_slice(&acc[..D]);
        pmb_tail(
            rows.positions[i],
            &neighbors[blocked..],
            &lengths[blocked..],
            &mut st[blocked..],
            rows.positions,
            rows.s0,
            rows.quadrature,
            &scalar_weight,
            &unit,
            (&mut acc_d, &mut w, &mut broken, &mut lost),
        );
        acc = [acc_d[0], acc_d[1], acc_d[2]];
        t_i.force.copy_from_slice(&acc[..D]);
        t_i.energy_density = 0.25 * w;
        t_i.broken_weight += lost;
    }
    broken
}

/// The positions of 8 neighbours as x, y and z vectors: one masked load of 3 doubles per
/// neighbour, paired into 4 registers and transposed.
///
/// Safety: every index in `neighbors[..8]` is a node of `positions` (3 doubles per node).
#[inline]
#[target_feature(enable = "avx512f,avx512vl,avx512dq,avx512bw")]
unsafe fn gather_positions(positions: &[f64], neighbors: &[u32]) -> (__m512d, __m512d, __m512d) {
    let p = positions.as_ptr();
    macro_rules! pair {
        ($a:expr, $b:expr) => {
            // SAFETY: the caller guarantees the indices; lane 4 of each load is masked off.
            unsafe {
                _mm512_insertf64x4::<1>(
                    _mm512_castpd256_pd512(_mm256_maskz_loadu_pd(
                        0b0111,
                        p.add(3 * neighbors[$a] as usize),
                    )),
                    _mm256_maskz_loadu_pd(0b0111, p.add(3 * neighbors[$b] as usize)),
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
    (
        _mm512_permutex2var_pd(lo01, firsts, lo23),
        _mm512_permutex2var_pd(hi01, firsts, hi23),
        _mm512_permutex2var_pd(lo01, seconds, lo23),
    )
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

/// The lanes' sum in lane order, as the portable loop's `iter().sum()`.
#[inline]
#[target_feature(enable = "avx512f,avx512vl,avx512dq,avx512bw")]
fn lanes_sum(v: __m512d) -> f64 {
    let mut lanes = [0.0; WIDE_LANES];
    // SAFETY: 8 doubles written to an array of 8.
    unsafe { _mm512_storeu_pd(lanes.as_mut_ptr(), v) };
    lanes.iter().sum()
}
