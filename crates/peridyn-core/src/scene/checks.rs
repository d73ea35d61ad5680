//! The checks every preset table shares, in one place: numbers in a range or > 0, lengths
//! relative to the spacing or horizon, points and axes of the scene's dimension, arrays of
//! tables, and the ranges of the parameters a live command may change too (χ, φ_c, α). Each
//! names the field it refused; the feature validators call them and none of them is imported
//! here.

use super::error::{ErrorContext, SceneError};
use super::geometry::{Point, si};
use super::units::{Measure, Relative};

/// χ where a preset does not set it (the thesis's switching margin, seed-thesis-ch2-3 §8.3).
pub const DEFAULT_CHI: f64 = 0.95;

/// The one check of the switching margin χ of (3.80), wherever it is set (preset, command,
/// running simulation): it must lie in (0, 1].
pub fn check_chi(chi: f64) -> Result<f64, String> {
    if chi.is_finite() && chi > 0.0 && chi <= 1.0 {
        Ok(chi)
    } else {
        Err(format!("χ must be in (0, 1], got {chi}"))
    }
}

/// φ_c of (15), wherever it is set: it must lie in [0, 1).
pub fn check_split_damage(phi: f64) -> Result<f64, String> {
    if (0.0..1.0).contains(&phi) {
        Ok(phi)
    } else {
        Err(format!("φ_c must lie in [0, 1), got {phi}"))
    }
}

/// α of (16), wherever it is set: it must lie in (0, 1).
pub fn check_split_strain(alpha: f64) -> Result<f64, String> {
    if alpha > 0.0 && alpha < 1.0 {
        Ok(alpha)
    } else {
        Err(format!("α must lie in (0, 1), got {alpha}"))
    }
}

/// A finite number > 0.
pub(super) fn positive(ctx: &ErrorContext, field: &str, v: f64) -> Result<f64, SceneError> {
    if v > 0.0 && v.is_finite() {
        Ok(v)
    } else {
        Err(ctx.error(field, format!("must be a finite number > 0, got {v}")))
    }
}

/// A finite number in `range` (`ok` says whether it is), or an error naming the range.
pub(super) fn in_range(
    ctx: &ErrorContext,
    field: &str,
    v: f64,
    ok: bool,
    range: &str,
) -> Result<f64, SceneError> {
    if ok && v.is_finite() {
        Ok(v)
    } else {
        Err(ctx.error(field, format!("must be in {range}, got {v}")))
    }
}

/// A length given in SI units or relative to the horizon or spacing.
pub(super) fn length(
    ctx: &ErrorContext,
    field: &str,
    m: Measure,
    spacing: f64,
    horizon: f64,
) -> Result<f64, SceneError> {
    match m {
        Measure::Si(b) => Ok(b),
        Measure::Relative(f, Relative::Horizon) => Ok(f * horizon),
        Measure::Relative(f, Relative::Spacing) => Ok(f * spacing),
        Measure::Relative(_, r) => Err(ctx.error(
            field,
            format!(
                "`{}` is not a length: give \"1.2 horizon\", \"5 dx\" or \"3 mm\"",
                r.unit()
            ),
        )),
    }
}

/// A point (or vector) with one component per dimension, in SI units.
pub(super) fn point(p: &Point, dim: usize, path: &str) -> Result<Vec<f64>, String> {
    if p.len() != dim {
        return Err(format!(
            "{path}: has {} components, the scene is {dim}-dimensional",
            p.len()
        ));
    }
    Ok(si(p))
}

/// A point as an array, for the parts defined in one dimension only (`N` = `dim`).
pub(super) fn fixed<const N: usize>(p: &Point, dim: usize, path: &str) -> Result<[f64; N], String> {
    let v = point(p, dim, path)?;
    let mut out = [0.0; N];
    out.copy_from_slice(&v);
    Ok(out)
}

/// An axis by name (`"x"`, `"y"`, `"z"`) that the scene's dimension has.
pub(super) fn axis_index(name: &str, dim: usize, path: &str) -> Result<usize, String> {
    let i = match name {
        "x" => 0,
        "y" => 1,
        "z" => 2,
        _ => {
            return Err(format!(
                "{path}: must be \"x\", \"y\" or \"z\", got \"{name}\""
            ));
        }
    };
    if i >= dim {
        return Err(format!("{path}: axis \"{name}\" does not exist in {dim}D"));
    }
    Ok(i)
}

/// Every entry of an array of tables (`table[i]`): `check` gets an entry and its path and answers
/// with a `path.field: message` error, which is located in the preset.
pub(super) fn each<T, U>(
    ctx: &ErrorContext,
    table: &str,
    entries: &[T],
    check: impl Fn(&T, &str) -> Result<U, String>,
) -> Result<Vec<U>, SceneError> {
    entries
        .iter()
        .enumerate()
        .map(|(i, entry)| check(entry, &format!("{table}[{i}]")))
        .collect::<Result<Vec<_>, _>>()
        .map_err(|m| ctx.from_path_message(&m))
}
