//! Why a run had to stop.

/// A run that had to stop.
#[derive(Debug, Clone, PartialEq)]
pub enum SimError {
    /// The state blew up: a node moved more than half a spacing in one step, or became NaN.
    Unstable {
        step: u64,
        time: f64,
        max_speed: f64,
        dt: f64,
        stable_dt: f64,
    },
    /// Forward Euler diverged: the field grew past 10⁶× its scale, or became NaN.
    Diverged {
        step: u64,
        time: f64,
        max_value: f64,
        dt: f64,
        stable_dt: f64,
    },
    /// A static solve failed.
    Solve(String),
}

impl std::fmt::Display for SimError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            SimError::Unstable {
                step,
                time,
                max_speed,
                dt,
                stable_dt,
            } => write!(
                f,
                "numerical instability at step {step} (t = {time:.4e} s): max speed {max_speed:.3e} m/s \
                 moves a node more than half a spacing per step. Δt = {dt:.3e} s is {:.2}× the stable \
                 bound {stable_dt:.3e} s; lower time.dt. The run was stopped \
                 before writing a non-finite frame.",
                dt / stable_dt
            ),
            SimError::Diverged {
                step,
                time,
                max_value,
                dt,
                stable_dt,
            } => write!(
                f,
                "forward Euler diverged at step {step} (t = {time:.4e} s): max |field| = \
                 {max_value:.3e}, over 10⁶× its scale. Δt = {dt:.3e} s is {:.2}× the bound \
                 {stable_dt:.3e} s (2/ρ, ρ the operator's spectral radius by power iteration); \
                 lower time.dt. The run was stopped before writing a non-finite frame.",
                dt / stable_dt
            ),
            SimError::Solve(message) => write!(f, "static solve failed: {message}"),
        }
    }
}

impl std::error::Error for SimError {}
