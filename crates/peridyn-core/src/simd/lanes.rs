//! The lane type every bond loop is written over once: N doubles side by side, with the
//! operations the loops need and nothing else. Each implementation does, lane by lane, the
//! IEEE operation the scalar code would do (no fused multiply-add, the correctly rounded
//! square root and division), so a loop gives the same bits in every implementation of one
//! width; only the order of the final lane sums depends on N.

use std::ops::{Add, Div, Mul, Neg, Sub};

/// A loop written once over a lane type: `Simd::run` calls `run` with the lane type of the
/// chosen implementation, inside a function compiled for its instruction set. `run` must
/// be `#[inline(always)]` (and so must what it calls with lanes), so that the lane
/// operations are compiled there.
pub trait LaneLoop {
    type Output;
    fn run<L: Lanes>(self) -> Self::Output;
}

/// N doubles processed together.
pub trait Lanes:
    Copy
    + Add<Output = Self>
    + Sub<Output = Self>
    + Mul<Output = Self>
    + Div<Output = Self>
    + Neg<Output = Self>
{
    /// How many lanes (at most 8).
    const N: usize;
    /// A true/false per lane.
    type Mask: Copy;

    /// x in every lane.
    fn splat(x: f64) -> Self;
    /// `values[..N]`; `values` holds at least N (callers pass blocks of N).
    fn load(values: &[f64]) -> Self;
    /// `gather` of 2 values per node (2D positions), transposing whole nodes' loads.
    ///
    /// # Safety
    /// As `gather`.
    unsafe fn gather2(values: &[f64], nodes: &[u32]) -> [Self; 2];
    /// `gather` of 3 values per node (3D positions), transposing whole nodes' loads.
    ///
    /// # Safety
    /// As `gather`.
    unsafe fn gather3(values: &[f64], nodes: &[u32]) -> [Self; 3];
    fn sqrt(self) -> Self;
    /// Per lane `if self > other { self } else { other }` (the x86 `max`: `other` where
    /// either is NaN).
    fn max(self, other: Self) -> Self;
    /// Per lane `if self < other { self } else { other }` (the x86 `min`).
    fn min(self, other: Self) -> Self;
    /// Per lane `self < other` (false where either is NaN).
    fn lt(self, other: Self) -> Self::Mask;
    /// The lanes where both masks hold.
    fn and(a: Self::Mask, b: Self::Mask) -> Self::Mask;
    /// Per lane `self` where `keep` holds, +0 elsewhere.
    fn zero_unless(self, keep: Self::Mask) -> Self;
    /// The lanes whose byte of `bytes[..N]` is not 0 (bond states).
    fn nonzero(bytes: &[u8]) -> Self::Mask;
    /// Bit l set where lane l of `mask` holds.
    fn bits(mask: Self::Mask) -> u32;
    /// The lanes into `out[..N]`.
    fn store(self, out: &mut [f64]);

    /// The `D` values per node of nodes `nodes[..N]` of `values` (node j at
    /// `values[D j..D j + D]`) as `D` vectors, lane l holding node `nodes[l]`: `gather2`,
    /// `gather3`, or one value at a time for other `D`.
    ///
    /// # Safety
    /// `nodes` holds at least N indices, each a node of `values` (`D j + D <= values.len()`).
    #[inline(always)]
    unsafe fn gather<const D: usize>(values: &[f64], nodes: &[u32]) -> [Self; D] {
        // SAFETY: the caller guarantees the indices.
        unsafe {
            match D {
                2 => {
                    let g = Self::gather2(values, nodes);
                    std::array::from_fn(|k| g[k])
                }
                3 => {
                    let g = Self::gather3(values, nodes);
                    std::array::from_fn(|k| g[k])
                }
                _ => gather_scalar::<Self, D>(values, nodes),
            }
        }
    }

    /// +0 in every lane.
    #[inline(always)]
    fn zero() -> Self {
        Self::splat(0.0)
    }

    /// The lanes' sum in lane order, as `iter().sum()` over the lane array.
    #[inline(always)]
    fn sum(self) -> f64 {
        let mut lanes = [0.0; 8];
        self.store(&mut lanes);
        lanes[..Self::N].iter().sum()
    }

    /// `f` folded over the lanes in lane order from `init`.
    #[inline(always)]
    fn fold(self, init: f64, f: impl Fn(f64, f64) -> f64) -> f64 {
        let mut lanes = [0.0; 8];
        self.store(&mut lanes);
        lanes[..Self::N].iter().fold(init, |a, &x| f(a, x))
    }
}

/// Where node `nodes[l]`'s `D` values start in `values` (a plain function: no intrinsic).
///
/// # Safety
/// `nodes[l]` is a node of `values`.
#[inline(always)]
pub(super) unsafe fn node_values<const D: usize>(
    values: &[f64],
    nodes: &[u32],
    l: usize,
) -> *const f64 {
    // SAFETY: the caller guarantees the index.
    unsafe { values.as_ptr().add(D * nodes[l] as usize) }
}

/// `Lanes::gather` one value at a time (the `D` without a vector form; the reference).
///
/// # Safety
/// As `Lanes::gather`.
#[inline(always)]
unsafe fn gather_scalar<L: Lanes, const D: usize>(values: &[f64], nodes: &[u32]) -> [L; D] {
    let mut lanes = [[0.0; 8]; D];
    for (k, lane) in lanes.iter_mut().enumerate() {
        for (l, x) in lane[..L::N].iter_mut().enumerate() {
            // SAFETY: the caller guarantees the index.
            *x = unsafe { *node_values::<D>(values, nodes, l).add(k) };
        }
    }
    lanes.map(|lane| L::load(&lane))
}

/// The methods of a vector lane type `$t` (a tuple struct around a register) that are one
/// intrinsic each, for its `Lanes` impl, and its arithmetic operators (`@operators`).
///
/// The intrinsics are unsafe to call from code not compiled for their instruction set;
/// these methods are only reached inside `Simd::run`'s entry point for that set (the lane
/// types are private to `simd`, and `run` checks the CPU first), where they are inlined.
macro_rules! vector_lanes {
    ($t:ident, $splat:ident, $load:ident, $store:ident, $sqrt:ident, $max:ident, $min:ident) => {
        #[inline(always)]
        fn splat(x: f64) -> Self {
            // SAFETY: see the macro's doc.
            unsafe { $t($splat(x)) }
        }

        #[inline(always)]
        fn load(values: &[f64]) -> Self {
            assert!(values.len() >= Self::N);
            // SAFETY: N doubles are there (checked above, on a block of N the compiler
            // knows); the instruction set: see the macro's doc.
            unsafe { $t($load(values.as_ptr())) }
        }

        #[inline(always)]
        fn store(self, out: &mut [f64]) {
            assert!(out.len() >= Self::N);
            // SAFETY: room for N doubles (checked above); the instruction set as for `load`.
            unsafe { $store(out.as_mut_ptr(), self.0) }
        }

        #[inline(always)]
        fn sqrt(self) -> Self {
            // SAFETY: see the macro's doc.
            unsafe { $t($sqrt(self.0)) }
        }

        #[inline(always)]
        fn max(self, other: Self) -> Self {
            // SAFETY: see the macro's doc.
            unsafe { $t($max(self.0, other.0)) }
        }

        #[inline(always)]
        fn min(self, other: Self) -> Self {
            // SAFETY: see the macro's doc.
            unsafe { $t($min(self.0, other.0)) }
        }
    };
    (@operators $t:ident, $add:ident, $sub:ident, $mul:ident, $div:ident, $xor:ident) => {
        vector_lanes!(@binary $t, Add, add, $add);
        vector_lanes!(@binary $t, Sub, sub, $sub);
        vector_lanes!(@binary $t, Mul, mul, $mul);
        vector_lanes!(@binary $t, Div, div, $div);
        impl std::ops::Neg for $t {
            type Output = $t;
            /// The sign bit flipped, as the scalar `-x` (not `0 − x`, which differs at ±0).
            #[inline(always)]
            fn neg(self) -> $t {
                // SAFETY: see the macro's doc.
                unsafe { $t($xor(self.0, <$t as $crate::simd::Lanes>::splat(-0.0).0)) }
            }
        }
    };
    (@binary $t:ident, $trait:ident, $method:ident, $intrinsic:ident) => {
        impl std::ops::$trait for $t {
            type Output = $t;
            #[inline(always)]
            fn $method(self, other: $t) -> $t {
                // SAFETY: see the macro's doc.
                unsafe { $t($intrinsic(self.0, other.0)) }
            }
        }
    };
}

pub(super) use vector_lanes;
