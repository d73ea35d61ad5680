//! Boundary layers: which nodes each layer of a scene selects.

use crate::scene::{Scene, SceneError};

/// The nodes each boundary layer selects, in the scene's order; an error naming the layer if
/// one selects no node.
pub fn select<const D: usize>(
    scene: &Scene,
    positions: &[[f64; D]],
) -> Result<Vec<Vec<u32>>, SceneError> {
    let (lo, hi) = scene.solid.bounds();
    let eps = 1e-9 * scene.spacing;
    scene
        .boundary
        .iter()
        .enumerate()
        .map(|(l, layer)| {
            let nodes: Vec<u32> = (0..positions.len() as u32)
                .filter(|&i| layer.contains(&positions[i as usize], &lo, &hi, eps))
                .collect();
            if nodes.is_empty() {
                return Err(scene.error(
                    &format!("boundary[{l}]"),
                    format!(
                        "layer `{}` selects no node; widen its region or thickness",
                        layer.name
                    ),
                ));
            }
            Ok(nodes)
        })
        .collect()
}
