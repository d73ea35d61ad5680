//! Global linear solves for static scenes: banded LU with partial pivoting.
//!
//! Both schemes give sparse matrices whose entries lie within a horizon of the diagonal when
//! the unknowns are numbered along the lattice (1D: half bandwidth ≈ m). The WLS matrix is not
//! symmetric, so the factorization pivots. Storage is n × (2 kl + ku + 1): row pivoting can
//! widen the upper band by kl.

/// Why a linear solve failed.
#[derive(Debug, Clone, PartialEq)]
pub enum LinearError {
    /// The band storage would exceed the memory budget.
    TooLarge { unknowns: usize, bytes: f64 },
    /// A zero pivot: the matrix is singular (e.g. a node with no held neighbour path).
    Singular { row: usize },
}

impl std::fmt::Display for LinearError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            LinearError::TooLarge { unknowns, bytes } => write!(
                f,
                "the banded matrix of {unknowns} unknowns needs {:.1} GB (limit {:.0} GB): \
                 coarsen the spacing or lower the horizon factor",
                bytes / 1e9,
                MAX_BYTES / 1e9
            ),
            LinearError::Singular { row } => write!(
                f,
                "the stiffness matrix is singular at unknown {row}: every node must be \
                 connected to a held (Dirichlet) layer"
            ),
        }
    }
}

impl std::error::Error for LinearError {}

const MAX_BYTES: f64 = 8e9;

/// A square matrix with `lower` sub- and `upper` super-diagonals, rows stored as windows of
/// columns [i − lower, i + lower + upper].
pub struct BandMatrix {
    n: usize,
    lower: usize,
    upper: usize,
    width: usize,
    data: Vec<f64>,
}

impl BandMatrix {
    pub fn new(n: usize, lower: usize, upper: usize) -> Result<Self, LinearError> {
        let width = 2 * lower + upper + 1;
        let bytes = n as f64 * width as f64 * 8.0;
        if bytes > MAX_BYTES {
            return Err(LinearError::TooLarge { unknowns: n, bytes });
        }
        Ok(BandMatrix {
            n,
            lower,
            upper,
            width,
            data: vec![0.0; n * width],
        })
    }

    /// Half bandwidths (lower, upper) of a set of (row, column) entries.
    pub fn bandwidths(entries: impl Iterator<Item = (usize, usize)>) -> (usize, usize) {
        entries.fold((0, 0), |(lo, up), (r, c)| {
            (lo.max(r.saturating_sub(c)), up.max(c.saturating_sub(r)))
        })
    }

    #[inline]
    fn slot(&self, row: usize, col: usize) -> usize {
        row * self.width + (col + self.lower - row)
    }

    /// Adds `value` at (row, col); the entry must lie inside the declared band.
    pub fn add(&mut self, row: usize, col: usize, value: f64) {
        debug_assert!(col + self.lower >= row && col <= row + self.upper);
        let s = self.slot(row, col);
        self.data[s] += value;
    }

    /// Solves A x = b in place (A is overwritten by its factors).
    pub fn solve(mut self, b: &mut [f64]) -> Result<(), LinearError> {
        let n = self.n;
        let reach = self.lower + self.upper;
        for p in 0..n {
            // Pivot: the largest |entry| in column p among rows p ..= p + lower.
            let last = (p + self.lower).min(n - 1);
            let (pivot_row, pivot) = (p..=last)
                .map(|r| (r, self.data[self.slot(r, p)].abs()))
                .fold((p, -1.0), |best, c| if c.1 > best.1 { c } else { best });
            if pivot == 0.0 || !pivot.is_finite() {
                return Err(LinearError::Singular { row: p });
            }
            let end = (p + reach).min(n - 1);
            if pivot_row != p {
                for col in p..=end {
                    let (a, c) = (self.slot(p, col), self.slot(pivot_row, col));
                    self.data.swap(a, c);
                }
                b.swap(p, pivot_row);
            }
            let diag = self.data[self.slot(p, p)];
            for r in p + 1..=last {
                let f = self.data[self.slot(r, p)] / diag;
                if f == 0.0 {
                    continue;
                }
                for col in p..=end {
                    let v = self.data[self.slot(p, col)];
                    let s = self.slot(r, col);
                    self.data[s] -= f * v;
                }
                b[r] -= f * b[p];
            }
        }
        for p in (0..n).rev() {
            let end = (p + reach).min(n - 1);
            let sum: f64 = (p + 1..=end)
                .map(|col| self.data[self.slot(p, col)] * b[col])
                .sum();
            b[p] = (b[p] - sum) / self.data[self.slot(p, p)];
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::discretization::grid::SplitMix64;

    /// A random non-symmetric banded system that needs pivoting (zero diagonal entries),
    /// checked against its residual.
    #[test]
    fn solves_a_random_banded_system_with_pivoting() {
        let (n, lower, upper) = (200, 3, 5);
        let mut rng = SplitMix64(9);
        let mut dense = vec![vec![0.0; n]; n];
        let mut a = BandMatrix::new(n, lower, upper).unwrap();
        for (r, row) in dense.iter_mut().enumerate() {
            let first = r.saturating_sub(lower);
            for (c, entry) in row
                .iter_mut()
                .enumerate()
                .take((r + upper).min(n - 1) + 1)
                .skip(first)
            {
                let v = if c == r && r % 7 == 0 {
                    0.0
                } else {
                    rng.next_f64() - 0.5
                };
                *entry = v;
                a.add(r, c, v);
            }
        }
        let x_true: Vec<f64> = (0..n).map(|i| (i as f64 * 0.1).sin()).collect();
        let mut b: Vec<f64> = dense
            .iter()
            .map(|row| row.iter().zip(&x_true).map(|(a, x)| a * x).sum())
            .collect();
        a.solve(&mut b).unwrap();
        let err = b
            .iter()
            .zip(&x_true)
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f64::max);
        assert!(err < 1e-9, "max error {err}");
    }

    #[test]
    fn reports_a_singular_matrix() {
        let mut a = BandMatrix::new(3, 1, 1).unwrap();
        a.add(0, 0, 1.0);
        a.add(2, 2, 1.0);
        assert_eq!(
            a.solve(&mut [1.0, 1.0, 1.0]),
            Err(LinearError::Singular { row: 1 })
        );
    }

    #[test]
    fn refuses_a_band_that_does_not_fit() {
        assert!(matches!(
            BandMatrix::new(1 << 30, 100, 100),
            Err(LinearError::TooLarge { .. })
        ));
    }
}
