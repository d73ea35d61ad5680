//! The absorbing layer of a bond-based simulation of an unbounded domain (thesis §4.3): the
//! linearized far field (4.100)–(4.102), the displacement and velocity of the previous time
//! level it fits on, and the near-field energy (4.169) the viewer watches fall.
//! The layer acts on displacements u = y − x; its nodes are overwritten after the drift
//! (u^{n+1}) and after the second kick (u̇^{n+1}), both from the state at t^n, t^{n−1} (4.166).

use super::scalar_layer::Absorber;
use crate::absorb::{BondFarField, BondLattice, dispersion};
use crate::adapt::interface::InterfaceDamping;
use crate::discretization::{Families, Quadrature};
use crate::model::pmb::PmbLaw;
use crate::scene::{Scene, SceneError};
use crate::solver::State;

pub struct BondLayer<const D: usize> {
    pub absorber: Absorber<D>,
    /// u and u̇ at t^{n−1}, flattened (D per node).
    previous_displacement: Vec<f64>,
    previous_velocity: Vec<f64>,
    /// u at t^n, flattened (scratch of `prepare`).
    displacement: Vec<f64>,
    /// The damped band inside the layer (`absorbing.damping` > 0), built by `start`.
    damping: Option<InterfaceDamping>,
}

/// The long-wave (local) speeds (c_P, c_S) of the bond-based continuum: √(M/(ρk²)) of (4.111)
/// at kδ → 0 (plane stress with ω0: √(9E/(8ρ)), √(3E/(8ρ)), Table 4.2, N = 1).
fn local_speeds(law: &PmbLaw, density: f64) -> (f64, f64) {
    let k = 1e-3 / law.horizon;
    let m = dispersion::continuum_bond_matrix(
        k,
        &[1.0, 0.0],
        law.micromodulus,
        law.influence,
        law.horizon,
    );
    let w = dispersion::bond_waves(m, density);
    (w.pressure.0 / k, w.shear.0 / k)
}

impl<const D: usize> BondLayer<D> {
    /// The layer of `scene` (none without `[absorbing]`), at rest before t = 0.
    pub fn new(
        scene: &Scene,
        reference: &[[f64; D]],
        law: &PmbLaw,
        density: f64,
    ) -> Result<Option<Self>, SceneError> {
        let Some(spec) = scene.absorbing else {
            return Ok(None);
        };
        let nodes = Absorber::<D>::nodes(scene, reference);
        if nodes.is_empty() {
            return Err(scene.error(
                "absorbing.width",
                "the layer holds no node: widen it (e.g. width = \"1 horizon\")",
            ));
        }
        let quadrature = Quadrature::of_scene(scene);
        let far = BondFarField {
            lattice: BondLattice::new(&quadrature, law.micromodulus, law.influence),
            density,
            speeds: local_speeds(law, density),
        };
        let n = reference.len();
        Ok(Some(BondLayer {
            absorber: Absorber::bond(scene, spec, nodes, far, n),
            previous_displacement: vec![0.0; n * D],
            previous_velocity: vec![0.0; n * D],
            displacement: vec![0.0; n * D],
            damping: None,
        }))
    }

    /// Fits the rows for `dt` (so `check` reports them); at rest before t = 0: the previous
    /// level is the initial state with u̇ = 0.
    pub fn start(
        &mut self,
        dt: f64,
        reference: &[[f64; D]],
        families: &Families,
        positions: &[[f64; D]],
    ) {
        self.absorber.ensure_fitted(dt, reference, families);
        displacement_into(reference, positions, &mut self.previous_displacement);
        self.previous_velocity.fill(0.0);
        let spec = &self.absorber.spec;
        if spec.damping > 0.0 && self.damping.is_none() {
            let mut damping = InterfaceDamping::new(spec.damping, spec.damping_band, families);
            damping.rebuild_inside(&self.absorber.is_absorbing);
            self.damping = Some(damping);
        }
    }

    /// The damped band's update after a step `dt` of a run whose stable step is `stable_dt`.
    pub fn damp(&mut self, velocities: &mut [[f64; D]], dt: f64, stable_dt: f64) {
        if let Some(d) = self.damping.as_mut() {
            d.apply(velocities, dt, stable_dt);
        }
    }

    /// The damped band's nodes (none without `absorbing.damping`).
    pub fn damped(&self) -> &[u32] {
        self.damping.as_ref().map_or(&[], |d| d.damped())
    }

    /// `check`'s lines: the layer's, then the damped band's.
    pub fn report(&self) -> Vec<String> {
        let mut lines = self.absorber.report();
        let spec = &self.absorber.spec;
        if spec.damping > 0.0 {
            lines.push(format!(
                "absorbing layer: damped band of {} near-field nodes ({:.3e} m wide, κ = {})",
                self.damped().len(),
                spec.damping_band,
                spec.damping
            ));
        }
        lines
    }

    /// The layer's u^{n+1} and u̇^{n+1} from the state at t^n and t^{n−1} (refitted first if
    /// Δt changed); then t^n becomes the previous level.
    pub fn prepare(
        &mut self,
        dt: f64,
        reference: &[[f64; D]],
        families: &Families,
        positions: &[[f64; D]],
        velocities: &[[f64; D]],
    ) {
        self.absorber.ensure_fitted(dt, reference, families);
        displacement_into(reference, positions, &mut self.displacement);
        let velocity = velocities.as_flattened();
        let a = &mut self.absorber;
        a.layer.values(
            &self.displacement,
            &self.previous_displacement,
            &mut a.values,
        );
        a.layer.rates(
            [&self.displacement, &self.previous_displacement],
            [velocity, &self.previous_velocity],
            &mut a.rates,
        );
        std::mem::swap(&mut self.displacement, &mut self.previous_displacement);
        self.previous_velocity.copy_from_slice(velocity);
    }

    /// y = x + u^{n+1} on the layer's nodes (through the layer's filter, if any, reading the
    /// near field's new displacements).
    pub fn overwrite_positions(&self, reference: &[[f64; D]], positions: &mut [[f64; D]]) {
        for (a, &i) in self.absorber.layer.nodes.iter().enumerate() {
            let i = i as usize;
            for k in 0..D {
                let u = self
                    .absorber
                    .new_value(a, k, |j| positions[j][k] - reference[j][k]);
                positions[i][k] = reference[i][k] + u;
            }
        }
    }

    /// u̇^{n+1} on the layer's nodes.
    pub fn overwrite_velocities(&self, velocities: &mut [[f64; D]]) {
        self.absorber.overwrite_rates(velocities.as_flattened_mut());
    }

    /// Σ over the near field (not the layer) of a per-node energy.
    pub fn near_field(&self, node_energy: &[f64]) -> f64 {
        node_energy
            .iter()
            .zip(&self.absorber.is_absorbing)
            .filter(|(_, a)| !**a)
            .map(|(e, _)| e)
            .sum()
    }

    pub fn save(&self, state: &mut State) {
        state.put_f64(
            "absorbing/previous_displacement",
            self.previous_displacement.clone(),
        );
        state.put_f64(
            "absorbing/previous_velocity",
            self.previous_velocity.clone(),
        );
    }

    /// Reads the previous level (validated before anything changes).
    pub fn restore(&mut self, state: &State) -> Result<(), String> {
        let n = self.previous_displacement.len();
        let u = state.f64("absorbing/previous_displacement", n)?;
        let v = state.f64("absorbing/previous_velocity", n)?;
        self.previous_displacement.copy_from_slice(u);
        self.previous_velocity.copy_from_slice(v);
        // The rows are refitted for whatever Δt the restored clock holds.
        Ok(())
    }
}

fn displacement_into<const D: usize>(
    reference: &[[f64; D]],
    positions: &[[f64; D]],
    out: &mut [f64],
) {
    for ((o, y), x) in out.chunks_exact_mut(D).zip(positions).zip(reference) {
        for k in 0..D {
            o[k] = y[k] - x[k];
        }
    }
}
