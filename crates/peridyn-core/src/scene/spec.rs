//! The validated parts of a scene, in SI units: what each preset table becomes once checked
//! (material, kernels, scheme, multi-grid, absorbing layer, pulses, boundary layers, time,
//! metrics). The feature validators build them; `validated::Scene` holds them.

use super::collocation::Collocation;
use super::geometry::Solid;
use super::schema::{
    AbsorbingMethod, CheckSet, Coupling, CrackEnds, Dispersion, SchemeKind, Transfer, WaveNumberSet,
};
use crate::model::pmb::{Influence, PmbConstants};

#[derive(Debug, Clone, PartialEq)]
pub struct MaterialSpec {
    pub density: f64,
    /// Stiffness, failure, influence and plane as given: the law (`model::pmb::PmbLaw`)
    /// derives c and s0 from them.
    pub constants: PmbConstants,
}

#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DiffusionSpec {
    /// κ (κ_liq for corrosion).
    pub diffusivity: f64,
    pub exponent: f64,
    pub influence: Influence,
    /// Corrosion only.
    pub corrosion: Option<CorrosionSpec>,
}

#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CorrosionSpec {
    /// κ_int of solid–liquid bonds.
    pub interface_diffusivity: f64,
    /// C_sat.
    pub saturation: f64,
}

#[derive(Debug, Clone, Copy, PartialEq)]
pub struct HybridSpec {
    pub adaptive: bool,
    /// Initial Ω_s band width (m).
    pub band: f64,
    pub chi: f64,
    pub check: CheckSet,
    pub check_every: u64,
    /// κ of the interface damping (`adapt::interface`): 0 turns it off.
    pub interface_damping: f64,
    /// Half-width of its band on each side of the Ω_s/Ω_w interface (m).
    pub interface_band: f64,
}

/// Two grid levels, the fine one `ratio` times finer (thesis §3.4–3.5).
#[derive(Debug, Clone)]
pub struct MultigridSpec {
    pub ratio: usize,
    pub refinement: Refinement,
    /// The coarse level's scheme (the fine level always runs the standard scheme).
    pub coarse: CoarseScheme,
    /// How the levels' fluxes through fictitious nodes are accounted (nernst-planck).
    pub coupling: Coupling,
}

/// The scheme on the coarse level of a multi-adaptive scene (thesis §3.5): "adaptive, standard"
/// or "adaptive, hybrid" (WLS-2 collocation on the coarse active nodes over the given rule).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub enum CoarseScheme {
    #[default]
    Standard,
    Wls(Collocation),
}

/// Where the fine level is active.
#[derive(Debug, Clone)]
pub enum Refinement {
    /// A predefined, fixed fine region (diffusion and corrosion, thesis §3.4).
    Region(Solid),
    /// The multi-adaptive switch (dynamic fracture, thesis §3.5): refined at the start within
    /// `band` of boundaries and pre-cracks, then around every coarse bond reaching χ·s0.
    Adaptive {
        band: f64,
        chi: f64,
        transfer: Transfer,
    },
}

/// The scalar wave (2.37)–(2.40): ü = L u − 2 d u̇, L the PD operator with c_s calibrated to
/// the local wave speed χ (thesis (4.47), (4.87)).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct WaveSpec {
    /// χ (m/s).
    pub speed: f64,
    /// d (1/s).
    pub damping: f64,
}

/// A Gaussian u0 = A exp(−a ‖x − x0‖²) added to the initial scalar field (thesis (4.96),
/// (4.97); the diffusion pulse of §4.1.4).
#[derive(Debug, Clone, PartialEq)]
pub struct Pulse {
    pub center: Vec<f64>,
    pub amplitude: f64,
    /// a (1/m²).
    pub decay: f64,
    /// Zero beyond this distance from the centre (m).
    pub radius: f64,
    /// A displacement pulse's direction (dynamics); `None` for scalar fields.
    pub direction: Option<PulseDirection>,
}

#[derive(Debug, Clone, PartialEq)]
pub enum PulseDirection {
    /// Along e_r = (x − x0)/‖x − x0‖ (zero at the centre; thesis (4.168)).
    Radial,
    /// Along a fixed unit vector.
    Fixed(Vec<f64>),
}

impl Pulse {
    pub fn value(&self, x: &[f64]) -> f64 {
        let r2: f64 = x
            .iter()
            .zip(&self.center)
            .map(|(a, b)| (a - b) * (a - b))
            .sum();
        if r2 > self.radius * self.radius {
            return 0.0;
        }
        self.amplitude * (-self.decay * r2).exp()
    }

    /// A displacement pulse's value at `x` (component k into `out[k]`, added).
    pub fn add_displacement(&self, x: &[f64], out: &mut [f64]) {
        let size = self.value(x);
        match &self.direction {
            Some(PulseDirection::Fixed(e)) => {
                for (o, e) in out.iter_mut().zip(e) {
                    *o += size * e;
                }
            }
            Some(PulseDirection::Radial) | None => {
                let rel: Vec<f64> = x.iter().zip(&self.center).map(|(a, b)| a - b).collect();
                let r = rel.iter().map(|v| v * v).sum::<f64>().sqrt();
                if r > 0.0 {
                    for (o, v) in out.iter_mut().zip(&rel) {
                        *o += size * v / r;
                    }
                }
            }
        }
    }
}

/// An absorbing layer at the truncation of an unbounded domain (thesis Chapter 4;
/// seed-thesis-ch4-5 §1.3 for the knobs and their defaults).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AbsorbingSpec {
    pub method: AbsorbingMethod,
    /// Nodes nearer the truncation than this are absorbing (m).
    pub width: f64,
    /// d∞, the cloud's radius (m).
    pub cloud_radius: f64,
    /// n_k per direction.
    pub wave_numbers: usize,
    /// n_φ.
    pub directions: usize,
    /// Δk (1/m).
    pub max_wave_number: f64,
    /// Δφ (rad): the waves' directions lie in θ_n + [−Δφ, Δφ]; also the backward cone's margin.
    pub spread: f64,
    pub wave_number_set: WaveNumberSet,
    pub dispersion: Dispersion,
    /// Relative SVD cut-off of the pseudo-inverse (seed-thesis-ch4-5 §3.7).
    pub cutoff: f64,
    /// λ of Tikhonov's filter factors σ/(σ² + (λ σ_max)²) in the pseudo-inverse (0: none, the
    /// thesis; see `absorb::Pseudoinverse`).
    pub tikhonov: f64,
    /// Clouds only behind the node (backward cone (4.86)).
    pub cone: bool,
    /// ‖V‖_max and cond(M) limits: `check` flags nodes above them; with `thinning` their clouds
    /// are thinned (density halved along the axes, Fig. 4.23) until they hold.
    pub max_norm: f64,
    pub max_condition: f64,
    pub thinning: bool,
    /// ε of the layer's selective filter (0: none, the thesis): after each overwrite an absorbing
    /// node's value becomes (1 − ε) u_a + ε · the mean of its lattice neighbours (not in the
    /// thesis; see `sim::far_field::Filter`).
    pub filter: f64,
    /// κ of a damped band of near-field nodes inside the layer (0: none, the thesis; not in the
    /// thesis): after every step v ← v − r L D L v there, r = κ ω_max Δt, as at the hybrid's
    /// interface (`adapt::interface`). It takes O(r (kΔx)⁴) per step from a smooth wave and O(r)
    /// from the lattice-scale waves that no fitted mode carries.
    pub damping: f64,
    /// The damped band's width (m); it starts two lattice hops inside the layer.
    pub damping_band: f64,
    /// Adds the far field's rest states to every node's modes: u = const (s = 0) and, for a
    /// damped wave, u = e^{−2dt} (s = −2d), the k → 0 limits of (4.53) (not in the thesis;
    /// see `absorb::scalar_modes`).
    pub rest_modes: bool,
}

#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SchemeSpec {
    pub kind: SchemeKind,
    /// WLS collocation rule (auxiliary grid δ/k_aux, or orbits); for the standard scheme the
    /// unused grid factor 0.
    pub collocation: Collocation,
}

#[derive(Debug, Clone)]
pub enum CrackGeometry {
    Point(f64),
    Segment([f64; 2], [f64; 2], CrackEnds),
    Patch {
        origin: [f64; 3],
        edge_a: [f64; 3],
        edge_b: [f64; 3],
    },
}

#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Condition {
    Velocity,
    Displacement,
    BodyForce,
    /// The scalar field is held at the reference solution.
    Reference,
    /// The scalar field is held at `value[0]`.
    Value,
}

#[derive(Debug, Clone)]
pub struct BoundarySpec {
    pub name: String,
    pub region: Option<Solid>,
    /// (axis, upper side, thickness)
    pub face: Option<(usize, bool, f64)>,
    pub condition: Condition,
    pub value: Vec<f64>,
    pub axes: Vec<usize>,
    /// The layer was added outside the body's face (the solid is already extended).
    pub outside: bool,
}

impl BoundarySpec {
    /// Whether node position `x` lies in the layer; `lo`, `hi` are the solid's bounds.
    pub fn contains(&self, x: &[f64], lo: &[f64], hi: &[f64], eps: f64) -> bool {
        let in_face = self.face.is_none_or(|(a, upper, t)| {
            if upper {
                x[a] >= hi[a] - t - eps
            } else {
                x[a] <= lo[a] + t + eps
            }
        });
        in_face && self.region.as_ref().is_none_or(|r| r.contains(x, eps))
    }
}

#[derive(Debug, Clone)]
pub enum InitialVelocity {
    Uniform(Vec<f64>),
    Ramp {
        component: usize,
        axis: usize,
        from: f64,
        to: f64,
    },
    Sine {
        component: usize,
        axis: usize,
        amplitude: f64,
        modes: f64,
    },
}

#[derive(Debug, Clone, Copy, PartialEq)]
pub enum StepSize {
    Absolute(f64),
    FractionOfStable(f64),
}

#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Duration {
    End(f64),
    Steps(u64),
}

#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TimeSpec {
    pub step: StepSize,
    pub duration: Duration,
    pub allow_unstable: bool,
}

#[derive(Debug, Clone)]
pub struct CrackAngleSpec {
    pub name: String,
    pub tip: Vec<f64>,
    pub direction: Vec<f64>,
    pub threshold: f64,
    pub region: Solid,
}

/// The length of the crack grown from `tip` (`metrics::crack_length`).
#[derive(Debug, Clone)]
pub struct CrackLengthSpec {
    pub name: String,
    pub tip: Vec<f64>,
    pub threshold: f64,
    pub region: Solid,
}

/// Kinetic plus strain energy within a circle (sphere) of the reference configuration.
#[derive(Debug, Clone)]
pub struct EnergyCircleSpec {
    pub name: String,
    pub center: Vec<f64>,
    pub radius: f64,
}

/// Nodes of a region whose damage reaches a threshold.
#[derive(Debug, Clone)]
pub struct DamageCountSpec {
    pub name: String,
    pub region: Solid,
    pub threshold: f64,
}
