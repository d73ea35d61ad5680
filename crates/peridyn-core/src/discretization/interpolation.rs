//! Nodes whose values are weighted sums of other nodes' values: the fictitious nodes of the
//! multi-grid coupling, by inverse-distance weighting (thesis (3.85)–(3.88); seed-thesis-ch2-3
//! §6). Explicit schemes apply the rows after each step (`transfer`); implicit ones put them
//! into their global systems as constraint rows v_t − Σ w v_s = 0 (the implicit variant of
//! (3.89)–(3.90)). `CrossBonds` lists the bonds through which the levels exchange and the
//! shares of the conservative balance of that exchange.

use super::Families;

/// Row k sets `targets[k]` to Σ w v over `sources[offsets[k]..offsets[k + 1]]`. Rows are
/// applied in order: a later row may read an earlier row's target.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Interpolation {
    pub targets: Vec<u32>,
    pub offsets: Vec<usize>,
    pub sources: Vec<u32>,
    pub weights: Vec<f64>,
}

impl Interpolation {
    pub fn new() -> Interpolation {
        Interpolation {
            offsets: vec![0],
            ..Default::default()
        }
    }

    /// Appends the row of `target` with its (source, weight) pairs.
    pub fn push(&mut self, target: u32, pairs: impl IntoIterator<Item = (u32, f64)>) {
        self.targets.push(target);
        for (s, w) in pairs {
            self.sources.push(s);
            self.weights.push(w);
        }
        self.offsets.push(self.sources.len());
    }

    pub fn len(&self) -> usize {
        self.targets.len()
    }

    pub fn is_empty(&self) -> bool {
        self.targets.is_empty()
    }

    /// Row k's sources and weights.
    pub fn row(&self, k: usize) -> (&[u32], &[f64]) {
        let range = self.offsets[k]..self.offsets[k + 1];
        (&self.sources[range.clone()], &self.weights[range])
    }

    /// Σ w v over row k's sources.
    #[inline]
    pub fn value(&self, k: usize, values: &[f64]) -> f64 {
        let (s, w) = self.row(k);
        s.iter().zip(w).map(|(&s, w)| w * values[s as usize]).sum()
    }

    /// Writes every row's value into its target, in order.
    pub fn transfer(&self, values: &mut [f64]) {
        for (k, &t) in self.targets.iter().enumerate() {
            values[t as usize] = self.value(k, values);
        }
    }

    /// The row of each of `n` nodes (u32::MAX where a node is not a target).
    pub fn row_of(&self, n: usize) -> Vec<u32> {
        let mut out = vec![u32::MAX; n];
        for (k, &t) in self.targets.iter().enumerate() {
            out[t as usize] = k as u32;
        }
        out
    }
}

/// The bonds through which a coupling by fictitious nodes exchanges: for each listed node (not
/// a target, admitted by `listed`), its bonds that end at a target. Each level's active nodes
/// see the other level through these bonds only, so D = Σ V_i (their fluxes) is the exchange
/// between the levels as both sides see it together: zero for a conservative scheme, and for
/// IDW values the coupling's conservation defect.
///
/// The balance takes D back from the receiving side (`receives`: a multi-grid's coarse
/// level, so the fine level keeps its own, more accurate view), node i's share a_i in
/// proportion to its exchange capacity V_i Σ_b capacity(b) over its cross bonds (the kernel
/// weights: where a node exchanges more, its view is corrected more). The shares are fixed,
/// so the balanced rate −a_i D(C)/V_i is linear in C and adds the rank-one term u vᵀ
/// (u = a/V, v = ∂D/∂C) to an implicit system.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct CrossBonds {
    /// The listed nodes, increasing.
    pub nodes: Vec<u32>,
    /// Their volumes.
    pub volumes: Vec<f64>,
    /// Each listed node's share a of the balance (Σ a = 1 over the receiving side, the one
    /// whose view of the exchange gives way; 0 on the other side).
    pub share: Vec<f64>,
    /// `offsets[k]..offsets[k + 1]`: node k's bonds in `bonds`.
    pub offsets: Vec<usize>,
    /// Bond indices into the families' CSR.
    pub bonds: Vec<u32>,
}

impl CrossBonds {
    pub fn new(
        families: &Families,
        interpolation: &Interpolation,
        volumes: &[f64],
        listed: impl Fn(usize) -> bool,
        receives: impl Fn(usize) -> bool,
        capacity: impl Fn(usize) -> f64,
    ) -> CrossBonds {
        let n = families.node_count();
        let row_of = interpolation.row_of(n);
        let mut out = CrossBonds {
            offsets: vec![0],
            ..Default::default()
        };
        for i in (0..n).filter(|&i| row_of[i] == u32::MAX && listed(i)) {
            let start = out.bonds.len();
            out.bonds.extend(
                families
                    .range(i)
                    .filter(|&b| row_of[families.neighbors[b] as usize] != u32::MAX)
                    .map(|b| b as u32),
            );
            if out.bonds.len() > start {
                out.nodes.push(i as u32);
                out.volumes.push(volumes[i]);
                out.share.push(if receives(i) {
                    volumes[i]
                        * out.bonds[start..]
                            .iter()
                            .map(|&b| capacity(b as usize))
                            .sum::<f64>()
                } else {
                    0.0
                });
                out.offsets.push(out.bonds.len());
            }
        }
        let total: f64 = out.share.iter().sum();
        if total > 0.0 {
            out.share.iter_mut().for_each(|a| *a /= total);
        }
        out
    }

    pub fn len(&self) -> usize {
        self.nodes.len()
    }

    pub fn is_empty(&self) -> bool {
        self.nodes.is_empty()
    }

    /// Listed node k's bonds.
    #[inline]
    pub fn range(&self, k: usize) -> std::ops::Range<usize> {
        self.offsets[k]..self.offsets[k + 1]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// In a chain 0 1 | 2 3 with node 2 interpolated, node 1's bond to 2 and node 3's bond to
    /// 2 cross; 2's own bonds and 0's do not.
    #[test]
    fn cross_bonds_end_at_targets() {
        let positions: Vec<[f64; 1]> = (0..4).map(|i| [i as f64]).collect();
        let families = Families::build(&positions, 1.5);
        let mut rows = Interpolation::new();
        rows.push(2, [(3, 1.0)]);
        let cross = CrossBonds::new(
            &families,
            &rows,
            &[1.0, 2.0, 3.0, 4.0],
            |_| true,
            |i| i < 2,
            |_| 1.0,
        );
        assert_eq!(cross.nodes, [1, 3]);
        assert_eq!(cross.share, [1.0, 0.0]);
        assert_eq!(cross.volumes, [2.0, 4.0]);
        for k in 0..cross.len() {
            for e in cross.range(k) {
                assert_eq!(families.neighbors[cross.bonds[e] as usize], 2);
            }
        }
    }
}
