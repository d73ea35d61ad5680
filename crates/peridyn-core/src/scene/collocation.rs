//! The WLS collocation rule a scene asks for (seed-004 §2.2, Remark 2; issue 14): where a
//! node's collocation targets lie and the fit's weight exponent. `scheme::wls` selects the
//! family nodes nearest to these targets and fits on them.

/// The exponent a = 16 of the papers' weight (3.26).
pub const PAPERS_WEIGHT_EXPONENT: f64 = 16.0;

/// Largest number of symmetric orbits in an [`Collocation`] template.
pub const MAX_ORBITS: usize = 8;

/// How a WLS node's collocation targets are laid out (seed-004 §2.2, Remark 2).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Targets {
    /// The papers' auxiliary grid of spacing δ/k_aux, its points within the ball.
    Grid(usize),
    /// 2D only: whole orbits of lattice offsets (a, b) under the square's symmetries (±a, ±b),
    /// (±b, ±a), in units of `spacing` (the lattice spacing Δx). A choice outside the papers
    /// (issue 14): a wide stencil whose offsets still generate the lattice, so that its
    /// stable step approaches the standard scheme's without decoupled sub-lattices.
    Orbits {
        spacing: f64,
        orbits: [[u8; 2]; MAX_ORBITS],
        count: usize,
    },
}

/// A collocation rule: where the targets lie, and the fit's weight exponent.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Collocation {
    pub targets: Targets,
    /// Exponent a of the weight exp(−a d²/r̄²) (the papers: 16).
    pub weight_exponent: f64,
}

impl From<usize> for Collocation {
    /// The papers' auxiliary grid δ/k_aux.
    fn from(k_aux: usize) -> Self {
        Collocation::grid(k_aux)
    }
}

impl Collocation {
    /// The papers' rule: auxiliary grid δ/k_aux, weight (3.26).
    pub fn grid(k_aux: usize) -> Self {
        Collocation {
            targets: Targets::Grid(k_aux),
            weight_exponent: PAPERS_WEIGHT_EXPONENT,
        }
    }

    /// The auxiliary grid's factor, if the rule is the papers' grid.
    pub fn grid_factor(&self) -> Option<usize> {
        match self.targets {
            Targets::Grid(k) => Some(k),
            Targets::Orbits { .. } => None,
        }
    }

    /// Orbits of lattice offsets (each [a, b] with a, b ≥ 0, not both 0) with weight exponent a.
    pub fn orbits(spacing: f64, orbits: &[[u8; 2]], weight_exponent: f64) -> Result<Self, String> {
        if orbits.is_empty() || orbits.len() > MAX_ORBITS {
            return Err(format!(
                "needs 1 to {MAX_ORBITS} orbits [a, b], got {}",
                orbits.len()
            ));
        }
        if let Some(o) = orbits.iter().find(|o| o[0] == 0 && o[1] == 0) {
            return Err(format!(
                "orbit {o:?} is the node itself; give offsets (a, b) ≠ (0, 0)"
            ));
        }
        let mut fixed = [[0u8; 2]; MAX_ORBITS];
        fixed[..orbits.len()].copy_from_slice(orbits);
        Collocation {
            targets: Targets::Orbits {
                spacing,
                orbits: fixed,
                count: orbits.len(),
            },
            weight_exponent: PAPERS_WEIGHT_EXPONENT,
        }
        .with_weight(weight_exponent)
    }

    /// The same targets with the weight exponent a, which must lie in [0, 64].
    pub fn with_weight(self, weight_exponent: f64) -> Result<Self, String> {
        if !(weight_exponent.is_finite() && (0.0..=64.0).contains(&weight_exponent)) {
            return Err(format!(
                "the weight exponent must be in [0, 64] (the papers' is 16), got {weight_exponent}"
            ));
        }
        Ok(Collocation {
            weight_exponent,
            ..self
        })
    }

    /// The field (within its preset table) that chose this rule, for error messages.
    pub fn field(&self) -> &'static str {
        match self.targets {
            Targets::Grid(_) => "collocation_factor",
            Targets::Orbits { .. } => "collocation_orbits",
        }
    }

    /// The target offsets from the node (the node itself excluded), in a fixed order.
    pub(crate) fn target_offsets<const D: usize>(&self, horizon: f64) -> Vec<[f64; D]> {
        match self.targets {
            Targets::Grid(k_aux) => {
                let h = horizon / k_aux as f64;
                let k = k_aux as i64;
                let mut out = Vec::new();
                let mut index = [-k; D];
                'grid: loop {
                    let n2: i64 = index.iter().map(|v| v * v).sum();
                    if n2 > 0 && n2 <= k * k {
                        out.push(std::array::from_fn(|a| index[a] as f64 * h));
                    }
                    for v in index.iter_mut() {
                        *v += 1;
                        if *v <= k {
                            continue 'grid;
                        }
                        *v = -k;
                    }
                    break;
                }
                out
            }
            Targets::Orbits {
                spacing,
                orbits,
                count,
            } => {
                let mut out: Vec<[f64; D]> = Vec::new();
                for &[a, b] in &orbits[..count] {
                    let (a, b) = (a as f64, b as f64);
                    for (x, y) in [(a, b), (b, a)] {
                        for (sx, sy) in [(1.0, 1.0), (-1.0, 1.0), (1.0, -1.0), (-1.0, -1.0)] {
                            let mut p = [0.0; D];
                            p[0] = sx * x * spacing;
                            if D > 1 {
                                p[1] = sy * y * spacing;
                            }
                            if !out.contains(&p) {
                                out.push(p);
                            }
                        }
                    }
                }
                out
            }
        }
    }

    /// The spacing that sets the search cells and the tie tolerance.
    pub(crate) fn cell(&self, horizon: f64) -> f64 {
        match self.targets {
            Targets::Grid(k_aux) => horizon / k_aux as f64,
            Targets::Orbits { spacing, .. } => spacing,
        }
    }
}
