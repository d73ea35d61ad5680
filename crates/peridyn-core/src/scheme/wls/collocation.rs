//! Collocation sets of the WLS scheme (thesis §3.2.3; seed-thesis-ch2-3 §3.3): the nodes
//! each row fits over, chosen from the family by the scene's collocation rule.

use super::*;

/// Collocation set of a node (seed-thesis-ch2-3 §3.1, seed-004 §2.2): for each point of an
/// auxiliary grid of spacing δ/k_aux centred at the node and inside the ball, the nearest family
/// node (the node itself included) not already chosen; ties go to the lower index. The node itself
/// comes first.
pub fn collocation_set<const D: usize>(
    i: usize,
    positions: &[[f64; D]],
    families: &Families,
    horizon: f64,
    rule: impl Into<Collocation>,
) -> Vec<u32> {
    let rule: Collocation = rule.into();
    let candidates = collocation_candidates(i, families);
    select_collocation_set(i, &candidates, positions, horizon, rule)
}

/// A node's collocation candidates: itself and its family, in index order.
pub(super) fn collocation_candidates(i: usize, families: &Families) -> Vec<u32> {
    let mut candidates: Vec<u32> = families.range(i).map(|b| families.neighbors[b]).collect();
    // Families are kept in index order: the node goes in at its place.
    if candidates.is_sorted() {
        candidates.insert(candidates.partition_point(|&j| j < i as u32), i as u32);
    } else {
        candidates.push(i as u32);
        candidates.sort_unstable();
    }
    candidates
}

/// [`collocation_set`] among given `candidates` (in index order, the node included).
pub(super) fn select_collocation_set<const D: usize>(
    i: usize,
    candidates: &[u32],
    positions: &[[f64; D]],
    horizon: f64,
    rule: Collocation,
) -> Vec<u32> {
    let h = rule.cell(horizon);
    let mut chosen = vec![i as u32];
    let mut taken = vec![false; candidates.len()];
    if let Ok(self_slot) = candidates.binary_search(&(i as u32)) {
        taken[self_slot] = true;
    }
    // Candidates bucketed by their offset rounded to cells of side h: a target's nearest
    // candidate is searched in the 3^D cells around it first. Anything outside them is at
    // least 1.5 h away on some axis, so a hit closer than that is the exact nearest (ties
    // included); otherwise the whole family is scanned.
    // Dense buckets (a head per cell, a chain through `next`), cells within reach of the node.
    let reach = (horizon / h).ceil() as i64 + 2;
    let side = (2 * reach + 1) as usize;
    let cell_index = |cell: [i64; D]| -> Option<usize> {
        cell.iter().try_fold(0usize, |acc, &c| {
            (c.abs() <= reach).then(|| acc * side + (c + reach) as usize)
        })
    };
    let mut head = vec![usize::MAX; side.pow(D as u32)];
    let mut next = vec![usize::MAX; candidates.len()];
    for (slot, &j) in candidates.iter().enumerate() {
        let cell: [i64; D] = std::array::from_fn(|a| {
            ((positions[j as usize][a] - positions[i][a]) / h).round() as i64
        });
        if let Some(c) = cell_index(cell) {
            next[slot] = head[c];
            head[c] = slot;
        }
    }
    let distance2 = |slot: usize, target: &[f64; D]| -> f64 {
        let j = candidates[slot] as usize;
        (0..D).map(|a| (positions[j][a] - target[a]).powi(2)).sum()
    };
    let closer = |a: &(f64, usize), b: &(f64, usize)| nearer(a, b, h);
    let exact_within = (1.5 * h).powi(2);
    for offset in rule.target_offsets::<D>(horizon) {
        let target: [f64; D] = std::array::from_fn(|a| positions[i][a] + offset[a]);
        let centre: [i64; D] = std::array::from_fn(|a| (offset[a] / h).round() as i64);
        let mut near: Option<(f64, usize)> = None;
        for code in 0..3usize.pow(D as u32) {
            let mut c = code;
            let cell: [i64; D] = std::array::from_fn(|a| {
                let v = centre[a] + (c % 3) as i64 - 1;
                c /= 3;
                v
            });
            let mut slot = cell_index(cell).map_or(usize::MAX, |c| head[c]);
            while slot != usize::MAX {
                if !taken[slot] {
                    let cand = (distance2(slot, &target), slot);
                    if near.is_none_or(|n| closer(&cand, &n).is_lt()) {
                        near = Some(cand);
                    }
                }
                slot = next[slot];
            }
        }
        let best = near.filter(|n| n.0 < exact_within).or_else(|| {
            (0..candidates.len())
                .filter(|&slot| !taken[slot])
                .map(|slot| (distance2(slot, &target), slot))
                .min_by(closer)
        });
        if let Some((_, slot)) = best {
            taken[slot] = true;
            chosen.push(candidates[slot]);
        }
    }
    chosen
}

/// Collocation sets of `rows` (in parallel), each equal to [`collocation_set`]. On a uniform
/// lattice most rows are translates of each other: a row whose candidates (node and family in
/// index order) have, slot by slot, the offsets of the first largest row's candidates to
/// 10⁻¹² δ gets that row's choice of slots without a search. The choice depends only on the
/// offsets and the slot order (ties go to the lower slot), so it is the same set; any other
/// row (boundaries, holes, perturbed lattices) is searched in full.
pub fn collocation_sets<const D: usize>(
    rows: &[u32],
    positions: &[[f64; D]],
    families: &Families,
    horizon: f64,
    rule: impl Into<Collocation>,
) -> Vec<Vec<u32>> {
    let rule: Collocation = rule.into();
    collocation_sets_counted(rows, positions, families, horizon, rule).0
}

/// [`collocation_sets`] and how many rows took the translated template.
pub(super) fn collocation_sets_counted<const D: usize>(
    rows: &[u32],
    positions: &[[f64; D]],
    families: &Families,
    horizon: f64,
    rule: Collocation,
) -> (Vec<Vec<u32>>, usize) {
    use rayon::prelude::*;
    let largest = rows.iter().map(|&i| i as usize).reduce(|a, b| {
        if families.range(b).len() > families.range(a).len() {
            b
        } else {
            a
        }
    });
    let Some(t) = largest else {
        return (Vec::new(), 0);
    };
    let template = collocation_candidates(t, families);
    let offset = |i: usize, j: u32| -> [f64; D] {
        std::array::from_fn(|a| positions[j as usize][a] - positions[i][a])
    };
    let template_offsets: Vec<[f64; D]> = template.iter().map(|&j| offset(t, j)).collect();
    let template_slots: Vec<usize> = select_collocation_set(t, &template, positions, horizon, rule)
        .iter()
        .filter_map(|j| template.binary_search(j).ok())
        .collect();
    let tolerance = 1e-12 * horizon;
    let sets: Vec<(Vec<u32>, bool)> = rows
        .par_iter()
        .map(|&i| {
            let i = i as usize;
            let candidates = collocation_candidates(i, families);
            let translated = candidates.len() == template.len()
                && candidates.iter().zip(&template_offsets).all(|(&j, o)| {
                    let d = offset(i, j);
                    (0..D).all(|a| (d[a] - o[a]).abs() <= tolerance)
                });
            let set = if translated {
                template_slots.iter().map(|&s| candidates[s]).collect()
            } else {
                select_collocation_set(i, &candidates, positions, horizon, rule)
            };
            (set, translated)
        })
        .collect();
    let translated = sets.iter().filter(|(_, t)| *t).count();
    (sets.into_iter().map(|(set, _)| set).collect(), translated)
}

/// Order of two (squared distance, slot) candidates of a collocation target on an auxiliary
/// grid of spacing h. Distances equal to 10⁻¹⁰ h² are ties, and ties go to the lower slot (the
/// lower node index): on a uniform lattice the geometric ties then break the same way at every
/// node, whatever the rounding of its absolute coordinates, so translated nodes get translated
/// collocation sets in the same order (one shared stencil, and the product's fast runs).
pub(super) fn nearer(a: &(f64, usize), b: &(f64, usize), h: f64) -> std::cmp::Ordering {
    if (a.0 - b.0).abs() <= 1e-10 * h * h {
        a.1.cmp(&b.1)
    } else {
        a.0.total_cmp(&b.0)
    }
}
