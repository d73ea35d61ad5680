//! The absorbing layer of a scalar simulation of an unbounded domain (diffusion, corrosion,
//! scalar waves): built from the scene and refitted when Δt changes (thesis §4.1–4.2), its
//! nodes' values (and a wave's rates) overwritten each step, and its conditioning for
//! `check`.

use crate::absorb::{self, AbsorbingLayer, BondFarField, ScalarFarField, ScalarLattice};
use crate::discretization::{Families, Quadrature};
use crate::frame::ClassField;
use crate::model::diffusion::DiffusionKernel;
use crate::scene::{AbsorbingMethod, AbsorbingSpec, Physics, Scene};

/// The layer's class field ids.
const NEAR_FIELD: u16 = 0;
const ABSORBING: u16 = 1;
const DAMPED: u16 = 2;
const CLASSES: &[(u16, &str, [u8; 3])] = &[
    (NEAR_FIELD, "near field", [200, 200, 200]),
    (ABSORBING, "absorbing", [217, 72, 1]),
    (DAMPED, "damped band", [253, 174, 107]),
];

/// The far field a layer absorbs into.
enum FarField<const D: usize> {
    Scalar {
        lattice: ScalarLattice<D>,
        far: ScalarFarField,
    },
    /// Linearized 2D bond-based PD (thesis §4.3).
    Bond(BondFarField),
}

/// Where a filtered node's neighbour value comes from: the layer's new value of absorbing node
/// `a` or the field's (already advanced) value of near-field node `j`.
#[derive(Debug, Clone, Copy)]
enum Source {
    Layer(u32),
    Field(u32),
}

/// The layer's selective filter (`absorbing.filter` = ε; not in the thesis). The fitted update
/// amplifies a lattice sawtooth (k ≈ π/Δx, no group velocity) outwards ring by ring at the
/// lattice-oblique angles of a disc (docs/validation.md, "2D scalar layer, long runs"); after each
/// overwrite every absorbing node becomes ũ_a = (1 − ε) u_a + ε ū_a, ū_a the mean of its lattice
/// neighbours (within 1.01 Δx). A convex combination: it never raises max |u|. On a 2D lattice
/// it multiplies a mode by 1 − ε (1 − (cos k_xΔx + cos k_yΔx)/2): the checkerboard by 1 − 2ε,
/// a smooth wave by 1 − ε (kΔx)²/4 (Jacobi: all from the unfiltered new values).
struct Filter {
    strength: f64,
    offsets: Vec<usize>,
    sources: Vec<Source>,
}

impl Filter {
    fn new(strength: f64, nodes: &[u32], families: &Families, spacing: f64, n: usize) -> Filter {
        let mut index = vec![u32::MAX; n];
        for (a, &i) in nodes.iter().enumerate() {
            index[i as usize] = a as u32;
        }
        let mut offsets = vec![0];
        let mut sources = Vec::new();
        for &i in nodes {
            let i = i as usize;
            for e in families.offsets[i]..families.offsets[i + 1] {
                if families.length(i, e) <= 1.01 * spacing {
                    let j = families.neighbors[e];
                    sources.push(match index[j as usize] {
                        u32::MAX => Source::Field(j),
                        a => Source::Layer(a),
                    });
                }
            }
            offsets.push(sources.len());
        }
        Filter {
            strength,
            offsets,
            sources,
        }
    }
}

/// An absorbing layer and what it needs to be refitted at another Δt.
pub struct Absorber<const D: usize> {
    pub spec: AbsorbingSpec,
    pub layer: AbsorbingLayer,
    nodes: Vec<(u32, [f64; D])>,
    far: FarField<D>,
    spacing: f64,
    /// The Δt the rows were fitted for.
    dt: f64,
    pub is_absorbing: Vec<bool>,
    /// The layer's new values and rates, one per absorbing node.
    pub values: Vec<f64>,
    pub rates: Vec<f64>,
    filter: Option<Filter>,
}

impl<const D: usize> Absorber<D> {
    /// The layer's nodes of `scene` (none without `[absorbing]`).
    pub fn nodes(scene: &Scene, positions: &[[f64; D]]) -> Vec<(u32, [f64; D])> {
        match &scene.absorbing {
            Some(spec) => {
                absorb::layer_nodes(&scene.solid, positions, spec.width, 1e-9 * scene.spacing)
            }
            None => Vec::new(),
        }
    }

    /// The far field of `scene` with `kernel` (κ = c_s for waves): its lattice quadrature and
    /// the local coefficient (D or χ²) of its modes.
    pub fn new(
        scene: &Scene,
        spec: AbsorbingSpec,
        nodes: Vec<(u32, [f64; D])>,
        kernel: &DiffusionKernel,
        n: usize,
    ) -> Self {
        let quadrature = Quadrature::of_scene(scene);
        let lattice = ScalarLattice::<D>::new(&quadrature, |r| kernel.weight(r));
        let local = kernel.diffusivity
            * crate::scene::second_moment(D, kernel.exponent, kernel.influence, kernel.horizon);
        let far = match (scene.physics, scene.wave) {
            (Physics::ScalarWave, Some(w)) => ScalarFarField::Wave {
                speed_squared: local,
                damping: w.damping,
            },
            _ => ScalarFarField::Diffusion { diffusivity: local },
        };
        Self::with(
            spec,
            nodes,
            FarField::Scalar { lattice, far },
            scene.spacing,
            n,
            1,
        )
    }

    /// The layer of a 2D bond-based scene (`far` its linearized far field).
    pub fn bond(
        scene: &Scene,
        spec: AbsorbingSpec,
        nodes: Vec<(u32, [f64; D])>,
        far: BondFarField,
        n: usize,
    ) -> Self {
        Self::with(spec, nodes, FarField::Bond(far), scene.spacing, n, D)
    }

    fn with(
        spec: AbsorbingSpec,
        nodes: Vec<(u32, [f64; D])>,
        far: FarField<D>,
        spacing: f64,
        n: usize,
        components: usize,
    ) -> Self {
        let mut is_absorbing = vec![false; n];
        nodes
            .iter()
            .for_each(|(i, _)| is_absorbing[*i as usize] = true);
        let count = nodes.len() * components;
        Absorber {
            spec,
            layer: AbsorbingLayer::empty(absorb::Levels::One, components),
            nodes,
            far,
            spacing,
            dt: f64::NAN,
            is_absorbing,
            values: vec![0.0; count],
            rates: vec![0.0; count],
            filter: None,
        }
    }

    /// Fits the rows for `dt` unless they already are.
    pub fn ensure_fitted(&mut self, dt: f64, positions: &[[f64; D]], families: &Families) {
        if self.dt == dt {
            return;
        }
        let (spec, nodes, spacing) = (&self.spec, &self.nodes, self.spacing);
        self.layer = match (spec.method, &self.far) {
            (AbsorbingMethod::Modes, FarField::Scalar { lattice, far }) => {
                absorb::fit_scalar_layer(
                    spec, nodes, positions, families, lattice, *far, spacing, dt,
                )
            }
            (AbsorbingMethod::Modes, FarField::Bond(far)) => {
                absorb::fit_bond_layer(spec, nodes, positions, families, far, spacing, dt)
            }
            (AbsorbingMethod::FirstOrder, far) => {
                let clouds = absorb::Clouds {
                    spec,
                    positions,
                    families,
                    spacing,
                };
                match far {
                    // (4.75): u̇ + χ ∂_n u + d u = 0 (a diffusion scene is refused by validation;
                    // its χ would be √D, a placeholder).
                    FarField::Scalar { far, .. } => {
                        let (speed, damping) = match *far {
                            ScalarFarField::Wave {
                                speed_squared,
                                damping,
                            } => (speed_squared.sqrt(), damping),
                            ScalarFarField::Diffusion { diffusivity } => (diffusivity.sqrt(), 0.0),
                        };
                        absorb::first_order::first_order_layer(
                            &clouds,
                            nodes,
                            1,
                            dt,
                            |_| vec![speed],
                            damping,
                        )
                    }
                    FarField::Bond(far) => {
                        let (cp, cs) = far.speeds;
                        absorb::first_order::first_order_layer(
                            &clouds,
                            nodes,
                            D,
                            dt,
                            |n| {
                                let t = [-n[1], n[0]];
                                (0..4)
                                    .map(|e| {
                                        let (a, b) = (e / 2, e % 2);
                                        cp * n[a] * n[b] + cs * t[a] * t[b]
                                    })
                                    .collect()
                            },
                            0.0,
                        )
                    }
                }
            }
        };
        self.dt = dt;
        if self.spec.filter > 0.0 && self.filter.is_none() {
            let n = self.is_absorbing.len();
            let filter = Filter::new(self.spec.filter, &self.layer.nodes, families, spacing, n);
            self.filter = Some(filter);
        }
    }

    /// Writes the layer's new values into the node field (`components` values per node).
    pub fn overwrite(&self, values: &mut [f64]) {
        self.scatter(&self.values, values);
    }

    /// Writes the layer's new rates (a wave's u̇) into the velocity field.
    pub fn overwrite_rates(&self, rates: &mut [f64]) {
        self.scatter(&self.rates, rates);
    }

    /// The layer's new values `from` into `to` (reading near-field neighbours from `to`,
    /// which the loop never writes).
    fn scatter(&self, from: &[f64], to: &mut [f64]) {
        let nc = self.layer.components;
        for (a, &i) in self.layer.nodes.iter().enumerate() {
            for q in 0..nc {
                to[i as usize * nc + q] = self.filtered(from, a, q, |j| to[j * nc + q]);
            }
        }
    }

    /// Absorbing node `a`'s new value of component `q` (filtered if the layer has a filter),
    /// `near(j)` the near field's already advanced component `q` at node `j`.
    pub fn new_value(&self, a: usize, q: usize, near: impl Fn(usize) -> f64) -> f64 {
        self.filtered(&self.values, a, q, near)
    }

    fn filtered(&self, from: &[f64], a: usize, q: usize, near: impl Fn(usize) -> f64) -> f64 {
        let nc = self.layer.components;
        let own = from[a * nc + q];
        let Some(f) = &self.filter else {
            return own;
        };
        let around = &f.sources[f.offsets[a]..f.offsets[a + 1]];
        if around.is_empty() {
            return own;
        }
        let sum: f64 = around
            .iter()
            .map(|s| match *s {
                Source::Layer(b) => from[b as usize * nc + q],
                Source::Field(j) => near(j as usize),
            })
            .sum();
        own + f.strength * (sum / around.len() as f64 - own)
    }

    /// The `boundary` classes: the layer, and the near-field nodes of a damped band inside it.
    pub fn class_field(&self, damped: &[u32]) -> ClassField {
        let mut ids: Vec<u16> = self
            .is_absorbing
            .iter()
            .map(|&a| if a { ABSORBING } else { NEAR_FIELD })
            .collect();
        for &i in damped {
            ids[i as usize] = DAMPED;
        }
        ClassField {
            name: "boundary",
            ids,
            classes: CLASSES,
        }
    }

    /// `check`'s lines: the layer's size and its worst ‖V‖ and cond(M) against the limits.
    pub fn report(&self) -> Vec<String> {
        let Some((norm, cond)) = self.layer.worst() else {
            return vec!["absorbing layer: no node".into()];
        };
        let above = |f: &dyn Fn(&absorb::NodeReport) -> bool| {
            self.layer.reports.iter().filter(|r| f(r)).count()
        };
        vec![
            format!(
                "absorbing layer: {} nodes, {} modes per node, clouds of {}–{} nodes",
                self.layer.nodes.len(),
                norm.modes,
                self.layer
                    .reports
                    .iter()
                    .map(|r| r.cloud)
                    .min()
                    .unwrap_or(0),
                self.layer
                    .reports
                    .iter()
                    .map(|r| r.cloud)
                    .max()
                    .unwrap_or(0),
            ),
            format!(
                "absorbing layer: max ‖Re V‖ = {:.4} at node {} ({} above the limit {}); max \
                 cond(M) = {:.3e} at node {} ({} above {:.1e}; SVD cut-off {:.1e}, Tikhonov \
                 λ {:.1e})",
                norm.norm,
                norm.node,
                above(&|r| r.norm > self.spec.max_norm),
                self.spec.max_norm,
                cond.condition,
                cond.node,
                above(&|r| r.condition > self.spec.max_condition),
                self.spec.max_condition,
                self.spec.cutoff,
                self.spec.tikhonov
            ),
            {
                let growth = self.layer.growth();
                format!(
                    "absorbing layer: own recurrence |z|max = {:.6} at node {} ({} nodes above 1)",
                    growth.worst, growth.node, growth.above_one
                )
            },
        ]
    }
}
