//! Adaptive particle splitting as a plug-in of a dual-horizon run (zeng2024 Sect. 3.3,
//! seed-002 §4): after each step the particles that meet (15) or (16) on the step's force pass
//! split (the next step's forces see the refined body), the split criteria the force pass
//! computes are set per particle, every split is logged for checkpoints, and φ_c and α are
//! live parameters.

use rayon::prelude::*;

use super::body::ParticleBody;
use crate::adapt::splitting::{self, SplitRule};
use crate::frame::Frame;
use crate::scene::Solid;
use crate::solver::{Adaptation, Clock, Param, State, Tick};

pub struct Splitting {
    rule: SplitRule,
    /// Whether (16)'s strains are skipped below the energy gate (`set_strain_gate`).
    strain_gate: bool,
    /// Splitting passes and particles split so far.
    pub splits: u64,
    pub split_parents: u64,
    /// The parents of every split since the scene was built, in order: a checkpoint replays
    /// them to rebuild the same particles and bond layout.
    log: Vec<Vec<u32>>,
    /// Events since the last frame.
    events: Vec<String>,
}

impl Splitting {
    /// The splitting of `body` under `rule`, after pre-processing (zeng2024 Sect. 3.3 step 4):
    /// every particle past φ_c, and every one inside `region`, split level by level before
    /// the run.
    pub fn new(rule: SplitRule, body: &mut ParticleBody, region: Option<&Solid>) -> Splitting {
        let mut s = Splitting {
            rule,
            strain_gate: true,
            splits: 0,
            split_parents: 0,
            log: Vec::new(),
            events: Vec::new(),
        };
        for _ in 0..rule.levels {
            let mut parents = s.candidates(body, true);
            if let Some(region) = region {
                let levels = body.levels();
                parents.extend((0..body.len() as u32).filter(|&k| {
                    let k = k as usize;
                    levels[k] < rule.levels && region.contains(&body.reference()[k], 1e-12)
                }));
                parents.sort_unstable();
                parents.dedup();
            }
            if parents.is_empty() {
                break;
            }
            body.split(&parents, rule.horizon_ratio);
            s.splits += 1;
            s.split_parents += parents.len() as u64;
        }
        if s.split_parents > 0 {
            s.events.push(format!(
                "pre-processing: {} particles past φ_c split before the run",
                s.split_parents
            ));
        }
        s.mark_splittable(body);
        s
    }

    /// The particles below the level cap get their split criteria from the force pass; those
    /// at the cap (children of the last level) skip them. The strains of (16) are computed
    /// only where they can pass α s_c: if ε_xx and ε_yy both exceed t, the classical energy
    /// density μ ε_dev:ε_dev + ½ κ (tr ε)² is at least 2 κ t², so a particle whose PD energy
    /// density W_k is below a quarter of that (a margin for the horizon's averaging) and
    /// whose bonds are all intact cannot meet (16); any broken bond computes them.
    fn mark_splittable(&self, body: &mut ParticleBody) {
        let rule = self.rule;
        let (kappa, gated) = (body.material().bulk_modulus(), self.strain_gate);
        let criteria: Vec<f64> = body
            .levels()
            .iter()
            .zip(body.constants())
            .map(|(&l, c)| {
                if l >= rule.levels {
                    f64::INFINITY
                } else if gated {
                    let t = rule.strain_factor * c.critical_stretch;
                    0.5 * kappa * t * t
                } else {
                    f64::MIN
                }
            })
            .collect();
        body.set_criteria(criteria.into_iter());
    }

    /// Verification: `false` computes (16)'s strains for every particle that may split, as
    /// without the energy gate of `mark_splittable` (the same splits, bit for bit, where the
    /// gate's bound holds).
    pub fn set_strain_gate(&mut self, on: bool, body: &mut ParticleBody) {
        self.strain_gate = on;
        self.mark_splittable(body);
    }

    /// The particles that meet (15) (and (16) unless `damage_only`: pre-processing, before
    /// any force pass). During the run both come from the last force pass.
    fn candidates(&self, body: &ParticleBody, damage_only: bool) -> Vec<u32> {
        let rule = &self.rule;
        let (levels, constants, terms) = (body.levels(), body.constants(), body.terms());
        let wants = |k: usize| {
            if levels[k] >= rule.levels {
                return false;
            }
            let (damage, strains) = if damage_only {
                (body.bonds.damage_of(k, body.volumes()), [0.0; 2])
            } else {
                (terms[k].damage, terms[k].strains)
            };
            splitting::wants(rule, damage, strains, &constants[k], levels[k])
        };
        // Most steps split nothing: look first, allocate only when something splits.
        if !(0..body.len()).into_par_iter().any(wants) {
            return Vec::new();
        }
        (0..body.len())
            .into_par_iter()
            .filter(|&k| wants(k))
            .map(|k| k as u32)
            .collect()
    }

    /// Splits `parents` and logs them.
    fn split(&mut self, body: &mut ParticleBody, parents: &[u32]) {
        body.split(parents, self.rule.horizon_ratio);
        self.mark_splittable(body);
        self.splits += 1;
        self.split_parents += parents.len() as u64;
        self.log.push(parents.to_vec());
    }

    /// Replays a checkpoint's split log on this freshly built scene.
    fn replay(&mut self, body: &mut ParticleBody, state: &State) -> Result<(), String> {
        let field = "dual_horizon/split_log";
        if !self.log.is_empty() {
            return Err("splits can be replayed on a freshly built scene only".into());
        }
        for parents in state.log(field, "parents")? {
            let (n, count) = (body.len(), parents.len());
            let mut distinct = parents.clone();
            distinct.sort_unstable();
            distinct.dedup();
            let levels = body.levels();
            if distinct.len() != count
                || distinct
                    .iter()
                    .any(|&k| k as usize >= n || levels[k as usize] >= self.rule.levels)
            {
                return Err(format!(
                    "`{field}` names a particle twice, one beyond the {n} particles, or one at \
                     the level cap {}",
                    self.rule.levels
                ));
            }
            self.split(body, &parents);
        }
        Ok(())
    }
}

impl Adaptation<ParticleBody> for Splitting {
    fn stage(&self) -> Option<&'static str> {
        Some("refine")
    }

    /// No force pass after a split: the children carry their parent's acceleration (per unit
    /// mass) into the next step's half kick, so the split falls between two kicks by the
    /// unrefined forces at y^i, exactly the paper's leapfrog order (zeng2024 Sect. 3.3,
    /// seed-002 §4: forces, update, damage and strain, refine; the next step's forces see the
    /// refined body). Σ m a stays 0, so momentum is kept through the split.
    fn after_step(&mut self, body: &mut ParticleBody, tick: Tick) {
        let parents = self.candidates(body, false);
        if parents.is_empty() {
            return;
        }
        self.split(body, &parents);
        self.events.push(format!(
            "split {} particles at t = {:.4e} s ({} particles now)",
            parents.len(),
            tick.start,
            body.len()
        ));
    }

    fn frame(&mut self, _body: &ParticleBody, _clock: &Clock, frame: &mut Frame) {
        frame.scalars.push((
            "metrics/refine/splits".to_string(),
            self.split_parents as f64,
        ));
        frame.events.append(&mut self.events);
    }

    /// Every split as its parent count then its parents, and the counters.
    fn save(&self, _body: &ParticleBody, state: &mut State) {
        state.put_log("dual_horizon/split_log", self.log.iter().map(Vec::as_slice));
        state.put_u64("dual_horizon/splits", vec![self.splits, self.split_parents]);
    }

    /// The splits since the start are replayed from the log (the same parents in the same
    /// order give the same particles and bond layout).
    fn restore(&mut self, body: &mut ParticleBody, state: &State) -> Result<(), String> {
        if state.has("dual_horizon/split_log") {
            self.replay(body, state)?;
        }
        let counters = state.u64("dual_horizon/splits", 2)?;
        (self.splits, self.split_parents) = (counters[0], counters[1]);
        Ok(())
    }

    fn owns_section(&self, section: &str) -> bool {
        section.starts_with("dual_horizon/split")
    }

    /// φ_c and α act in place from the next step's check on.
    fn tune(&mut self, body: &mut ParticleBody, param: Param) -> Option<Result<(), String>> {
        let result = match param {
            Param::SplitDamage(phi) => {
                crate::scene::check_split_damage(phi).map(|phi| self.rule.damage = phi)
            }
            Param::SplitStrain(alpha) => crate::scene::check_split_strain(alpha).map(|alpha| {
                self.rule.strain_factor = alpha;
                self.mark_splittable(body);
            }),
            _ => return None,
        };
        Some(result)
    }
}
