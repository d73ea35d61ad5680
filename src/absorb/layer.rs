//! The absorbing layer (thesis §4.1.3–4.1.4, §4.2.3, §4.3.3; seed-thesis-ch4-5 §1): every node
//! within the layer width of the truncation gets a cloud of nearby nodes and one precomputed
//! update row per fitted quantity; each step the layer's values are overwritten from the old
//! state (Jacobi style, §1.2 [inferred]): u_i^{n+1} = V_G·G^n (4.31)/(4.82), and for waves
//! v_i^{n+1} = V_H·H^n (4.82), G^n and H^n the cloud's values at t^n (and t^{n−1} for waves).

use nalgebra::{Complex, DMatrix};

use super::fit::{Fit, min_norm_row};

/// One far-field mode ψ = exp(a·x̄ + s t̄) about an absorbing node (x̄ = x − x_i): a real
/// diffusion mode exp(k N·x̄ + ω̄ t̄) (4.25) or a damped outgoing wave
/// e^{−d t̄} exp(i(k N·x̄ − ω̃ t̄)) (4.53), (4.57); its rate ψ̇ = s ψ.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Mode<const D: usize> {
    pub wave_vector: [Complex<f64>; D],
    pub rate: Complex<f64>,
}

impl<const D: usize> Mode<D> {
    fn at(&self, x: &[f64; D], t: f64) -> Complex<f64> {
        let mut e = self.rate * t;
        for (a, v) in self.wave_vector.iter().zip(x) {
            e += a * v;
        }
        e.exp()
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
    offsets: Vec<usize>,
    cloud: Vec<u32>,
    /// Re V_G per cloud entry and level (`levels` values per entry: t^n, then t^{n−1}).
    value_weights: Vec<f64>,
    /// Re V_H likewise (waves only).
    rate_weights: Vec<f64>,
    pub reports: Vec<NodeReport>,
}

/// The fitted row of one quantity: V = ψ(0, Δt) M⁺, M's rows ψ(x̄_j, t̄) for the cloud's
/// nodes j and the levels t̄ (entries ordered node-major, level-minor); `scale` multiplies
/// each mode (the rate row's ṡ = s).
fn fit_row<const D: usize>(
    positions: &[[f64; D]],
    spec: &CloudSpec<D>,
    levels: &[f64],
    dt: f64,
    scaled: bool,
    cutoff: f64,
) -> Fit {
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
    let rows = local.len() * levels.len();
    let matrix = DMatrix::from_fn(rows, spec.modes.len(), |r, b| {
        let mode = &spec.modes[b];
        factor(mode) * mode.at(&local[r / levels.len()], levels[r % levels.len()])
    });
    let psi: Vec<Complex<f64>> = spec
        .modes
        .iter()
        .map(|m| factor(m) * m.at(&[0.0; D], dt))
        .collect();
    min_norm_row(matrix, &psi, cutoff)
}

impl AbsorbingLayer {
    /// Fits every node's rows (one SVD per quantity and node, at setup only).
    pub fn fit<const D: usize>(
        positions: &[[f64; D]],
        specs: &[CloudSpec<D>],
        levels: Levels,
        dt: f64,
        cutoff: f64,
    ) -> AbsorbingLayer {
        use rayon::prelude::*;
        let times: &[f64] = match levels {
            Levels::One => &[0.0],
            Levels::Two => &[0.0, -dt],
        };
        let fitted: Vec<(Fit, Option<Fit>)> = specs
            .par_iter()
            .map(|s| {
                let value = fit_row(positions, s, times, dt, false, cutoff);
                let rate =
                    (levels == Levels::Two).then(|| fit_row(positions, s, times, dt, true, cutoff));
                (value, rate)
            })
            .collect();
        let mut layer = AbsorbingLayer {
            nodes: specs.iter().map(|s| s.node).collect(),
            levels,
            offsets: vec![0],
            cloud: Vec::new(),
            value_weights: Vec::new(),
            rate_weights: Vec::new(),
            reports: Vec::new(),
        };
        for (s, (value, rate)) in specs.iter().zip(fitted) {
            layer.cloud.extend_from_slice(&s.cloud);
            layer.offsets.push(layer.cloud.len());
            let largest = |f: &Fit| f.row.iter().fold(0.0f64, |a, v| a.max(v.re.abs()));
            let mut norm = largest(&value);
            layer.value_weights.extend(value.row.iter().map(|v| v.re));
            if let Some(rate) = &rate {
                norm = norm.max(largest(rate));
                layer.rate_weights.extend(rate.row.iter().map(|v| v.re));
            }
            layer.reports.push(NodeReport {
                node: s.node,
                cloud: s.cloud.len(),
                modes: s.modes.len(),
                norm,
                condition: value.condition,
                rank: value.rank,
            });
        }
        layer
    }

    fn levels(&self) -> usize {
        match self.levels {
            Levels::One => 1,
            Levels::Two => 2,
        }
    }

    /// The new values of the absorbing nodes from the cloud's `now` and `before` (t^{n−1};
    /// unused with one level) values through `weights`, into `out` (one per absorbing node).
    fn apply(&self, weights: &[f64], now: &[f64], before: &[f64], out: &mut [f64]) {
        let levels = self.levels();
        for (a, o) in out.iter_mut().enumerate() {
            let mut sum = 0.0;
            for e in self.offsets[a]..self.offsets[a + 1] {
                let j = self.cloud[e] as usize;
                let w = &weights[e * levels..(e + 1) * levels];
                sum += w[0] * now[j];
                if levels == 2 {
                    sum += w[1] * before[j];
                }
            }
            *o = sum;
        }
    }

    /// u_i^{n+1} = V_G·G^n of every absorbing node (4.31), (4.82).
    pub fn values(&self, now: &[f64], before: &[f64], out: &mut [f64]) {
        self.apply(&self.value_weights, now, before, out);
    }

    /// v_i^{n+1} = V_H·H^n (4.82); waves only.
    pub fn rates(&self, now: &[f64], before: &[f64], out: &mut [f64]) {
        self.apply(&self.rate_weights, now, before, out);
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
                }
            })
            .collect();
        let spec = CloudSpec {
            node: 0,
            modes,
            cloud: vec![0, 1, 2],
        };
        let layer = AbsorbingLayer::fit(&positions, &[spec], Levels::One, 1e-3, 1e-15);
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
