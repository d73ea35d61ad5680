//! Typed per-node masks, each with its one annotation table (class id, name, colour) for
//! recordings: the scheme region of a hybrid and the phase of a corrosion scene.

use crate::discretization::NodeValue;
use crate::frame::ClassField;
use crate::scheme::RowMask;

/// One class of a mask as recorded: id, name, colour.
pub type Class = (u16, &'static str, [u8; 3]);

/// Which scheme evaluates a node (thesis §3.3): Ω_s, Ω_w, or neither (a held Dirichlet node
/// of a scalar scene).
#[repr(u8)]
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Hash)]
pub enum SchemeClass {
    /// Ω_s: the standard scheme.
    #[default]
    Standard = 0,
    /// Ω_w: WLS collocation.
    Wls = 1,
    /// Held at a prescribed value (scalar scenes' Dirichlet layers).
    Held = 2,
}

impl SchemeClass {
    /// The `nodes/scheme` classes.
    pub const TABLE: &'static [Class] = &[
        (SchemeClass::Standard as u16, "standard", [230, 85, 13]),
        (SchemeClass::Wls as u16, "WLS", [49, 130, 189]),
        (SchemeClass::Held as u16, "held", [120, 120, 120]),
    ];

    pub fn id(self) -> u16 {
        self as u16
    }

    /// The mask as a recorded class field; `held`: the scene has held nodes (scalar scenes),
    /// else only the two schemes are annotated.
    pub fn field(mask: &[SchemeClass], held: bool) -> ClassField {
        ClassField {
            name: "scheme",
            ids: mask.iter().map(|m| m.id()).collect(),
            classes: if held { Self::TABLE } else { &Self::TABLE[..2] },
        }
    }

    /// Fraction of the nodes in Ω_s.
    pub fn standard_fraction(mask: &[SchemeClass]) -> f64 {
        let standard = mask.iter().filter(|&&m| m == SchemeClass::Standard).count();
        standard as f64 / mask.len().max(1) as f64
    }
}

impl NodeValue for SchemeClass {
    const EMPTY: Self = SchemeClass::Standard;
}

/// The standard bond loop evaluates Ω_s rows only.
impl RowMask for SchemeClass {
    #[inline(always)]
    fn skipped(self) -> bool {
        self != SchemeClass::Standard
    }
}

/// Only active nodes are integrated: a mask of the nodes a level pass or a kick skips.
impl RowMask for GridClass {
    #[inline(always)]
    fn skipped(self) -> bool {
        !self.is_active()
    }
}

/// The phase of a node (defined with the laws that read it, `model::corrosion`).
pub use crate::model::corrosion::Phase;

impl Phase {
    /// The `nodes/phase` classes.
    pub const TABLE: &'static [Class] = &[
        (Phase::Liquid as u16, "liquid", [107, 174, 214]),
        (Phase::Solid as u16, "solid", [150, 150, 150]),
    ];

    pub fn field(phase: &[Phase]) -> ClassField {
        ClassField {
            name: "phase",
            ids: phase.iter().map(|p| p.id()).collect(),
            classes: Self::TABLE,
        }
    }
}

impl NodeValue for Phase {
    const EMPTY: Self = Phase::Liquid;
}

/// A node's grid level and role in a multi-grid scene (thesis §3.4): active nodes are
/// computed; fictitious ones complete the families of active nodes near the interface, their
/// values interpolated from the other level. Inactive nodes (stored only by the multi-adaptive
/// scheme, whose fine level covers the body) are neither computed nor drawn.
#[repr(u8)]
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Hash)]
pub enum GridClass {
    #[default]
    CoarseActive = 0,
    FineActive = 1,
    CoarseFictitious = 2,
    FineFictitious = 3,
    CoarseInactive = 4,
    FineInactive = 5,
}

impl GridClass {
    /// The `nodes/grid` classes.
    pub const TABLE: &'static [Class] = &[
        (
            GridClass::CoarseActive as u16,
            "coarse active",
            [120, 160, 200],
        ),
        (GridClass::FineActive as u16, "fine active", [230, 85, 13]),
        (
            GridClass::CoarseFictitious as u16,
            "coarse fictitious",
            [190, 190, 190],
        ),
        (
            GridClass::FineFictitious as u16,
            "fine fictitious",
            [253, 190, 133],
        ),
    ];

    pub fn id(self) -> u16 {
        self as u16
    }

    pub fn is_fine(self) -> bool {
        matches!(
            self,
            GridClass::FineActive | GridClass::FineFictitious | GridClass::FineInactive
        )
    }

    pub fn is_inactive(self) -> bool {
        matches!(self, GridClass::CoarseInactive | GridClass::FineInactive)
    }

    pub fn is_fictitious(self) -> bool {
        matches!(
            self,
            GridClass::CoarseFictitious | GridClass::FineFictitious
        )
    }

    pub fn is_active(self) -> bool {
        matches!(self, GridClass::CoarseActive | GridClass::FineActive)
    }

    /// Each node's volume where it is active, 0 elsewhere: Σ C V (or Σ ρ V) over these is the
    /// body's total.
    pub fn active_volumes(class: &[GridClass], volumes: &[f64]) -> Vec<f64> {
        volumes
            .iter()
            .zip(class)
            .map(|(&v, c)| if c.is_active() { v } else { 0.0 })
            .collect()
    }

    /// Node counts: (coarse active, fine active, fictitious of both levels).
    pub fn counts(class: &[GridClass]) -> (usize, usize, usize) {
        let count = |c: GridClass| class.iter().filter(|&&k| k == c).count();
        (
            count(GridClass::CoarseActive),
            count(GridClass::FineActive),
            count(GridClass::CoarseFictitious) + count(GridClass::FineFictitious),
        )
    }

    /// Drawing radii, half of each node's level spacing.
    pub fn radii(class: &[GridClass], coarse_spacing: f64, fine_spacing: f64) -> Vec<f32> {
        let (coarse, fine) = ((0.5 * coarse_spacing) as f32, (0.5 * fine_spacing) as f32);
        class
            .iter()
            .map(|c| if c.is_fine() { fine } else { coarse })
            .collect()
    }

    pub fn field(class: &[GridClass]) -> ClassField {
        ClassField {
            name: "grid",
            ids: class.iter().map(|c| c.id()).collect(),
            classes: Self::TABLE,
        }
    }
}

impl NodeValue for GridClass {
    const EMPTY: Self = GridClass::CoarseActive;
}
