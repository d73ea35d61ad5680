//! Transient PD diffusion (thesis §3.2.6; seed-004 Example 2) and bi-material corrosion
//! (thesis §2.3.3; seed-thesis-ch2-3 §1.6) by forward Euler (3.10) (`integrate::euler`): the
//! field body with its scheme — the operator's rows (`rates::Standard`) or the fixed hybrid
//! (`hybrid`) — and its plug-ins: the phase change (`phase`), the multi-grid transfer (`grid`)
//! and the absorbing layer (`layer`).

use std::any::Any;
use std::ops::Deref;

use super::body::FieldBody;
use super::frame::Shown;
use super::hybrid::Hybrid;
use super::layer::Layer;
use super::layout::Layout;
use super::operator::{kernel, operator, wls_mask};
use super::phase::Phases;
use super::rates::{Bonds, DiffusionScheme, Standard};
use super::stable::stable_step;
use crate::absorb::scalar_layer::Absorber;
use crate::adapt::fixed::FixedHybrid;
use crate::adapt::masks::SchemeClass;
use crate::adapt::multigrid::MultiGrid;
use crate::adapt::phase::PhaseChange;
use crate::discretization::Discretization;
use crate::frame::Frame;
use crate::integrate::euler;
use crate::model::corrosion::CorrosionLaw;
use crate::model::diffusion::DiffusionKernel;
use crate::scene::{Scene, SceneError};
use crate::scheme::VectorOperator;
use crate::solver::adaptation::{notes_of, restore_each, save_each, tune_each};
use crate::solver::{
    Adaptation, Clock, Integrator, Param, RunState, SimError, SimInfo, Stages, State, Stepper,
};

pub struct DiffusionSimulation<const D: usize> {
    pub body: FieldBody<D>,
    scheme: Box<dyn DiffusionScheme<D>>,
    plugins: Vec<Box<dyn Adaptation<FieldBody<D>>>>,
    run: RunState,
}

/// A simulation reads as its body (field, positions, operator) for measurements.
impl<const D: usize> Deref for DiffusionSimulation<D> {
    type Target = FieldBody<D>;

    fn deref(&self) -> &FieldBody<D> {
        &self.body
    }
}

/// The discretization of `scene`, with the two levels where it has them.
fn discretize<const D: usize>(
    scene: &Scene,
) -> Result<(Discretization<D>, Option<MultiGrid<D>>), SceneError> {
    match &scene.multigrid {
        None => Ok((Discretization::<D>::of_scene(scene)?, None)),
        Some(spec) => {
            let (d, grid) = MultiGrid::<D>::discretize(scene, spec)?;
            Ok((d, Some(grid)))
        }
    }
}

/// A corrosion scene's law, and the phases of the initial field with the change that follows
/// them.
type Corrosion = (CorrosionLaw, PhaseChange, Vec<crate::adapt::masks::Phase>);

fn corrosion<const D: usize>(
    scene: &Scene,
    kernel: &DiffusionKernel,
    layout: &Layout<D>,
) -> Option<Corrosion> {
    let c = scene.diffusion.and_then(|d| d.corrosion)?;
    let law = CorrosionLaw {
        kappa_liquid: kernel.diffusivity,
        kappa_interface: c.interface_diffusivity,
        saturation: c.saturation,
    };
    let (change, phase) = PhaseChange::initial(&law, &layout.field, &layout.active_volumes);
    Some((law, change, phase))
}

/// The fixed hybrid's WLS rows on the scene's mask, if it has one.
fn fixed_hybrid<const D: usize>(
    scene: &Scene,
    layout: &Layout<D>,
    corrosion: Option<&Corrosion>,
    multigrid: Option<&MultiGrid<D>>,
    kernel: &DiffusionKernel,
) -> Result<Option<FixedHybrid>, SceneError> {
    let positions = layout.discretization.nodes.reference();
    let phase = corrosion.map(|(_, _, phase)| phase.as_slice());
    let Some((mask, rule, table)) = wls_mask(scene, positions, phase, multigrid, &layout.is_held)
    else {
        return Ok(None);
    };
    let families = &layout.discretization.families;
    let h = FixedHybrid::new(mask, positions, families, kernel, rule)
        .map_err(|e| scene.error(&format!("{table}.{}", rule.field()), e.to_string()))?;
    Ok(Some(h))
}

impl<const D: usize> DiffusionSimulation<D> {
    pub fn new(scene: &Scene) -> Result<Self, SceneError> {
        let (discretization, multigrid) = discretize::<D>(scene)?;
        let mut layout = Layout::new(scene, discretization, multigrid.as_ref())?;
        let kernel = kernel(scene, D);
        let corrosion = corrosion(scene, &kernel, &layout);
        let hybrid = fixed_hybrid(
            scene,
            &layout,
            corrosion.as_ref(),
            multigrid.as_ref(),
            &kernel,
        )?;
        let standard_rows: Vec<u32> = match &hybrid {
            Some(h) => (layout.free.iter().copied())
                .filter(|&i| h.mask[i as usize] == SchemeClass::Standard)
                .collect(),
            None => layout.free.clone(),
        };
        // Corrosion: κ depends on the bond's class; the operator is assembled with κ = 1 and
        // the bond sum weights each bond by its κ.
        let assembled = match corrosion {
            Some(_) => DiffusionKernel {
                diffusivity: 1.0,
                ..kernel
            },
            None => kernel,
        };
        let disc = &layout.discretization;
        let operator = operator(scene, disc, multigrid.as_ref(), &assembled, &standard_rows)?;
        let absorbing = std::mem::take(&mut layout.absorbing);
        let mut body = FieldBody::new(scene, layout, kernel, operator);
        // The unit operator times the largest bond κ bounds the corrosion operator's spectrum.
        let kappa_scale = corrosion.as_ref().map_or(1.0, |(law, ..)| law.kappa_max());
        let wls = hybrid.as_ref().map(|h| &h.wls);
        let (n, op) = (body.len(), &body.operator);
        let stable = stable_step(scene, n, op, kappa_scale, wls, Integrator::Euler);
        let run = RunState::new(scene, stable, &[])?;
        let mut plugins: Vec<Box<dyn Adaptation<FieldBody<D>>>> = Vec::new();
        let bonds = match corrosion {
            Some((law, change, phase)) => {
                let phase = body.discretization.nodes.fields.add_values("phase", phase);
                plugins.push(Box::new(Phases::new(change, phase)));
                Bonds::Corrosion { law, phase }
            }
            None => Bonds::Uniform,
        };
        if let Some(g) = multigrid {
            plugins.push(Box::new(g));
        }
        if let Some(spec) = scene.absorbing {
            let a = Absorber::new(scene, spec, absorbing, &kernel, n);
            plugins.push(Box::new(Layer::fitted(a, &body, run.clock.dt())));
        }
        let scheme: Box<dyn DiffusionScheme<D>> = match hybrid {
            Some(hybrid) => Box::new(Hybrid { bonds, hybrid }),
            None => Box::new(Standard(bonds)),
        };
        let mut sim = DiffusionSimulation {
            body,
            scheme,
            plugins,
            run,
        };
        sim.run.stages = Stages::new(&euler::stage_names(&*sim.scheme, &sim.plugins));
        Ok(sim)
    }

    /// The multi-grid levels, on such a scene.
    fn multigrid(&self) -> Option<&MultiGrid<D>> {
        self.plugins
            .iter()
            .find_map(|p| (&**p as &dyn Any).downcast_ref::<MultiGrid<D>>())
    }

    /// Sets the field (tests, restarts): `values` per node, a multi-grid scene's fictitious
    /// values replaced by their interpolation from the other level.
    pub fn set_field(&mut self, values: &mut [f64]) {
        if let Some(g) = self.multigrid() {
            g.transfer(values);
        }
        self.body.field_mut().copy_from_slice(values);
    }

    /// The WLS rows (Ω_w of a fixed corrosion hybrid, or a multi-grid scene's WLS coarse
    /// level), with the liquid's κ, if any.
    pub fn wls_operator(&self) -> Option<&VectorOperator<1>> {
        self.scheme.wls()
    }
}

impl<const D: usize> Stepper for DiffusionSimulation<D> {
    fn step(&mut self) -> Result<(), SimError> {
        euler::step(
            &mut self.body,
            &mut *self.scheme,
            &mut self.plugins,
            &mut self.run,
        )
    }

    /// The field, then what each plug-in and finally the scheme add.
    fn frame(&mut self) -> Frame {
        let shown = Shown {
            name: "concentration",
            nonnegative: self.scene.diffusion.is_some_and(|d| d.corrosion.is_some()),
        };
        let mut frame = self.body.frame(&mut self.run, shown, None);
        let clock = &self.run.clock;
        for p in &mut self.plugins {
            p.frame(&self.body, clock, &mut frame);
        }
        self.scheme.frame(&self.body, clock, &mut frame);
        frame
    }

    fn info(&self) -> SimInfo {
        let wls = self.scheme.wls();
        let extra = wls.map_or((0, 0), |w| (w.columns.len(), w.rows.len()));
        let mut info = self.run.info(self.body.size(extra));
        info.notes = notes_of(&self.plugins);
        info
    }

    fn run(&self) -> &RunState {
        &self.run
    }

    fn run_mut(&mut self) -> &mut RunState {
        &mut self.run
    }

    fn save_state(&self) -> State {
        let mut state = State::default();
        self.run.clock.save(&mut state);
        self.body.save(&mut state);
        save_each(
            Some(&*self.scheme as &dyn Adaptation<_>),
            &self.plugins,
            &self.body,
            &mut state,
        );
        state
    }

    fn restore_state(&mut self, state: &State) -> Result<(), String> {
        let clock = Clock::restore(state)?;
        let field = self.body.read(state)?;
        let scheme = Some(&mut *self.scheme as &mut dyn Adaptation<_>);
        restore_each(scheme, &mut self.plugins, &mut self.body, state)?;
        self.body.field_mut().copy_from_slice(field);
        self.run.clock = clock;
        Ok(())
    }

    fn tune(&mut self, param: Param) -> Result<(), String> {
        tune_each(&mut *self.scheme, &mut self.plugins, &mut self.body, param)
    }
}
