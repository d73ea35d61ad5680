//! 1D static PD elasticity with a manufactured solution (seed-004 Example 1, thesis §3.2.5), run
//! through the `static-1d-manufactured` preset and `peridyn sweep`'s runner: Ω = (−100, 100),
//! E = 1, c = 2E/δ², ω0, u = sin(x/10), Dirichlet collars of width δ outside Ω, one banded
//! solve. Standard scheme against WLS-2/4/6 (5/11/13 collocation nodes).

use peridyn::report::{self, Axis, SweepRow, SweepSpec};
use peridyn::scene::SchemeKind;

const PRESET: &str = "static-1d-manufactured";

fn sweep(
    variant: Option<&str>,
    set: &[&str],
    spacings: &[f64],
    schemes: &[SchemeKind],
) -> Vec<SweepRow> {
    let spec = SweepSpec {
        preset: PRESET.into(),
        variant: variant.map(str::to_string),
        set: set.iter().map(|s| s.to_string()).collect(),
        axes: vec![Axis {
            key: "discretization.spacing".into(),
            values: spacings.iter().map(|d| format!("{d:?}")).collect(),
        }],
        schemes: schemes.to_vec(),
    };
    let rows = report::run(&spec, &mut |_| {}).expect("the sweep runs");
    for r in &rows {
        assert!(r.failure.is_none(), "{r:?}");
        eprintln!(
            "{:?} {:>8} {:<8} stencil {:>5.1}: error {:.3e}",
            variant,
            r.values[0],
            r.scheme.name(),
            r.stencil,
            r.error.unwrap()
        );
    }
    rows
}

/// Errors by scheme (rows of the same spacing are consecutive).
fn column(rows: &[SweepRow], scheme: SchemeKind) -> Vec<f64> {
    rows.iter()
        .filter(|r| r.scheme == scheme)
        .map(|r| r.error.unwrap())
        .collect()
}

const ALL: [SchemeKind; 4] = [
    SchemeKind::Standard,
    SchemeKind::Wls2,
    SchemeKind::Wls4,
    SchemeKind::Wls6,
];
/// δ = 6 and m = 6, 12, 24, 33 (the papers' finest standard grid: 67 family nodes).
const M_SPACINGS: [f64; 4] = [1.0, 0.5, 0.25, 6.0 / 33.0];

#[test]
fn m_convergence() {
    let rows = sweep(None, &[], &M_SPACINGS, &ALL);
    let [standard, wls2, wls4, wls6] = ALL.map(|s| column(&rows, s));
    // Stencils: the papers' counts.
    let stencils: Vec<f64> = rows.iter().map(|r| r.stencil).collect();
    assert_eq!(&stencils[12..], [67.0, 5.0, 11.0, 13.0]);
    // The standard scheme's error falls as m grows (second order: β makes the 1D quadrature
    // of the second moment exact at integer m).
    for w in standard.windows(2) {
        assert!(w[1] < w[0], "standard: {standard:?}");
    }
    for k in 0..M_SPACINGS.len() {
        // The papers: WLS-4 ≈ 10² and WLS-6 ≈ 10⁵ times more accurate than WLS-2; asserted
        // at half and a tenth of that (issue 14 item 6).
        assert!(
            wls4[k] * 50.0 <= wls2[k],
            "WLS-4 ≥ 50× WLS-2 at grid {k}: {wls4:?} {wls2:?}"
        );
        assert!(
            wls6[k] * 1e4 <= wls2[k],
            "WLS-6 ≥ 10⁴× WLS-2 at grid {k}: {wls6:?} {wls2:?}"
        );
    }
    // The WLS errors plateau: set by the basis order, not by m (within 3×: at m = 33 the
    // auxiliary points of WLS-2 fall half-way between nodes and the tie rule picks an
    // asymmetric set).
    for col in [&wls2, &wls4, &wls6] {
        let (lo, hi) = col.iter().fold((f64::INFINITY, 0.0f64), |(lo, hi), &v| {
            (lo.min(v), hi.max(v))
        });
        assert!(hi < 3.0 * lo, "WLS should plateau: {col:?}");
    }
}

/// "WLS-2 on a coarse grid beats the standard scheme with 67 family nodes" holds against the
/// original standard scheme (β = 1, variant `no-beta`), whose error falls only as 1/m. With β
/// (3.2), the standard scheme at m = 33 is 500× better than WLS-2: WLS-2 is E u'' locally and
/// misses the nonlocal c δ⁴ u⁗/48 term (≈ 1 % at δ = 6).
#[test]
fn coarse_wls2_against_the_standard_scheme_with_67_family_nodes() {
    let wls2_coarse = column(
        &sweep(None, &[], &[1.0], &[SchemeKind::Wls2]),
        SchemeKind::Wls2,
    )[0];
    let original = sweep(Some("no-beta"), &[], &[6.0 / 33.0], &[SchemeKind::Standard]);
    assert_eq!(original[0].stencil, 67.0);
    assert!(
        wls2_coarse < original[0].error.unwrap(),
        "{wls2_coarse} vs {original:?}"
    );
    let with_beta = sweep(None, &[], &[6.0 / 33.0], &[SchemeKind::Standard]);
    assert!(with_beta[0].error.unwrap() < wls2_coarse / 100.0);
}

/// δ = 8, 4, 2, 1, 0.5, 0.25 at m = 12 (variant `delta`, the local problem (3.75)–(3.76)).
const DELTA_SPACINGS: [f64; 6] = [
    8.0 / 12.0,
    4.0 / 12.0,
    2.0 / 12.0,
    1.0 / 12.0,
    0.5 / 12.0,
    0.25 / 12.0,
];

/// Every WLS error falls monotonically as δ shrinks (asymptotic compatibility). The standard
/// scheme of the papers (β = 1) does not: its error grows, then stalls at ≈ 9 % (its discrete
/// second moment is m(m+1)/2 Δx², 1/m too large). With β (3.2) at integer m the 1D quadrature
/// of the second moment is exact and it converges at second order — not what the thesis
/// reports, stated in docs/validation.md.
#[test]
fn delta_convergence() {
    let rows = sweep(Some("delta"), &[], &DELTA_SPACINGS, &ALL);
    for scheme in [SchemeKind::Wls2, SchemeKind::Wls4, SchemeKind::Wls6] {
        let col = column(&rows, scheme);
        for w in col.windows(2) {
            assert!(w[1] < w[0], "{scheme:?}: {col:?}");
        }
    }
    let with_beta = column(&rows, SchemeKind::Standard);
    for w in with_beta.windows(2) {
        assert!(w[1] < w[0] / 3.0, "second order with β: {with_beta:?}");
    }
    let original = column(
        &sweep(
            Some("delta"),
            &["discretization.volume_correction=false"],
            &DELTA_SPACINGS,
            &[SchemeKind::Standard],
        ),
        SchemeKind::Standard,
    );
    assert!(
        original.windows(2).any(|w| w[1] >= w[0]),
        "β = 1 must not decrease monotonically: {original:?}"
    );
    assert!(original[5] > 0.5 * original[0], "stalls: {original:?}");
}
