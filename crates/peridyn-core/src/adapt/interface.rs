//! Damping at the hybrid's Ω_s/Ω_w interface (not in the papers; docs/validation.md "The
//! hybrid's coupling is unstable").
//!
//! The hybrid couples the two schemes row by row (seed-004 §4.3: an Ω_s node sums PD bond forces
//! over its whole family, an Ω_w node applies its WLS row, whose columns may lie in Ω_s). Each row
//! is consistent, but the coupled stiffness is not symmetric, and its eigenvalues are not all
//! real: modes at about 0.6 of the top lattice frequency, concentrated within a horizon of the
//! interface, grow exponentially whatever Δt (a free plate ringing with a smooth pulse: energy
//! ×2.6·10⁵ in 500 µs with the m = 4 orbit stencil, ×15 in 160 µs with the papers' δ/3 stencil
//! at m = 8). A symmetric (energy-based) coupling is no cure: its truncated WLS pair sums are
//! indefinite (a real unstable mode in a lattice model) and it has ghost forces.
//!
//! The cure kept here: a velocity damping v ← v − r L D L v after every step, L the lattice
//! graph Laplacian (Σ_j (v_i − v_j) over the lattice neighbours), D the indicator of a band of
//! half-width `hybrid.interface_band` (default δ/2) on both sides of the interface, r = κ ω_max
//! Δt with ω_max = 2/Δt_stable (`hybrid.interface_damping` = κ, default 0.02). L D L is
//! symmetric positive semi-definite with zero column sums, so linear momentum is exact and the
//! kinetic energy never rises; on a smooth field L v = O(Δx² ∇²v), so a wave of wave number k
//! loses O(r (kΔx)⁴) per step while it crosses the band, whereas the growing modes (kΔx ≈ 1–2)
//! lose O(r). The explicit update is stable for r · λ_max(L)² < 2, λ_max(L) ≤ 2 · (largest
//! lattice degree): 64 in 2D, 144 in 3D. κ = 0.02 at 0.7 of the stable step gives r = 0.028,
//! r · 64 = 1.79 in 2D; r is clamped to 1.8 / λ² (the same 90 % of the limit) wherever κ and Δt
//! would go past it (a larger Δt, or 3D).
//! (A Laplacian damping r L D would take O(r (kΔx)²) from smooth waves.) Measured on a free
//! plate ringing with a smooth pulse: 5–12 % of its energy in 160 µs (docs/validation.md).
//! Not handled: a lattice pair across a crack is still damped (cracks stay ≥ δ inside Ω_s
//! because switching moves H_i ∪ H_j of every critical bond, and the band reaches δ/2 into it).

use super::masks::SchemeClass;
use crate::discretization::Families;
use rayon::prelude::*;

/// Lattice neighbours are family members within this multiple of the grid's shortest bond.
const LATTICE_REACH: f64 = 1.01;

pub struct InterfaceDamping {
    /// κ: the damping rate as a share of the top lattice frequency.
    pub strength: f64,
    /// The band's half-width in lattice hops.
    hops: usize,
    /// The largest r the explicit update takes: 1.8 / (2 · largest lattice degree)².
    max_rate: f64,
    /// Per node, its lattice neighbours (CSR; a symmetric relation on a uniform lattice).
    lattice_offsets: Vec<usize>,
    lattice: Vec<u32>,
    /// The band's nodes (B), where the damping weighs the lattice Laplacian of v.
    band: Vec<u32>,
    /// The nodes the update changes (B and their lattice neighbours), each with its slot in
    /// `band` (u32::MAX if outside) and the band slots of its lattice neighbours in B (CSR).
    touched: Vec<(u32, u32)>,
    touched_offsets: Vec<usize>,
    touched_partners: Vec<u32>,
    /// Scratch: (L v)_b per band node, then the change per touched node.
    laplacian: Vec<[f64; 3]>,
    change: Vec<[f64; 3]>,
}

impl InterfaceDamping {
    /// The lattice-neighbour lists of every node (built once): family members within
    /// LATTICE_REACH of the shortest bond of the whole grid.
    /// `band`: the band's half-width (m), rounded to lattice hops.
    pub fn new(strength: f64, band: f64, families: &Families) -> Self {
        let n = families.offsets.len() - 1;
        let shortest = families.shortest();
        let mut lattice_offsets = Vec::with_capacity(n + 1);
        lattice_offsets.push(0);
        let mut lattice = Vec::new();
        for i in 0..n {
            lattice.extend(
                families
                    .range(i)
                    .filter(|&b| families.length(i, b) <= LATTICE_REACH * shortest)
                    .map(|b| families.neighbors[b]),
            );
            lattice_offsets.push(lattice.len());
        }
        let hops = ((band / shortest).round() as usize).max(1);
        let degree = lattice_offsets
            .windows(2)
            .map(|w| w[1] - w[0])
            .max()
            .unwrap_or(0);
        let max_rate = 1.8 / (2.0 * degree.max(1) as f64).powi(2);
        InterfaceDamping {
            strength,
            hops,
            max_rate,
            lattice_offsets,
            lattice,
            band: Vec::new(),
            touched: Vec::new(),
            touched_offsets: vec![0],
            touched_partners: Vec::new(),
            laplacian: Vec::new(),
            change: Vec::new(),
        }
    }

    fn neighbours(&self, i: usize) -> &[u32] {
        &self.lattice[self.lattice_offsets[i]..self.lattice_offsets[i + 1]]
    }

    /// Rebuilds the band for `mask` (after every switch; nothing to do when switched off).
    pub fn rebuild(&mut self, mask: &[SchemeClass]) {
        if self.strength == 0.0 {
            return;
        }
        let n = mask.len();
        // Hop 0: nodes with a lattice neighbour of the other class.
        let mut in_band: Vec<bool> = (0..n)
            .into_par_iter()
            .map(|i| {
                self.neighbours(i)
                    .iter()
                    .any(|&j| mask[j as usize] != mask[i])
            })
            .collect();
        for _ in 1..self.hops {
            in_band = self.grown(&in_band, None);
        }
        self.set_band(&in_band);
    }

    /// `in_band` and every node a lattice hop from it (among the `allowed` ones, if given).
    fn grown(&self, in_band: &[bool], allowed: Option<&[bool]>) -> Vec<bool> {
        (0..in_band.len())
            .into_par_iter()
            .map(|i| {
                in_band[i]
                    || (allowed.is_none_or(|a| a[i])
                        && self.neighbours(i).iter().any(|&j| in_band[j as usize]))
            })
            .collect()
    }

    /// A band inside a boundary zone's edge (the absorbing layer's, issue 19): the nodes
    /// outside `outside` at 2 … hops + 1 lattice hops from it. The first hop is left out so that
    /// L D L reads and writes no node of the zone: the damping acts on the inside alone, and
    /// there it keeps momentum and never raises the kinetic energy.
    pub fn rebuild_inside(&mut self, outside: &[bool]) {
        if self.strength == 0.0 {
            return;
        }
        let inside: Vec<bool> = outside.iter().map(|o| !o).collect();
        let first = self.grown(outside, Some(&inside));
        let mut reach = first.clone();
        for _ in 0..self.hops {
            reach = self.grown(&reach, Some(&inside));
        }
        let band: Vec<bool> = reach.iter().zip(&first).map(|(r, f)| *r && !f).collect();
        self.set_band(&band);
    }

    fn set_band(&mut self, in_band: &[bool]) {
        let n = in_band.len();
        let mut slot = vec![u32::MAX; n];
        self.band.clear();
        for i in (0..n).filter(|&i| in_band[i]) {
            slot[i] = self.band.len() as u32;
            self.band.push(i as u32);
        }
        self.touched.clear();
        self.touched_partners.clear();
        self.touched_offsets.clear();
        self.touched_offsets.push(0);
        for i in 0..n {
            let before = self.touched_partners.len();
            let lattice = &self.lattice[self.lattice_offsets[i]..self.lattice_offsets[i + 1]];
            let partners = lattice.iter().filter(|&&j| in_band[j as usize]);
            self.touched_partners
                .extend(partners.map(|&j| slot[j as usize]));
            if in_band[i] || self.touched_partners.len() > before {
                self.touched.push((i as u32, slot[i]));
                self.touched_offsets.push(self.touched_partners.len());
            }
        }
        self.laplacian.resize(self.band.len(), [0.0; 3]);
        self.change.resize(self.touched.len(), [0.0; 3]);
    }

    /// The band's nodes.
    pub fn damped(&self) -> &[u32] {
        &self.band
    }

    /// One damping update of `velocities` after a step `dt` of a run whose stable step is
    /// `stable_dt`: v ← v − r L D L v, L the lattice graph Laplacian (Σ_j (v_i − v_j) over the
    /// lattice neighbours), D the band's indicator, r = κ ω_max Δt (at most `max_rate`),
    /// ω_max = 2/stable_dt. L D L is
    /// symmetric positive semi-definite with zero column sums: momentum exact, kinetic energy
    /// never rises; on a smooth field L v = O(Δx² ∇²v), so smooth waves lose O((kΔx)⁴).
    pub fn apply<const D: usize>(&mut self, velocities: &mut [[f64; D]], dt: f64, stable_dt: f64) {
        if self.strength == 0.0 || self.band.is_empty() {
            return;
        }
        let rate = (self.strength * 2.0 / stable_dt * dt).min(self.max_rate);
        let v = &*velocities;
        let (lattice, lattice_offsets) = (&self.lattice, &self.lattice_offsets);
        let band = &self.band;
        self.laplacian
            .par_iter_mut()
            .enumerate()
            .with_min_len(1024)
            .for_each(|(b, l)| {
                let i = band[b] as usize;
                *l = [0.0; 3];
                for &j in &lattice[lattice_offsets[i]..lattice_offsets[i + 1]] {
                    for k in 0..D {
                        l[k] += v[i][k] - v[j as usize][k];
                    }
                }
            });
        let w = &self.laplacian;
        let (touched, offsets, partners) =
            (&self.touched, &self.touched_offsets, &self.touched_partners);
        self.change
            .par_iter_mut()
            .enumerate()
            .with_min_len(1024)
            .for_each(|(t, c)| {
                let (i, own) = touched[t];
                let degree = (lattice_offsets[i as usize + 1] - lattice_offsets[i as usize]) as f64;
                *c = [0.0; 3];
                if own != u32::MAX {
                    for k in 0..D {
                        c[k] = degree * w[own as usize][k];
                    }
                }
                for &b in &partners[offsets[t]..offsets[t + 1]] {
                    for k in 0..D {
                        c[k] -= w[b as usize][k];
                    }
                }
                for x in c.iter_mut() {
                    *x *= -rate;
                }
            });
        for (&(i, _), change) in touched.iter().zip(&self.change) {
            for k in 0..D {
                velocities[i as usize][k] += change[k];
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A 20 × 20 lattice (Δx = 1, horizon 3) with Ω_s the left half.
    fn lattice() -> (Vec<[f64; 2]>, Families, Vec<SchemeClass>) {
        let positions: Vec<[f64; 2]> = (0..400)
            .map(|k| [(k / 20) as f64, (k % 20) as f64])
            .collect();
        let families = Families::build(&positions, 3.0);
        let mask = positions
            .iter()
            .map(|x| {
                if x[0] < 10.0 {
                    SchemeClass::Standard
                } else {
                    SchemeClass::Wls
                }
            })
            .collect();
        (positions, families, mask)
    }

    /// Momentum is exact (Σ v unchanged to round-off), the kinetic energy falls, only nodes
    /// within the band and their lattice neighbours change, and a velocity field linear in x
    /// (L v = 0 away from the lattice's edge) passes the band unchanged.
    #[test]
    fn the_damping_keeps_momentum_takes_energy_and_leaves_linear_fields_alone() {
        let (x, families, mask) = lattice();
        let mut damping = InterfaceDamping::new(0.02, 1.0, &families);
        damping.rebuild(&mask);
        // The band: the columns x = 9 and 10 (one hop on each side).
        assert_eq!(damping.damped().len(), 40);
        assert!(damping.damped().iter().all(|&i| {
            let c = x[i as usize][0];
            c == 9.0 || c == 10.0
        }));
        let mut state = 0x1234_5678_u64;
        let mut random = || {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (state >> 11) as f64 / (1u64 << 53) as f64 - 0.5
        };
        let before: Vec<[f64; 2]> = (0..x.len()).map(|_| [random(), random()]).collect();
        let mut v = before.clone();
        damping.apply(&mut v, 0.7, 1.0);
        let sum = |v: &[[f64; 2]]| v.iter().fold([0.0, 0.0], |s, a| [s[0] + a[0], s[1] + a[1]]);
        let energy = |v: &[[f64; 2]]| v.iter().map(|a| a[0] * a[0] + a[1] * a[1]).sum::<f64>();
        let (p0, p1) = (sum(&before), sum(&v));
        assert!((p0[0] - p1[0]).abs() < 1e-13 && (p0[1] - p1[1]).abs() < 1e-13);
        assert!(energy(&v) < energy(&before));
        for (i, (a, b)) in before.iter().zip(&v).enumerate() {
            if a != b {
                assert!(
                    (8.0..=11.0).contains(&x[i][0]),
                    "node {i} at {:?} changed",
                    x[i]
                );
            }
        }
        let linear: Vec<[f64; 2]> = x.iter().map(|p| [0.3 * p[0], -0.1 * p[0] + 2.0]).collect();
        let mut w = linear.clone();
        damping.apply(&mut w, 0.7, 1.0);
        for (a, b) in linear.iter().zip(&w) {
            assert!((a[0] - b[0]).abs() < 1e-12 && (a[1] - b[1]).abs() < 1e-12);
        }
    }

    /// A band inside a zone (the absorbing layer's use): the zone is the columns x ≥ 16; a band
    /// of 2 hops is the columns 13 and 14 (hops 2 and 3), and the update reads and writes no
    /// node of the zone or of column 15 beyond the band's lattice neighbours: the zone's
    /// velocities stay as they are, the inside keeps its momentum and loses kinetic energy.
    #[test]
    fn a_band_inside_a_zone_leaves_the_zone_alone() {
        let (x, families, _) = lattice();
        let zone: Vec<bool> = x.iter().map(|p| p[0] >= 16.0).collect();
        let mut damping = InterfaceDamping::new(0.02, 2.0, &families);
        damping.rebuild_inside(&zone);
        assert_eq!(damping.damped().len(), 40);
        assert!(damping.damped().iter().all(|&i| {
            let c = x[i as usize][0];
            c == 13.0 || c == 14.0
        }));
        let before: Vec<[f64; 2]> = x
            .iter()
            .map(|p| [(p[0] * 1.7).sin() + p[1], (p[1] * 2.3).cos() * p[0]])
            .collect();
        let mut v = before.clone();
        // Velocities in the zone that would change the band's Laplacian if it were read.
        for (vi, z) in v.iter_mut().zip(&zone) {
            if *z {
                *vi = [1e3, -1e3];
            }
        }
        let zone_before = v.clone();
        damping.apply(&mut v, 0.7, 1.0);
        let inside = |v: &[[f64; 2]]| {
            v.iter()
                .zip(&zone)
                .filter(|(_, z)| !**z)
                .fold(([0.0, 0.0], 0.0), |(p, e), (a, _)| {
                    ([p[0] + a[0], p[1] + a[1]], e + a[0] * a[0] + a[1] * a[1])
                })
        };
        let ((p0, e0), (p1, e1)) = (inside(&zone_before), inside(&v));
        assert!((p0[0] - p1[0]).abs() < 1e-12 && (p0[1] - p1[1]).abs() < 1e-12);
        assert!(e1 < e0);
        for (i, (a, b)) in zone_before.iter().zip(&v).enumerate() {
            if a != b {
                assert!((12.0..=15.0).contains(&x[i][0]), "node {i} at {:?}", x[i]);
            }
        }
    }

    /// The explicit update stays stable where κ and Δt alone would take it past its limit: a
    /// 3D lattice (degree 6, λ_max(L) = 12) at ten times the stable step, 200 updates of random
    /// velocities, the kinetic energy falling at every one.
    #[test]
    fn the_rate_is_clamped_to_the_explicit_limit() {
        let positions: Vec<[f64; 3]> = (0..512)
            .map(|k| [(k / 64) as f64, ((k / 8) % 8) as f64, (k % 8) as f64])
            .collect();
        let families = Families::build(&positions, 1.5);
        let mask: Vec<SchemeClass> = positions
            .iter()
            .map(|x| {
                if x[0] < 4.0 {
                    SchemeClass::Standard
                } else {
                    SchemeClass::Wls
                }
            })
            .collect();
        let mut damping = InterfaceDamping::new(0.02, 1.0, &families);
        damping.rebuild(&mask);
        let mut v: Vec<[f64; 3]> = (0..512)
            .map(|k| {
                let s = if k % 2 == 0 { 1.0 } else { -1.0 };
                [s, -s * 0.5, s * 0.25]
            })
            .collect();
        let energy = |v: &[[f64; 3]]| v.iter().flatten().map(|x| x * x).sum::<f64>();
        let mut last = energy(&v);
        for _ in 0..200 {
            damping.apply(&mut v, 10.0, 1.0);
            let now = energy(&v);
            assert!(now <= last * (1.0 + 1e-12), "{last} → {now}");
            last = now;
        }
    }
}
