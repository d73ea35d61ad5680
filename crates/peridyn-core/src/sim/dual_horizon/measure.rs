//! Measurements on a particle body: the crack-mouth opening (zeng2024 Sect. 4.1, Table 2) and
//! crack angles (`metrics::cracks`).

use super::body::ParticleBody;
use crate::metrics;

impl ParticleBody {
    /// The opening at a crack mouth (see `schema::OpeningTable`).
    pub fn opening(&self, mouth: &[f64], axis: usize) -> Option<f64> {
        let other = 1 - axis;
        let (x, y) = (self.reference(), self.positions());
        let spacing = self.spacings();
        let nearest = |upper: bool| -> Option<usize> {
            (0..x.len())
                .filter(|&k| (x[k][axis] > mouth[axis]) == upper)
                .filter(|&k| (x[k][other] - mouth[other]).abs() < spacing[k])
                .min_by(|&a, &b| {
                    let d = |k: usize| (x[k][0] - mouth[0]).powi(2) + (x[k][1] - mouth[1]).powi(2);
                    d(a).total_cmp(&d(b))
                })
        };
        // Each face's displacement along `axis`, extrapolated linearly to the mouth from its
        // particle nearest the mouth and the next one of the same row inwards (Tada's d0 is
        // the opening at the edge, the particles sit Δ/2 and 3Δ/2 inside it); the nearest
        // particle's own value when the row has no second one.
        let face = |k: usize| -> f64 {
            let u = |i: usize| y[i][axis] - x[i][axis];
            let inward = (x[k][other] - mouth[other]).signum();
            let same_row = |i: usize| (x[i][axis] - x[k][axis]).abs() < 1e-9 * spacing[k];
            let next = (0..x.len())
                .filter(|&i| same_row(i) && (x[i][other] - x[k][other]) * inward > 0.0)
                .min_by(|&a, &b| {
                    let d = |i: usize| (x[i][other] - x[k][other]).abs();
                    d(a).total_cmp(&d(b))
                });
            match next {
                Some(n) => {
                    let slope = (u(n) - u(k)) / (x[n][other] - x[k][other]);
                    u(k) + slope * (mouth[other] - x[k][other])
                }
                None => u(k),
            }
        };
        let (up, down) = (nearest(true)?, nearest(false)?);
        Some(face(up) - face(down))
    }

    /// Crack angles `(name, degrees)` of the scene's `[[metrics.crack_angle]]` for `damage`.
    pub fn crack_angles_for(&self, damage: &[f64]) -> Vec<(String, Option<f64>)> {
        metrics::crack_angles(&self.scene, self.reference(), damage, self.scene.spacing)
    }
}
