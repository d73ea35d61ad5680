//! Measurements on the node state: energies, momentum, crack-path angle, crack branching,
//! probes and the near-field energy.

pub mod branching;
pub mod probes;

use std::collections::VecDeque;

use crate::discretization::family::Families;
use crate::scene::CrackAngleSpec;

/// Kinetic energy Σ ½ ρ V |v|² and linear momentum Σ ρ V v.
pub fn kinetic_energy_and_momentum<const D: usize>(
    velocities: &[[f64; D]],
    volumes: &[f64],
    density: f64,
) -> (f64, [f64; D]) {
    let mut energy = 0.0;
    let mut momentum = [0.0; D];
    for (v, &vol) in velocities.iter().zip(volumes) {
        let m = density * vol;
        for k in 0..D {
            energy += 0.5 * m * v[k] * v[k];
            momentum[k] += m * v[k];
        }
    }
    (energy, momentum)
}

/// Crack angle in degrees (0–90) between `spec.direction` and the least-squares line through
/// the damaged nodes (φ ≥ threshold) inside `spec.region` that are connected, through
/// nearest-neighbor bonds, to the damaged nodes near `spec.tip`. None if fewer than 5 nodes.
pub fn crack_angle<const D: usize>(
    spec: &CrackAngleSpec,
    reference: &[[f64; D]],
    damage: &[f64],
    families: &Families,
    spacing: f64,
    horizon: f64,
) -> Option<f64> {
    let n = reference.len();
    let eligible = |i: usize| {
        damage[i] >= spec.threshold && spec.region.contains(&reference[i], 1e-9 * spacing)
    };
    let mut seen = vec![false; n];
    let mut queue = VecDeque::new();
    for i in 0..n {
        let d2: f64 = (0..D)
            .map(|k| (reference[i][k] - spec.tip[k]).powi(2))
            .sum();
        if d2 <= (2.0 * horizon).powi(2) && eligible(i) {
            seen[i] = true;
            queue.push_back(i);
        }
    }
    let mut members = Vec::new();
    while let Some(i) = queue.pop_front() {
        members.push(i);
        for b in families.range(i) {
            let j = families.neighbors[b] as usize;
            if !seen[j] && families.length(i, b) <= 1.5 * spacing && eligible(j) {
                seen[j] = true;
                queue.push_back(j);
            }
        }
    }
    if members.len() < 5 {
        return None;
    }
    let axis = principal_axis(members.iter().map(|&i| &reference[i][..]), D);
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

/// `damage/count/<name>`: the nodes of each `[[metrics.damage_count]]` region whose damage
/// reaches its threshold.
pub fn damage_counts<const D: usize>(
    scene: &crate::scene::Scene,
    reference: &[[f64; D]],
    damage: &[f64],
    scalars: &mut Vec<(String, f64)>,
) {
    let eps = 1e-9 * scene.spacing;
    for d in &scene.damage_counts {
        let count = (0..reference.len())
            .filter(|&i| damage[i] >= d.threshold && d.region.contains(&reference[i], eps))
            .count();
        scalars.push((format!("damage/count/{}", d.name), count as f64));
    }
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

/// The fraction of the cube cell of side `h` centred at `x` that lies inside the ball of
/// `radius` about `center`: 1 or 0 where the cell is wholly inside or outside, else the
/// fraction of a 16ᵈ (2D) or 8ᵈ (3D) grid of sub-cell midpoints inside (the cells the
/// sphere cuts are a thin shell, so the sum over a lattice errs by far less than node
/// centres alone).
pub fn ball_fraction<const D: usize>(x: &[f64; D], h: f64, center: &[f64], radius: f64) -> f64 {
    let (mut near, mut far) = (0.0, 0.0);
    for k in 0..D {
        let d = (x[k] - center[k]).abs();
        near += (d - 0.5 * h).max(0.0).powi(2);
        far += (d + 0.5 * h).powi(2);
    }
    let r2 = radius * radius;
    if far <= r2 {
        return 1.0;
    }
    if near > r2 {
        return 0.0;
    }
    let s: usize = if D <= 2 { 16 } else { 8 };
    let total = s.pow(D as u32);
    let inside = (0..total)
        .filter(|&code| {
            let mut c = code;
            let mut d2 = 0.0;
            for k in 0..D {
                let t = ((c % s) as f64 + 0.5) / s as f64 - 0.5;
                c /= s;
                d2 += (x[k] + t * h - center[k]).powi(2);
            }
            d2 <= r2
        })
        .count();
    inside as f64 / total as f64
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::Solid;

    #[test]
    fn cell_fractions_integrate_the_area_of_a_circle_and_a_sphere() {
        // A circle of radius 10 about a point off the lattice, on two spacings: the node
        // centres alone miss its area by ≈ 1 % at h = 2/3; the fractions by less than 1e-3.
        for h in [2.0 / 3.0, 1.0 / 3.0] {
            let (center, r) = ([50.0, 25.0], 10.0);
            let n = (30.0 / h) as i64;
            let (mut area, mut centres) = (0.0, 0.0);
            for i in -n..=n {
                for j in -n..=n {
                    let x = [50.0 + i as f64 * h, 25.0 + 0.5 * h + j as f64 * h];
                    area += ball_fraction(&x, h, &center, r) * h * h;
                    let d2 = (x[0] - center[0]).powi(2) + (x[1] - center[1]).powi(2);
                    centres += if d2 <= r * r { h * h } else { 0.0 };
                }
            }
            let exact = std::f64::consts::PI * r * r;
            assert!(
                (area / exact - 1.0).abs() < 1e-3,
                "h = {h}: {area} vs {exact}"
            );
            eprintln!(
                "h = {h}: fractions {:.2e}, centres {:.2e}",
                area / exact - 1.0,
                centres / exact - 1.0
            );
        }
        let (h, r) = (0.5, 3.0);
        let mut volume = 0.0;
        for i in -10..=10 {
            for j in -10..=10 {
                for k in -10..=10 {
                    let x = [i as f64 * h + 0.1, j as f64 * h, k as f64 * h];
                    volume += ball_fraction(&x, h, &[0.0, 0.0, 0.0], r) * h.powi(3);
                }
            }
        }
        let exact = 4.0 / 3.0 * std::f64::consts::PI * r.powi(3);
        assert!((volume / exact - 1.0).abs() < 2e-3, "{volume} vs {exact}");
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
        // Lattice with a damaged line at 65° from the tip (0,0).
        let dx = 1.0;
        let mut pos = Vec::new();
        for i in 0..40 {
            for j in 0..40 {
                pos.push([i as f64 * dx, j as f64 * dx]);
            }
        }
        let fam = Families::build(&pos, 1.5);
        let (s, c) = 65f64.to_radians().sin_cos();
        let damage: Vec<f64> = pos
            .iter()
            .map(|p| {
                if (p[0] * s - p[1] * c).abs() < 0.8 {
                    0.5
                } else {
                    0.0
                }
            })
            .collect();
        let spec = CrackAngleSpec {
            name: "test".into(),
            tip: vec![0.0, 0.0],
            direction: vec![1.0, 0.0],
            threshold: 0.35,
            region: Solid::Box {
                min: vec![0.0, 0.0],
                max: vec![40.0, 40.0],
            },
        };
        let angle = crack_angle(&spec, &pos, &damage, &fam, dx, 2.0).unwrap();
        assert!((angle - 65.0).abs() < 2.0, "{angle}");
    }
}
