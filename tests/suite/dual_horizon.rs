//! Dual-horizon OSB with particle splitting and ADR (issue 17; zeng2024): patch tests of the
//! operator against the classical energy and stress, rigid motions across a size change,
//! conservation through splits, the crack opening against Tada's formula and a finite-element
//! reference, branching onset and the Kalthoff–Winkler DH crack angles.

use peridyn::adapt::splitting::{self, SplitColumns};
use peridyn::discretization::Nodes;
use peridyn::discretization::buckets::Buckets;
use peridyn::metrics::branching::{BranchProbe, Branches};
use peridyn::model::osb::{OsbHorizon, OsbMaterial};
use peridyn::model::pmb::Plane;
use peridyn::scene::Scene;
use peridyn::scheme::dual_horizon::{Body, BondWeights, DualBonds, ParticleTerms};
use peridyn::sim::DualHorizonSimulation;
use peridyn::solver::Stepper;

const DX: f64 = 1e-3;
const M: f64 = 3.015;

fn material(nu: f64, plane: Plane) -> OsbMaterial {
    OsbMaterial {
        youngs_modulus: 200e9,
        poisson_ratio: nu,
        plane,
        thickness: 1e-3,
        fracture_energy: None,
    }
}

/// An n × n cell-centred lattice at DX.
fn lattice(n: usize) -> Vec<[f64; 2]> {
    (0..n * n)
        .map(|k| [((k % n) as f64 + 0.5) * DX, ((k / n) as f64 + 0.5) * DX])
        .collect()
}

/// Positions of a homogeneous deformation y = x + ε x (ε symmetric) or a rigid motion.
fn deform(x: &[[f64; 2]], f: [[f64; 2]; 2], shift: [f64; 2]) -> Vec<[f64; 2]> {
    x.iter()
        .map(|p| {
            [
                f[0][0] * p[0] + f[0][1] * p[1] + shift[0],
                f[1][0] * p[0] + f[1][1] * p[1] + shift[1],
            ]
        })
        .collect()
}

/// Relative error of W and the largest relative stress error over the particles at least
/// `inset` from every edge of an n × n lattice, for strain ε.
fn patch_errors(
    m: &OsbMaterial,
    weights: BondWeights,
    strain: [[f64; 2]; 2],
    n: usize,
    inset: f64,
) -> (f64, f64) {
    let x = lattice(n);
    let volumes = vec![DX * DX * m.thickness; x.len()];
    let constants = vec![m.at(M * DX); x.len()];
    let body = Body {
        reference: &x,
        volumes: &volumes,
        constants: &constants,
        thickness: m.thickness,
    };
    let buckets = Buckets::new(&x, M * DX * 1.01, DX);
    let mut bonds = DualBonds::build(&body, &buckets, weights);
    if std::env::var("SHOW").is_ok() {
        println!("{} moment fits fell back", bonds.fallbacks);
    }
    let f = [
        [1.0 + strain[0][0], strain[0][1]],
        [strain[1][0], 1.0 + strain[1][1]],
    ];
    let y = deform(&x, f, [0.0; 2]);
    let mut terms = vec![ParticleTerms::default(); x.len()];
    bonds.evaluate(&body, &y, &mut terms);
    let (w_classical, s_classical) = m.classical(strain);
    let s_scale = s_classical
        .iter()
        .flatten()
        .fold(0.0f64, |a, s| a.max(s.abs()));
    let side = n as f64 * DX;
    let (mut w_err, mut s_err) = (0.0f64, 0.0f64);
    for (k, p) in x.iter().enumerate() {
        if p.iter().any(|&c| c < inset || c > side - inset) {
            continue;
        }
        // The corner particles: a quarter horizon cannot carry the zero shear moment with
        // positive weights, so their fit falls back to scalar factors (`moment_fit`).
        if p.iter().all(|&c| c < DX || c > side - DX) {
            continue;
        }
        let e = (terms[k].energy_density / w_classical - 1.0).abs();
        if e > 1e-2 && std::env::var("SHOW").is_ok() {
            println!(
                "particle {k} at {:?}: W error {e:.3e}",
                [p[0] / DX, p[1] / DX]
            );
        }
        w_err = w_err.max(e);
        let s = bonds.stress(k, &body);
        for i in 0..2 {
            for j in 0..2 {
                s_err = s_err.max((s[i][j] - s_classical[i][j]).abs() / s_scale);
            }
        }
    }
    (w_err, s_err)
}

/// zeng2024 §1 patch test (issue 17): a homogeneous strain gives the classical energy density
/// and stress within 1 % away from the boundary at ν = 0.2 and 0.33, δ = 3.015 Δ. The plain
/// volumes of the paper's quadrature (without its surface correction) miss 1 % in the bulk
/// (the test can fail); the moment-matched weights meet it, and at the free edges too (all
/// but the four corner particles, whose fit falls back to scalar factors).
#[test]
fn homogeneous_strain_gives_the_classical_energy_and_stress() {
    // A general small strain: both normal components and a shear.
    let strain = [[1.0e-4, 2.0e-5], [2.0e-5, -3.0e-5]];
    for (nu, plane) in [
        (0.2, Plane::Stress),
        (0.33, Plane::Stress),
        (0.2, Plane::Strain),
    ] {
        let m = material(nu, plane);
        let (w, s) = patch_errors(&m, BondWeights::Moments, strain, 21, 4.0 * DX);
        println!("ν = {nu} {plane:?}: moments, bulk: W {w:.2e}, σ {s:.2e}");
        assert!(w < 1e-2 && s < 1e-2, "moments, bulk: W {w}, σ {s}");
        let (w_edge, s_edge) = patch_errors(&m, BondWeights::Moments, strain, 21, 0.0);
        println!("ν = {nu} {plane:?}: moments, every particle: W {w_edge:.2e}, σ {s_edge:.2e}");
        assert!(
            w_edge < 1e-2 && s_edge < 1e-2,
            "moments, edges: W {w_edge}, σ {s_edge}"
        );
        let (w_plain, s_plain) = patch_errors(&m, BondWeights::Volume, strain, 21, 4.0 * DX);
        println!("ν = {nu} {plane:?}: plain volumes, bulk: W {w_plain:.2e}, σ {s_plain:.2e}");
        assert!(
            w_plain.max(s_plain) > 1e-2,
            "the plain quadrature misses 1 %"
        );
    }
}

/// A lattice whose right half has split once: the DH body of the size-change tests.
struct Refined {
    nodes: Nodes<2>,
    columns: SplitColumns,
    bonds: DualBonds,
    buckets: Buckets,
    material: OsbMaterial,
}

impl Refined {
    fn new(n: usize, weights: BondWeights, horizon_ratio: f64) -> Refined {
        let mut body = Refined::unsplit(n, weights);
        let (x, side) = (body.nodes.reference().to_vec(), n as f64 * DX);
        let parents: Vec<u32> = (0..x.len() as u32)
            .filter(|&k| x[k as usize][0] > 0.5 * side)
            .collect();
        body.split(&parents, horizon_ratio);
        body
    }

    /// The n × n lattice before any split.
    fn unsplit(n: usize, weights: BondWeights) -> Refined {
        let material = material(0.25, Plane::Stress);
        let x = lattice(n);
        let volumes = vec![DX * DX * material.thickness; x.len()];
        let mut nodes = Nodes::new(x.clone(), volumes);
        let columns = SplitColumns {
            position: nodes.fields.add_values("position", x.clone()),
            constants: nodes.fields.add("constants", material.at(M * DX)),
            level: nodes.fields.add("level", 0u8),
            spacing: nodes.fields.add("spacing", DX),
        };
        let buckets = Buckets::new(&x, (M + 1.0) * DX, DX);
        let bonds = DualBonds::build(&body_of(&nodes, &columns, &material), &buckets, weights);
        Refined {
            nodes,
            columns,
            bonds,
            buckets,
            material,
        }
    }

    fn split(&mut self, parents: &[u32], horizon_ratio: f64) {
        splitting::split(
            parents,
            &mut self.nodes,
            &self.columns,
            &mut self.bonds,
            &mut self.buckets,
            &self.material,
            horizon_ratio,
            &[],
        );
    }

    /// Forces at positions y.
    fn forces(&mut self, y: &[[f64; 2]]) -> Vec<ParticleTerms> {
        let body = body_of(&self.nodes, &self.columns, &self.material);
        let mut terms = vec![ParticleTerms::default(); y.len()];
        self.bonds.evaluate(&body, y, &mut terms);
        terms
    }

    /// A bulk bond force scale: one parent bond at a stretch of 1e-3, the order of a brittle
    /// solid's s_c (round-off of positions ~1e-2 m at 1 mm bonds is a stretch of ~1e-15, so a
    /// rigid motion's forces are ~1e-12 of it).
    fn bond_force_scale(&self) -> f64 {
        let c: &OsbHorizon = &self.nodes.fields.get(self.columns.constants)[0];
        let v = DX * DX * self.material.thickness;
        2.0 * c.horizon * c.b * 1e-3 * v * v
    }
}

fn body_of<'a>(nodes: &'a Nodes<2>, columns: &SplitColumns, material: &OsbMaterial) -> Body<'a> {
    Body {
        reference: nodes.reference(),
        volumes: nodes.volumes(),
        constants: nodes.fields.get(columns.constants),
        thickness: material.thickness,
    }
}

/// Issue 17, item 3 (families rebuilt locally): a split appends the rows it changes and
/// renews only the dual lists they reach, compacting now and then. After 24 or more splits of
/// one parent each (children of earlier splits among them, so three particle sizes meet; two
/// compactions or more, and rows left behind since the last) the bonds must be those of a global rebuild of the final body: the
/// same families and dual horizons, the same weights (the same fit of the same rows), and
/// with the bonds across a line cut (after a force pass with them intact) and a homogeneous
/// strain, the same forces (to summation order, 1e-10 of a bond force) and damage (1e-12).
#[test]
fn local_row_updates_match_a_global_rebuild() {
    let n = 16;
    let mut local = Refined::unsplit(n, BondWeights::Moments);
    // A walk along the diagonal, then into the children of its first splits, until at least
    // 24 splits and two compactions are done and rows are left behind again.
    let (mut splits, mut compactions) = (0u32, 0);
    while splits < 24 || compactions < 2 || local.bonds.slot_count() == local.bonds.bond_count() {
        let parent = if splits < 16 {
            splits * (n as u32 + 1)
        } else {
            256 + 3 * (splits - 16)
        };
        let before = local.bonds.slot_count();
        local.split(&[parent], 0.5);
        compactions += usize::from(local.bonds.slot_count() < before);
        assert!(
            local.bonds.rows_are_disjoint(),
            "rows overlap after split {splits}"
        );
        splits += 1;
        assert!(splits < 40, "{compactions} compactions in {splits} splits");
    }
    let count = local.nodes.len();
    assert_eq!(count, 256 + 3 * splits as usize);
    let body = body_of(&local.nodes, &local.columns, &local.material);
    let buckets = Buckets::new(body.reference, (M + 1.0) * DX, 0.0);
    let mut global = DualBonds::build(&body, &buckets, BondWeights::Moments);
    assert_eq!(local.bonds.bond_count(), global.bond_count());
    let owners = |bonds: &DualBonds, k: usize| -> Vec<u32> {
        let (offsets, neighbors) = bonds.compact_rows();
        let mut owners: Vec<u32> = (0..count as u32)
            .filter(|&i| {
                neighbors[offsets[i as usize]..offsets[i as usize + 1]].contains(&(k as u32))
            })
            .collect();
        owners.sort_unstable();
        owners
    };
    for k in 0..count {
        let (a, b) = (local.bonds.range(k), global.range(k));
        assert_eq!(
            local.bonds.neighbors[a.clone()],
            global.neighbors[b.clone()],
            "family of {k}"
        );
        for (wa, wb) in [
            (&local.bonds.weight_theta, &global.weight_theta),
            (&local.bonds.weight_distortion, &global.weight_distortion),
        ] {
            for (p, q) in wa[a.clone()].iter().zip(&wb[b.clone()]) {
                assert!(
                    (p - q).abs() <= 1e-12 * q.abs(),
                    "weights of {k}: {p} against {q}"
                );
            }
        }
        let dual_owners = |bonds: &DualBonds| -> Vec<u32> {
            let mut owners: Vec<u32> = bonds
                .dual_bonds(k)
                .iter()
                .map(|&d| {
                    // The owner of slot d: the row whose range holds it.
                    (0..count as u32)
                        .find(|&i| bonds.range(i as usize).contains(&(d as usize)))
                        .unwrap()
                })
                .collect();
            owners.sort_unstable();
            owners
        };
        assert_eq!(
            dual_owners(&local.bonds),
            owners(&global, k),
            "dual horizon of {k}"
        );
        assert_eq!(
            dual_owners(&global),
            owners(&global, k),
            "dual horizon of {k} (global)"
        );
    }
    // The bonds across y = 8.2 DX cut in both (the material has no s_c), then a small
    // homogeneous strain.
    let cut = |bonds: &mut DualBonds| {
        let x = body.reference;
        for k in 0..count {
            for b in bonds.range(k) {
                let j = bonds.neighbors[b] as usize;
                if (x[k][1] - 8.2 * DX).signum() != (x[j][1] - 8.2 * DX).signum() {
                    bonds.intact[b] = 0;
                }
            }
        }
    };
    let y = deform(
        body.reference,
        [[1.0 + 1e-4, 2e-5], [2e-5, 1.0 - 3e-5]],
        [0.0; 2],
    );
    let mut from_local = vec![ParticleTerms::default(); count];
    let mut from_global = vec![ParticleTerms::default(); count];
    // A pass before the cut leaves every bond's force in the local arrays: the cut bonds'
    // must not come back as reactions.
    local.bonds.evaluate(&body, &y, &mut from_local);
    cut(&mut local.bonds);
    cut(&mut global);
    // Every particle splittable: the force pass gives the damage from its cached
    // denominators and the strains of (16).
    local.bonds.criteria = vec![f64::MIN; count];
    global.criteria = vec![f64::MIN; count];
    local.bonds.evaluate(&body, &y, &mut from_local);
    global.evaluate(&body, &y, &mut from_global);
    // Summation order moves a force by ~1e-15 of a bond force; a missing or doubled bond
    // by ~1e-1 of one.
    let scale = local.bond_force_scale();
    for k in 0..count {
        for i in 0..2 {
            let (p, q) = (from_local[k].force[i], from_global[k].force[i]);
            assert!(
                (p - q).abs() <= 1e-10 * scale,
                "force on {k}: {p} against {q}"
            );
        }
    }
    let (da, db) = (
        local.bonds.damage(body.volumes),
        global.damage(body.volumes),
    );
    assert!(da.iter().any(|&d| d > 0.1));
    for k in 0..count {
        for (what, a, b) in [
            ("damage", da[k], db[k]),
            ("force pass's damage", from_local[k].damage, db[k]),
            ("ε_xx", from_local[k].strains[0], from_global[k].strains[0]),
            ("ε_yy", from_local[k].strains[1], from_global[k].strains[1]),
        ] {
            assert!((a - b).abs() <= 1e-12, "{what} of {k}: {a} against {b}");
        }
    }
}

/// zeng2024 §2 (issue 17): particles of different sizes interact without ghost forces — a
/// rigid translation and a finite rigid rotation across a size change give zero force on every
/// particle to 1e-10 of a bulk bond force; a homogeneous strain's interface force is reported.
#[test]
fn rigid_motions_across_a_size_change_give_no_force() {
    let mut body = Refined::new(16, BondWeights::Moments, 0.5);
    let n = body.nodes.len();
    assert_eq!(n, 16 * 8 + 4 * 16 * 8, "the right half split once");
    let x = body.nodes.reference().to_vec();
    let scale = body.bond_force_scale();
    let (c, s) = (0.3f64.cos(), 0.3f64.sin());
    for (name, f, shift) in [
        ("translation", [[1.0, 0.0], [0.0, 1.0]], [3e-4, -2e-4]),
        ("rotation 0.3 rad", [[c, -s], [s, c]], [1e-3, 5e-4]),
    ] {
        let y = deform(&x, f, shift);
        let terms = body.forces(&y);
        let worst = terms
            .iter()
            .map(|t| t.force[0].hypot(t.force[1]))
            .fold(0.0f64, f64::max);
        println!("{name}: largest force / bond force {:.2e}", worst / scale);
        assert!(worst <= 1e-10 * scale, "{name}: {worst} vs scale {scale}");
    }
    // A homogeneous strain: zero in each uniform region's interior, a residual at the size
    // change (the horizon jump's, next test).
    let e = 1e-4;
    let y = deform(&x, [[1.0 + e, 0.0], [0.0, 1.0]], [0.0; 2]);
    let terms = body.forces(&y);
    let side = 16.0 * DX;
    let (mut interface, mut interior) = (0.0f64, 0.0f64);
    for (k, p) in x.iter().enumerate() {
        let f = terms[k].force[0].hypot(terms[k].force[1]);
        let inner = p.iter().all(|&q| q > 4.0 * DX && q < side - 4.0 * DX);
        if (p[0] - 0.5 * side).abs() < 3.5 * DX {
            interface = interface.max(f);
        } else if inner {
            interior = interior.max(f);
        }
    }
    println!(
        "uniform strain 1e-4: interface force / bond force {:.3e}, interior {:.2e}",
        interface / scale,
        interior / scale
    );
    assert!(interior <= 1e-9 * scale, "interior {interior}");
}

/// Where the strain field's force at a size change comes from (docs/validation.md):
/// under a homogeneous strain the reactions k receives from its dual horizon H'_k are bonds
/// owned by particles with their own horizon's constants. In the continuum each side's half
/// of H'_k gives a force ∝ c(δ) δ² ∝ 1/δ, so a horizon jump δ_f ≠ δ_c leaves a net force
/// ∝ (1/δ_f − 1/δ_c) — of the order of a free edge's — and one horizon on both sizes
/// (zeng2024 Table 3's δ₂ = δ₁) leaves only the quadrature's residual. Asserted: the jump's
/// interface force is at least 5 times the one-horizon body's (the continuum says unbounded)
/// and at least a tenth of the free edge's traction force in the same field.
#[test]
fn a_horizon_jump_leaves_a_force_under_strain_one_horizon_does_not() {
    let e = 1e-4;
    let side = 24.0 * DX;
    let interface_and_edge = |ratio: f64| {
        let mut body = Refined::new(24, BondWeights::Moments, ratio);
        let x = body.nodes.reference().to_vec();
        let y = deform(&x, [[1.0 + e, 0.0], [0.0, 1.0 - 0.3 * e]], [0.0; 2]);
        let terms = body.forces(&y);
        let volumes = body.nodes.volumes().to_vec();
        let (mut interface, mut edge) = (0.0f64, 0.0f64);
        for (k, p) in x.iter().enumerate() {
            if (p[1] - 0.5 * side).abs() > 4.0 * DX {
                continue;
            }
            // Force per unit volume: children and parents compare.
            let f = terms[k].force[0].abs() / volumes[k];
            if (p[0] - 0.5 * side).abs() < 3.5 * DX {
                interface = interface.max(f);
            } else if p[0] < DX {
                edge = edge.max(f);
            }
        }
        (interface, edge)
    };
    let (jump, edge) = interface_and_edge(0.5);
    let (one, _) = interface_and_edge(1.0);
    println!(
        "force per volume at the size change / at the free edge: horizon jump {:.3}, one horizon {:.3}",
        jump / edge,
        one / edge
    );
    assert!(jump >= 5.0 * one, "jump {jump:e}, one horizon {one:e}");
    assert!(jump >= 0.1 * edge, "jump {jump:e}, edge {edge:e}");
}

/// Steps `sim` to its last step, or until its relaxation converges.
fn run_to_end(sim: &mut DualHorizonSimulation) {
    let total = sim.info().total_steps;
    while sim.steps_done() < total && !sim.converged() {
        sim.step().unwrap();
    }
}

/// Tada's crack-mouth opening d0 = 4σa/E f(a/L), zeng2024 (31)–(32).
fn tada(stress: f64, crack: f64, width: f64, young: f64) -> f64 {
    let c = (std::f64::consts::PI * crack / (2.0 * width)).cos();
    4.0 * stress * crack / young * (1.46 + 3.42 * (1.0 - c)) / (c * c)
}

#[test]
fn tada_formula_reproduces_the_printed_values() {
    // zeng2024 Table 2, "Analytic Formula" (μm), at L = 50 mm.
    for (a, printed) in [(5.0, 1.5398), (10.0, 3.5984), (25.0, 24.6169)] {
        let d = tada(10e6, a * 1e-3, 50e-3, 200e9) * 1e6;
        assert!((d - printed).abs() < 1e-4, "a = {a} mm: {d} vs {printed}");
    }
}

/// The elastic mouth opening (m) of the 50 × 200 mm strip at σ = 10 MPa, E = 200 GPa, plane
/// stress, by `scripts/sent_cmod_fem.py` (8-node quadrilaterals graded to the tip, four
/// nested meshes, Richardson-extrapolated; converged to < 10⁻⁴, and to 10⁻⁶ of the H = 400 mm
/// strip's): (a/L, opening). Tada's formula lies 0.35–1.57 % below these.
const ELASTIC_OPENING: [(f64, f64); 5] = [
    (0.1, 1.54900e-6),
    (0.2, 3.65426e-6),
    (0.3, 7.03595e-6),
    (0.4, 13.04774e-6),
    (0.5, 24.70218e-6),
];

#[test]
fn tada_formula_is_below_the_finite_element_opening() {
    // Tada quotes his fit as accurate to 1 %; the independent FEM says 1.6 % at a/L = 0.3.
    for (ratio, fem) in ELASTIC_OPENING {
        let d = tada(10e6, ratio * 50e-3, 50e-3, 200e9);
        let gap = d / fem - 1.0;
        assert!((-0.016..-0.003).contains(&gap), "a/L = {ratio}: {gap:+e}");
    }
}

/// zeng2024 Sect. 4.1 against an independent reference: the coarse plate (Δ = 1 mm, δ =
/// 3.015 mm, no refinement) relaxed by ADR opens within 1.5 % (the issue's bound for the
/// paper's fine run, here against an exact elastic answer instead of Tada's fit) of the
/// finite-element opening at a/L = 0.1, 0.3 and 0.5 (measured +0.35 %, +0.86 %, +1.03 %;
/// with the tip's tie bonds cut, `ends = "closed"`, a/L = 0.5 opens +4.8 % and fails it).
#[test]
fn crack_opening_matches_the_elastic_opening_of_the_strip() {
    for (ratio, fem) in [ELASTIC_OPENING[0], ELASTIC_OPENING[2], ELASTIC_OPENING[4]] {
        let tip = format!("{} mm", ratio * 50.0);
        let crack = format!(
            r#"precracks=[{{segment={{from=["-1 mm","100 mm"],to=["{tip}","100 mm"],ends="open"}}}}]"#
        );
        let scene = Scene::load_with("crack-opening", Some("coarse"), &[crack]).unwrap();
        let mut sim = DualHorizonSimulation::new(&scene).unwrap();
        run_to_end(&mut sim);
        assert!(sim.converged(), "a/L = {ratio}: not converged");
        let opening = sim.frame().scalar("opening/mouth").unwrap();
        let error = opening / fem - 1.0;
        println!(
            "a/L = {ratio}: {:.4} µm against {:.4} µm (FEM): {:+.2} %, {} iterations",
            opening * 1e6,
            fem * 1e6,
            100.0 * error,
            sim.steps_done()
        );
        assert!(error.abs() < 0.015, "a/L = {ratio}: error {error:+e}");
    }
}

/// The branching plate's probe (`metrics::branching`): the pre-crack on y = 20 mm ends at
/// x = 50 mm; cracked means φ > 0.45 (a pre-crack face keeps φ = 0.393); columns of one
/// coarse cell; two bands more than one coarse horizon apart are two cracks.
const BRANCH_PROBE: BranchProbe = BranchProbe {
    line_y: 20e-3,
    from_x: 50e-3,
    threshold: 0.45,
    column: 1e-3,
    gap: 3.015e-3,
};

/// Runs `sim` for `steps`, sampling the crack front every `sample` steps; returns the
/// branches of the last damage field and the time the front first reached the branch point
/// (linear between samples).
fn branching_run(
    sim: &mut DualHorizonSimulation,
    steps: u64,
    sample: u64,
) -> (Option<Branches>, Option<f64>) {
    let mut fronts = vec![(0.0, f64::NEG_INFINITY)];
    while sim.steps_done() < steps {
        sim.step().unwrap();
        if sim.steps_done().is_multiple_of(sample) {
            let front = BRANCH_PROBE.front(sim.reference(), &sim.damage());
            fronts.push((sim.time(), front.unwrap_or(f64::NEG_INFINITY)));
        }
    }
    let branches = BRANCH_PROBE.branches(sim.reference(), &sim.damage());
    let onset = branches.and_then(|b| {
        fronts.windows(2).find_map(|w| {
            let ((t0, f0), (t1, f1)) = (w[0], w[1]);
            let xb = b.point[0];
            (f1 >= xb).then(|| {
                if f0.is_finite() && f0 < xb {
                    t0 + (xb - f0) / (f1 - f0) * (t1 - t0)
                } else {
                    t1
                }
            })
        })
    });
    (branches, onset)
}

/// zeng2024 Sect. 4.2, Case 1 (σ = 1 MPa), adaptive: the crack branches at ≈ 35 µs. The
/// branch point is where the lines through the two branches meet; the onset is when the
/// crack front (sampled every 0.5 µs) reached it. Acceptance: 35 ± 5 µs, the branches
/// diverging (upper above, lower below the original line).
#[test]
fn branching_case_1_branches_at_35_microseconds() {
    let scene = Scene::load_with("branching", None, &["time.end=\"60 us\"".into()]).unwrap();
    let mut sim = DualHorizonSimulation::new(&scene).unwrap();
    let steps = sim.info().total_steps;
    let (branches, onset) = branching_run(&mut sim, steps, 50);
    let b = branches.expect("two branches by 60 µs");
    let onset = onset.expect("the front passed the branch point");
    println!(
        "branch point ({:.2}, {:.2}) mm, first two-band column {:.1} mm, angles {:.1}° / {:.1}°, onset {:.2} µs, {} particles",
        b.point[0] * 1e3,
        b.point[1] * 1e3,
        b.first_split_column * 1e3,
        b.angles[0],
        b.angles[1],
        onset * 1e6,
        sim.len()
    );
    assert!(b.angles[0] > 5.0 && b.angles[1] < -5.0, "{b:?}");
    assert!((30e-6..=40e-6).contains(&onset), "onset {onset:e} s");
}

/// The primary crack angles (upper, lower) of `kalthoff-winkler-dh` `variant` at 100 µs.
fn kalthoff_winkler_dh_angles(variant: &str) -> [f64; 2] {
    let scene = Scene::load("kalthoff-winkler-dh", Some(variant)).unwrap();
    let mut sim = DualHorizonSimulation::new(&scene).unwrap();
    run_to_end(&mut sim);
    let angles = sim.crack_angles();
    let angle = |name: &str| {
        angles
            .iter()
            .find(|(n, _)| n == name)
            .and_then(|(_, a)| *a)
            .unwrap_or_else(|| panic!("{variant}: no {name} crack"))
    };
    [angle("upper"), angle("lower")]
}

/// Issue 17, zeng2024 Sect. 4.3 (Table 8: coarse 61.80°, adaptive 60.88°, fine 66.06°): each
/// run at 0.7 of its own stable step, the adaptive run's primary crack angles lie within 3° of
/// the fine run's (the issue's criterion), and the fine run's within the same 3° of the
/// paper's fine angle, the one we reproduce (the paper's adaptive angle is not closer to its
/// fine one than its coarse angle is, so it is no reference for an adaptive run).
#[test]
fn kalthoff_winkler_dh_adaptive_angles_follow_the_fine_run() {
    let adaptive = kalthoff_winkler_dh_angles("own-step");
    let fine = kalthoff_winkler_dh_angles("fine-own-step");
    println!("adaptive {adaptive:.2?}°, fine {fine:.2?}° (paper fine 66.06°)");
    for (a, f) in adaptive.iter().zip(fine) {
        assert!((a - f).abs() <= 3.0, "adaptive {adaptive:?} fine {fine:?}");
        assert!((f - 66.06).abs() <= 3.0, "fine {fine:?}");
    }
}

/// Exploration and the measurements of docs/validation.md: runs PRESET (default crack-opening),
/// variant PRESET_VARIANT (default small; empty: the base), overrides SET (separated by `;`),
/// printing the ADR history every EVERY steps and the final frame's figures.
#[test]
#[ignore = "a measurement: PRESET, PRESET_VARIANT, SET, EVERY"]
fn dual_horizon_measurement() {
    let preset = std::env::var("PRESET").unwrap_or_else(|_| "crack-opening".into());
    let variant = std::env::var("PRESET_VARIANT").unwrap_or_else(|_| "small".into());
    let sets = crate::common::env_overrides("SET");
    let variant = (!variant.is_empty()).then_some(variant.as_str());
    let scene = Scene::load_with(&preset, variant, &sets).unwrap();
    let start = std::time::Instant::now();
    let mut sim = DualHorizonSimulation::new(&scene).unwrap();
    let setup = start.elapsed().as_secs_f64();
    let first = sim.len();
    let every: u64 = std::env::var("EVERY")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(u64::MAX);
    let total = sim.info().total_steps;
    if preset == "branching" {
        let (_, onset) = branching_run(&mut sim, total, 50);
        println!("branching onset {:?} µs", onset.map(|t| t * 1e6));
    }
    while sim.steps_done() < total && !sim.converged() {
        sim.step().unwrap();
        if sim.steps_done().is_multiple_of(every) {
            let f = sim.frame();
            let get = |n: &str| f.scalar(n).unwrap_or(f64::NAN);
            println!(
                "{:6} t {:.3e} particles {} residual {:.3e} opening {:.5e} strain {:.4e}",
                sim.steps_done(),
                sim.time(),
                sim.len(),
                get("adr/residual"),
                get("opening/mouth"),
                get("energy/strain"),
            );
        }
    }
    let wall = start.elapsed().as_secs_f64();
    if preset == "branching" {
        let (x, damage) = (sim.reference(), sim.damage());
        let b = BRANCH_PROBE.branches(x, &damage);
        println!(
            "branches {b:?}; damaged (φ ≥ 0.2 / 0.3 / 0.45) between them: {} / {} / {}",
            BRANCH_PROBE.between(x, &damage, 0.2),
            BRANCH_PROBE.between(x, &damage, 0.3),
            BRANCH_PROBE.between(x, &damage, 0.45)
        );
    }
    if let Ok(line) = std::env::var("PROFILE_Y") {
        // The opening u_y(above) − u_y(below) of the rows nearest y = PROFILE_Y (m), per
        // column x < 6 mm.
        let line: f64 = line.parse().unwrap();
        let (x, y) = (sim.reference(), sim.positions());
        let mut columns: std::collections::BTreeMap<i64, (Option<usize>, Option<usize>)> =
            Default::default();
        for k in 0..x.len() {
            if x[k][0] > 6e-3 {
                continue;
            }
            let entry = columns.entry((x[k][0] * 1e7).round() as i64).or_default();
            let slot = if x[k][1] > line {
                &mut entry.0
            } else {
                &mut entry.1
            };
            let better = slot.is_none_or(|s| (x[k][1] - line).abs() < (x[s][1] - line).abs());
            if better {
                *slot = Some(k);
            }
        }
        for (col, (up, down)) in columns {
            if let (Some(u), Some(d)) = (up, down) {
                let open = (y[u][1] - x[u][1]) - (y[d][1] - x[d][1]);
                println!(
                    "profile x {:.3} mm rows {:.3}/{:.3} mm opening {:.6} µm",
                    col as f64 * 1e-4,
                    (x[u][1] - line) * 1e3,
                    (x[d][1] - line) * 1e3,
                    open * 1e6
                );
            }
        }
    }
    let f = sim.frame();
    let stages: Vec<String> = sim
        .stages()
        .named()
        .map(|(n, d)| format!("{n} {:.2}", d.as_secs_f64()))
        .collect();
    println!(
        "{preset} {variant:?} {sets:?}: {} steps (dt {:.3e}), wall {wall:.2} s (setup {setup:.2} s; {}), particles {first} → {}",
        sim.steps_done(),
        sim.info().dt,
        stages.join(", "),
        sim.len()
    );
    for (name, value) in &f.scalars {
        if [
            "opening",
            "damage/count",
            "crack_angle",
            "refine",
            "energy",
            "adr",
            "bonds",
        ]
        .iter()
        .any(|p| name.starts_with(p))
        {
            println!("  {name} = {value:.6e}");
        }
    }
}

/// A free 30 × 30 mm steel plate expanding from a velocity ramp (±8 m/s across it, plus a
/// uniform drift): its strains pass α s_c and particles split during the run.
const EXPANDING_PLATE: &str = r#"
name = "expanding-plate"
dimension = 2
[geometry]
box = { min = ["0 mm", "0 mm"], max = ["30 mm", "30 mm"] }
[discretization]
spacing = "1 mm"
horizon = "3.015 dx"
origin = ["0.5 mm", "0.5 mm"]
[material]
model = "osb"
density = "7850 kg/m^3"
youngs_modulus = "200 GPa"
poisson_ratio = 0.3333333333333333
plane = "stress"
thickness = "1 mm"
fracture_energy = "1000 J/m^2"
[refinement]
[[initial.velocity]]
ramp = { component = "x", axis = "x", from = "-8 m/s", to = "8 m/s" }
[[initial.velocity]]
ramp = { component = "y", axis = "y", from = "-8 m/s", to = "8 m/s" }
[[initial.velocity]]
uniform = { value = ["3 m/s", "-2 m/s"] }
[time]
dt = "0.5 stable"
end = "400 steps"
"#;

/// Issue 17: on a free body whose initial velocity triggers splits, linear momentum and mass
/// are conserved through every split to 1e-10 relative (children take a quarter of the
/// parent's mass and its velocity; every directed bond acts on both ends); the total energy
/// changes by the split's placement only, reported.
#[test]
fn splits_conserve_mass_and_momentum_on_a_free_body() {
    let scene = Scene::from_text("expanding-plate.toml", EXPANDING_PLATE, None).unwrap();
    let mut sim = DualHorizonSimulation::new(&scene).unwrap();
    let mass = sim.mass();
    let (_, _, p0) = sim.energies();
    let expected = [3.0 * mass, -2.0 * mass];
    for i in 0..2 {
        assert!(
            (p0[i] - expected[i]).abs() <= 1e-12 * mass * 3.0,
            "initial momentum {p0:?}"
        );
    }
    let scale = p0[0].hypot(p0[1]);
    let mut split_steps = 0;
    let mut last = sim.len();
    let total = sim.info().total_steps;
    while sim.steps_done() < total {
        sim.step().unwrap();
        if sim.len() != last {
            split_steps += 1;
            last = sim.len();
        }
        let (_, _, p) = sim.energies();
        let (dm, dp) = (
            (sim.mass() - mass).abs() / mass,
            (p[0] - p0[0]).hypot(p[1] - p0[1]) / scale,
        );
        assert!(
            dm <= 1e-10 && dp <= 1e-10,
            "step {}: mass {dm:e}, momentum {dp:e}",
            sim.steps_done()
        );
    }
    println!(
        "{} particles after {split_steps} splitting steps ({} parents), {} bonds broken",
        sim.len(),
        sim.split_parents(),
        sim.broken_bonds()
    );
    assert!(
        split_steps >= 1 && sim.len() > 900,
        "the expansion must trigger splits"
    );
    assert_eq!(sim.len(), 900 + 3 * sim.split_parents() as usize);
    let levels = sim.levels();
    assert!(levels.iter().all(|&l| l <= 1), "one refinement level");
    assert_eq!(
        levels.iter().filter(|&&l| l == 1).count(),
        4 * sim.split_parents() as usize
    );
}

/// A relaxation run from the command line stops where ADR meets its tolerance (the step count
/// is only a cap) and says so; its last frame's residual is below the tolerance (1e-6).
#[test]
fn a_recorded_relaxation_stops_when_it_converges() {
    let out = crate::common::temp("dual_horizon", "relaxation.rrd");
    let output = crate::common::peridyn(&[
        "record",
        "crack-opening",
        "--variant",
        "small",
        "--set",
        "refinement.enabled=false",
        "-q",
        "-o",
        out.to_str().unwrap(),
    ]);
    let stdout = String::from_utf8_lossy(&output.stdout);
    assert!(output.status.success(), "{stdout}");
    let line = stdout
        .lines()
        .find(|l| l.starts_with("dynamic relaxation: residual"))
        .unwrap_or_else(|| panic!("no residual line in {stdout}"));
    let words: Vec<&str> = line.split_whitespace().collect();
    let residual: f64 = words[4].parse().unwrap();
    let iterations: u64 = words[6].parse().unwrap();
    assert!(residual < 1e-6, "{line}");
    assert!(iterations < 40_000, "stopped at the step cap: {line}");
}

/// zeng2024 Sect. 4.1 on the `small` plate (50 × 100 mm, a/L = 0.5, coarse): ADR converges to
/// its stated residual and the mouth opening lies within the paper's coarse-grid error band
/// (its Table 2: 1.55–4.21 %, here bounded by 5 %) of Tada's formula.
#[test]
fn crack_opening_relaxes_to_tadas_opening() {
    let scene = Scene::load_with(
        "crack-opening",
        Some("small"),
        &["refinement.enabled=false".into()],
    )
    .unwrap();
    let mut sim = DualHorizonSimulation::new(&scene).unwrap();
    run_to_end(&mut sim);
    let residual = sim.residual().unwrap();
    assert!(
        sim.converged() && residual < 1e-6,
        "residual {residual:e} after {} iterations",
        sim.steps_done()
    );
    let opening = sim.frame().scalar("opening/mouth").unwrap();
    let exact = tada(10e6, 25e-3, 50e-3, 200e9);
    let error = opening / exact - 1.0;
    println!(
        "{} iterations, opening {:.4} µm against {:.4} µm: {:+.2} %",
        sim.steps_done(),
        opening * 1e6,
        exact * 1e6,
        100.0 * error
    );
    assert!(error.abs() < 0.05, "opening error {error}");
}

/// Relaxes the `small` crack-opening plate under `sets` and returns its mouth opening (m).
fn small_plate_opening(sets: &[&str]) -> f64 {
    let sets: Vec<String> = sets.iter().map(|s| s.to_string()).collect();
    let scene = Scene::load_with("crack-opening", Some("small"), &sets).unwrap();
    let mut sim = DualHorizonSimulation::new(&scene).unwrap();
    run_to_end(&mut sim);
    assert!(sim.converged(), "{sets:?}: not converged");
    sim.frame().scalar("opening/mouth").unwrap()
}

/// Splitting every particle before the run gives the fine lattice: the same places, volumes
/// and horizons (δ/2 = 3.015 Δ/2), and the same pre-crack, since a pre-crack's cut is decided
/// by each new bond's own crossing, not inherited from the coarse bond it replaces (which
/// may cross the crack near its tip where the new bond does not). The two relaxed openings
/// then differ only by where each relaxation stopped (residual 10⁻⁶); with the coarse cut
/// inherited the split plate opened 1.7 % wider than the fine lattice (a = 25 mm, 50 × 200 mm).
#[test]
fn a_plate_split_everywhere_opens_like_the_fine_lattice() {
    let coarse = r#"discretization={spacing="2 mm",horizon="3.015 dx",origin=["1 mm","1 mm"]}"#;
    let everywhere = r#"refinement.region={box={min=["0 mm","0 mm"],max=["50 mm","100 mm"]}}"#;
    let fine = r#"discretization={spacing="1 mm",horizon="3.015 dx",origin=["0.5 mm","0.5 mm"]}"#;
    // σ = 10 MPa over one coarse row (two fine rows) at each loaded face.
    let load = r#"boundary=[{name="top",face="y+",thickness="2 mm",body_force=[0.0,5e9]},{name="bottom",face="y-",thickness="2 mm",body_force=[0.0,-5e9]}]"#;
    let split = small_plate_opening(&[coarse, load, everywhere]);
    let lattice = small_plate_opening(&[fine, load, "refinement.enabled=false"]);
    let unsplit = small_plate_opening(&[coarse, load, "refinement.enabled=false"]);
    println!(
        "openings: split everywhere {:.6} µm, fine lattice {:.6} µm, coarse {:.6} µm",
        split * 1e6,
        lattice * 1e6,
        unsplit * 1e6
    );
    assert!(
        (split / lattice - 1.0).abs() < 1e-4,
        "{split:e} vs {lattice:e}"
    );
    // The comparison can fail: the coarse plate opens differently.
    assert!(
        (unsplit / lattice - 1.0).abs() > 1e-3,
        "{unsplit:e} vs {lattice:e}"
    );
}

/// The pre-crack's tip at a whole number of millimetres lies on a symmetry point of the
/// cell-centred lattice, with pairs of bonds through it. Those bonds are left intact (`open`
/// ends, the preset's) or cut (`closed`), whatever the rounding of the tip's and the
/// particles' coordinates (`family::crosses`): a tip moved by 10⁻⁹ mm either way cuts the same
/// bonds; a tip moved by 10⁻³ mm forwards (open) or backwards (closed) changes the cut.
#[test]
fn a_crack_tip_on_a_lattice_symmetry_point_cuts_the_same_bonds_however_it_rounds() {
    for (ends, moved) in [("open", "25.001"), ("closed", "24.999")] {
        let broken = |tip: &str| -> f64 {
            let crack = format!(
                r#"precracks=[{{segment={{from=["-1 mm","50 mm"],to=["{tip} mm","50 mm"],ends="{ends}"}}}}]"#
            );
            let scene = Scene::load_with(
                "crack-opening",
                Some("small"),
                &[crack, "refinement.enabled=false".into()],
            )
            .unwrap();
            let sim = DualHorizonSimulation::new(&scene).unwrap();
            sim.damage().iter().sum()
        };
        let at = broken("25");
        for tip in ["24.999999999", "25.000000001", "25.0000000000000001"] {
            assert_eq!(broken(tip), at, "{ends}: tip at {tip} mm");
        }
        assert_ne!(broken(moved), at, "{ends}: the bonds through the tip");
    }
}

/// α and φ_c act in place (issue 17, live): a stricter α splits fewer particles of the
/// expanding plate over the same steps; values outside their ranges are refused.
#[test]
fn split_parameters_act_in_place() {
    use peridyn::solver::Param;
    let scene = Scene::from_text("expanding-plate.toml", EXPANDING_PLATE, None).unwrap();
    let run = |alpha: Option<f64>| {
        let mut sim = DualHorizonSimulation::new(&scene).unwrap();
        if let Some(a) = alpha {
            sim.tune(Param::SplitStrain(a)).unwrap();
        }
        for _ in 0..150 {
            sim.step().unwrap();
        }
        sim.split_parents()
    };
    let (default, strict) = (run(None), run(Some(0.9)));
    println!("parents split in 150 steps: α = 0.5: {default}, α = 0.9: {strict}");
    assert!(strict < default, "{strict} vs {default}");
    let mut sim = DualHorizonSimulation::new(&scene).unwrap();
    assert!(sim.tune(Param::SplitStrain(1.0)).is_err());
    assert!(sim.tune(Param::SplitDamage(-0.1)).is_err());
    assert!(sim.tune(Param::Chi(0.9)).is_err());
    sim.tune(Param::SplitDamage(0.3)).unwrap();
}

/// A recording of the branching run (`small`: Case 2, adaptive, 30 µs) read back (issue 17):
/// point counts grow between frames, and the `nodes/level` classes of every frame match the
/// logged `metrics/refine/particles`.
#[test]
fn the_branching_recording_grows_its_point_cloud() {
    use peridyn::readback;
    let path = crate::common::temp("dual-horizon", "branching-small.rrd");
    let out = crate::common::peridyn(&[
        "record",
        "branching",
        "--variant",
        "small",
        "-q",
        "-o",
        path.to_str().unwrap(),
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let rec = readback::read(&path).unwrap();
    let level = rec
        .entity("/nodes/level")
        .expect("the level classes are logged");
    let particles = &rec
        .entity("/metrics/refine/particles")
        .expect("the particle count is logged")
        .scalars;
    for (step, ids) in &level.classes {
        assert_eq!(ids.len() as f64, particles[step], "step {step}");
        let children = ids.iter().filter(|&&l| l == 1).count();
        assert_eq!(children % 4, 0, "children come in fours");
    }
    let counts: Vec<usize> = level.points.values().copied().collect();
    assert!(counts.windows(2).all(|w| w[0] <= w[1]), "{counts:?}");
    assert!(counts.last() > counts.first(), "{counts:?}");
    println!("points per frame: {counts:?}");
    assert!(
        rec.entity("/log/events")
            .unwrap()
            .texts
            .iter()
            .any(|t| t.contains("split")),
        "split events logged"
    );
}

/// The refinement's horizon ratio and predefined region are checked like every preset value:
/// the message names the field and the allowed range.
#[test]
fn bad_refinement_options_are_refused_with_the_field_and_range() {
    let refused = |set: &str| {
        Scene::load_with("branching", None, &[set.to_string()])
            .err()
            .unwrap_or_else(|| panic!("`{set}` was accepted"))
            .to_string()
    };
    let ratio = refused("refinement.horizon_ratio=0.3");
    assert!(
        ratio.contains("refinement.horizon_ratio") && ratio.contains("[0.5, 1]"),
        "{ratio}"
    );
    let region = refused("refinement.region={ box = { min = [\"0 mm\"], max = [\"1 mm\"] } }");
    assert!(region.contains("refinement.region"), "{region}");
    let scene = Scene::load_with(
        "branching",
        Some("small"),
        &[
            "refinement.region={ box = { min = [\"60 mm\", \"15 mm\"], max = [\"70 mm\", \"25 mm\"] } }"
                .into(),
            "time.end=\"10 ns\"".into(),
        ],
    )
    .unwrap();
    let sim = DualHorizonSimulation::new(&scene).unwrap();
    // 10 × 10 parents in the box split before the run, beside the pre-crack's 18.
    let children = sim.levels().iter().filter(|&&l| l == 1).count();
    assert_eq!(children % 4, 0);
    assert!(children >= 4 * 100, "{children} children");
}

/// The strain criterion (16) is evaluated only where the energy density can reach it (the
/// bound 2 κ t² of `mark_splittable`, with a margin of 4): on the expanding plate, whose
/// intact particles split by (16), and on Case 2's adaptive run (`branching` small, 30 µs),
/// the gated run splits exactly the particles the ungated one does (positions equal bit for
/// bit at every check).
#[test]
fn the_strain_gate_changes_no_split() {
    let plate = Scene::from_text("expanding-plate.toml", EXPANDING_PLATE, None).unwrap();
    let branching = Scene::load_with("branching", Some("small"), &[]).unwrap();
    for (scene, every) in [(plate, 5), (branching, 100)] {
        let mut gated = DualHorizonSimulation::new(&scene).unwrap();
        let mut ungated = DualHorizonSimulation::new(&scene).unwrap();
        ungated.gate_strains(false);
        let steps = gated.info().total_steps;
        while gated.steps_done() < steps {
            gated.step().unwrap();
            ungated.step().unwrap();
            if gated.steps_done().is_multiple_of(every) {
                assert_eq!(
                    gated.len(),
                    ungated.len(),
                    "{}: step {}",
                    scene.name,
                    gated.steps_done()
                );
                assert!(
                    gated.positions() == ungated.positions(),
                    "{}: step {}",
                    scene.name,
                    gated.steps_done()
                );
            }
        }
        println!(
            "{}: {} particles ({} parents split)",
            scene.name,
            gated.len(),
            gated.split_parents()
        );
        assert!(gated.split_parents() > 0);
    }
}

/// The force pass on lanes gives the bits of the scalar loop it replaced, on every lane
/// implementation this CPU runs: the adaptive Kalthoff–Winkler run at its own step (499 steps,
/// particles splitting and bonds breaking) ends on the field hashes the one-bond-at-a-time loop
/// gave (recorded on that code, commit 7898b5b).
#[test]
fn the_vector_force_pass_gives_the_scalar_loops_fields() {
    let scalar = "positions 966bebb8fb00e364, damage e451f21c859dddf7, velocity 64141c0fe3bb8f5b, \
                  level 28bd836240cb5c05";
    for simd in peridyn::simd::Simd::supported() {
        let out = crate::common::temp("dual_horizon", &format!("kw-{}.rrd", simd.name()));
        let run = std::process::Command::new(env!("CARGO_BIN_EXE_peridyn"))
            .args([
                "record",
                "kalthoff-winkler-dh",
                "--variant",
                "own-step",
                "-q",
                "-o",
            ])
            .arg(&out)
            .env("PERIDYN_SIMD", simd.name())
            .output()
            .expect("run peridyn");
        let stdout = String::from_utf8_lossy(&run.stdout);
        assert!(
            run.status.success(),
            "{}",
            String::from_utf8_lossy(&run.stderr)
        );
        assert!(stdout.contains(scalar), "{}: {stdout}", simd.name());
    }
}
