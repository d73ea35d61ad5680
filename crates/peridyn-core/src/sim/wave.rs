//! The velocity state of a scalar wave (4.62).

/// The velocity state of damped velocity-Verlet (4.62) for a scalar wave, and the previous
/// time level the absorbing layer fits on.
pub struct Wave {
    pub damping: f64,
    pub velocity: Vec<f64>,
    pub previous_field: Vec<f64>,
    pub previous_velocity: Vec<f64>,
    /// Per operator row: v^n + Δt/2 a^n between the two half steps.
    pub half: Vec<f64>,
    /// The rate buffer holds L u of the current field.
    pub forces_fresh: bool,
}

impl Wave {
    pub fn new(damping: f64, field: &[f64], rows: usize) -> Wave {
        Wave {
            damping,
            velocity: vec![0.0; field.len()],
            // At rest before t = 0 (the far field is at rest; u̇0 = 0 in every example).
            previous_field: field.to_vec(),
            previous_velocity: vec![0.0; field.len()],
            half: vec![0.0; rows],
            forces_fresh: false,
        }
    }
}
