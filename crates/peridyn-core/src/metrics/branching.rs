//! Crack branching on a 2D plate (zeng2024 Sect. 4.2, the Borden / Ha–Bobaru plate): how far
//! the crack has run, where it split into two branches, and damage between the branches.
//!
//! Measured on the damage field (14) in the reference configuration, the crack running along
//! +x from a pre-crack on the line y = `line_y`:
//! - a particle is *cracked* when φ > `threshold` (on the branching preset's lattice a face of
//!   the cut pre-crack keeps 17 of its 28 bonds, φ = 0.393; a particle beside a crack that
//!   has opened loses more than half, so 0.45 tells the running crack from the pre-crack);
//! - columns `column` wide (the coarse spacing) are scanned along x beyond `from_x`; a column
//!   whose cracked particles fall into runs more than `gap` apart along y (one horizon: two
//!   damage bands farther apart than a horizon do not share a bond) holds two cracks;
//! - the branch point is the intersection of the least-squares lines through the cracked
//!   particles of the upper and the lower band beyond the first such column (the bands are
//!   straight there; where two bands first show, they have already run apart by a horizon).

/// What the measurement needs of the scene.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BranchProbe {
    /// The original crack's line.
    pub line_y: f64,
    /// Where the search starts along x (the pre-crack tip).
    pub from_x: f64,
    /// φ above which a particle is cracked.
    pub threshold: f64,
    /// Column width along x.
    pub column: f64,
    /// Two runs of cracked particles farther apart than this along y are two cracks.
    pub gap: f64,
}

/// Two branches found in one damage field.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Branches {
    /// Where the two lines meet.
    pub point: [f64; 2],
    /// The left edge of the first column that holds two bands.
    pub first_split_column: f64,
    /// Angles of the upper and lower branch lines from +x, in degrees (upper > 0 > lower
    /// when they diverge).
    pub angles: [f64; 2],
}

impl BranchProbe {
    /// The cracked particles beyond `from_x`.
    fn cracked(&self, reference: &[[f64; 2]], damage: &[f64]) -> Vec<[f64; 2]> {
        reference
            .iter()
            .zip(damage)
            .filter(|(x, d)| **d > self.threshold && x[0] >= self.from_x)
            .map(|(x, _)| *x)
            .collect()
    }

    /// The crack front: the largest x of a cracked particle beyond `from_x`.
    pub fn front(&self, reference: &[[f64; 2]], damage: &[f64]) -> Option<f64> {
        self.cracked(reference, damage)
            .iter()
            .map(|x| x[0])
            .reduce(f64::max)
    }

    /// The runs (y ranges) of cracked particles in the column starting at `x0`, bottom to top.
    fn runs(&self, cracked: &[[f64; 2]], x0: f64) -> Vec<(f64, f64)> {
        let mut ys: Vec<f64> = cracked
            .iter()
            .filter(|x| x[0] >= x0 && x[0] < x0 + self.column)
            .map(|x| x[1])
            .collect();
        ys.sort_by(f64::total_cmp);
        let mut runs: Vec<(f64, f64)> = Vec::new();
        for y in ys {
            match runs.last_mut() {
                Some(run) if y - run.1 <= self.gap => run.1 = y,
                _ => runs.push((y, y)),
            }
        }
        runs
    }

    /// The branch point, if the field holds two bands somewhere beyond `from_x`.
    pub fn branches(&self, reference: &[[f64; 2]], damage: &[f64]) -> Option<Branches> {
        let cracked = self.cracked(reference, damage);
        let end = cracked.iter().map(|x| x[0]).reduce(f64::max)?;
        let columns = ((end - self.from_x) / self.column).floor() as usize + 1;
        let first = (0..columns)
            .map(|c| self.from_x + c as f64 * self.column)
            .find(|&x0| self.runs(&cracked, x0).len() >= 2)?;
        let beyond = || cracked.iter().filter(move |x| x[0] >= first);
        let upper = line_fit(beyond().filter(|x| x[1] > self.line_y))?;
        let lower = line_fit(beyond().filter(|x| x[1] < self.line_y))?;
        let slope_gap = upper.1 - lower.1;
        if slope_gap.abs() < 1e-12 {
            return None;
        }
        let x = (lower.0 - upper.0) / slope_gap;
        Some(Branches {
            point: [x, upper.0 + upper.1 * x],
            first_split_column: first,
            angles: [upper.1.atan().to_degrees(), lower.1.atan().to_degrees()],
        })
    }

    /// Particles with φ ≥ `threshold` in the columns beyond the first split that lie between
    /// the two outer bands and farther than `gap` from both: damage the two branches do not
    /// account for (zeng2024 Sect. 4.2 Case 2, "fake damage between the two branches").
    pub fn between(&self, reference: &[[f64; 2]], damage: &[f64], threshold: f64) -> usize {
        let Some(b) = self.branches(reference, damage) else {
            return 0;
        };
        let cracked = self.cracked(reference, damage);
        let mut count = 0;
        let mut x0 = b.first_split_column;
        let end = cracked.iter().map(|x| x[0]).fold(x0, f64::max);
        while x0 <= end {
            let runs = self.runs(&cracked, x0);
            if let (Some(low), Some(high)) = (runs.first(), runs.last())
                && runs.len() >= 2
            {
                let (bottom, top) = (low.1 + self.gap, high.0 - self.gap);
                count += reference
                    .iter()
                    .zip(damage)
                    .filter(|(x, d)| {
                        **d >= threshold
                            && x[0] >= x0
                            && x[0] < x0 + self.column
                            && x[1] > bottom
                            && x[1] < top
                    })
                    .count();
            }
            x0 += self.column;
        }
        count
    }
}

/// Least-squares line y = a + b x through the points: (a, b); None for fewer than 3 points or
/// a vertical set.
fn line_fit<'a>(points: impl Iterator<Item = &'a [f64; 2]>) -> Option<(f64, f64)> {
    let (mut n, mut sx, mut sy, mut sxx, mut sxy) = (0.0, 0.0, 0.0, 0.0, 0.0);
    for p in points {
        n += 1.0;
        sx += p[0];
        sy += p[1];
        sxx += p[0] * p[0];
        sxy += p[0] * p[1];
    }
    let det = n * sxx - sx * sx;
    if n < 3.0 || det.abs() <= 1e-12 * n * sxx.max(1e-300) {
        return None;
    }
    let b = (n * sxy - sx * sy) / det;
    Some(((sy - b * sx) / n, b))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A drawn Y: a band along y = 0 up to x = 10, then two bands at ±30° — the branch point
    /// comes back at (10, 0) and the angles at ±30°; a spot between the branches is counted.
    #[test]
    fn a_drawn_y_gives_its_branch_point_and_angles() {
        let h = 0.25;
        let mut points = Vec::new();
        let mut damage = Vec::new();
        let slope = 30f64.to_radians().tan();
        for i in 0..160 {
            for j in -80..80 {
                let (x, y) = (i as f64 * h, j as f64 * h);
                let on_stem = x <= 10.0 && y.abs() < 0.3;
                let on_branch = x > 10.0 && (y.abs() - slope * (x - 10.0)).abs() < 0.3;
                let spot = (x - 30.0).abs() < 0.3 && y.abs() < 0.3;
                points.push([x, y]);
                damage.push(if on_stem || on_branch {
                    0.6
                } else if spot {
                    0.3
                } else {
                    0.0
                });
            }
        }
        let probe = BranchProbe {
            line_y: 0.0,
            from_x: 0.0,
            threshold: 0.45,
            column: 1.0,
            gap: 3.0,
        };
        let b = probe.branches(&points, &damage).unwrap();
        assert!((b.point[0] - 10.0).abs() < 0.3, "{b:?}");
        assert!(b.point[1].abs() < 0.1, "{b:?}");
        assert!((b.angles[0] - 30.0).abs() < 1.0 && (b.angles[1] + 30.0).abs() < 1.0);
        assert!(b.first_split_column > 10.0 + 1.5 / slope, "{b:?}");
        assert_eq!(probe.front(&points, &damage), Some(39.75));
        assert!(probe.between(&points, &damage, 0.2) > 0);
        assert_eq!(probe.between(&points, &damage, 0.45), 0);
    }
}
