//! Node lattices: vertex-centred uniform grids clipped to the body, with optional perturbation.

use crate::scene::{Scene, SceneError, Solid};

/// Nodes of one grid level, struct-of-arrays.
#[derive(Debug, Clone)]
pub struct Lattice<const D: usize> {
    pub positions: Vec<[f64; D]>,
    pub volumes: Vec<f64>,
    pub spacing: f64,
}

impl<const D: usize> Lattice<D> {
    /// Vertex-centred lattice of spacing `dx` over the solid's bounding box, keeping the nodes
    /// inside the solid; then each component is offset by a uniform random value in
    /// [lo, hi]·dx with `perturbation = [lo, hi]` (deterministic in `seed`).
    pub fn build(solid: &Solid, dx: f64, perturbation: [f64; 2], seed: u64) -> Self {
        Self::build_anchored(solid, dx, None, perturbation, seed)
    }

    /// [`Self::build`] with the nodes at origin + k·Δx (k integer) when an origin is given,
    /// computed from k so that they do not depend on the body's extent.
    pub fn build_anchored(
        solid: &Solid,
        dx: f64,
        origin: Option<&[f64]>,
        perturbation: [f64; 2],
        seed: u64,
    ) -> Self {
        let (mut lo, hi) = solid.bounds();
        // With an origin, node k sits at origin + k·Δx exactly (k integer, counted from the
        // origin), so nested bodies share their common nodes to the last bit.
        let mut first = [0i64; D];
        let mut anchor = [0.0; D];
        if let Some(o) = origin {
            for a in 0..D {
                first[a] = ((lo[a] - o[a]) / dx - 1e-9).ceil() as i64;
                anchor[a] = o[a];
                lo[a] = o[a] + first[a] as f64 * dx;
            }
        }
        let counts: Vec<usize> = (0..D)
            .map(|a| ((hi[a] - lo[a]) / dx + 1e-9).floor() as usize + 1)
            .collect();
        let eps = 1e-9 * dx;
        let mut positions = Vec::with_capacity(counts.iter().product());
        let mut index = [0usize; D];
        'outer: loop {
            let mut x = [0.0; D];
            for a in 0..D {
                x[a] = if origin.is_some() {
                    anchor[a] + (first[a] + index[a] as i64) as f64 * dx
                } else {
                    lo[a] + index[a] as f64 * dx
                };
            }
            if solid.contains(&x, eps) {
                positions.push(x);
            }
            for a in 0..D {
                index[a] += 1;
                if index[a] < counts[a] {
                    continue 'outer;
                }
                index[a] = 0;
            }
            break;
        }
        let [p_lo, p_hi] = perturbation;
        if p_lo != 0.0 || p_hi != 0.0 {
            let mut rng = SplitMix64(seed);
            for x in &mut positions {
                for v in x.iter_mut() {
                    *v += (p_lo + (p_hi - p_lo) * rng.next_f64()) * dx;
                }
            }
        }
        let volumes = vec![dx.powi(D as i32); positions.len()];
        Lattice {
            positions,
            volumes,
            spacing: dx,
        }
    }

    /// The scene's lattice; an error if the body holds no node.
    pub fn of_scene(scene: &Scene) -> Result<Self, SceneError> {
        let lattice = Lattice::build_anchored(
            &scene.solid,
            scene.spacing,
            scene.origin.as_deref(),
            scene.perturbation,
            scene.seed,
        );
        if lattice.is_empty() {
            return Err(scene.error(
                "geometry",
                "the body contains no lattice node; check its size against discretization.spacing",
            ));
        }
        Ok(lattice)
    }

    pub fn len(&self) -> usize {
        self.positions.len()
    }

    pub fn is_empty(&self) -> bool {
        self.positions.is_empty()
    }
}

/// Small deterministic generator (SplitMix64) for reproducible perturbations.
pub struct SplitMix64(pub u64);

impl SplitMix64 {
    pub fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    /// Uniform in [0, 1).
    pub fn next_f64(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 * (1.0 / (1u64 << 53) as f64)
    }
}

/// Positions off a lattice by more than this share of the spacing are not on it.
const OFF_LATTICE: f64 = 1e-6;

/// The integer coordinates of every point of `reference` on the lattice of spacing `spacing`
/// through the first point, if each lies on it to 10⁻⁶ of the spacing (`None` otherwise, and
/// for a NaN coordinate or a spacing that is not positive and finite).
pub fn lattice_points<const D: usize>(
    reference: &[[f64; D]],
    spacing: f64,
) -> Option<Vec<[i64; D]>> {
    let origin = *reference.first()?;
    if !(spacing > 0.0 && spacing.is_finite()) {
        return None;
    }
    let mut points = Vec::with_capacity(reference.len());
    for x in reference {
        let mut p = [0i64; D];
        for a in 0..D {
            let q = (x[a] - origin[a]) / spacing;
            let r = q.round();
            // A NaN coordinate fails too.
            if (q - r).abs().partial_cmp(&OFF_LATTICE) != Some(std::cmp::Ordering::Less) {
                return None;
            }
            p[a] = r as i64;
        }
        points.push(p);
    }
    Some(points)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn kalthoff_winkler_paper_grid_has_321201_nodes() {
        let plate = Solid::Box {
            min: vec![0.0, -0.1],
            max: vec![0.1, 0.1],
        };
        let lattice = Lattice::<2>::build(&plate, 0.25e-3, [0.0; 2], 1);
        assert_eq!(lattice.len(), 321_201);
    }

    #[test]
    fn anchored_lattices_of_nested_bodies_share_their_nodes_bit_for_bit() {
        // Node k of an anchored lattice is origin + k·Δx whatever the body's extent, so a
        // truncated domain and its large reference carry their common nodes at the same bits
        // (the lower bound's own rounding would otherwise move them by ulps).
        let disc = |r: f64| Solid::Sphere {
            center: vec![0.0, 0.0],
            radius: r,
        };
        let origin = [0.0, 0.0];
        let small = Lattice::<2>::build_anchored(&disc(0.25), 1e-3, Some(&origin), [0.0; 2], 1);
        let large = Lattice::<2>::build_anchored(&disc(0.67), 1e-3, Some(&origin), [0.0; 2], 1);
        let bits = |x: &[f64; 2]| [x[0].to_bits(), x[1].to_bits()];
        let in_large: std::collections::HashSet<_> = large.positions.iter().map(bits).collect();
        assert!(small.positions.iter().all(|x| in_large.contains(&bits(x))));
        for &c in small.positions.iter().flatten() {
            let k = (c / 1e-3).round();
            assert_eq!(c.to_bits(), (k * 1e-3).to_bits());
        }
    }

    #[test]
    fn perturbation_stays_within_bounds_and_is_reproducible() {
        let cube = Solid::Box {
            min: vec![0.0; 3],
            max: vec![1.0; 3],
        };
        let a = Lattice::<3>::build(&cube, 0.1, [-0.35, 0.35], 7);
        let b = Lattice::<3>::build(&cube, 0.1, [-0.35, 0.35], 7);
        let plain = Lattice::<3>::build(&cube, 0.1, [0.0; 2], 7);
        assert_eq!(a.positions, b.positions);
        for (p, q) in a.positions.iter().zip(&plain.positions) {
            for k in 0..3 {
                assert!((p[k] - q[k]).abs() <= 0.035 + 1e-15);
            }
        }
    }
}
