//! The fixed hybrid (`adapt::fixed`, thesis §3.3.2) as a diffusion body's scheme: the
//! operator's rows on Ω_s and WLS rows on Ω_w (or on a multi-grid scene's active coarse
//! nodes), both advanced from the same C^n; in frames its scheme mask, the Ω_s fraction and
//! the invariant (no solid node in Ω_w).

use super::body::FieldBody;
use super::rates::{Bonds, DiffusionScheme};
use crate::adapt::fixed::FixedHybrid;
use crate::adapt::masks::SchemeClass;
use crate::frame::Frame;
use crate::integrate::euler::RateTerms;
use crate::scheme::VectorOperator;
use crate::solver::{Adaptation, Clock, Tick};

pub struct Hybrid {
    /// The bonds of the operator's (Ω_s) rows.
    pub bonds: Bonds,
    pub hybrid: FixedHybrid,
}

impl<const D: usize> Adaptation<FieldBody<D>> for Hybrid {
    fn frame(&mut self, body: &FieldBody<D>, _clock: &Clock, frame: &mut Frame) {
        let h = &self.hybrid;
        if let Some(phase) = self.bonds.phase() {
            let phase = body.discretization.nodes.fields.get(phase);
            let violations = h.violations(phase) as f64;
            frame
                .scalars
                .push(("hybrid/violations".to_string(), violations));
        }
        frame.scalars.push((
            "hybrid/omega_s_fraction".to_string(),
            SchemeClass::standard_fraction(&h.mask),
        ));
        frame.classes.push(SchemeClass::field(&h.mask, true));
    }
}

impl<const D: usize> RateTerms<FieldBody<D>> for Hybrid {
    fn rates(&mut self, body: &mut FieldBody<D>) {
        self.bonds.rates(body);
        self.hybrid.rates(body.field());
    }

    /// Both row sets' new values from C^n first, then written (the update is Jacobi-like).
    fn update(&mut self, body: &mut FieldBody<D>, tick: Tick) -> f64 {
        let h = &mut self.hybrid;
        let standard = body.euler_rows(tick);
        let wls = body.euler(&h.wls.rows, &mut h.rate, tick);
        body.write_rows();
        body.write(&h.wls.rows, &h.rate);
        standard.max(wls)
    }
}

impl<const D: usize> DiffusionScheme<D> for Hybrid {
    fn wls(&self) -> Option<&VectorOperator<1>> {
        Some(&self.hybrid.wls)
    }
}
