//! The discretization of a scene, built once: lattice (grid level), CSR families, the β
//! quadrature, the horizon (uniform or per node), the per-node store and the nodes each
//! boundary layer selects.

pub mod buckets;
pub mod family;
pub mod grid;
pub mod interpolation;
pub mod layers;
pub mod nodes;

pub use family::{Families, RowValues};
pub use grid::Lattice;
pub use interpolation::{CrossBonds, Interpolation};
pub use nodes::{Field, NodeValue, Nodes};

use rayon::prelude::*;

use crate::scene::{Scene, SceneError};

/// The horizon δ: one value for the whole body, or one per node (dual-horizon schemes).
#[derive(Debug, Clone, PartialEq)]
pub enum Horizon {
    Uniform(f64),
    PerNode(Vec<f64>),
}

impl Horizon {
    /// δ of node `i`.
    pub fn of(&self, i: usize) -> f64 {
        match self {
            Horizon::Uniform(d) => *d,
            Horizon::PerNode(d) => d[i],
        }
    }

    /// The largest δ (the reach of any family).
    pub fn max(&self) -> f64 {
        match self {
            Horizon::Uniform(d) => *d,
            Horizon::PerNode(d) => d.iter().copied().fold(0.0, f64::max),
        }
    }

    pub fn uniform(&self) -> Option<f64> {
        match self {
            Horizon::Uniform(d) => Some(*d),
            Horizon::PerNode(_) => None,
        }
    }
}

/// Quadrature data shared by every bond: β on/off, spacing, horizon.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Quadrature {
    pub spacing: f64,
    pub horizon: f64,
    pub volume_correction: bool,
}

impl Quadrature {
    pub fn of_scene(scene: &Scene) -> Quadrature {
        Quadrature {
            spacing: scene.spacing,
            horizon: scene.horizon,
            volume_correction: scene.volume_correction,
        }
    }

    /// β(‖ξ‖) of (3.2), or 1 when the correction is off.
    #[inline(always)]
    pub fn beta(&self, length: f64) -> f64 {
        if self.volume_correction {
            family::partial_volume(length, self.horizon, self.spacing)
        } else {
            1.0
        }
    }
}

/// One grid level of a scene with its families, quadrature and per-node store.
#[derive(Debug)]
pub struct Discretization<const D: usize> {
    pub nodes: Nodes<D>,
    pub families: Families,
    pub quadrature: Quadrature,
    pub horizon: Horizon,
    pub spacing: f64,
    /// The volume of every cell where all are equal (a lattice without holes' corrections).
    pub uniform_volume: Option<f64>,
    /// The nodes each of the scene's boundary layers selects, in the scene's order.
    pub layers: Vec<Vec<u32>>,
}

impl<const D: usize> Discretization<D> {
    /// The scene's lattice, its families within the search radius, and its layers; an error if
    /// the body holds no node or a layer selects none.
    pub fn of_scene(scene: &Scene) -> Result<Self, SceneError> {
        let lattice = Lattice::<D>::of_scene(scene)?;
        let radius = family::search_radius(scene.family_radius, scene.horizon, scene.spacing);
        let families = Families::build(&lattice.positions, radius);
        let layers = layers::select(scene, &lattice.positions)?;
        let v0 = lattice.volumes[0];
        let uniform_volume = lattice.volumes.iter().all(|&v| v == v0).then_some(v0);
        Ok(Discretization {
            nodes: Nodes::new(lattice.positions, lattice.volumes),
            families,
            quadrature: Quadrature::of_scene(scene),
            horizon: Horizon::Uniform(scene.horizon),
            spacing: scene.spacing,
            uniform_volume,
            layers,
        })
    }

    /// A discretization of given nodes and families (several grid levels in one index space);
    /// the quadrature is the scene's (the coarse level's).
    pub fn of_nodes(
        scene: &Scene,
        positions: Vec<[f64; D]>,
        volumes: Vec<f64>,
        families: Families,
    ) -> Result<Self, SceneError> {
        let layers = layers::select(scene, &positions)?;
        Ok(Discretization {
            nodes: Nodes::new(positions, volumes),
            families,
            quadrature: Quadrature::of_scene(scene),
            horizon: Horizon::Uniform(scene.horizon),
            spacing: scene.spacing,
            uniform_volume: None,
            layers,
        })
    }

    pub fn len(&self) -> usize {
        self.nodes.len()
    }

    pub fn is_empty(&self) -> bool {
        self.nodes.is_empty()
    }

    /// Bond states (1 intact, 0 broken) with the scene's pre-cracks cut: every bond that
    /// crosses one, from either end. An error names a pre-crack that cuts no bond.
    pub fn intact_bonds(&self, scene: &Scene) -> Result<Vec<u8>, SceneError> {
        let positions = self.nodes.reference();
        let families = &self.families;
        let mut intact = vec![1u8; families.bond_count()];
        for (c, crack) in scene.precracks.iter().enumerate() {
            // The bonds each node's row loses, rows in parallel; then cut.
            let cut: Vec<usize> = (0..positions.len())
                .into_par_iter()
                .flat_map_iter(|i| family::cut_bonds(crack, positions, families, i))
                .collect();
            if cut.is_empty() {
                return Err(scene.error(
                    &format!("precracks[{c}]"),
                    "cuts no bond: the pre-crack lies outside the body (or between nodes)",
                ));
            }
            for b in cut {
                intact[b] = 0;
            }
        }
        Ok(intact)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn per_node_horizons() {
        let h = Horizon::PerNode(vec![1.0, 3.0, 2.0]);
        assert_eq!((h.of(1), h.max(), h.uniform()), (3.0, 3.0, None));
        assert_eq!(Horizon::Uniform(2.0).uniform(), Some(2.0));
    }
}
