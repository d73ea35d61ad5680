//! One row of the standard scheme's linearized operator (`Standard::apply_linearized`):
//! Σ_j c_ij ((ξ · (u_i − u_j)) ξ over the row's intact bonds, written once over the lanes
//! of `simd`: N bonds together (a broken bond's coefficient counts as 0), the per-lane sums
//! added in lane order, then the remainder one bond at a time.

use crate::simd::{LaneLoop, Lanes, Portable};

/// One row of [`super::Standard::apply_linearized`]: node i's bonds, their states and
/// coefficients.
pub(super) struct LinearizedRow<'a> {
    pub i: usize,
    pub neighbors: &'a [u32],
    pub states: &'a [u8],
    pub coefficients: &'a [f64],
}

/// A row for `Simd::run`, at the reference positions `reference` and displacements `u`.
pub(super) struct RowLoop<'a, const D: usize> {
    pub row: &'a LinearizedRow<'a>,
    pub reference: &'a [[f64; D]],
    pub u: &'a [[f64; D]],
}

impl<const D: usize> LaneLoop for RowLoop<'_, D> {
    type Output = [f64; D];

    #[inline(always)]
    fn run<L: Lanes>(self) -> [f64; D] {
        let Self { row, reference, u } = self;
        let (x_i, u_i) = (reference[row.i], u[row.i]);
        let (flat_reference, flat_u) = (reference.as_flattened(), u.as_flattened());
        // Every neighbour is a node (checked once per row: the gathers do not check).
        let last = row.neighbors.iter().copied().max().unwrap_or(0) as usize;
        assert!(reference.len() == u.len() && (row.neighbors.is_empty() || last < u.len()));
        assert!(
            row.states.len() == row.neighbors.len()
                && row.coefficients.len() == row.neighbors.len()
        );
        let blocked = row.neighbors.len() / L::N * L::N;
        let mut acc = [L::zero(); D];
        for ((nodes, states), coefficients) in row.neighbors[..blocked]
            .chunks_exact(L::N)
            .zip(row.states[..blocked].chunks_exact(L::N))
            .zip(row.coefficients[..blocked].chunks_exact(L::N))
        {
            let bonds = Bonds {
                nodes,
                states,
                coefficients,
            };
            // SAFETY: the indices were checked above.
            unsafe { bonds.add(x_i, u_i, flat_reference, flat_u, &mut acc) };
        }
        let mut row_acc = acc.map(|a| Portable([a.sum()]));
        for b in blocked..row.neighbors.len() {
            // A broken bond of the remainder is skipped (in a block it weighs 0).
            if row.states[b] != 0 {
                let bond = Bonds {
                    nodes: &row.neighbors[b..b + 1],
                    states: &row.states[b..b + 1],
                    coefficients: &row.coefficients[b..b + 1],
                };
                // SAFETY: the index was checked above.
                unsafe { bond.add(x_i, u_i, flat_reference, flat_u, &mut row_acc) };
            }
        }
        row_acc.map(|a| a.0[0])
    }
}

/// N bonds of a row.
struct Bonds<'a> {
    nodes: &'a [u32],
    states: &'a [u8],
    coefficients: &'a [f64],
}

impl Bonds<'_> {
    /// c ((ξ · (u_i − u_j)) ξ on N bonds (0 for a broken one) added to `acc`, node i at
    /// `x_i` displaced by `u_i`; `reference` and `u` hold D values per node.
    ///
    /// # Safety
    /// Every index in `nodes` is a node of `reference` and `u`.
    #[inline(always)]
    unsafe fn add<L: Lanes, const D: usize>(
        &self,
        x_i: [f64; D],
        u_i: [f64; D],
        reference: &[f64],
        u: &[f64],
        acc: &mut [L; D],
    ) {
        // SAFETY: the caller guarantees the indices.
        let (x, u_j) = unsafe {
            (
                L::gather::<D>(reference, self.nodes),
                L::gather::<D>(u, self.nodes),
            )
        };
        let xi: [L; D] = std::array::from_fn(|k| x[k] - L::splat(x_i[k]));
        let du: [L; D] = std::array::from_fn(|k| L::splat(u_i[k]) - u_j[k]);
        let mut proj = xi[0] * du[0];
        for k in 1..D {
            proj = proj + xi[k] * du[k];
        }
        let scale = (L::load(self.coefficients) * proj).zero_unless(L::nonzero(self.states));
        for (a, xi_k) in acc.iter_mut().zip(&xi) {
            *a = *a + scale * *xi_k;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::discretization::Families;
    use crate::discretization::grid::Lattice;
    use crate::scene::Solid;
    use crate::simd::Simd;

    /// The row as plain scalar code in the order of the `lanes`-lane loop: of its n bonds the
    /// first ⌊n/N⌋·N go to lane b mod N (a broken one adding 0), the lanes' sums are added in
    /// lane order, then the intact others one by one.
    fn scalar_row<const D: usize>(
        lanes: usize,
        row: &LinearizedRow,
        reference: &[[f64; D]],
        u: &[[f64; D]],
    ) -> [f64; D] {
        let i = row.i;
        let term = |b: usize| -> [f64; D] {
            let j = row.neighbors[b] as usize;
            let xi: [f64; D] = std::array::from_fn(|k| reference[j][k] - reference[i][k]);
            let proj = (1..D).fold(xi[0] * (u[i][0] - u[j][0]), |p, k| {
                p + xi[k] * (u[i][k] - u[j][k])
            });
            let scale = if row.states[b] != 0 {
                row.coefficients[b] * proj
            } else {
                0.0
            };
            xi.map(|x| scale * x)
        };
        let blocked = row.neighbors.len() / lanes * lanes;
        let mut lane_sums = vec![[0.0; D]; lanes];
        for b in 0..blocked {
            let t = term(b);
            for k in 0..D {
                lane_sums[b % lanes][k] += t[k];
            }
        }
        let mut acc: [f64; D] = std::array::from_fn(|k| lane_sums.iter().map(|s| s[k]).sum());
        for b in (blocked..row.neighbors.len()).filter(|&b| row.states[b] != 0) {
            let t = term(b);
            for k in 0..D {
                acc[k] += t[k];
            }
        }
        acc
    }

    /// Every lane implementation this CPU runs gives the scalar row's bits in its lane
    /// count's order, in 1D, 2D and 3D, with broken bonds and a displacement field without
    /// symmetry.
    #[test]
    fn every_lane_implementation_gives_the_scalar_rows_bits() {
        fn compare<const D: usize>(side: f64, seed: u64) {
            let solid = Solid::Box {
                min: vec![0.0; D],
                max: vec![side; D],
            };
            let reference = Lattice::<D>::build(&solid, 1.0, [-0.2, 0.2], seed).positions;
            let families = Families::build(&reference, 3.0);
            let coefficients: Vec<f64> = (0..families.bond_count())
                .map(|b| 1.0 + (b % 7) as f64 * 0.37)
                .collect();
            let states: Vec<u8> = (0..families.bond_count())
                .map(|b| u8::from(b % 5 != 3))
                .collect();
            let u: Vec<[f64; D]> = (0..reference.len())
                .map(|i| std::array::from_fn(|k| ((i * (k + 3)) as f64 * 0.618).sin()))
                .collect();
            let supported = Simd::supported();
            assert!(supported.contains(&Simd::Portable) && supported.contains(&Simd::Portable8));
            for i in 0..reference.len() {
                let range = families.range(i);
                let row = LinearizedRow {
                    i,
                    neighbors: &families.neighbors[range.clone()],
                    states: &states[range.clone()],
                    coefficients: &coefficients[range],
                };
                for &simd in &supported {
                    let rows = RowLoop {
                        row: &row,
                        reference: &reference,
                        u: &u,
                    };
                    let expected = scalar_row(simd.lanes(), &row, &reference, &u);
                    assert_eq!(
                        simd.run(rows).map(f64::to_bits),
                        expected.map(f64::to_bits),
                        "{simd:?}, row {i}, D = {D}"
                    );
                    assert!(expected.iter().any(|&x| x != 0.0));
                }
            }
        }
        compare::<3>(7.0, 5);
        compare::<2>(12.0, 9);
        compare::<1>(60.0, 3);
    }
}
