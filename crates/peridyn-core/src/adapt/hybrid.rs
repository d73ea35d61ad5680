//! The hybrid configuration (thesis §3.3, seed-thesis-ch2-3 §5, seed-004 §4): one grid, a per-node
//! mask. Ω_s nodes run the standard scheme (nonlinear PMB with failure) over their whole
//! family; Ω_w nodes run WLS-2 (linearized, precomputed blocks K_ij = L̄ Q̄_i) over their
//! collocation nodes, wherever those lie. No ghost layer, no interpolation.
//!
//! Ω_s starts as a band around boundaries and pre-cracks. In the adaptive configuration it
//! only grows: a bond is critical when its stretch reaches χ·s0 — (3.80) without the upper
//! bound s ≤ s0, per seed-thesis-ch2-3 erratum 15 (a bond that jumps past s0 in one step is still
//! caught) — and then every node of H_i ∪ H_j switches to the standard scheme. The check runs on
//! the positions u^{n+1} right after the drift, before the force pass breaks any bond: the thesis's
//! "end of step n, before the critical zone is evaluated for damage".

use crate::scheme::wls::Collocation;
use rayon::prelude::*;

use super::bonds::{BondView, Measure, bond_squares, critical_margin};
use super::interface::InterfaceDamping;
use super::masks::SchemeClass;
use super::motion::MotionBound;
use crate::discretization::family::{self, Families};
use crate::model::pmb::PmbLaw;
use crate::scene::{CheckSet, CrackGeometry, HybridSpec, Solid};
use crate::scheme::wls::FitError;
use crate::scheme::wls_rows::WlsRows;
use crate::solver::State;

/// A switching event: at `step` (time `time`), `nodes` nodes moved to Ω_s.
#[derive(Debug, Clone, PartialEq)]
pub struct SwitchEvent {
    pub step: u64,
    pub time: f64,
    pub nodes: usize,
    /// The switch was forced by damage found in Ω_w (a check policy that missed it).
    pub forced: bool,
}

impl std::fmt::Display for SwitchEvent {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let (t, step, n) = (self.time, self.step, self.nodes);
        if self.forced {
            write!(
                f,
                "t = {t:.4e} s (step {step}): damage reached Ω_w; {n} nodes switched to the standard scheme"
            )
        } else {
            write!(
                f,
                "t = {t:.4e} s (step {step}): {n} nodes switched to the standard scheme"
            )
        }
    }
}

/// An epoch (every slack refreshed, or kept less the motion bound) follows a filtered check
/// that flagged more than 1/EPOCH_SHARE of the checked nodes. Measured on Kalthoff–Winkler
/// medium-fast at 0.7 of its stable step (docs/validation.md), before epochs kept slacks: 2 → 4 →
/// 8 → 16 gave 2.0–2.3, 1.55–1.61, 1.46–1.63, 1.52–1.56 s of switching. Since epochs keep
/// quiet nodes' slacks they are cheaper, and more frequent ones pay (session 29, the paper
/// grid's `hybrid` at 0.7 of its step, bonds visited and switching time): 4: 6.28·10⁹, 9.3 s;
/// 8: 5.67·10⁹, 9.1–9.5 s; 16: 5.46·10⁹, 8.5–8.7 s; 32: 5.48·10⁹, 10.2 s; 64: 5.49·10⁹,
/// 9.2 s; on `medium-fast` 8: 2.12·10⁸, 0.85–0.90 s; 16: 1.99·10⁸, 0.82–0.84 s.
const EPOCH_SHARE: usize = 16;

pub struct Hybrid<const D: usize> {
    pub spec: HybridSpec,
    /// Ω_s (standard) or Ω_w (WLS), per node.
    mask: Vec<SchemeClass>,
    /// Rows: the initial Ω_w nodes; a row is skipped once its node switched.
    wls: WlsRows<D>,
    /// Ω_w nodes whose bonds the switching check visits, and their bond count.
    check_nodes: Vec<u32>,
    in_check: Vec<bool>,
    /// Each bond between two checked nodes is checked once, from its lower-index end: per node
    /// the CSR position of its first neighbour j > i (rows are sorted by index) …
    forward_start: Vec<usize>,
    /// … and whether the node also has a lower-index neighbour outside the check set, whose
    /// bond it must check itself (may be conservatively true); such a node checks its whole
    /// family (one SIMD pass; a bond checked from both ends is harmless).
    scans_backward: Vec<bool>,
    check_bonds: u64,
    /// Skips nodes whose bonds provably cannot be critical (policies `all` and `near`).
    motion: Option<MotionBound<D>>,
    /// The shortest bond (m), which turns a stretch slack into a length slack.
    shortest_bond: f64,
    /// The last filtered check flagged so many nodes that the next check starts an epoch.
    epoch_due: bool,
    /// Checked nodes and their family members (the motion bound's tracked nodes), and
    /// whether the check set changed since they were listed.
    tracked: Vec<bool>,
    tracked_stale: bool,
    standard_nodes: usize,
    initial_standard: usize,
    events: Vec<SwitchEvent>,
    /// Bond evaluations spent in switching checks so far.
    pub checked_bonds: u64,
    /// Checks so far that visited every node (epochs of the motion bound) and that were
    /// filtered by it.
    pub full_checks: u64,
    /// Slacks an epoch kept (less the motion bound) instead of visiting the node's bonds.
    pub reused_slacks: u64,
    pub filtered_checks: u64,
    /// Tests: every check visits every node (no motion filter), the reference behaviour.
    pub exhaustive: bool,
    /// Velocity exchange near the Ω_s/Ω_w interface (rebuilt with the mask).
    damping: InterfaceDamping,
}

/// Ω_s of the initial configuration: nodes within `band` of the body's boundary (sampled on
/// rays at 1/4 … 1 of the band in 2·D axis and diagonal directions) or of a pre-crack.
pub fn initial_mask<const D: usize>(
    positions: &[[f64; D]],
    solid: &Solid,
    precracks: &[CrackGeometry],
    band: f64,
    spacing: f64,
) -> Vec<SchemeClass> {
    let directions: Vec<[f64; D]> = (1..3usize.pow(D as u32))
        .filter_map(|code| {
            let mut d = [0.0; D];
            let mut c = code;
            for v in d.iter_mut() {
                *v = (c % 3) as f64 - 1.0;
                c /= 3;
            }
            let n = d.iter().map(|v| v * v).sum::<f64>().sqrt();
            (n > 0.0).then(|| d.map(|v| v / n))
        })
        .collect();
    let eps = 1e-9 * spacing;
    positions
        .par_iter()
        .map(|x| {
            let near_crack = precracks
                .iter()
                .any(|c| family::distance_to_crack(c, x) < band);
            let near_boundary = directions.iter().any(|d| {
                [0.25, 0.5, 0.75, 1.0].iter().any(|f| {
                    let p: Vec<f64> = (0..D).map(|k| x[k] + f * band * d[k]).collect();
                    !solid.contains(&p, eps)
                })
            });
            if near_crack || near_boundary {
                SchemeClass::Standard
            } else {
                SchemeClass::Wls
            }
        })
        .collect()
}

impl<const D: usize> Hybrid<D> {
    /// Builds the mask and the WLS-2 blocks of the Ω_w nodes (rule: the collocation rule).
    pub fn new(
        spec: HybridSpec,
        mask: Vec<SchemeClass>,
        reference: &[[f64; D]],
        families: &Families,
        law: &PmbLaw,
        rule: impl Into<Collocation>,
    ) -> Result<Self, FitError> {
        let rows: Vec<u32> = (0..mask.len() as u32)
            .filter(|&i| mask[i as usize] == SchemeClass::Wls)
            .collect();
        // (3.54)–(3.56): the linearized bond-based operator over the full ball.
        let wls = WlsRows::elasticity(&rows, reference, families, law, rule)?;
        let standard_nodes = mask.len() - rows.len();
        let mask_len = mask.len();
        let mut hybrid = Hybrid {
            spec,
            mask,
            wls,
            check_nodes: Vec::new(),
            in_check: Vec::new(),
            forward_start: (0..mask_len)
                .map(|i| {
                    let range = families.range(i);
                    range.start + families.neighbors[range].partition_point(|&j| (j as usize) < i)
                })
                .collect(),
            scans_backward: Vec::new(),
            check_bonds: 0,
            motion: (spec.check != CheckSet::Collocation).then(|| {
                let reach = families.longest();
                MotionBound::new(reference, reach, families.shortest())
            }),
            epoch_due: false,
            shortest_bond: families.shortest(),
            tracked: vec![false; mask_len],
            tracked_stale: true,
            standard_nodes,
            initial_standard: standard_nodes,
            events: Vec::new(),
            checked_bonds: 0,
            full_checks: 0,
            reused_slacks: 0,
            filtered_checks: 0,
            exhaustive: false,
            damping: InterfaceDamping::new(spec.interface_damping, spec.interface_band, families),
        };
        hybrid.damping.rebuild(&hybrid.mask);
        hybrid.rebuild_check_set(families);
        Ok(hybrid)
    }

    /// The switching filter's lattice-path bound: whether it is in use, and dropping it (the
    /// cell bound alone; tests and measurements).
    pub fn uses_lattice_paths(&self) -> bool {
        self.motion.as_ref().is_some_and(|m| m.on_lattice())
    }

    pub fn drop_lattice_paths(&mut self) {
        if let Some(m) = self.motion.as_mut() {
            m.drop_lattice_paths();
        }
    }

    pub fn mask(&self) -> &[SchemeClass] {
        &self.mask
    }

    /// The Ω_w nodes the switching check visits.
    pub fn check_nodes(&self) -> &[u32] {
        &self.check_nodes
    }

    /// Fraction of nodes in Ω_s.
    pub fn standard_fraction(&self) -> f64 {
        self.standard_nodes as f64 / self.mask.len().max(1) as f64
    }

    pub fn initial_standard_fraction(&self) -> f64 {
        self.initial_standard as f64 / self.mask.len().max(1) as f64
    }

    /// Mean collocation nodes per Ω_w node.
    pub fn collocation_size(&self) -> f64 {
        self.wls.collocation_size()
    }

    /// Changes χ in place (live control).
    pub fn set_chi(&mut self, chi: f64) -> Result<(), String> {
        self.spec.chi = crate::scene::check_chi(chi)?;
        Ok(())
    }

    /// Switching events since the last call.
    pub fn take_events(&mut self) -> Vec<SwitchEvent> {
        std::mem::take(&mut self.events)
    }

    /// Bonds one check visits under the policy.
    fn bonds_to_check(&self, families: &Families) -> u64 {
        self.check_nodes
            .par_iter()
            .map(|&i| self.bond_count(i as usize, families))
            .sum()
    }

    /// Bonds node `i`'s check visits under the policy.
    fn bond_count(&self, i: usize, families: &Families) -> u64 {
        if self.spec.check == CheckSet::Collocation {
            self.wls.columns(i).len() as u64 - 1
        } else {
            self.checked_bonds_of(i, families).len() as u64
        }
    }

    /// The CSR positions of the bonds node `i` (in the check set) checks: those to
    /// higher-index neighbours, or its whole family if it scans backward.
    fn checked_bonds_of(&self, i: usize, families: &Families) -> std::ops::Range<usize> {
        let range = families.range(i);
        if self.scans_backward[i] {
            range
        } else {
            self.forward_start[i]..range.end
        }
    }

    /// The least `measure` of the bonds node `i` (in the check set) checks (+∞ if none), r
    /// and l a bond's current and reference lengths, in SIMD lanes, streaming only the
    /// neighbour indices (bond lengths come from the cache-resident reference positions).
    #[inline(always)]
    fn node_least(&self, i: usize, bonds: &BondView<D>, measure: Measure) -> f64 {
        let families = bonds.families;
        bonds.least(
            i,
            &families.neighbors[self.checked_bonds_of(i, families)],
            measure,
        )
    }

    /// Whether Ω_w node `i` (in the check set) has a critical bond, r² ≥ f l², among those it
    /// checks (f l² − r² has the sign of the exact difference, so "least ≤ 0" is that test).
    fn node_critical(&self, i: usize, bonds: &BondView<D>, factor: f64) -> bool {
        self.mask[i] == SchemeClass::Wls
            && self.node_least(i, bonds, Measure::Margin(factor)) <= 0.0
    }

    /// The check under the `all` and `near` policies, filtered by the motion bound: nodes whose
    /// bound stays below their slack are skipped; the rest are checked exactly. After a check
    /// that flagged more than 1/EPOCH_SHARE of the nodes (or when χ changed), an epoch pass checks
    /// every node and records fresh slacks. Returns the nodes with a critical bond.
    fn critical_by_motion(
        &mut self,
        reference: &[[f64; D]],
        positions: &[[f64; D]],
        families: &Families,
        factor: f64,
    ) -> Vec<u32> {
        let Some(mut motion) = self.motion.take() else {
            return Vec::new();
        };
        let epoch = self.exhaustive || self.epoch_due || motion.needs_epoch(factor);
        // An epoch called for by the flagged share (not by χ, a rebuild or the exhaustive
        // mode) may keep the slacks of quiet nodes: it needs the bounds of the motion since
        // the last epoch too.
        let reuse = epoch && !self.exhaustive && !motion.needs_epoch(factor);
        if !epoch || reuse {
            motion.update(positions);
        }
        let this = &*self;
        let bonds = BondView::new(reference, positions, families);
        let node_critical = |&i: &u32| this.node_critical(i as usize, &bonds, factor);
        let critical = if epoch {
            // Slack √f·l − r per node over the bonds it checks (+∞ off the check set); then
            // the exact test on the nodes whose slack is (about) exhausted, so the verdict is
            // the plain check's.
            let sqrt_f = factor.sqrt();
            let shortest = this.shortest_bond;
            let first_bond = (families.node_count() > 0)
                .then(|| families.row_lengths(0).first().copied())
                .flatten();
            let tolerance = 1e-9 * first_bond.unwrap_or(0.0);
            let (reused, recomputed_bonds) = motion.refresh_slacks(
                reuse,
                |i| this.in_check[i] && this.mask[i] == SchemeClass::Wls,
                |i| {
                    // √f·l − r = l (√f − r/l) ≥ l_min (√f − max r/l) while that is ≥ 0:
                    // one division per bond and one square root per node.
                    let least = this.node_least(i, &bonds, Measure::NegatedSquaredRatio);
                    let slack = match sqrt_f - (-least).sqrt() {
                        // No checked bond (least = +∞ gives NaN here).
                        _ if least == f64::INFINITY => f64::INFINITY,
                        stretch if stretch >= 0.0 => stretch * shortest,
                        _ => f64::NEG_INFINITY,
                    };
                    (slack, this.bond_count(i, families))
                },
            );
            let slack = &motion.slack;
            let exhausted = |i: &u32| slack[*i as usize] <= tolerance && node_critical(i);
            // Listed (allocated) only when something is critical.
            let critical: Vec<u32> = if this.check_nodes.par_iter().any(exhausted) {
                this.check_nodes
                    .par_iter()
                    .copied()
                    .filter(exhausted)
                    .collect()
            } else {
                Vec::new()
            };
            if self.tracked_stale {
                let (in_check, neighbors) = (&self.in_check, &families.neighbors);
                self.tracked.par_iter_mut().enumerate().for_each(|(k, t)| {
                    *t = in_check[k] || families.range(k).any(|b| in_check[neighbors[b] as usize]);
                });
                self.tracked_stale = false;
            }
            let tracked = &self.tracked;
            motion.start_epoch(positions, factor, |k| tracked[k]);
            self.checked_bonds += recomputed_bonds;
            self.reused_slacks += reused;
            self.full_checks += 1;
            self.epoch_due = false;
            critical
        } else {
            // One parallel pass over the cells counts the flagged nodes and the bonds visited,
            // checks them exactly and lists the critical ones (allocating only for those).
            // Too many flagged nodes: the next check starts an epoch (this one is exact either
            // way).
            let in_check_wls = |k: usize| this.in_check[k] && this.mask[k] == SchemeClass::Wls;
            let (flagged, (counted, critical)) = motion.fold_flagged(
                in_check_wls,
                || (0u64, Vec::new()),
                |(bonds, mut list): (u64, Vec<u32>), i| {
                    if node_critical(&(i as u32)) {
                        list.push(i as u32);
                    }
                    (bonds + this.bond_count(i, families), list)
                },
                |(bonds, mut list), (more, mut found)| {
                    list.append(&mut found);
                    (bonds + more, list)
                },
            );
            self.epoch_due = flagged * EPOCH_SHARE > self.check_nodes.len();
            self.checked_bonds += counted;
            self.filtered_checks += 1;
            critical
        };
        self.motion = Some(motion);
        critical
    }

    fn needs_backward_scan(&self, i: usize, families: &Families) -> bool {
        families.neighbors[families.range(i).start..self.forward_start[i]]
            .iter()
            .any(|&j| !self.in_check[j as usize])
    }

    /// The initial check set of the policy.
    fn rebuild_check_set(&mut self, families: &Families) {
        let mask = &self.mask;
        self.check_nodes = match self.spec.check {
            CheckSet::All => (0..mask.len() as u32)
                .filter(|&i| mask[i as usize] == SchemeClass::Wls)
                .collect(),
            CheckSet::Near | CheckSet::Collocation => {
                // Ω_w nodes with an Ω_s node within one family hop, then within two.
                let touches = |i: usize, flag: &[bool]| {
                    families
                        .range(i)
                        .any(|b| flag[families.neighbors[b] as usize])
                };
                let standard: Vec<bool> =
                    mask.iter().map(|&m| m == SchemeClass::Standard).collect();
                let ring1: Vec<bool> = (0..mask.len())
                    .into_par_iter()
                    .map(|i| mask[i] == SchemeClass::Wls && touches(i, &standard))
                    .collect();
                let near: Vec<bool> = (0..mask.len())
                    .into_par_iter()
                    .map(|i| mask[i] == SchemeClass::Wls && (ring1[i] || touches(i, &ring1)))
                    .collect();
                (0..mask.len() as u32)
                    .filter(|&i| near[i as usize])
                    .collect()
            }
        };
        self.in_check = vec![false; mask.len()];
        for &i in &self.check_nodes {
            self.in_check[i as usize] = true;
        }
        self.scans_backward = (0..mask.len())
            .into_par_iter()
            .map(|i| self.needs_backward_scan(i, families))
            .collect();
        if let Some(m) = self.motion.as_mut() {
            m.invalidate();
        }
        self.tracked_stale = true;
        self.check_bonds = self.bonds_to_check(families);
    }

    /// Moves every node of H_i ∪ H_j of each listed bond end to Ω_s and updates the check set;
    /// returns how many moved.
    fn switch(&mut self, ends: &[u32], families: &Families) -> usize {
        let mut switched = Vec::new();
        for &i in ends {
            let i = i as usize;
            let neighborhood =
                std::iter::once(i).chain(families.range(i).map(|b| families.neighbors[b] as usize));
            for k in neighborhood {
                if self.mask[k] == SchemeClass::Wls {
                    self.mask[k] = SchemeClass::Standard;
                    switched.push(k as u32);
                }
            }
        }
        self.standard_nodes += switched.len();
        if !switched.is_empty() {
            self.damping.rebuild(&self.mask);
        }
        self.extend_check_set(&switched, families);
        switched.len()
    }

    /// After a switch: drop switched nodes from the check set and, for the `near` policy, add
    /// the Ω_w nodes within two family hops of them (incremental, local work only).
    fn extend_check_set(&mut self, switched: &[u32], families: &Families) {
        let mask = &self.mask;
        let mut added = Vec::new();
        if self.spec.check != CheckSet::All {
            for &k in switched {
                for b in families.range(k as usize) {
                    let j = families.neighbors[b] as usize;
                    let two_hops = std::iter::once(j)
                        .chain(families.range(j).map(|b2| families.neighbors[b2] as usize));
                    for c in two_hops {
                        if mask[c] == SchemeClass::Wls && !self.in_check[c] {
                            self.in_check[c] = true;
                            self.check_nodes.push(c as u32);
                            added.push(c);
                        }
                    }
                }
            }
        }
        for &k in switched {
            self.in_check[k as usize] = false;
        }
        // Bonds whose lower end left the check set are now checked from their upper end.
        for &k in switched {
            for b in families.range(k as usize) {
                let i = families.neighbors[b] as usize;
                if i > k as usize {
                    self.scans_backward[i] = true;
                    if let Some(m) = self.motion.as_mut() {
                        m.force(i);
                    }
                }
            }
        }
        for c in added {
            self.scans_backward[c] = self.needs_backward_scan(c, families);
            if let Some(m) = self.motion.as_mut() {
                m.force(c);
            }
        }
        let in_check = &self.in_check;
        self.check_nodes.retain(|&i| in_check[i as usize]);
        self.tracked_stale = true;
        self.check_bonds = self.bonds_to_check(families);
    }

    /// The switching check (3.80) on `positions` (u^{n+1}), if due at `step`: returns the
    /// number of nodes switched.
    pub fn check(
        &mut self,
        step: u64,
        time: f64,
        reference: &[[f64; D]],
        positions: &[[f64; D]],
        families: &Families,
        critical_stretch: f64,
    ) -> usize {
        if !self.spec.adaptive || !step.is_multiple_of(self.spec.check_every) {
            return 0;
        }
        // s ≥ χ s0  ⟺  r² ≥ (1 + χ s0)² l²: no square root on the common path.
        let factor = (1.0 + self.spec.chi * critical_stretch).powi(2);
        let collocation = self.spec.check == CheckSet::Collocation;
        let filtered = if collocation {
            Vec::new()
        } else {
            self.critical_by_motion(reference, positions, families, factor)
        };
        let mask = &self.mask;
        // One criterion for every path (a collocation row also lists the node itself).
        let bond_critical = |i: usize, j: usize| {
            let (r2, l2) = bond_squares(i, j, reference, positions);
            j != i && critical_margin(factor, r2, l2) <= 0.0
        };
        // The collocation policy checks row r's columns of the WLS operator instead.
        let columns = |i: usize| self.wls.columns(i);
        let has_critical = |&i: &u32| {
            let i = i as usize;
            mask[i] == SchemeClass::Wls && columns(i).iter().any(|&j| bond_critical(i, j as usize))
        };
        let critical_nodes: Vec<u32> = if collocation {
            // The common case finds nothing: `any` allocates nothing; the nodes are listed
            // only when there is something to switch.
            self.checked_bonds += self.check_bonds;
            if self
                .check_nodes
                .par_iter()
                .with_min_len(256)
                .any(has_critical)
            {
                self.check_nodes
                    .par_iter()
                    .with_min_len(256)
                    .copied()
                    .filter(has_critical)
                    .collect()
            } else {
                Vec::new()
            }
        } else {
            filtered
        };
        let mut ends: Vec<u32> = Vec::new();
        for &i in &critical_nodes {
            let i = i as usize;
            if collocation {
                for &j in columns(i) {
                    if bond_critical(i, j as usize) {
                        ends.extend([i as u32, j]);
                    }
                }
            } else {
                for b in self
                    .checked_bonds_of(i, families)
                    .filter(|&b| bond_critical(i, families.neighbors[b] as usize))
                {
                    ends.extend([i as u32, families.neighbors[b]]);
                }
            }
        }
        if ends.is_empty() {
            return 0;
        }
        let moved = self.switch(&ends, families);
        if moved > 0 {
            self.events.push(SwitchEvent {
                step,
                time,
                nodes: moved,
                forced: false,
            });
        }
        moved
    }

    /// Into a checkpoint's state: the mask, χ and the check counters (the check set and the
    /// motion filter are rebuilt from the mask; the filter changes the work, not the result).
    pub fn save(&self, state: &mut State) {
        state.put_u8("hybrid/mask", self.mask.iter().map(|&m| m as u8).collect());
        state.put_f64("hybrid/chi", vec![self.spec.chi]);
        state.put_u64(
            "hybrid/counters",
            vec![self.checked_bonds, self.full_checks, self.filtered_checks],
        );
    }

    /// From a checkpoint's state of the same scene: the nodes that switched since the start
    /// switch again (Ω_s only grows), and the check set is rebuilt.
    pub fn restore(&mut self, state: &State, families: &Families) -> Result<(), String> {
        let saved = state.u8("hybrid/mask", self.mask.len())?;
        let chi = crate::scene::check_chi(state.f64("hybrid/chi", 1)?[0])?;
        let counters = state.u64("hybrid/counters", 3)?;
        let mut mask = Vec::with_capacity(saved.len());
        for (i, (&m, &now)) in saved.iter().zip(&self.mask).enumerate() {
            let class = match m {
                0 => SchemeClass::Standard,
                1 => SchemeClass::Wls,
                _ => return Err(format!("hybrid/mask: node {i} has no scheme class {m}")),
            };
            if class == SchemeClass::Wls && now == SchemeClass::Standard {
                return Err(format!(
                    "hybrid/mask: node {i} is in Ω_w but started in Ω_s (Ω_s only grows)"
                ));
            }
            mask.push(class);
        }
        self.standard_nodes = mask.iter().filter(|&&m| m == SchemeClass::Standard).count();
        self.mask = mask;
        self.spec.chi = chi;
        (self.checked_bonds, self.full_checks, self.filtered_checks) =
            (counters[0], counters[1], counters[2]);
        self.events.clear();
        self.damping.rebuild(&self.mask);
        self.rebuild_check_set(families);
        Ok(())
    }

    /// Ω_w nodes that lost a bond (broken from the Ω_s side): damage reached Ω_w. They and their
    /// neighbourhoods switch at once, with a forced event; returns how many were found.
    pub fn enforce(&mut self, step: u64, time: f64, intact: &[u8], families: &Families) -> usize {
        let mask = &self.mask;
        let reached: Vec<u32> = (0..mask.len())
            .into_par_iter()
            .filter(|&j| mask[j] == SchemeClass::Standard)
            .flat_map_iter(|j| {
                families
                    .range(j)
                    .filter(|&b| {
                        intact[b] == 0 && mask[families.neighbors[b] as usize] == SchemeClass::Wls
                    })
                    .map(|b| families.neighbors[b])
            })
            .collect();
        if reached.is_empty() {
            return 0;
        }
        let moved = self.switch(&reached, families);
        self.events.push(SwitchEvent {
            step,
            time,
            nodes: moved,
            forced: true,
        });
        reached.len()
    }

    /// The linearized operator per unit mass on the Ω_w rows, −K u / ρ (the sign of the
    /// standard scheme's `apply_linearized`), for stable-step estimates; other rows untouched.
    pub fn apply_linearized(&self, u: &[[f64; D]], density: f64, out: &mut [[f64; D]]) {
        let mask = &self.mask;
        self.wls
            .apply_linearized(u, density, out, |i| mask[i] == SchemeClass::Wls);
    }

    /// WLS forces K u on the Ω_w nodes (u = positions − reference), kept per row; the
    /// simulation's acceleration pass picks them up with [`Self::wls_force_of`] (no scatter
    /// pass of its own).
    pub fn wls_forces(&mut self, reference: &[[f64; D]], positions: &[[f64; D]]) {
        let mask = &self.mask;
        self.wls
            .forces(reference, positions, |i| mask[i] == SchemeClass::Wls);
    }

    /// The interface damping's exchange on the new velocities of a step `dt` (the run's stable
    /// step `stable_dt` sets its rate).
    pub fn damp_interface(&mut self, velocities: &mut [[f64; D]], dt: f64, stable_dt: f64) {
        self.damping.apply(velocities, dt, stable_dt);
    }

    /// Node i's WLS force from the last [`Self::wls_forces`], if it is in Ω_w.
    #[inline]
    pub fn wls_force_of(&self, i: usize) -> Option<[f64; D]> {
        (self.mask[i] == SchemeClass::Wls).then(|| self.wls.force_of(i))
    }
}
