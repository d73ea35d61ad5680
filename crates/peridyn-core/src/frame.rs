//! Plain-data snapshots handed from the solver to sinks (Rerun, reports). Nothing here knows
//! about a viewer.

/// One per-node field with the fixed color range it is shown in.
#[derive(Debug, Clone)]
pub struct NodeField {
    /// The entity name under `nodes/` (`species/<name>` for an NNPP species).
    pub name: std::borrow::Cow<'static, str>,
    pub values: Vec<f64>,
    pub range: (f64, f64),
}

impl NodeField {
    /// The damage field φ ∈ [0, 1] (thesis (2.38)).
    pub fn damage(values: Vec<f64>) -> NodeField {
        NodeField {
            name: "damage".into(),
            values,
            range: (0.0, 1.0),
        }
    }

    /// The speed |u̇| shown on `[0, scale]`.
    pub fn speed(values: Vec<f64>, scale: f64) -> NodeField {
        NodeField {
            name: "velocity".into(),
            values,
            range: (0.0, scale),
        }
    }
}

/// One per-node class field (a mask): class ids and the classes' names and colors, shown with
/// an annotation context so the viewer names each class.
#[derive(Debug, Clone)]
pub struct ClassField {
    pub name: &'static str,
    pub ids: Vec<u16>,
    pub classes: &'static [(u16, &'static str, [u8; 3])],
}

#[derive(Debug, Clone)]
pub struct Frame {
    pub step: u64,
    pub time: f64,
    pub dim: usize,
    /// Current positions, `dim` values per node.
    pub positions: Vec<f64>,
    pub fields: Vec<NodeField>,
    /// Per-node masks (scheme region, phase).
    pub classes: Vec<ClassField>,
    /// Events since the previous frame (e.g. nodes switched to the standard scheme).
    pub events: Vec<String>,
    /// Scalar series: `(name, value)`, names are slash paths like `energy/kinetic`.
    pub scalars: Vec<(String, f64)>,
    /// Each node's drawing radius (m), half its cell; empty: half the scene's spacing for all
    /// (grid levels of a multi-grid scene draw at their own size).
    pub radii: Vec<f32>,
}

impl Frame {
    /// Keeps the nodes whose `keep` entry is set, in every per-node array.
    pub fn retain_nodes(&mut self, keep: &[bool]) {
        let order: Vec<u32> = (0..keep.len() as u32)
            .filter(|&i| keep[i as usize])
            .collect();
        self.select_nodes(&order);
    }

    /// Keeps the nodes `order` lists, in that order, in every per-node array.
    pub fn select_nodes(&mut self, order: &[u32]) {
        fn pick<T: Copy>(values: &[T], order: &[u32], per_node: usize) -> Vec<T> {
            order
                .iter()
                .flat_map(|&i| {
                    let i = i as usize * per_node;
                    values[i..i + per_node].iter().copied()
                })
                .collect()
        }
        self.positions = pick(&self.positions, order, self.dim);
        for f in &mut self.fields {
            f.values = pick(&f.values, order, 1);
        }
        for c in &mut self.classes {
            c.ids = pick(&c.ids, order, 1);
        }
        if !self.radii.is_empty() {
            self.radii = pick(&self.radii, order, 1);
        }
    }

    pub fn scalar(&self, name: &str) -> Option<f64> {
        self.scalars
            .iter()
            .find(|(n, _)| n == name)
            .map(|(_, v)| *v)
    }
}
