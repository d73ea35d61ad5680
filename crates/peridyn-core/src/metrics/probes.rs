//! Probes (`[[metrics.probe]]`: the node nearest a point, its value and energy density over
//! time) and the near-field energy of a scalar field, (4.99) and seed-thesis-ch4-5 erratum 13.

use crate::scene::Scene;
use crate::scheme::ScalarOperator;

/// A probe: its name and the node nearest its point.
pub struct Probe {
    pub name: String,
    pub node: usize,
    /// The operator row of the node (None if it is held or in the layer).
    pub row: Option<usize>,
}

impl Probe {
    pub fn resolve<const D: usize>(
        probes: &[(String, Vec<f64>)],
        positions: &[[f64; D]],
        operator: &ScalarOperator,
    ) -> Vec<Probe> {
        probes
            .iter()
            .map(|(name, p)| {
                let node = nearest_node(positions, p);
                let row = operator.rows.iter().position(|&i| i as usize == node);
                Probe {
                    name: name.clone(),
                    node,
                    row,
                }
            })
            .collect()
    }

    /// The field and its energy density ½ u̇² + ¼ Σ_j w (u_j − u_i)² (waves) or ½ C²
    /// (diffusion) at the probe's node.
    pub fn scalars(
        &self,
        operator: &ScalarOperator,
        field: &[f64],
        velocity: Option<&[f64]>,
    ) -> [(String, f64); 2] {
        let u = field[self.node];
        let density = match (velocity, self.row) {
            (Some(v), Some(r)) => {
                0.5 * v[self.node] * v[self.node] + 0.25 * bond_squares(operator, r, field)
            }
            (Some(v), None) => 0.5 * v[self.node] * v[self.node],
            (None, _) => 0.5 * u * u,
        };
        [
            (format!("probe/{}/value", self.name), u),
            (format!("probe/{}/energy_density", self.name), density),
        ]
    }
}

/// The node nearest point `p`.
pub fn nearest_node<const D: usize>(positions: &[[f64; D]], p: &[f64]) -> usize {
    let distance = |x: &[f64; D]| x.iter().zip(p).map(|(a, b)| (a - b) * (a - b)).sum::<f64>();
    (0..positions.len())
        .min_by(|&a, &b| distance(&positions[a]).total_cmp(&distance(&positions[b])))
        .unwrap_or(0)
}

/// Σ_j w_ij (u_j − u_i)² over row `r`'s off-diagonal entries (i its node).
fn bond_squares(operator: &ScalarOperator, r: usize, field: &[f64]) -> f64 {
    let i = operator.rows[r];
    let range = operator.offsets[r]..operator.offsets[r + 1];
    operator.columns[range.clone()]
        .iter()
        .zip(&operator.weights[range])
        .filter(|&(&j, _)| j != i)
        .map(|(&j, w)| w * (field[j as usize] - field[i as usize]).powi(2))
        .sum()
}

/// The energy in the near field (rows of `operator` not in the layer, weighted by `volumes`):
/// diffusion Π = ½ Σ C² V (seed-thesis-ch4-5 erratum 13); a wave
/// ½ Σ V (u̇² + ½ Σ_j w_ij (u_j − u_i)²) (the discrete form of (4.99)).
pub fn near_field_energy(
    operator: &ScalarOperator,
    field: &[f64],
    velocity: Option<&[f64]>,
    volumes: &[f64],
    absorbing: Option<&[bool]>,
) -> f64 {
    let mut sum = 0.0;
    for (r, &i) in operator.rows.iter().enumerate() {
        let i = i as usize;
        if absorbing.is_some_and(|a| a[i]) {
            continue;
        }
        let u = field[i];
        sum += 0.5
            * volumes[i]
            * match velocity {
                None => u * u,
                Some(v) => v[i] * v[i] + 0.5 * bond_squares(operator, r, field),
            };
    }
    sum
}

/// The probes of a dynamic scene: (name, nearest node).
pub fn probes<const D: usize>(scene: &Scene, reference: &[[f64; D]]) -> Vec<(String, usize)> {
    scene
        .probes
        .iter()
        .map(|(name, p)| (name.clone(), nearest_node(reference, p)))
        .collect()
}

/// `probe/<name>/{displacement_<axis>,energy_density}` of every probe.
pub fn probe_scalars<const D: usize>(
    probes: &[(String, usize)],
    reference: &[[f64; D]],
    positions: &[[f64; D]],
    energy_density: impl Fn(usize) -> f64,
    out: &mut Vec<(String, f64)>,
) {
    for (name, i) in probes {
        for k in 0..D {
            out.push((
                format!("probe/{name}/displacement_{}", ["x", "y", "z"][k]),
                positions[*i][k] - reference[*i][k],
            ));
        }
        out.push((format!("probe/{name}/energy_density"), energy_density(*i)));
    }
}
