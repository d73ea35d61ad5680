//! Lanes as a plain array: the reference every vector implementation of the same width
//! matches bit for bit, the build for CPUs without AVX2 (4 lanes), and the one-lane form of
//! the loops' remainders. The lane loops compile to whatever SIMD the enclosing function is
//! built for.

use super::Lanes;

/// `N` lanes in an array.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Portable<const N: usize>(pub [f64; N]);

impl<const N: usize> Portable<N> {
    #[inline(always)]
    fn map2(self, other: Self, f: impl Fn(f64, f64) -> f64) -> Self {
        Portable(std::array::from_fn(|l| f(self.0[l], other.0[l])))
    }
}

/// A binary operator of `Portable`, lane by lane.
macro_rules! operator {
    ($trait:ident, $method:ident, $op:tt) => {
        impl<const N: usize> std::ops::$trait for Portable<N> {
            type Output = Self;
            #[inline(always)]
            fn $method(self, other: Self) -> Self {
                self.map2(other, |a, b| a $op b)
            }
        }
    };
}

operator!(Add, add, +);
operator!(Sub, sub, -);
operator!(Mul, mul, *);
operator!(Div, div, /);

impl<const N: usize> std::ops::Neg for Portable<N> {
    type Output = Self;
    #[inline(always)]
    fn neg(self) -> Self {
        Portable(self.0.map(|x| -x))
    }
}

impl<const N: usize> Lanes for Portable<N> {
    const N: usize = N;
    type Mask = [bool; N];

    #[inline(always)]
    fn splat(x: f64) -> Self {
        Portable([x; N])
    }

    #[inline(always)]
    fn load(values: &[f64]) -> Self {
        Portable(std::array::from_fn(|l| values[l]))
    }

    /// Node by node, bounds checked (once per node): these lanes are the reference.
    #[inline(always)]
    unsafe fn gather<const D: usize>(values: &[f64], nodes: &[u32]) -> [Self; D] {
        let (per_node, _) = values.as_chunks::<D>();
        let mut out = [Portable([0.0; N]); D];
        for (l, &j) in nodes[..N].iter().enumerate() {
            for (k, x) in per_node[j as usize].iter().enumerate() {
                out[k].0[l] = *x;
            }
        }
        out
    }

    #[inline(always)]
    unsafe fn gather2(values: &[f64], nodes: &[u32]) -> [Self; 2] {
        // SAFETY: `gather` checks every index.
        unsafe { Self::gather::<2>(values, nodes) }
    }

    #[inline(always)]
    unsafe fn gather3(values: &[f64], nodes: &[u32]) -> [Self; 3] {
        // SAFETY: `gather` checks every index.
        unsafe { Self::gather::<3>(values, nodes) }
    }

    #[inline(always)]
    fn sqrt(self) -> Self {
        Portable(self.0.map(f64::sqrt))
    }

    #[inline(always)]
    fn max(self, other: Self) -> Self {
        self.map2(other, |a, b| if a > b { a } else { b })
    }

    #[inline(always)]
    fn min(self, other: Self) -> Self {
        self.map2(other, |a, b| if a < b { a } else { b })
    }

    #[inline(always)]
    fn lt(self, other: Self) -> [bool; N] {
        std::array::from_fn(|l| self.0[l] < other.0[l])
    }

    #[inline(always)]
    fn and(a: [bool; N], b: [bool; N]) -> [bool; N] {
        std::array::from_fn(|l| a[l] && b[l])
    }

    #[inline(always)]
    fn zero_unless(self, keep: [bool; N]) -> Self {
        Portable(std::array::from_fn(
            |l| if keep[l] { self.0[l] } else { 0.0 },
        ))
    }

    #[inline(always)]
    fn nonzero(bytes: &[u8]) -> [bool; N] {
        std::array::from_fn(|l| bytes[l] != 0)
    }

    #[inline(always)]
    fn bits(mask: [bool; N]) -> u32 {
        (0..N).fold(0, |bits, l| bits | (u32::from(mask[l]) << l))
    }

    #[inline(always)]
    fn store(self, out: &mut [f64]) {
        out[..N].copy_from_slice(&self.0);
    }
}
