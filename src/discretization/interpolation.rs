//! Nodes whose values are weighted sums of other nodes' values: the fictitious nodes of the
//! multi-grid coupling, by inverse-distance weighting (thesis (3.85)–(3.88); seed-thesis-ch2-3
//! §6). Explicit schemes apply the rows after each step (`transfer`); implicit ones put them
//! into their global systems as constraint rows v_t − Σ w v_s = 0 (the implicit variant of
//! (3.89)–(3.90)).

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
