//! The crack grown from a pre-crack tip, measured on the damage field and the reference
//! positions alone (any scene, any scheme): the damaged nodes connected to the tip, the angle of
//! their least-squares line (`[[metrics.crack_angle]]`) and how far they reach from the tip
//! along it (`[[metrics.crack_length]]`).

use std::collections::{HashMap, VecDeque};

use crate::scene::{CrackAngleSpec, CrackLengthSpec, Scene, Solid};

/// Fewer connected damaged nodes than this are no crack yet (the tip's own damage).
const MIN_NODES: usize = 5;

/// Where a crack is searched: from the damaged nodes within 2δ of `tip`, through damaged nodes
/// (φ ≥ `threshold`) inside `region`.
struct Search<'a> {
    tip: &'a [f64],
    threshold: f64,
    region: &'a Solid,
}

/// The damaged nodes inside the region connected to the tip, two nodes connected when they are
/// within 1.5 Δx (lattice neighbours along the axes and the diagonals: a crack one node wide
/// running obliquely stays one set). The neighbours are found on a grid of the damaged nodes
/// only, so the search costs what the crack holds, not the body.
fn crack_nodes<const D: usize>(
    search: &Search,
    reference: &[[f64; D]],
    damage: &[f64],
    spacing: f64,
    horizon: f64,
) -> Vec<usize> {
    let eps = 1e-9 * spacing;
    let reach = 1.5 * spacing;
    let cell =
        |x: &[f64; D]| -> [i64; D] { std::array::from_fn(|k| (x[k] / reach).floor() as i64) };
    let distance2 =
        |x: &[f64; D], y: &[f64]| -> f64 { (0..D).map(|k| (x[k] - y[k]).powi(2)).sum() };
    let mut grid: HashMap<[i64; D], Vec<usize>> = HashMap::new();
    for (i, x) in reference.iter().enumerate() {
        if damage[i] >= search.threshold && search.region.contains(x, eps) {
            grid.entry(cell(x)).or_default().push(i);
        }
    }
    let mut seen = vec![false; reference.len()];
    let mut queue = VecDeque::new();
    let mut seeds: Vec<usize> = grid
        .values()
        .flatten()
        .copied()
        .filter(|&i| distance2(&reference[i], search.tip) <= (2.0 * horizon).powi(2))
        .collect();
    seeds.sort_unstable();
    for i in seeds {
        seen[i] = true;
        queue.push_back(i);
    }
    let neighbour_cells = 3usize.pow(D as u32);
    let mut members = Vec::new();
    while let Some(i) = queue.pop_front() {
        members.push(i);
        let home = cell(&reference[i]);
        for code in 0..neighbour_cells {
            let mut c = code;
            let key: [i64; D] = std::array::from_fn(|k| {
                let offset = (c % 3) as i64 - 1;
                c /= 3;
                home[k] + offset
            });
            for &j in grid.get(&key).into_iter().flatten() {
                if !seen[j] && distance2(&reference[j], &reference[i]) <= reach * reach {
                    seen[j] = true;
                    queue.push_back(j);
                }
            }
        }
    }
    members
}

/// The crack's nodes (`crack_nodes`) and the direction of their least-squares line; None below
/// `MIN_NODES` nodes.
fn crack_line<const D: usize>(
    search: &Search,
    reference: &[[f64; D]],
    damage: &[f64],
    spacing: f64,
    horizon: f64,
) -> Option<(Vec<usize>, Vec<f64>)> {
    let members = crack_nodes(search, reference, damage, spacing, horizon);
    if members.len() < MIN_NODES {
        return None;
    }
    let axis = principal_axis(members.iter().map(|&i| &reference[i][..]), D);
    Some((members, axis))
}

/// Crack angle in degrees (0–90) between `spec.direction` and the least-squares line through
/// the damaged nodes (φ ≥ threshold) inside `spec.region` that are connected to the damaged
/// nodes near `spec.tip`. None if fewer than 5 nodes.
pub fn crack_angle<const D: usize>(
    spec: &CrackAngleSpec,
    reference: &[[f64; D]],
    damage: &[f64],
    spacing: f64,
    horizon: f64,
) -> Option<f64> {
    let search = Search {
        tip: &spec.tip,
        threshold: spec.threshold,
        region: &spec.region,
    };
    let (_, axis) = crack_line(&search, reference, damage, spacing, horizon)?;
    let norm = spec.direction.iter().map(|v| v * v).sum::<f64>().sqrt();
    let cos: f64 = axis
        .iter()
        .zip(&spec.direction)
        .map(|(a, b)| a * b / norm)
        .sum::<f64>()
        .abs()
        .min(1.0);
    Some(cos.acos().to_degrees())
}

/// Crack length: how far the damaged nodes connected to the tip (as for the crack angle) reach
/// from `spec.tip` along their least-squares line, max (x_i − tip)·a with a the line's direction
/// pointing from the tip into the crack (towards the nodes' mean). 0 below 5 nodes. On a lattice
/// it is the farthest damaged node's distance, so it grows in steps of about Δx.
pub fn crack_length<const D: usize>(
    spec: &CrackLengthSpec,
    reference: &[[f64; D]],
    damage: &[f64],
    spacing: f64,
    horizon: f64,
) -> f64 {
    let search = Search {
        tip: &spec.tip,
        threshold: spec.threshold,
        region: &spec.region,
    };
    let Some((members, axis)) = crack_line(&search, reference, damage, spacing, horizon) else {
        return 0.0;
    };
    let along = |i: usize| -> f64 {
        (0..D)
            .map(|k| (reference[i][k] - spec.tip[k]) * axis[k])
            .sum()
    };
    let sign = if members.iter().map(|&i| along(i)).sum::<f64>() < 0.0 {
        -1.0
    } else {
        1.0
    };
    members.iter().map(|&i| sign * along(i)).fold(0.0, f64::max)
}

/// The crack angles `(name, degrees)` of the scene's `[[metrics.crack_angle]]` for `damage`
/// (`spacing`: the finest lattice's).
pub fn crack_angles<const D: usize>(
    scene: &Scene,
    reference: &[[f64; D]],
    damage: &[f64],
    spacing: f64,
) -> Vec<(String, Option<f64>)> {
    scene
        .crack_angles
        .iter()
        .map(|spec| {
            let angle = crack_angle(spec, reference, damage, spacing, scene.horizon);
            (spec.name.clone(), angle)
        })
        .collect()
}

/// `crack_length/<name>` (m) of each `[[metrics.crack_length]]` for `damage`.
pub fn crack_lengths<const D: usize>(
    scene: &Scene,
    reference: &[[f64; D]],
    damage: &[f64],
    spacing: f64,
    scalars: &mut Vec<(String, f64)>,
) {
    for spec in &scene.crack_lengths {
        let length = crack_length(spec, reference, damage, spacing, scene.horizon);
        scalars.push((format!("crack_length/{}", spec.name), length));
    }
}

/// The frame scalars of the scene's crack measures for `damage`: `crack_angle_deg/<name>`
/// of each crack found, and `crack_length/<name>` (m) of each length measure.
pub fn crack_scalars<const D: usize>(
    scene: &Scene,
    reference: &[[f64; D]],
    damage: &[f64],
    spacing: f64,
    scalars: &mut Vec<(String, f64)>,
) {
    for (name, angle) in crack_angles(scene, reference, damage, spacing) {
        if let Some(a) = angle {
            scalars.push((format!("crack_angle_deg/{name}"), a));
        }
    }
    crack_lengths(scene, reference, damage, spacing, scalars);
}

/// Unit principal axis (largest-variance direction) of a point set, by power iteration on the
/// covariance matrix: the total-least-squares line direction.
fn principal_axis<'a>(points: impl Iterator<Item = &'a [f64]> + Clone, dim: usize) -> Vec<f64> {
    let count = points.clone().count() as f64;
    let mut mean = vec![0.0; dim];
    for p in points.clone() {
        for k in 0..dim {
            mean[k] += p[k] / count;
        }
    }
    let mut cov = vec![vec![0.0; dim]; dim];
    for p in points {
        for a in 0..dim {
            for b in 0..dim {
                cov[a][b] += (p[a] - mean[a]) * (p[b] - mean[b]);
            }
        }
    }
    let mut v: Vec<f64> = (0..dim).map(|k| 1.0 + 0.1 * k as f64).collect();
    for _ in 0..200 {
        let w: Vec<f64> = (0..dim)
            .map(|a| (0..dim).map(|b| cov[a][b] * v[b]).sum())
            .collect();
        let norm = w.iter().map(|x| x * x).sum::<f64>().sqrt();
        if norm == 0.0 {
            break;
        }
        v = w.iter().map(|x| x / norm).collect();
    }
    v
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A 60 × 40 lattice of spacing 1 and damage 0.5 on the nodes within `half_width` of the
    /// segment from `from` to `to`.
    fn band(from: [f64; 2], to: [f64; 2], half_width: f64) -> (Vec<[f64; 2]>, Vec<f64>) {
        let mut pos = Vec::new();
        for i in 0..60 {
            for j in 0..40 {
                pos.push([i as f64, j as f64]);
            }
        }
        let d = [to[0] - from[0], to[1] - from[1]];
        let len2 = d[0] * d[0] + d[1] * d[1];
        let damage = pos
            .iter()
            .map(|p| {
                let t =
                    (((p[0] - from[0]) * d[0] + (p[1] - from[1]) * d[1]) / len2).clamp(0.0, 1.0);
                let gap = (p[0] - from[0] - t * d[0]).hypot(p[1] - from[1] - t * d[1]);
                if gap < half_width { 0.5 } else { 0.0 }
            })
            .collect();
        (pos, damage)
    }

    fn whole() -> Solid {
        Solid::Box {
            min: vec![0.0, 0.0],
            max: vec![60.0, 40.0],
        }
    }

    #[test]
    fn principal_axis_of_a_line() {
        let pts: Vec<[f64; 2]> = (0..20)
            .map(|i| {
                let t = i as f64;
                [
                    t * 60f64.to_radians().cos(),
                    t * 60f64.to_radians().sin() + 0.01 * (i % 2) as f64,
                ]
            })
            .collect();
        let axis = principal_axis(pts.iter().map(|p| &p[..]), 2);
        let angle = axis[1].atan2(axis[0]).to_degrees().rem_euclid(180.0);
        assert!((angle - 60.0).abs() < 0.1, "{angle}");
    }

    #[test]
    fn crack_angle_of_a_damaged_band() {
        // A damaged line at 65° from the tip (0, 0).
        let (s, c) = 65f64.to_radians().sin_cos();
        let (pos, damage) = band([0.0, 0.0], [40.0 * c, 40.0 * s], 0.8);
        let spec = CrackAngleSpec {
            name: "test".into(),
            tip: vec![0.0, 0.0],
            direction: vec![1.0, 0.0],
            threshold: 0.35,
            region: whole(),
        };
        let angle = crack_angle(&spec, &pos, &damage, 1.0, 2.0).unwrap();
        assert!((angle - 65.0).abs() < 2.0, "{angle}");
    }

    /// A straight crack of known length from the tip: along a lattice row it is exact; at 30°
    /// the farthest damaged node lies within a spacing of the segment's end; damage elsewhere
    /// (a pre-crack's face outside the region, a separate damaged patch) does not count.
    #[test]
    fn crack_length_of_a_straight_band() {
        let spec = |tip: [f64; 2]| CrackLengthSpec {
            name: "test".into(),
            tip: tip.to_vec(),
            threshold: 0.35,
            region: Solid::Box {
                min: vec![tip[0], 0.0],
                max: vec![60.0, 40.0],
            },
        };
        // Along the row y = 20 from x = 10 to 35, with the pre-crack's face on x ≤ 9 (outside
        // the region) and a patch beyond a gap of 3 spacings.
        let (pos, mut damage) = band([0.0, 20.0], [35.0, 20.0], 0.1);
        for (p, d) in pos.iter().zip(&mut damage) {
            if p[1] == 20.0 && (39.0..=45.0).contains(&p[0]) {
                *d = 0.9;
            }
        }
        let length = crack_length(&spec([10.0, 20.0]), &pos, &damage, 1.0, 2.0);
        assert_eq!(length, 25.0);
        // At 30° over 30 spacings from (5, 5), a band ±0.8 wide.
        let (s, c) = 30f64.to_radians().sin_cos();
        let end = [5.0 + 30.0 * c, 5.0 + 30.0 * s];
        let (pos, damage) = band([5.0, 5.0], end, 0.8);
        let length = crack_length(&spec([5.0, 5.0]), &pos, &damage, 1.0, 2.0);
        assert!((length - 30.0).abs() <= 1.0, "{length}");
        // No damage: no crack.
        let quiet = vec![0.0; pos.len()];
        assert_eq!(crack_length(&spec([5.0, 5.0]), &pos, &quiet, 1.0, 2.0), 0.0);
    }
}
