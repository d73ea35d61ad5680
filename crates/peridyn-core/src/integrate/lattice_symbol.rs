//! A rigorous upper bound of the largest eigenvalue of a linearized bond operator on a lattice,
//! from the infinite lattice's symbol: the stable step of a lattice scene without iterating
//! the whole operator (Lanczos needs 26–55 applications of it).
//!
//! The operator per unit mass (K u)_i = Σ_j c(‖ξ_ij‖) ξ_ij ξ_ijᵀ (u_i − u_j), c ≥ 0
//! (`Standard::apply_linearized`; thesis (3.1) linearized, seed-thesis-ch2-3 §3.1), on nodes
//! of one mass: uᵀKu = ½ Σ_(i,j) c (ξ_ij · (u_i − u_j))², a sum of positive semi-definite bond
//! terms. Any set of nodes of the lattice h ℤ^D + x_0 (one node per point), with any bonds
//! removed (free edges, holes, pre-cracks, broken bonds), keeps a subset of the infinite
//! lattice's terms, so its λ_max is at most the infinite lattice's: sup_k λ_max(A(k)), with the
//! symbol A(k) = Σ_ξ c(‖ξ‖) (1 − cos k·ξ) ξ ξᵀ over every lattice offset of a family (the
//! Fourier modes e^{i k·x} over the Brillouin zone [−π/h, π/h]^D; A(−k) = A(k)).
//!
//! The supremum is bounded by branch and bound over half the zone. On a box with centre k_c
//! and half-widths w, A(k_c + Δ) = A(k_c) + Σ_d Δ_d ∂_d A(k_c) + R with ‖R‖ ≤ ½ ‖Δ‖² H,
//! H = Σ_ξ c ‖ξ‖⁴ (the second derivative along a unit e is Σ c cos(k·ξ) (e·ξ)² ξ ξᵀ); λ_max of
//! the affine part is convex in Δ, so it is largest at a vertex; so over the box
//! λ_max(A(k)) ≤ max_vertices λ_max(A(k_c) + Σ_d s_d w_d ∂_d A(k_c)) + ½ ‖w‖² H (Weyl).
//! Boxes whose bound exceeds (1 + tolerance) × the largest centre value found are split into
//! 2^D; the result is that value × (1 + tolerance), never below the supremum.

use std::f64::consts::PI;

use rayon::prelude::*;

/// Relative allowance for rounding in the sums and the closed-form eigenvalues (the 3 × 3
/// trigonometric form loses up to ~1e-8 near a double eigenvalue).
const ROUNDING: f64 = 1e-6;

/// Boxes per axis of the first level (half as many along the first axis: A(−k) = A(k)).
const FIRST_LEVEL: usize = 8;

/// The symbol of a lattice bond operator: its offsets and their coefficients.
pub struct LatticeSymbol<const D: usize> {
    offsets: Vec<[f64; D]>,
    coefficients: Vec<f64>,
    /// π/h: the Brillouin zone's half-width.
    zone: f64,
    /// H = Σ c ‖ξ‖⁴, the bound of the symbol's second derivatives.
    curvature: f64,
}

impl<const D: usize> LatticeSymbol<D> {
    /// Every lattice offset h q (q ∈ ℤ^D, q ≠ 0) no longer than `reach`, with coefficient
    /// `coefficient(‖h q‖)` (offsets with a zero coefficient dropped; the coefficient must be
    /// ≥ 0 and finite, and D 1, 2 or 3, else `None`).
    pub fn new(spacing: f64, reach: f64, coefficient: impl Fn(f64) -> f64) -> Option<Self> {
        let usable = spacing > 0.0 && spacing.is_finite() && reach.is_finite() && reach >= 0.0;
        if !(usable && (1..=3).contains(&D)) {
            return None;
        }
        let most = (reach / spacing).floor() as i64;
        let (mut offsets, mut coefficients) = (Vec::new(), Vec::new());
        let mut q = [-most; D];
        loop {
            if q.iter().any(|&x| x != 0) {
                let xi: [f64; D] = std::array::from_fn(|a| q[a] as f64 * spacing);
                let l = xi.iter().map(|x| x * x).sum::<f64>().sqrt();
                if l <= reach {
                    let c = coefficient(l);
                    if !(c >= 0.0 && c.is_finite()) {
                        return None;
                    }
                    if c > 0.0 {
                        offsets.push(xi);
                        coefficients.push(c);
                    }
                }
            }
            // The next q in lexicographic order over [−most, most]^D.
            let Some(a) = (0..D).find(|&a| q[a] < most) else {
                break;
            };
            q[a] += 1;
            q[..a].fill(-most);
        }
        let curvature = offsets
            .iter()
            .zip(&coefficients)
            .map(|(xi, c)| c * xi.iter().map(|x| x * x).sum::<f64>().powi(2))
            .sum();
        Some(LatticeSymbol {
            offsets,
            coefficients,
            zone: PI / spacing,
            curvature,
        })
    }

    /// The symbol of a family whose longest bond is `longest_bond`: every bond's offset is a
    /// lattice vector no longer than that, and the reach's rounding allowance only adds
    /// (positive semi-definite) terms.
    pub fn of_bonds(
        spacing: f64,
        longest_bond: f64,
        coefficient: impl Fn(f64) -> f64,
    ) -> Option<Self> {
        Self::new(spacing, longest_bond * (1.0 + 1e-9), coefficient)
    }

    /// λ_max(A(k)).
    pub fn value(&self, k: [f64; D]) -> f64 {
        largest_eigenvalue(&self.symbol(k).0)
    }

    /// A(k) and its derivatives ∂_d A(k), as row-major D × D matrices.
    fn symbol(&self, k: [f64; D]) -> ([[f64; D]; D], [[[f64; D]; D]; D]) {
        let mut a = [[0.0; D]; D];
        let mut da = [[[0.0; D]; D]; D];
        for (xi, &c) in self.offsets.iter().zip(&self.coefficients) {
            let phase: f64 = (0..D).map(|d| k[d] * xi[d]).sum();
            let (s, cos) = phase.sin_cos();
            let (even, odd) = (c * (1.0 - cos), c * s);
            for r in 0..D {
                for col in 0..D {
                    let outer = xi[r] * xi[col];
                    a[r][col] += even * outer;
                    for d in 0..D {
                        da[d][r][col] += odd * xi[d] * outer;
                    }
                }
            }
        }
        (a, da)
    }

    /// (λ_max at the box's centre, the bound of λ_max over the box).
    fn box_bound(&self, centre: [f64; D], half: [f64; D]) -> (f64, f64) {
        let (a, da) = self.symbol(centre);
        let mut most = f64::NEG_INFINITY;
        for vertex in 0..1usize << D {
            let mut m = a;
            for d in 0..D {
                let step = if vertex >> d & 1 == 1 {
                    half[d]
                } else {
                    -half[d]
                };
                for r in 0..D {
                    for col in 0..D {
                        m[r][col] += step * da[d][r][col];
                    }
                }
            }
            most = most.max(largest_eigenvalue(&m));
        }
        let radius2: f64 = half.iter().map(|w| w * w).sum();
        (
            largest_eigenvalue(&a),
            most + 0.5 * radius2 * self.curvature,
        )
    }

    /// An upper bound of sup_k λ_max(A(k)), at most (1 + `tolerance`)(1 + 10⁻⁶) times it;
    /// `None` if the branch and bound needs more than `max_evaluations` boxes (a very flat top).
    pub fn max_eigenvalue_bound(&self, tolerance: f64, max_evaluations: usize) -> Option<f64> {
        if self.offsets.is_empty() {
            return Some(0.0);
        }
        let counts: [usize; D] =
            std::array::from_fn(|d| if d == 0 { FIRST_LEVEL / 2 } else { FIRST_LEVEL });
        let half: [f64; D] = std::array::from_fn(|d| {
            let width = if d == 0 { self.zone } else { 2.0 * self.zone };
            0.5 * width / counts[d] as f64
        });
        let mut level: Vec<([f64; D], [f64; D])> = Vec::new();
        let total: usize = counts.iter().product();
        for index in 0..total {
            let mut rest = index;
            let centre = std::array::from_fn(|d| {
                let i = rest % counts[d];
                rest /= counts[d];
                let low = if d == 0 { 0.0 } else { -self.zone };
                low + half[d] * (2 * i + 1) as f64
            });
            level.push((centre, half));
        }
        let mut best = 0.0f64;
        let mut evaluations = 0;
        while !level.is_empty() {
            evaluations += level.len();
            if evaluations > max_evaluations {
                return None;
            }
            let bounds: Vec<(f64, f64)> = level
                .par_iter()
                .map(|&(c, w)| self.box_bound(c, w))
                .collect();
            for &(at_centre, _) in &bounds {
                best = best.max(at_centre);
            }
            let target = best * (1.0 + tolerance);
            let mut next = Vec::new();
            for (&(centre, half), &(_, bound)) in level.iter().zip(&bounds) {
                // A NaN bound is split too (and fails at the cap).
                if bound <= target {
                    continue;
                }
                let quarter = half.map(|w| 0.5 * w);
                for child in 0..1usize << D {
                    let c = std::array::from_fn(|d| {
                        centre[d]
                            + if child >> d & 1 == 1 {
                                quarter[d]
                            } else {
                                -quarter[d]
                            }
                    });
                    next.push((c, quarter));
                }
            }
            level = next;
        }
        Some(best * (1.0 + tolerance) * (1.0 + ROUNDING))
    }
}

/// The largest eigenvalue of a symmetric D × D matrix (D ≤ 3), in closed form.
fn largest_eigenvalue<const D: usize>(m: &[[f64; D]; D]) -> f64 {
    match D {
        1 => m[0][0],
        2 => {
            let (a, b, d) = (m[0][0], m[0][1], m[1][1]);
            0.5 * (a + d) + (0.25 * (a - d) * (a - d) + b * b).sqrt()
        }
        3 => {
            // Trigonometric form for a symmetric 3 × 3 matrix (Smith 1961).
            let p1 = m[0][1] * m[0][1] + m[0][2] * m[0][2] + m[1][2] * m[1][2];
            let q = (m[0][0] + m[1][1] + m[2][2]) / 3.0;
            let p2 = (0..3).map(|i| (m[i][i] - q).powi(2)).sum::<f64>() + 2.0 * p1;
            if p2 == 0.0 {
                return q;
            }
            let p = (p2 / 6.0).sqrt();
            let b: [[f64; 3]; 3] = std::array::from_fn(|r| {
                std::array::from_fn(|c| (m[r][c] - if r == c { q } else { 0.0 }) / p)
            });
            let det = b[0][0] * (b[1][1] * b[2][2] - b[1][2] * b[2][1])
                - b[0][1] * (b[1][0] * b[2][2] - b[1][2] * b[2][0])
                + b[0][2] * (b[1][0] * b[2][1] - b[1][1] * b[2][0]);
            let phi = (0.5 * det).clamp(-1.0, 1.0).acos() / 3.0;
            q + 2.0 * p * phi.cos()
        }
        _ => panic!("the lattice symbol is for D = 1, 2 or 3"),
    }
}

/// Whether every point of `reference` lies on the lattice of spacing `spacing` through its
/// first point (to 10⁻⁶ of the spacing), one point per lattice point: then the operator on
/// them is bounded by a [`LatticeSymbol`] of that spacing.
pub fn on_lattice<const D: usize>(reference: &[[f64; D]], spacing: f64) -> bool {
    let Some(points) = crate::discretization::grid::lattice_points(reference, spacing) else {
        return false;
    };
    let mut sorted = points;
    sorted.sort_unstable();
    sorted.windows(2).all(|w| w[0] != w[1])
}

#[cfg(test)]
mod tests {
    use super::*;

    const TOLERANCE: f64 = 1e-3;

    /// The nearest-neighbour chain: A(k) = 2 c h² (1 − cos k h), largest 4 c h² at k = π/h.
    #[test]
    fn a_chain_s_bound_is_its_zone_edge_value() {
        let symbol = LatticeSymbol::<1>::new(0.5, 0.5, |_| 3.0).unwrap();
        let exact = 4.0 * 3.0 * 0.25;
        let bound = symbol.max_eigenvalue_bound(TOLERANCE, 100_000).unwrap();
        assert!(bound >= exact && bound <= exact * (1.0 + TOLERANCE) * (1.0 + ROUNDING));
    }

    /// A 2D family of horizon 4 spacings with β-like weights: the bound is at least the symbol
    /// anywhere on a fine grid of the zone, and within the tolerance of the grid's largest.
    #[test]
    fn the_bound_covers_the_symbol_on_a_fine_grid() {
        let h = 0.5;
        let reach = 4.0 * h;
        let weight = |l: f64| ((reach + 0.5 * h - l) / h).clamp(0.0, 1.0) / (l * l * l);
        let symbol = LatticeSymbol::<2>::new(h, reach, weight).unwrap();
        let bound = symbol.max_eigenvalue_bound(TOLERANCE, 1_000_000).unwrap();
        let n = 300;
        let mut grid_max = 0.0f64;
        for i in 0..=n {
            for j in 0..=2 * n {
                let k = [
                    symbol.zone * i as f64 / n as f64,
                    symbol.zone * (j as f64 / n as f64 - 1.0),
                ];
                grid_max = grid_max.max(symbol.value(k));
            }
        }
        assert!(bound >= grid_max, "{bound} < {grid_max}");
        assert!(
            bound <= grid_max * (1.0 + 2.0 * TOLERANCE),
            "{bound} against {grid_max}"
        );
    }

    /// The 3 × 3 closed form against the characteristic polynomial and a diagonal matrix.
    #[test]
    fn closed_form_eigenvalues() {
        let m = [[4.0, 1.0, 0.5], [1.0, 3.0, -0.2], [0.5, -0.2, 2.0]];
        let l = largest_eigenvalue(&m);
        let det = |x: f64| {
            let a: [[f64; 3]; 3] = std::array::from_fn(|r| {
                std::array::from_fn(|c| m[r][c] - if r == c { x } else { 0.0 })
            });
            a[0][0] * (a[1][1] * a[2][2] - a[1][2] * a[2][1])
                - a[0][1] * (a[1][0] * a[2][2] - a[1][2] * a[2][0])
                + a[0][2] * (a[1][0] * a[2][1] - a[1][1] * a[2][0])
        };
        assert!(det(l).abs() < 1e-12 && l > 4.0 && det(l + 1e-6) * det(l - 1e-6) < 0.0);
        let diagonal = [[1.0, 0.0, 0.0], [0.0, 5.0, 0.0], [0.0, 0.0, 2.0]];
        assert!((largest_eigenvalue(&diagonal) - 5.0).abs() < 1e-12);
        assert_eq!(largest_eigenvalue(&[[2.0, 1.0], [1.0, 2.0]]), 3.0);
    }

    /// The operator of an open 12 × 12 patch of the 2D lattice with a cut (built as an
    /// explicit matrix, independently of the symbol; λ_max by the solver's Lanczos, a value
    /// from below) stays below the symbol's bound, and not far below it.
    #[test]
    fn an_open_patch_with_a_cut_stays_below_the_bound() {
        let (reach, side) = (2.5f64, 12usize);
        let weight = |l: f64| 1.0 / (l * l * l);
        let symbol = LatticeSymbol::<2>::new(1.0, reach, weight).unwrap();
        let bound = symbol.max_eigenvalue_bound(TOLERANCE, 1_000_000).unwrap();
        let n = side * side;
        let mut k = vec![vec![0.0; 2 * n]; 2 * n];
        let (r, s) = (reach as i64, side as i64);
        for i in 0..n {
            let (xi, yi) = ((i % side) as i64, (i / side) as i64);
            for dx in -r..=r {
                for dy in -r..=r {
                    let l = ((dx * dx + dy * dy) as f64).sqrt();
                    let (x, y) = (xi + dx, yi + dy);
                    let outside = !(0..s).contains(&x) || !(0..s).contains(&y);
                    // A cut between rows 5 and 6 for x < 6.
                    let cut = x < 6 && xi < 6 && (yi <= 5) != (y <= 5);
                    if (dx, dy) == (0, 0) || l > reach || outside || cut {
                        continue;
                    }
                    let j = (y * s + x) as usize;
                    let e = [dx as f64, dy as f64];
                    for a in 0..2 {
                        for b in 0..2 {
                            let v = weight(l) * e[a] * e[b];
                            k[2 * i + a][2 * i + b] += v;
                            k[2 * i + a][2 * j + b] -= v;
                        }
                    }
                }
            }
        }
        let lanczos = crate::integrate::stability::max_eigenvalue::<2>(
            n,
            &vec![1.0; n],
            200,
            |u: &[[f64; 2]], out: &mut [[f64; 2]]| {
                let flat = u.as_flattened();
                for (o, row) in out.as_flattened_mut().iter_mut().zip(&k) {
                    *o = row.iter().zip(flat).map(|(a, b)| a * b).sum();
                }
            },
        );
        assert!(lanczos <= bound, "{lanczos} against {bound}");
        assert!(lanczos >= 0.85 * bound, "{lanczos} against {bound}");
    }

    #[test]
    fn lattice_membership() {
        let square: Vec<[f64; 2]> = (0..16)
            .map(|i| [0.3 + (i % 4) as f64 * 0.5, (i / 4) as f64 * 0.5])
            .collect();
        assert!(on_lattice(&square, 0.5));
        let mut doubled = square.clone();
        doubled.push(square[3]);
        assert!(!on_lattice(&doubled, 0.5));
        let mut off = square;
        off[5][0] += 1e-4;
        assert!(!on_lattice(&off, 0.5));
    }
}
