//! Plain-data snapshots handed from the solver to sinks (Rerun, reports). Nothing here knows
//! about a viewer.

/// One per-node field with the fixed color range it is shown in.
#[derive(Debug, Clone)]
pub struct NodeField {
    pub name: &'static str,
    pub values: Vec<f64>,
    pub range: (f64, f64),
}

#[derive(Debug, Clone)]
pub struct Frame {
    pub step: u64,
    pub time: f64,
    pub dim: usize,
    /// Current positions, `dim` values per node.
    pub positions: Vec<f64>,
    pub fields: Vec<NodeField>,
    /// Scalar series: `(name, value)`, names are slash paths like `energy/kinetic`.
    pub scalars: Vec<(String, f64)>,
}

impl Frame {
    pub fn scalar(&self, name: &str) -> Option<f64> {
        self.scalars
            .iter()
            .find(|(n, _)| n == name)
            .map(|(_, v)| *v)
    }
}
