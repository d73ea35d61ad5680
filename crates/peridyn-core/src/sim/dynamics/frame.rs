//! A dynamic simulation's frame: positions, damage and speed per node, the energies, momentum,
//! broken bonds, timings, region metrics, probes, crack angles and lengths; then what each plug-in and
//! finally the scheme add (the scheme last: a multi-level scheme thins the cloud to its
//! active levels).

use rayon::prelude::*;

use super::DynamicSimulation;
use crate::frame::{Frame, NodeField};
use crate::metrics::{self, probes};
use crate::scheme::RowMask;

impl<const D: usize> DynamicSimulation<D> {
    pub(super) fn build_frame(&mut self) -> Frame {
        let body = &self.body;
        let scheme = &*self.scheme;
        let mut damage = body.damage();
        if let Some(idle) = scheme.idle() {
            // Only integrated nodes carry the solution (fictitious ones mirror the other level).
            for (d, m) in damage.iter_mut().zip(idle) {
                if m.skipped() {
                    *d = 0.0;
                }
            }
        }
        let mass_volumes = scheme.mass_volumes(body.volumes()).into_owned();
        let speed: Vec<f64> = body
            .velocities()
            .iter()
            .map(|v| v.iter().map(|x| x * x).sum::<f64>().sqrt())
            .collect();
        let (kinetic, momentum) = body.kinetic_energy_and_momentum_over(&mass_volumes);
        // W_i from the last force evaluation, at the current positions, where it holds one;
        // the others' evaluated here (`ElasticScheme::stale_energy_terms`).
        let terms = body.terms();
        let recomputed = scheme.stale_energy_terms(body);
        let strain_energy: Vec<f64> = (0..mass_volumes.len())
            .into_par_iter()
            .map(|i| {
                if mass_volumes[i] == 0.0 {
                    return 0.0;
                }
                let w = match &recomputed {
                    _ if !scheme.runs_wls(i) && body.energy_current => terms[i].energy_density,
                    Some(fresh) => fresh[i].energy_density,
                    None => scheme.energy_density(body, i),
                };
                w * mass_volumes[i]
            })
            .collect();
        let strain: f64 = strain_energy.iter().sum();
        let mut scalars = vec![
            ("energy/kinetic".to_string(), kinetic),
            ("energy/strain".to_string(), strain),
            ("energy/total".to_string(), kinetic + strain),
            ("bonds/broken".to_string(), body.broken as f64),
        ];
        scalars.extend(self.run.timing_scalars());
        for (k, p) in momentum.iter().enumerate() {
            scalars.push((format!("momentum/{}", ["x", "y", "z"][k]), *p));
        }
        let scene = &body.scene;
        let regions = !(scene.energy_circles.is_empty() && scene.damage_counts.is_empty());
        // Kinetic plus strain energy per node, for the region metrics, probes and plug-ins.
        let node_energy: Vec<f64> =
            if regions || !self.probes.is_empty() || !self.plugins.is_empty() {
                strain_energy
                    .iter()
                    .zip(&speed)
                    .zip(&mass_volumes)
                    .map(|((w, s), v)| w + 0.5 * body.density * v * s * s)
                    .collect()
            } else {
                Vec::new()
            };
        if regions {
            self.region_metrics(&node_energy, &damage, &mut scalars);
        }
        let density = |i: usize| node_energy[i] / mass_volumes[i].max(f64::MIN_POSITIVE);
        let (reference, positions) = (body.reference(), body.positions());
        probes::probe_scalars(&self.probes, reference, positions, density, &mut scalars);
        let spacing = self.scheme.finest_spacing(body);
        metrics::crack_scalars(scene, reference, &damage, spacing, &mut scalars);
        let mut frame = Frame {
            step: self.run.clock.step(),
            time: self.run.clock.time(),
            dim: D,
            positions: body.positions().as_flattened().to_vec(),
            fields: vec![
                NodeField::damage(damage),
                NodeField::speed(speed, body.velocity_scale),
            ],
            classes: Vec::new(),
            events: Vec::new(),
            scalars,
            radii: Vec::new(),
        };
        self.body.node_energy = node_energy;
        let clock = self.run.clock.clone();
        for p in &mut self.plugins {
            p.frame(&self.body, &clock, &mut frame);
        }
        self.scheme.frame(&self.body, &clock, &mut frame);
        frame
    }

    /// Metrics of the scene's energy circles and damage counts, from per-node kinetic plus
    /// strain energy and damage (zero on nodes that carry no mass).
    fn region_metrics(
        &self,
        node_energy: &[f64],
        damage: &[f64],
        scalars: &mut Vec<(String, f64)>,
    ) {
        let (body, scheme) = (&self.body, &*self.scheme);
        let reference = body.reference();
        for c in &body.scene.energy_circles {
            // ∫ over the circle of the energy density: each node's energy weighted by the
            // fraction of its cell inside (node centres alone sample the circle's area to
            // ≈ 1 % on a 15-cell radius, differently on each level).
            let energy: f64 = (0..reference.len())
                .into_par_iter()
                .map(|i| {
                    let e = node_energy[i];
                    if e == 0.0 {
                        return 0.0;
                    }
                    let cell = scheme.cell_size(body, i);
                    e * metrics::ball_fraction(&reference[i], cell, &c.center, c.radius)
                })
                .sum();
            scalars.push((format!("energy/circle/{}", c.name), energy));
        }
        metrics::damage_counts(&body.scene, reference, damage, scalars);
    }

    /// Crack angles `(name, degrees)` of the scene's `[[metrics.crack_angle]]` for `damage`.
    pub(super) fn crack_angles_for(&self, damage: &[f64]) -> Vec<(String, Option<f64>)> {
        let body = &self.body;
        let spacing = self.scheme.finest_spacing(body);
        metrics::crack_angles(&body.scene, body.reference(), damage, spacing)
    }
}
