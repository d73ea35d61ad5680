//! Which rows of a diffusion body get which rates: the [`DiffusionScheme`] contract and its
//! plainest form, the operator's rows alone ([`Standard`]), each bond at one κ or at the κ of
//! its ends' phases (corrosion, thesis (2.48)–(2.49)). The fixed hybrid (`super::hybrid`)
//! implements it too, with WLS rows beside the standard ones.

use super::body::FieldBody;
use crate::adapt::masks::Phase;
use crate::discretization::Field;
use crate::integrate::euler::RateTerms;
use crate::model::corrosion::CorrosionLaw;
use crate::scheme::VectorOperator;
use crate::solver::{Adaptation, Tick};

/// A scheme of a diffusion body: its rates and forward-Euler update (`RateTerms`), its
/// hooks (`Adaptation`), and the WLS rows it runs beside the body's operator.
pub trait DiffusionScheme<const D: usize>: RateTerms<FieldBody<D>> {
    /// The WLS rows (Ω_w of a fixed hybrid, or a WLS coarse level), if any.
    fn wls(&self) -> Option<&VectorOperator<1>> {
        None
    }
}

/// The κ of each bond of the operator's rows.
#[derive(Debug, Clone, Copy)]
pub enum Bonds {
    /// The kernel's, which the operator holds.
    Uniform,
    /// Corrosion: the operator is assembled with κ = 1 and each bond weighted by the κ of its
    /// ends' phases.
    Corrosion {
        law: CorrosionLaw,
        phase: Field<Phase>,
    },
}

impl Bonds {
    /// L C on the operator's rows into the body's rate buffer.
    pub fn rates<const D: usize>(&self, body: &mut FieldBody<D>) {
        let Bonds::Corrosion { law, phase } = *self else {
            body.rates();
            return;
        };
        let fields = &body.discretization.nodes.fields;
        let (field, phase) = (fields.get(body.values), fields.get(phase));
        body.operator
            .apply_rows_bond_weighted(field, &mut body.rate, |i, j| {
                law.bond_diffusivity(phase[i].is_solid(), phase[j].is_solid())
            });
    }

    /// The phases of a corrosion scene.
    pub fn phase(&self) -> Option<Field<Phase>> {
        match *self {
            Bonds::Uniform => None,
            Bonds::Corrosion { phase, .. } => Some(phase),
        }
    }
}

/// The operator's rows alone.
pub struct Standard(pub Bonds);

impl<const D: usize> Adaptation<FieldBody<D>> for Standard {}

impl<const D: usize> RateTerms<FieldBody<D>> for Standard {
    fn rates(&mut self, body: &mut FieldBody<D>) {
        self.0.rates(body);
    }

    fn update(&mut self, body: &mut FieldBody<D>, tick: Tick) -> f64 {
        let updated = body.euler_rows(tick);
        body.write_rows();
        updated
    }
}

impl<const D: usize> DiffusionScheme<D> for Standard {}
