//! SIMD for the bond loops: each loop (the PMB force loop of `scheme::standard`, its
//! linearized operator, the switching scan of `adapt::bonds`) is written once over a lane type
//! ([`Lanes`]), and runs on the implementation chosen once per process ([`Simd::selected`]):
//!
//! - `avx512`: 8 lanes in one AVX-512 register (needs AVX-512 F, VL, DQ and BW);
//! - `avx2`: 4 lanes in one AVX2 register;
//! - `portable`: 4 lanes as a plain array (any CPU); `portable8`: 8 lanes as an array.
//!
//! By default the widest the CPU runs. The environment variable
//! `PERIDYN_SIMD=portable|portable8|avx2|avx512` forces one (comparisons, CI, another
//! machine's bits); the command line rejects a value that is not one of these or that
//! this CPU cannot run (`Simd::from_env`).
//!
//! Every lane does the scalar code's IEEE operations in its order (no FMA), so the results
//! depend on the lane count only, through the order the per-lane partial sums are added:
//! `avx2` gives `portable`'s bits, `avx512` gives `portable8`'s (so `portable8` gives these
//! loops an AVX-512 machine's bits on any CPU), and 4 against 8 lanes agree to rounding. The
//! linearized operator sums in 4 lanes on every implementation (`Simd::four_lanes`): its sums
//! decide the stable step Δt, which thus does not depend on whether the CPU has AVX-512.

mod lanes;
mod portable;

#[cfg(target_arch = "x86_64")]
mod avx2;
#[cfg(target_arch = "x86_64")]
mod avx512;

use std::sync::OnceLock;

pub use lanes::{LaneLoop, Lanes};
pub use portable::Portable;

/// A lane implementation.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Simd {
    /// [`Portable`] with 4 lanes.
    Portable,
    /// [`Portable`] with 8 lanes.
    Portable8,
    /// AVX2, 4 lanes.
    Avx2,
    /// AVX-512, 8 lanes.
    Avx512,
}

/// The environment variable that forces an implementation.
pub const ENV: &str = "PERIDYN_SIMD";

impl Simd {
    pub const ALL: [Simd; 4] = [Simd::Portable, Simd::Portable8, Simd::Avx2, Simd::Avx512];

    /// The name `PERIDYN_SIMD` takes.
    pub fn name(self) -> &'static str {
        match self {
            Simd::Portable => "portable",
            Simd::Portable8 => "portable8",
            Simd::Avx2 => "avx2",
            Simd::Avx512 => "avx512",
        }
    }

    /// Lanes per vector.
    pub fn lanes(self) -> usize {
        match self {
            Simd::Portable | Simd::Avx2 => 4,
            Simd::Portable8 | Simd::Avx512 => 8,
        }
    }

    /// Whether this CPU runs it (detected once: `run` asks on every call).
    pub fn runs_here(self) -> bool {
        static RUNS: OnceLock<[bool; 4]> = OnceLock::new();
        RUNS.get_or_init(|| Simd::ALL.map(Simd::detect))[self as usize]
    }

    fn detect(self) -> bool {
        match self {
            Simd::Portable | Simd::Portable8 => true,
            #[cfg(target_arch = "x86_64")]
            Simd::Avx2 => std::arch::is_x86_feature_detected!("avx2"),
            #[cfg(target_arch = "x86_64")]
            Simd::Avx512 => {
                Simd::Avx2.detect()
                    && std::arch::is_x86_feature_detected!("avx512f")
                    && std::arch::is_x86_feature_detected!("avx512vl")
                    && std::arch::is_x86_feature_detected!("avx512dq")
                    && std::arch::is_x86_feature_detected!("avx512bw")
            }
            #[cfg(not(target_arch = "x86_64"))]
            Simd::Avx2 | Simd::Avx512 => false,
        }
    }

    /// Every implementation this CPU runs (the portable ones always).
    pub fn supported() -> Vec<Simd> {
        Simd::ALL.into_iter().filter(|s| s.runs_here()).collect()
    }

    /// The widest this CPU runs (AVX-512 over AVX2 over portable).
    pub fn widest() -> Simd {
        [Simd::Avx512, Simd::Avx2]
            .into_iter()
            .find(|s| s.runs_here())
            .unwrap_or(Simd::Portable)
    }

    /// The implementation `PERIDYN_SIMD` asks for (None where it is not set), or why it
    /// cannot be had.
    pub fn from_env() -> Result<Option<Simd>, String> {
        Simd::parse(std::env::var_os(ENV).as_deref())
    }

    /// `from_env` on the variable's value.
    fn parse(value: Option<&std::ffi::OsStr>) -> Result<Option<Simd>, String> {
        let Some(value) = value else {
            return Ok(None);
        };
        let names = |set: &[Simd]| set.iter().map(|s| s.name()).collect::<Vec<_>>().join(", ");
        let wanted = value
            .to_str()
            .and_then(|v| Simd::ALL.into_iter().find(|s| s.name() == v))
            .ok_or_else(|| {
                let all = names(&Simd::ALL);
                format!("environment variable {ENV}={value:?}: expected one of {all}")
            })?;
        if !wanted.runs_here() {
            let here = names(&Simd::supported());
            return Err(format!(
                "environment variable {ENV}={}: this CPU cannot run it; it runs {here}",
                wanted.name()
            ));
        }
        Ok(Some(wanted))
    }

    /// The implementation of this process, chosen on first use: `PERIDYN_SIMD` where it is
    /// set to one this CPU runs, the widest otherwise.
    pub fn selected() -> Simd {
        static SELECTED: OnceLock<Simd> = OnceLock::new();
        *SELECTED.get_or_init(|| Simd::from_env().ok().flatten().unwrap_or_else(Simd::widest))
    }

    /// The 4-lane implementation of the same kind (the linearized operator's).
    pub fn four_lanes(self) -> Simd {
        match self {
            Simd::Portable | Simd::Portable8 => Simd::Portable,
            Simd::Avx2 | Simd::Avx512 => Simd::Avx2,
        }
    }

    /// `body` over this implementation's lanes.
    ///
    /// # Panics
    /// If this CPU cannot run it (`runs_here`): the vector types would be undefined
    /// behaviour there. `selected` and `supported` only give ones it runs.
    #[inline]
    pub fn run<K: LaneLoop>(self, body: K) -> K::Output {
        assert!(self.runs_here(), "{} does not run on this CPU", self.name());
        match self {
            Simd::Portable => body.run::<Portable<4>>(),
            Simd::Portable8 => body.run::<Portable<8>>(),
            // SAFETY: checked above.
            #[cfg(target_arch = "x86_64")]
            Simd::Avx2 => unsafe { avx2::run(body) },
            // SAFETY: checked above.
            #[cfg(target_arch = "x86_64")]
            Simd::Avx512 => unsafe { avx512::run(body) },
            #[cfg(not(target_arch = "x86_64"))]
            Simd::Avx2 | Simd::Avx512 => unreachable!("never runs here"),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::ffi::OsStr;

    /// Each lane operation of `Lanes` on 8 pairs of special and ordinary values, as bits:
    /// the x86 max/min and ordered less-than, the sign flip, ±0 and NaN included.
    struct Operations<'a> {
        a: &'a [f64; 8],
        b: &'a [f64; 8],
    }

    impl LaneLoop for Operations<'_> {
        type Output = Vec<u64>;

        #[inline(always)]
        fn run<L: Lanes>(self) -> Vec<u64> {
            let mut out = Vec::new();
            for block in (0..8).step_by(L::N) {
                let (a, b) = (L::load(&self.a[block..]), L::load(&self.b[block..]));
                let nodes: Vec<u32> = (0..L::N as u32).rev().collect();
                // SAFETY: nodes 0..N of 8 values, 1 per node.
                let [g] = unsafe { L::gather::<1>(&self.a[block..], &nodes) };
                let states: Vec<u8> = (0..L::N).map(|l| (l % 3) as u8 * 7).collect();
                let lt = L::lt(a, b);
                let results = [
                    a + b,
                    a - b,
                    a * b,
                    a / b,
                    -a,
                    a.sqrt(),
                    a.max(b),
                    a.min(b),
                    a.zero_unless(lt),
                    a.zero_unless(L::and(lt, L::nonzero(&states))),
                    g,
                ];
                for r in results {
                    let mut lanes = [0.0; 8];
                    r.store(&mut lanes);
                    out.extend(lanes[..L::N].iter().map(|x| x.to_bits()));
                }
                out.push(u64::from(L::bits(lt)));
                out.push(a.sum().to_bits());
            }
            out
        }
    }

    /// Every implementation this CPU runs gives the portable lanes' bits lane by lane (the
    /// sums of a width: `portable`'s at 4 lanes, `portable8`'s at 8).
    #[test]
    fn every_implementation_does_the_portable_lane_operations() {
        let nan = f64::NAN;
        let a = [1.5, -0.0, 0.0, nan, 2.0, f64::INFINITY, -3.25, 1e-310];
        let b = [0.0, 0.0, -0.0, 1.0, nan, 2.0, -3.25, 7.0];
        let body = || Operations { a: &a, b: &b };
        let (four, eight) = (Simd::Portable.run(body()), Simd::Portable8.run(body()));
        for simd in Simd::supported() {
            let want = if simd.lanes() == 8 { &eight } else { &four };
            assert_eq!(&simd.run(body()), want, "{simd:?}");
        }
        // The x86 semantics of the portable lanes: max and min give the second operand where
        // either is NaN or both are zeros.
        let max = |x: f64, y: f64| Portable([x]).max(Portable([y])).0[0].to_bits();
        assert_eq!(max(nan, 1.0), 1.0f64.to_bits());
        assert_eq!(max(-0.0, 0.0), 0.0f64.to_bits());
        assert_eq!(max(0.0, -0.0), (-0.0f64).to_bits());
    }

    /// `PERIDYN_SIMD` takes the four names; another value, or one this CPU cannot run, is
    /// refused with a message that names the variable and what it takes.
    #[test]
    fn the_environment_names_an_implementation() {
        assert_eq!(Simd::parse(None), Ok(None));
        assert_eq!(
            Simd::parse(Some(OsStr::new("portable"))),
            Ok(Some(Simd::Portable))
        );
        assert_eq!(
            Simd::parse(Some(OsStr::new("portable8"))),
            Ok(Some(Simd::Portable8))
        );
        let error = Simd::parse(Some(OsStr::new("sse9"))).unwrap_err();
        assert!(
            error.contains("PERIDYN_SIMD") && error.contains("portable, portable8, avx2, avx512")
        );
        for simd in Simd::ALL {
            let parsed = Simd::parse(Some(OsStr::new(simd.name())));
            assert_eq!(parsed.is_ok(), simd.runs_here(), "{simd:?}");
        }
        assert!(Simd::widest().runs_here() && Simd::selected().runs_here());
    }
}
