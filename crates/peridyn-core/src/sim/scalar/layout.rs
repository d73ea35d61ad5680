//! The nodes of a scalar scene by role — held (the `hold_reference` and `hold_value` layers and
//! an absorbing layer), free (solved), fictitious (a multi-grid scene's, interpolated) — and the
//! initial field on them.

use crate::absorb::scalar_layer::Absorber;
use crate::adapt::multigrid::MultiGrid;
use crate::discretization::Discretization;
use crate::scene::{Condition, Scene, SceneError};

/// A scalar scene's discretization with its nodes sorted by role and its initial field.
pub struct Layout<const D: usize> {
    pub discretization: Discretization<D>,
    pub is_held: Vec<bool>,
    /// The solved nodes, in increasing order.
    pub free: Vec<u32>,
    pub held: Vec<u32>,
    /// The absorbing layer's nodes (held: overwritten each step, never solved for).
    pub absorbing: Vec<(u32, [f64; D])>,
    /// Each node's volume where it is active (0 on fictitious nodes).
    pub active_volumes: Vec<f64>,
    pub field: Vec<f64>,
}

impl<const D: usize> Layout<D> {
    /// The layout of `discretization` (with `multigrid`'s levels on a multi-grid scene).
    pub fn new(
        scene: &Scene,
        mut discretization: Discretization<D>,
        multigrid: Option<&MultiGrid<D>>,
    ) -> Result<Layout<D>, SceneError> {
        if !scene.precracks.is_empty() {
            // Scalar fields: a notch removes the bonds across it (no flux through a defect).
            discretization.families = discretization
                .families
                .without_crossing(discretization.nodes.reference(), &scene.precracks);
        }
        let n = discretization.len();
        let mut is_held = vec![false; n];
        for (layer, nodes) in scene.boundary.iter().zip(&discretization.layers) {
            if matches!(layer.condition, Condition::Reference | Condition::Value) {
                nodes.iter().for_each(|&i| is_held[i as usize] = true);
            }
        }
        let absorbing = Absorber::<D>::nodes(scene, discretization.nodes.reference());
        if scene.absorbing.is_some() && absorbing.is_empty() {
            return Err(scene.error(
                "absorbing.width",
                "the layer holds no node: widen it (e.g. width = \"1 horizon\")",
            ));
        }
        absorbing
            .iter()
            .for_each(|(i, _)| is_held[*i as usize] = true);
        // Fictitious nodes of a multi-grid scene are neither solved nor held: interpolated.
        let active = |i: u32| multigrid.is_none_or(|g| g.class[i as usize].is_active());
        let (free, held): (Vec<u32>, Vec<u32>) = (0..n as u32)
            .filter(|&i| active(i) || is_held[i as usize])
            .partition(|&i| !is_held[i as usize]);
        let active_volumes = match multigrid {
            Some(g) => g.active_volumes(discretization.nodes.volumes()),
            None => discretization.nodes.volumes().to_vec(),
        };
        if free.is_empty() {
            return Err(scene.error(
                "boundary",
                "the held layers cover every node: nothing is left to solve",
            ));
        }
        let mut field = initial_field(scene, &discretization);
        if let Some(g) = multigrid {
            g.transfer(&mut field);
        }
        Ok(Layout {
            discretization,
            is_held,
            free,
            held,
            absorbing,
            active_volumes,
            field,
        })
    }
}

/// The initial field: the initial-concentration regions (later ones win), else the reference
/// at t = 0, else 0, plus the initial pulses; `hold_value` layers hold their value from the
/// start (later layers win).
fn initial_field<const D: usize>(scene: &Scene, discretization: &Discretization<D>) -> Vec<f64> {
    let eps = 1e-9 * scene.spacing;
    let mut field: Vec<f64> = discretization
        .nodes
        .reference()
        .iter()
        .map(|x| {
            let set = scene
                .initial_concentration
                .iter()
                .rev()
                .find(|(region, _)| region.contains(x, eps))
                .map(|(_, v)| *v);
            let base = set.unwrap_or_else(|| scene.reference.map_or(0.0, |r| r.value(x, 0.0)));
            base + scene.initial_pulses.iter().map(|p| p.value(x)).sum::<f64>()
        })
        .collect();
    for (layer, nodes) in scene.boundary.iter().zip(&discretization.layers) {
        if layer.condition == Condition::Value {
            for &i in nodes {
                field[i as usize] = layer.value[0];
            }
        }
    }
    field
}
