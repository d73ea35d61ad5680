//! The absorbing layer (thesis §4.1.3–4.1.4, §4.2.3, §4.3.3; seed-thesis-ch4-5 §1): every node
//! within the layer width of the truncation gets a cloud of nearby nodes and one precomputed
//! update row per fitted quantity; each step the layer's values are overwritten from the old
//! state (Jacobi style, §1.2 [inferred]): u_i^{n+1} = V_G·G^n (4.31)/(4.82), and for waves
//! v_i^{n+1} = V_H·H^n (4.82), G^n and H^n the cloud's values at t^n (and t^{n−1} for waves).

use nalgebra::{Complex, DMatrix};

use super::fit::{Fit, Pseudoinverse, min_norm_rows};

/// One far-field mode ψ = exp(a·x̄ + s t̄) about an absorbing node (x̄ = x − x_i): a real
/// diffusion mode exp(k N·x̄ + ω̄ t̄) (4.25) or a damped outgoing wave
/// e^{−d t̄} exp(i(k N·x̄ − ω̃ t̄)) (4.53), (4.57); its rate ψ̇ = s ψ.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Mode<const D: usize> {
    pub wave_vector: [Complex<f64>; D],
    pub rate: Complex<f64>,
    /// A vector field's polarization γ (bond-based PD, (4.152)); `None` for scalar fields.
    pub polarization: Option<[f64; D]>,
}

impl<const D: usize> Mode<D> {
    fn at(&self, x: &[f64; D], t: f64) -> Complex<f64> {
        let mut e = self.rate * t;
        for (a, v) in self.wave_vector.iter().zip(x) {
            e += a * v;
        }
        e.exp()
    }

    /// The polarization's component `q` (1 for a scalar field).
    fn component(&self, q: usize) -> f64 {
        self.polarization.map_or(1.0, |g| g[q])
    }
}

/// What the layer fits: the field only at t^n (diffusion, one level), or field and rate on two
/// time levels t^n, t^{n−1} each (waves, (4.78)–(4.79)).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Levels {
    One,
    Two,
}

/// An absorbing node before fitting: its index, its modes and its cloud (the node first).
pub struct CloudSpec<const D: usize> {
    pub node: u32,
    pub modes: Vec<Mode<D>>,
    pub cloud: Vec<u32>,
}

/// What `check` reports of one absorbing node.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NodeReport {
    pub node: u32,
    pub cloud: usize,
    pub modes: usize,
    /// max_j |Re V_j| of the field row (and the rate row for waves) (thesis §4.2.3).
    pub norm: f64,
    /// cond(M) = σ_max/σ_min of the field fit.
    pub condition: f64,
    pub rank: usize,
}

/// The precomputed update rows of every absorbing node, in CSR form.
#[derive(Debug, Clone)]
pub struct AbsorbingLayer {
    pub nodes: Vec<u32>,
    pub levels: Levels,
    /// Field components per node: 1 (scalar fields) or D (displacements).
    pub components: usize,
    offsets: Vec<usize>,
    cloud: Vec<u32>,
    /// Re V_G per cloud entry, level and input component, for each output component
    /// (entry-major: `levels · components²` values per cloud entry, output component fastest).
    value_weights: Vec<f64>,
    /// Re V_H likewise (waves only).
    rate_weights: Vec<f64>,
    /// The rate rows act on the field's values (the first-order boundary's u̇ = −A ∂_n u − d u),
    /// not on the rates' (the fitted modes' V_H·H^n).
    pub rates_from_field: bool,
    pub reports: Vec<NodeReport>,
    /// `growth()`, computed on first use (an eigenproblem per node and quantity) and kept
    /// until a node is pushed: every `info()` of a run reports it.
    growth: std::sync::OnceLock<Growth>,
}

/// The largest spectral radius of the absorbing nodes' own recurrences (`own_growth`), the
/// node it occurs at and how many nodes exceed 1.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Growth {
    pub worst: f64,
    pub node: u32,
    pub above_one: usize,
}

/// The fitted rows of one quantity, one per output component c: V_c = ψ_c(0, Δt) M⁺, M's rows
/// γ_q ψ(x̄_j, t̄) for the cloud's nodes j, the levels t̄ and the components q (entries ordered
/// node, level, component; (4.162)–(4.166) for vector fields); `scaled` multiplies each mode by
/// its rate (the rate rows' ψ̇ = s ψ).
fn fit_rows<const D: usize>(
    positions: &[[f64; D]],
    spec: &CloudSpec<D>,
    levels: &[f64],
    components: usize,
    dt: f64,
    scaled: bool,
    inverse: Pseudoinverse,
) -> Vec<Fit> {
    let xi = positions[spec.node as usize];
    let local: Vec<[f64; D]> = spec
        .cloud
        .iter()
        .map(|&j| std::array::from_fn(|k| positions[j as usize][k] - xi[k]))
        .collect();
    let factor = |m: &Mode<D>| {
        if scaled {
            m.rate
        } else {
            Complex::new(1.0, 0.0)
        }
    };
    let per_node = levels.len() * components;
    let matrix = DMatrix::from_fn(local.len() * per_node, spec.modes.len(), |r, b| {
        let mode = &spec.modes[b];
        let (j, l, q) = (r / per_node, (r % per_node) / components, r % components);
        factor(mode) * mode.component(q) * mode.at(&local[j], levels[l])
    });
    let targets: Vec<Vec<Complex<f64>>> = (0..components)
        .map(|c| {
            spec.modes
                .iter()
                .map(|m| factor(m) * m.component(c) * m.at(&[0.0; D], dt))
                .collect()
        })
        .collect();
    let targets: Vec<&[Complex<f64>]> = targets.iter().map(Vec::as_slice).collect();
    min_norm_rows(matrix, &targets, inverse)
}

/// The largest |Re V_j| over rows.
fn largest(fits: &[Fit]) -> f64 {
    fits.iter()
        .flat_map(|f| &f.row)
        .fold(0.0f64, |a, v| a.max(v.re.abs()))
}

/// Interleaves the output components' rows: entry r of output c at `r · components + c`.
fn interleave(fits: &[Fit], out: &mut Vec<f64>) {
    let Some(first) = fits.first() else { return };
    for r in 0..first.row.len() {
        out.extend(fits.iter().map(|f| f.row[r].re));
    }
}

impl AbsorbingLayer {
    /// Fits every node's rows (one SVD per quantity and node, at setup only). A mode with a
    /// polarization makes the layer a vector one (D components per node).
    pub fn fit<const D: usize>(
        positions: &[[f64; D]],
        specs: &[CloudSpec<D>],
        levels: Levels,
        dt: f64,
        inverse: Pseudoinverse,
    ) -> AbsorbingLayer {
        use rayon::prelude::*;
        let times: &[f64] = match levels {
            Levels::One => &[0.0],
            Levels::Two => &[0.0, -dt],
        };
        let vector = specs
            .iter()
            .flat_map(|s| s.modes.first())
            .any(|m| m.polarization.is_some());
        let components = if vector { D } else { 1 };
        let fitted: Vec<(Vec<Fit>, Vec<Fit>)> = specs
            .par_iter()
            .map(|s| {
                let rows = |scaled| fit_rows(positions, s, times, components, dt, scaled, inverse);
                let value = rows(false);
                let rate = if levels == Levels::Two {
                    rows(true)
                } else {
                    Vec::new()
                };
                (value, rate)
            })
            .collect();
        let mut layer = AbsorbingLayer::empty(levels, components);
        for (s, (value, rate)) in specs.iter().zip(fitted) {
            let report = NodeReport {
                node: s.node,
                cloud: s.cloud.len(),
                modes: s.modes.len(),
                norm: largest(&value).max(largest(&rate)),
                condition: value.first().map_or(f64::NAN, |f| f.condition),
                rank: value.first().map_or(0, |f| f.rank),
            };
            let (mut v, mut r) = (Vec::new(), Vec::new());
            interleave(&value, &mut v);
            interleave(&rate, &mut r);
            layer.push(s.node, &s.cloud, &v, &r, report);
        }
        layer
    }

    /// A layer without nodes.
    pub fn empty(levels: Levels, components: usize) -> AbsorbingLayer {
        AbsorbingLayer {
            nodes: Vec::new(),
            levels,
            components,
            offsets: vec![0],
            cloud: Vec::new(),
            value_weights: Vec::new(),
            rate_weights: Vec::new(),
            rates_from_field: false,
            reports: Vec::new(),
            growth: std::sync::OnceLock::new(),
        }
    }

    /// Appends absorbing node `node` with its cloud and weights (`levels · components²` per
    /// cloud entry, laid out as `value_weights` says; `rate` empty with one level).
    pub fn push(&mut self, node: u32, cloud: &[u32], value: &[f64], rate: &[f64], r: NodeReport) {
        self.growth = std::sync::OnceLock::new();
        let per_entry = self.levels() * self.components * self.components;
        debug_assert_eq!(value.len(), cloud.len() * per_entry);
        debug_assert!(rate.is_empty() || rate.len() == value.len());
        self.nodes.push(node);
        self.cloud.extend_from_slice(cloud);
        self.offsets.push(self.cloud.len());
        self.value_weights.extend_from_slice(value);
        self.rate_weights.extend_from_slice(rate);
        self.reports.push(r);
    }

    fn levels(&self) -> usize {
        match self.levels {
            Levels::One => 1,
            Levels::Two => 2,
        }
    }

    /// The new values of the absorbing nodes from the cloud's `now` and `before` (t^{n−1};
    /// unused with one level) values through `weights`, into `out` (`components` per absorbing
    /// node; `now` and `before` hold `components` values per node too).
    fn apply(&self, weights: &[f64], now: &[f64], before: &[f64], out: &mut [f64]) {
        let (levels, nc) = (self.levels(), self.components);
        let per_entry = levels * nc * nc;
        for (a, o) in out.chunks_exact_mut(nc).enumerate() {
            o.fill(0.0);
            for e in self.offsets[a]..self.offsets[a + 1] {
                let j = self.cloud[e] as usize;
                let w = &weights[e * per_entry..(e + 1) * per_entry];
                for (l, data) in [now, before].iter().take(levels).enumerate() {
                    for q in 0..nc {
                        let x = data[j * nc + q];
                        let w = &w[(l * nc + q) * nc..(l * nc + q + 1) * nc];
                        for (o, w) in o.iter_mut().zip(w) {
                            *o += w * x;
                        }
                    }
                }
            }
        }
    }

    /// u_i^{n+1} = V_G·G^n of every absorbing node (4.31), (4.82), (4.166).
    pub fn values(&self, now: &[f64], before: &[f64], out: &mut [f64]) {
        self.apply(&self.value_weights, now, before, out);
    }

    /// v_i^{n+1} = V_H·H^n (4.82), (4.166) from the rates at t^n, t^{n−1} (`rates_now`,
    /// `rates_before`), or from the field's values for the first-order boundary; waves only.
    pub fn rates(&self, field: [&[f64]; 2], rates: [&[f64]; 2], out: &mut [f64]) {
        let [now, before] = if self.rates_from_field { field } else { rates };
        self.apply(&self.rate_weights, now, before, out);
    }

    /// The spectral radius of absorbing node `a`'s own recurrence through `weights`: its
    /// value at t^{n+1} from its own values at t^n and t^{n−1}, z² − A₀ z − A₁ (a companion
    /// matrix of size `levels · components`). The first entry of every cloud is the node, and
    /// no other absorbing node's cloud reaches it from ahead (the backward cone (4.86)), so on
    /// the outermost ring this recurrence alone decides whether a disturbance grows.
    fn own_radius(&self, weights: &[f64], a: usize) -> f64 {
        let (levels, nc) = (self.levels(), self.components);
        if weights.is_empty() {
            return 0.0;
        }
        let n = levels * nc;
        let w = &weights[self.offsets[a] * levels * nc * nc..];
        let companion = nalgebra::DMatrix::from_fn(n, n, |r, c| {
            if r < nc {
                let (l, q) = (c / nc, c % nc);
                w[(l * nc + q) * nc + r]
            } else if c + nc == r {
                1.0
            } else {
                0.0
            }
        });
        companion
            .complex_eigenvalues()
            .iter()
            .fold(0.0f64, |m, z| m.max(z.norm()))
    }

    /// The largest spectral radius of node `a`'s own recurrence over its value and rate rows.
    pub fn own_growth(&self, a: usize) -> f64 {
        self.own_radius(&self.value_weights, a)
            .max(self.own_radius(&self.rate_weights, a))
    }

    /// `own_growth` over the layer (computed once per fit).
    pub fn growth(&self) -> Growth {
        *self.growth.get_or_init(|| {
            let growth: Vec<f64> = (0..self.nodes.len()).map(|a| self.own_growth(a)).collect();
            let (at, worst) = growth
                .iter()
                .copied()
                .enumerate()
                .max_by(|a, b| a.1.total_cmp(&b.1))
                .unwrap_or((0, 0.0));
            Growth {
                worst,
                node: self.nodes.get(at).copied().unwrap_or(0),
                above_one: growth.iter().filter(|&&g| g > 1.0 + 1e-12).count(),
            }
        })
    }

    /// The largest ‖V‖ and cond(M) over the layer, and the node they occur at.
    pub fn worst(&self) -> Option<(NodeReport, NodeReport)> {
        let by = |f: fn(&NodeReport) -> f64| {
            self.reports
                .iter()
                .copied()
                .max_by(|a, b| f(a).total_cmp(&f(b)))
        };
        Some((by(|r| r.norm)?, by(|r| r.condition)?))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// seed-thesis-ch4-5 §2.6's check of the 1D diffusion layer: 3-node cloud (x_i and two
    /// behind), Δx = 0.125, Δt = 10⁻³, D = 1, Δk = 1, n_k = 20 modes exp(k x̄ + D k² t̄) with
    /// k equally spaced in Δk·[−1, 0): V_G = [1.0518, −0.1042, 0.0524] (NumPy, the note).
    #[test]
    fn diffusion_row_of_the_note() {
        let positions: Vec<[f64; 1]> = (0..3).map(|i| [-0.125 * i as f64]).collect();
        let modes: Vec<Mode<1>> = (0..20)
            .map(|m| {
                let k = -1.0 + m as f64 / 20.0;
                Mode {
                    wave_vector: [Complex::new(k, 0.0)],
                    rate: Complex::new(k * k, 0.0),
                    polarization: None,
                }
            })
            .collect();
        let spec = CloudSpec {
            node: 0,
            modes,
            cloud: vec![0, 1, 2],
        };
        let layer = AbsorbingLayer::fit(
            &positions,
            &[spec],
            Levels::One,
            1e-3,
            Pseudoinverse::cut(1e-15),
        );
        let want = [1.0518, -0.1042, 0.0524];
        for (got, want) in layer.value_weights.iter().zip(want) {
            assert!((got - want).abs() < 1e-4, "{:?}", layer.value_weights);
        }
        let mut out = [0.0];
        layer.values(&[1.0, 1.0, 1.0], &[], &mut out);
        assert!(
            (out[0] - 1.0).abs() < 1e-3,
            "a constant field stays nearly constant"
        );
    }
}
