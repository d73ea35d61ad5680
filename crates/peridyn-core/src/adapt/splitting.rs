//! Adaptive particle splitting (zeng2024 Sect. 3, (15)–(23), (30); extraction
//! `seed-002-dual-horizon` §3, whose ambiguities are resolved as it recommends):
//! - criteria: φ_k > φ_c (15), or min_i ε_ii > α s_c(δ_k) (16) read on the strain itself
//!   (ambiguity 2), ε_ii in the regression form of (17) (ambiguity 1);
//! - a parent becomes 2ᵈ children at the sub-cell centres x_k ± Δ_k/4 (ambiguity 3), placed in
//!   the current configuration with the parent's normal stretches (18), each with a quarter of
//!   its volume and mass, its velocity and half its horizon (30; `SplitRule::horizon_ratio`:
//!   Table 3's other choice keeps the parent's); one level by default (the paper's examples);
//! - families: the children's from the parent's neighbourhood (22) and, for every particle
//!   whose horizon can reach a child, its own row again (ambiguity 4); only those rows are
//!   searched and refitted;
//! - bond states (ambiguity 5): a bond of or to a child inherits the state of the bond between
//!   the particles it replaces (either direction), sibling bonds start intact, and the next
//!   force pass breaks any bond already past s_c; pre-cracks are geometry: a new bond is cut
//!   exactly when it crosses one, whatever the bond it replaces (that bond may cross the
//!   pre-crack near its tip where the new one does not);
//! - quadrature weights of the new rows are fitted over their bonds not cut by a pre-crack
//!   (the pre-crack is a surface; bonds broken during the run soften the material, as they do
//!   for the parents, whose weights were fitted before the run).

use rayon::prelude::*;

use crate::discretization::buckets::Buckets;
use crate::discretization::family::crosses;
use crate::discretization::{Field, Nodes};
use crate::model::osb::{OsbHorizon, OsbMaterial};
use crate::scene::CrackGeometry;
pub use crate::scene::SplitRule;
use crate::scheme::dual_horizon::{Body, DualBonds, NewRow, family_of};

/// Whether a particle meets (15) or (16) under `rule`.
pub fn wants(
    rule: &SplitRule,
    damage: f64,
    strains: [f64; 2],
    constants: &OsbHorizon,
    level: u8,
) -> bool {
    level < rule.levels
        && (damage > rule.damage
            || strains[0].min(strains[1]) > rule.strain_factor * constants.critical_stretch)
}

/// The per-particle columns a split writes.
#[derive(Debug, Clone, Copy)]
pub struct SplitColumns {
    pub position: Field<[f64; 2]>,
    pub constants: Field<OsbHorizon>,
    pub level: Field<u8>,
    /// Δ_k, the particle's cell length.
    pub spacing: Field<f64>,
}

/// The sub-cell offsets (ξ, η) of (18)–(19).
const SIGNS: [[f64; 2]; 4] = [[-1.0, -1.0], [1.0, -1.0], [-1.0, 1.0], [1.0, 1.0]];

/// A parent's four children: reference positions (19) and current positions (18).
type Placement = ([[f64; 2]; 4], [[f64; 2]; 4]);

/// What one splitting pass did.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct SplitReport {
    pub parents: usize,
    /// Rows searched again (children and the particles that see them).
    pub rows: usize,
}

/// Splits `parents` (distinct, all below the level cap) in place: the store grows by 3 per
/// parent, `bonds` gets the new rows, `buckets` the new positions.
#[allow(clippy::too_many_arguments)]
pub fn split(
    parents: &[u32],
    nodes: &mut Nodes<2>,
    columns: &SplitColumns,
    bonds: &mut DualBonds,
    buckets: &mut Buckets,
    material: &OsbMaterial,
    horizon_ratio: f64,
    precracks: &[CrackGeometry],
) -> SplitReport {
    if parents.is_empty() {
        return SplitReport::default();
    }
    let old_count = nodes.len();
    // The children's places, from the parents' state before anything moves.
    let placements = placements(parents, nodes, columns, bonds, material);
    let mut affected = affected(parents, nodes, columns, buckets);
    // The old particles' places (a parent's index goes to its first child): pre-crack
    // crossings of the bonds the new ones replace. Only kept when there is a pre-crack.
    let reference_of: Vec<[f64; 2]> = if precracks.is_empty() {
        Vec::new()
    } else {
        nodes.reference()[..old_count].to_vec()
    };
    // parent_of[i]: the parent whose child node i is (new indices), or u32::MAX.
    let mut parent_of = vec![u32::MAX; old_count + 3 * parents.len()];
    for (&p, (reference, current)) in parents.iter().zip(&placements) {
        let p = p as usize;
        let (old_x, volume) = (nodes.reference()[p], nodes.volumes()[p] * 0.25);
        let added = nodes.split(p, reference, volume);
        buckets.relocate(p as u32, &old_x, &reference[0]);
        let children: Vec<usize> = std::iter::once(p).chain(added).collect();
        let parent_constants = nodes.fields.get(columns.constants)[p];
        let child_constants = material.at(horizon_ratio * parent_constants.horizon);
        for (c, &i) in children.iter().enumerate() {
            nodes.fields.get_mut(columns.position)[i] = current[c];
            nodes.fields.get_mut(columns.constants)[i] = child_constants;
            nodes.fields.get_mut(columns.level)[i] += 1;
            nodes.fields.get_mut(columns.spacing)[i] *= 0.5;
            if i != p {
                buckets.insert(i as u32, &reference[c]);
            }
            parent_of[i] = p as u32;
            if i < old_count {
                affected[i] = false;
            }
        }
    }
    let body = Body {
        reference: nodes.reference(),
        volumes: nodes.volumes(),
        constants: nodes.fields.get(columns.constants),
        thickness: material.thickness,
    };
    let rows_to_search: Vec<usize> = (0..nodes.len())
        .filter(|&i| parent_of[i] != u32::MAX || (i < old_count && affected[i]))
        .collect();
    let inherited = |a: usize, b: usize| -> u8 {
        let (pa, pb) = (parent_of[a], parent_of[b]);
        if pa != u32::MAX && pa == pb {
            return 1;
        }
        let origin = |i: usize, p: u32| if p == u32::MAX { i as u32 } else { p };
        let (oa, ob) = (origin(a, pa), origin(b, pb));
        // A pre-crack's cut is geometry, not history: the new bond's own crossing (`fitted`
        // below) decides it. Inheriting it would carry the coarse lattice's crack tip (the
        // cut bonds nearest the tip end up to Δ beyond it) into the children.
        let pre_cut = |c: &CrackGeometry| {
            let (xa, xb) = (&reference_of[oa as usize], &reference_of[ob as usize]);
            crosses(c, xa, xb) || crosses(c, xb, xa)
        };
        if precracks.iter().any(pre_cut) {
            return 1;
        }
        bonds
            .state(oa as usize, ob)
            .or_else(|| bonds.state(ob as usize, oa))
            .unwrap_or(1)
    };
    let rows: Vec<NewRow> = rows_to_search
        .par_iter()
        .map(|&k| {
            let mut found = Vec::new();
            let delta = body.constants[k].horizon;
            buckets.within(body.reference, &body.reference[k], delta, |j| found.push(j));
            let neighbors = family_of(k, &body, found.into_iter());
            let fitted: Vec<u8> = neighbors
                .iter()
                .map(|&j| {
                    let (a, b) = (&body.reference[k], &body.reference[j as usize]);
                    u8::from(
                        !precracks
                            .iter()
                            .any(|c| crosses(c, a, b) || crosses(c, b, a)),
                    )
                })
                .collect();
            let states = neighbors
                .iter()
                .zip(&fitted)
                .map(|(&j, &f)| if f == 0 { 0 } else { inherited(k, j as usize) })
                .collect();
            NewRow {
                particle: k as u32,
                neighbors,
                states,
                fitted,
            }
        })
        .collect();
    let report = SplitReport {
        parents: parents.len(),
        rows: rows.len(),
    };
    bonds.replace_rows(&body, &rows);
    report
}

/// Each parent's four children: reference positions (19) and current positions (18) with the
/// parent's normal stretches.
fn placements(
    parents: &[u32],
    nodes: &Nodes<2>,
    columns: &SplitColumns,
    bonds: &DualBonds,
    material: &OsbMaterial,
) -> Vec<Placement> {
    let body = Body {
        reference: nodes.reference(),
        volumes: nodes.volumes(),
        constants: nodes.fields.get(columns.constants),
        thickness: material.thickness,
    };
    let positions = nodes.fields.get(columns.position);
    let spacing = nodes.fields.get(columns.spacing);
    parents
        .iter()
        .map(|&p| {
            let p = p as usize;
            let strain = bonds.normal_strains(p, &body, positions);
            let quarter = 0.25 * spacing[p];
            let (x, y) = (body.reference[p], positions[p]);
            let reference = SIGNS.map(|s| [x[0] + quarter * s[0], x[1] + quarter * s[1]]);
            let current = SIGNS.map(|s| {
                [
                    y[0] + quarter * (1.0 + strain[0]) * s[0],
                    y[1] + quarter * (1.0 + strain[1]) * s[1],
                ]
            });
            (reference, current)
        })
        .collect()
}

/// The old particles whose rows must be searched again because their horizon may reach one of
/// `parents`' children.
fn affected(
    parents: &[u32],
    nodes: &Nodes<2>,
    columns: &SplitColumns,
    buckets: &Buckets,
) -> Vec<bool> {
    // Old particles whose horizon may reach a child: a child lies √2 Δ_p/4 from its parent, so
    // particle k can see one only if |x_k − x_p| < δ_k + √2 Δ_p/4 (the bucket cell, at least
    // δ_max + Δ_p/2 wide, holds every candidate). The parents' own neighbors are among them.
    let mut affected = vec![false; nodes.len()];
    let reference = nodes.reference();
    let constants = nodes.fields.get(columns.constants);
    let spacing = nodes.fields.get(columns.spacing);
    for &p in parents {
        let x = reference[p as usize];
        let offset = std::f64::consts::SQRT_2 * 0.25 * spacing[p as usize];
        buckets.within(reference, &x, buckets.cell(), |j| {
            let (k, y) = (j as usize, reference[j as usize]);
            let reach = constants[k].horizon + offset;
            if (y[0] - x[0]).powi(2) + (y[1] - x[1]).powi(2) < reach * reach {
                affected[k] = true;
            }
        });
    }
    affected
}
