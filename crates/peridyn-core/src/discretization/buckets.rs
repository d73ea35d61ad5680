//! A uniform cell grid over 2D reference positions for radius searches whose node set changes
//! during a run (particle splitting moves one node and adds others). Cells are `cell` wide; a
//! search of radius r ≤ `cell` visits the 3×3 block around the query's cell.

/// Node indices bucketed by cell.
#[derive(Debug, Clone)]
pub struct Buckets {
    origin: [f64; 2],
    cell: f64,
    shape: [usize; 2],
    cells: Vec<Vec<u32>>,
}

impl Buckets {
    /// Buckets of `positions` with cells `cell` wide over their bounding box grown by `margin`
    /// (room for nodes added later within it).
    pub fn new(positions: &[[f64; 2]], cell: f64, margin: f64) -> Buckets {
        assert!(cell > 0.0 && cell.is_finite(), "a positive cell size");
        let mut lo = [f64::INFINITY; 2];
        let mut hi = [f64::NEG_INFINITY; 2];
        for x in positions {
            for a in 0..2 {
                lo[a] = lo[a].min(x[a]);
                hi[a] = hi[a].max(x[a]);
            }
        }
        if positions.is_empty() {
            (lo, hi) = ([0.0; 2], [0.0; 2]);
        }
        let origin = [lo[0] - margin, lo[1] - margin];
        let shape = [0, 1].map(|a| (((hi[a] + margin - origin[a]) / cell).floor() as usize) + 1);
        let mut buckets = Buckets {
            origin,
            cell,
            shape,
            cells: vec![Vec::new(); shape[0] * shape[1]],
        };
        for (i, x) in positions.iter().enumerate() {
            buckets.insert(i as u32, x);
        }
        buckets
    }

    /// The cell width: the largest radius a search may ask for.
    pub fn cell(&self) -> f64 {
        self.cell
    }

    fn coordinates(&self, x: &[f64; 2]) -> [usize; 2] {
        [0, 1].map(|a| {
            let c = ((x[a] - self.origin[a]) / self.cell).floor();
            (c.max(0.0) as usize).min(self.shape[a] - 1)
        })
    }

    fn index(&self, c: [usize; 2]) -> usize {
        c[1] * self.shape[0] + c[0]
    }

    pub fn insert(&mut self, node: u32, x: &[f64; 2]) {
        let k = self.index(self.coordinates(x));
        self.cells[k].push(node);
    }

    /// Moves `node` from its cell at `from` to the cell at `to`.
    pub fn relocate(&mut self, node: u32, from: &[f64; 2], to: &[f64; 2]) {
        let k = self.index(self.coordinates(from));
        if let Some(p) = self.cells[k].iter().position(|&n| n == node) {
            self.cells[k].swap_remove(p);
        }
        self.insert(node, to);
    }

    /// Calls `visit(j)` for every node j with |x_j − x| < radius (radius ≤ the cell size),
    /// in no particular order.
    pub fn within(
        &self,
        positions: &[[f64; 2]],
        x: &[f64; 2],
        radius: f64,
        mut visit: impl FnMut(u32),
    ) {
        debug_assert!(radius <= self.cell * (1.0 + 1e-12));
        let c = self.coordinates(x);
        let r2 = radius * radius;
        for cy in c[1].saturating_sub(1)..(c[1] + 2).min(self.shape[1]) {
            for cx in c[0].saturating_sub(1)..(c[0] + 2).min(self.shape[0]) {
                for &j in &self.cells[self.index([cx, cy])] {
                    let y = &positions[j as usize];
                    let d2 = (y[0] - x[0]).powi(2) + (y[1] - x[1]).powi(2);
                    if d2 < r2 {
                        visit(j);
                    }
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn radius_search_matches_a_brute_force_scan() {
        let mut positions: Vec<[f64; 2]> = (0..400)
            .map(|k| [(k % 20) as f64 * 0.1, (k / 20) as f64 * 0.1])
            .collect();
        let mut b = Buckets::new(&positions, 0.31, 0.1);
        // A moved node and an added one.
        let old = positions[7];
        positions[7] = [0.72, 0.05];
        b.relocate(7, &old, &positions[7]);
        positions.push([0.69, 0.11]);
        b.insert(400, &positions[400]);
        for x in [[0.7, 0.1], [0.0, 0.0], [1.9, 1.9], [0.95, 1.05]] {
            let mut found = Vec::new();
            b.within(&positions, &x, 0.3, |j| found.push(j));
            found.sort_unstable();
            let brute: Vec<u32> = (0..positions.len() as u32)
                .filter(|&j| {
                    let y = positions[j as usize];
                    (y[0] - x[0]).powi(2) + (y[1] - x[1]).powi(2) < 0.09
                })
                .collect();
            assert_eq!(found, brute, "at {x:?}");
        }
    }
}
