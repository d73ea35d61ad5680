//! What the force loop adds up per node.

use crate::discretization::NodeValue;

/// What the force loop produces per node.
#[derive(Debug, Clone, Copy, PartialEq)]
#[repr(C)]
pub struct NodeTerms<const D: usize> {
    /// Force density (N/m³).
    pub force: [f64; D],
    /// Strain-energy density W_i over the intact bonds (J/m³).
    pub energy_density: f64,
    /// Σ β V'_j over the node's broken bonds, V' = 1 where all volumes are equal (the damage
    /// numerator, kept up to date as bonds break).
    pub broken_weight: f64,
}

impl<const D: usize> NodeValue for NodeTerms<D> {
    const EMPTY: Self = NodeTerms {
        force: [0.0; D],
        energy_density: 0.0,
        broken_weight: 0.0,
    };
}

impl<const D: usize> Default for NodeTerms<D> {
    fn default() -> Self {
        NodeTerms {
            force: [0.0; D],
            energy_density: 0.0,
            broken_weight: 0.0,
        }
    }
}
