//! Solid geometry of a scene: boxes, discs/spheres, cylinders and their unions and differences.
//! Coordinates are SI lengths; a shape is evaluated by point membership only.

use serde::Deserialize;

use super::units::Quantity;

/// A point given component by component, each component a length.
pub type Point = Vec<Quantity>;

#[derive(Debug, Clone, Deserialize)]
#[serde(rename_all = "snake_case", deny_unknown_fields)]
pub enum Shape {
    /// Axis-aligned box (interval in 1D, rectangle in 2D).
    Box {
        min: Point,
        max: Point,
    },
    /// Disc (2D) or ball (3D).
    Sphere {
        center: Point,
        radius: Quantity,
    },
    /// 3D cylinder from `base` along `axis` (any direction) over `length`; in 2D a rectangle
    /// of width 2·radius around the segment.
    Cylinder {
        base: Point,
        axis: Point,
        radius: Quantity,
        length: Quantity,
    },
    Union(Vec<Shape>),
    Difference {
        base: std::boxed::Box<Shape>,
        minus: Vec<Shape>,
    },
}

/// A shape converted to plain f64 coordinates of a fixed dimension.
#[derive(Debug, Clone)]
pub enum Solid {
    Box {
        min: Vec<f64>,
        max: Vec<f64>,
    },
    Sphere {
        center: Vec<f64>,
        radius: f64,
    },
    Cylinder {
        base: Vec<f64>,
        unit_axis: Vec<f64>,
        radius: f64,
        length: f64,
    },
    Union(Vec<Solid>),
    Difference {
        base: std::boxed::Box<Solid>,
        minus: Vec<Solid>,
    },
}

pub fn si(point: &[Quantity]) -> Vec<f64> {
    point.iter().map(|q| q.si()).collect()
}

impl Shape {
    /// Checks dimensions and sizes; `path` names the field for error messages.
    pub fn to_solid(&self, dim: usize, path: &str) -> Result<Solid, String> {
        let point = |p: &Point, name: &str| -> Result<Vec<f64>, String> {
            if p.len() != dim {
                return Err(format!(
                    "{path}.{name}: has {} components, the scene is {dim}-dimensional",
                    p.len()
                ));
            }
            Ok(si(p))
        };
        let positive = |q: Quantity, name: &str| -> Result<f64, String> {
            if q.si() > 0.0 && q.si().is_finite() {
                Ok(q.si())
            } else {
                Err(format!("{path}.{name}: must be > 0, got {}", q.si()))
            }
        };
        Ok(match self {
            Shape::Box { min, max } => {
                let (lo, hi) = (point(min, "min")?, point(max, "max")?);
                if lo.iter().zip(&hi).any(|(a, b)| a >= b) {
                    return Err(format!("{path}: min must be below max in every component"));
                }
                Solid::Box { min: lo, max: hi }
            }
            Shape::Sphere { center, radius } => Solid::Sphere {
                center: point(center, "center")?,
                radius: positive(*radius, "radius")?,
            },
            Shape::Cylinder {
                base,
                axis,
                radius,
                length,
            } => {
                let a = point(axis, "axis")?;
                let norm = a.iter().map(|v| v * v).sum::<f64>().sqrt();
                if norm == 0.0 {
                    return Err(format!("{path}.axis: must not be zero"));
                }
                Solid::Cylinder {
                    base: point(base, "base")?,
                    unit_axis: a.iter().map(|v| v / norm).collect(),
                    radius: positive(*radius, "radius")?,
                    length: positive(*length, "length")?,
                }
            }
            Shape::Union(parts) => Solid::Union(
                parts
                    .iter()
                    .enumerate()
                    .map(|(i, s)| s.to_solid(dim, &format!("{path}.union[{i}]")))
                    .collect::<Result<_, _>>()?,
            ),
            Shape::Difference { base, minus } => Solid::Difference {
                base: std::boxed::Box::new(base.to_solid(dim, &format!("{path}.difference.base"))?),
                minus: minus
                    .iter()
                    .enumerate()
                    .map(|(i, s)| s.to_solid(dim, &format!("{path}.difference.minus[{i}]")))
                    .collect::<Result<_, _>>()?,
            },
        })
    }
}

impl Solid {
    /// Point membership with a small tolerance `eps` so lattice nodes on faces are inside.
    pub fn contains(&self, x: &[f64], eps: f64) -> bool {
        match self {
            Solid::Box { min, max } => x
                .iter()
                .zip(min.iter().zip(max))
                .all(|(v, (lo, hi))| *v >= lo - eps && *v <= hi + eps),
            Solid::Sphere { center, radius } => dist2(x, center) <= (radius + eps) * (radius + eps),
            Solid::Cylinder {
                base,
                unit_axis,
                radius,
                length,
            } => {
                let rel: Vec<f64> = x.iter().zip(base).map(|(a, b)| a - b).collect();
                let along: f64 = rel.iter().zip(unit_axis).map(|(a, b)| a * b).sum();
                let radial2 = rel.iter().map(|v| v * v).sum::<f64>() - along * along;
                along >= -eps && along <= length + eps && radial2 <= (radius + eps) * (radius + eps)
            }
            Solid::Union(parts) => parts.iter().any(|s| s.contains(x, eps)),
            Solid::Difference { base, minus } => {
                base.contains(x, eps) && !minus.iter().any(|s| s.contains(x, -eps))
            }
        }
    }

    /// Axis-aligned bounding box (min, max).
    pub fn bounds(&self) -> (Vec<f64>, Vec<f64>) {
        match self {
            Solid::Box { min, max } => (min.clone(), max.clone()),
            Solid::Sphere { center, radius } => (
                center.iter().map(|c| c - radius).collect(),
                center.iter().map(|c| c + radius).collect(),
            ),
            Solid::Cylinder {
                base,
                unit_axis,
                radius,
                length,
            } => {
                let top: Vec<f64> = base
                    .iter()
                    .zip(unit_axis)
                    .map(|(b, a)| b + a * length)
                    .collect();
                (
                    base.iter()
                        .zip(&top)
                        .map(|(a, b)| a.min(*b) - radius)
                        .collect(),
                    base.iter()
                        .zip(&top)
                        .map(|(a, b)| a.max(*b) + radius)
                        .collect(),
                )
            }
            Solid::Union(parts) => {
                let mut it = parts.iter().map(Solid::bounds);
                let first = it.next().unwrap_or_default();
                it.fold(first, |(lo, hi), (l, h)| {
                    (
                        lo.iter().zip(&l).map(|(a, b)| a.min(*b)).collect(),
                        hi.iter().zip(&h).map(|(a, b)| a.max(*b)).collect(),
                    )
                })
            }
            Solid::Difference { base, .. } => base.bounds(),
        }
    }
}

fn dist2(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| (x - y) * (x - y)).sum()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn q(v: &[f64]) -> Point {
        v.iter().map(|&x| Quantity(x)).collect()
    }

    #[test]
    fn membership_of_composites() {
        let plate_with_hole = Shape::Difference {
            base: std::boxed::Box::new(Shape::Box {
                min: q(&[0.0, 0.0]),
                max: q(&[2.0, 1.0]),
            }),
            minus: vec![Shape::Sphere {
                center: q(&[1.0, 0.5]),
                radius: Quantity(0.25),
            }],
        };
        let solid = plate_with_hole.to_solid(2, "geometry").unwrap();
        assert!(solid.contains(&[0.1, 0.1], 1e-9));
        assert!(solid.contains(&[2.0, 1.0], 1e-9));
        assert!(!solid.contains(&[1.0, 0.5], 1e-9));
        assert!(!solid.contains(&[2.1, 0.5], 1e-9));
        let cyl = Shape::Cylinder {
            base: q(&[0.0, 0.0, 0.0]),
            axis: q(&[0.0, 0.0, 2.0]),
            radius: Quantity(0.5),
            length: Quantity(1.0),
        }
        .to_solid(3, "g")
        .unwrap();
        assert!(cyl.contains(&[0.3, 0.3, 0.9], 0.0));
        assert!(!cyl.contains(&[0.3, 0.3, 1.1], 0.0));
        assert!(!cyl.contains(&[0.4, 0.4, 0.5], 0.0));
        let (lo, hi) = cyl.bounds();
        assert_eq!(lo, vec![-0.5, -0.5, -0.5]);
        assert_eq!(hi, vec![0.5, 0.5, 1.5]);
    }

    #[test]
    fn wrong_dimension_is_named() {
        let err = Shape::Box {
            min: q(&[0.0]),
            max: q(&[1.0, 1.0]),
        }
        .to_solid(2, "geometry")
        .unwrap_err();
        assert!(err.contains("geometry.min"), "{err}");
    }
}
