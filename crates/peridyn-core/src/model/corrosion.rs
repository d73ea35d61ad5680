//! Bi-material PD corrosion (thesis (2.48)–(2.49), phase variable (2.79); seed-thesis-ch2-3 §1.6):
//! diffusion whose bond micro-diffusivity depends on the phases of its two ends — κ_liq for
//! liquid–liquid, κ_int for solid–liquid, no flux for solid–solid — and a solid node turns
//! liquid when its concentration drops below C_sat (irreversibly: seed-thesis-ch2-3 erratum 18's
//! reading of (2.79)). The law gives the bond diffusivities; the scheme does the sum (`scheme`) and
//! the phase change runs between steps (`adapt::phase`).

/// The phase of a node of a corrosion or Nernst–Planck scene (thesis (2.79)).
#[repr(u8)]
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Hash)]
pub enum Phase {
    #[default]
    Liquid = 0,
    Solid = 1,
}

impl Phase {
    pub fn id(self) -> u16 {
        self as u16
    }

    pub fn is_solid(self) -> bool {
        self == Phase::Solid
    }

    /// The phases stored as bytes (a checkpoint's `phase` section), or the first byte that is
    /// no phase, named.
    pub fn decode(saved: &[u8]) -> Result<Vec<Phase>, String> {
        saved
            .iter()
            .enumerate()
            .map(|(i, &p)| match p {
                0 => Ok(Phase::Liquid),
                1 => Ok(Phase::Solid),
                _ => Err(format!("phase: node {i} has no phase {p}")),
            })
            .collect()
    }
}

/// κ_liq, κ_int and C_sat of a corrosion scene.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CorrosionLaw {
    pub kappa_liquid: f64,
    pub kappa_interface: f64,
    pub saturation: f64,
}

impl CorrosionLaw {
    /// κ of a bond between two nodes, each solid or liquid.
    #[inline(always)]
    pub fn bond_diffusivity(&self, solid_i: bool, solid_j: bool) -> f64 {
        match (solid_i, solid_j) {
            (false, false) => self.kappa_liquid,
            (true, true) => 0.0,
            _ => self.kappa_interface,
        }
    }

    /// A node at concentration `c` is solid where C ≥ C_sat (the initial phases).
    pub fn solid_at(&self, c: f64) -> bool {
        c >= self.saturation
    }

    /// The largest bond κ: operators built with it bound the spectral radius from above.
    pub fn kappa_max(&self) -> f64 {
        self.kappa_liquid.max(self.kappa_interface)
    }
}
