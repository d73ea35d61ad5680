//! Physical quantities in presets: a bare number is SI, a string carries its unit ("2 mm",
//! "190 GPa", "8000 kg/m^3", "16.5 m/s", "2 ns"). Everything is converted to SI on parsing.

use serde::{Deserialize, Deserializer};

/// A preset value as written: a number or a string with a unit.
#[derive(Deserialize)]
#[serde(untagged)]
enum Raw {
    Number(f64),
    Integer(i64),
    Text(String),
}

/// A scalar already converted to SI units.
#[derive(Debug, Clone, Copy, PartialEq, PartialOrd)]
pub struct Quantity(pub f64);

impl Quantity {
    pub fn si(self) -> f64 {
        self.0
    }
}

impl<'de> Deserialize<'de> for Quantity {
    fn deserialize<D: Deserializer<'de>>(deserializer: D) -> Result<Self, D::Error> {
        match Raw::deserialize(deserializer)? {
            Raw::Number(v) => Ok(Quantity(v)),
            Raw::Integer(v) => Ok(Quantity(v as f64)),
            Raw::Text(text) => parse_quantity(&text)
                .map(Quantity)
                .map_err(serde::de::Error::custom),
        }
    }
}

/// Parses "value unit-expression", e.g. "22.17 N/mm" or "8e-9 t/mm^3", into SI.
pub fn parse_quantity(text: &str) -> Result<f64, String> {
    let text = text.trim();
    let split = text
        .char_indices()
        .find(|&(i, c)| {
            c.is_alphabetic() && !(c == 'e' || c == 'E') || (c == ' ' && i > 0) || c == 'µ'
        })
        .map(|(i, _)| i)
        .unwrap_or(text.len());
    let (number, unit) = text.split_at(split);
    let value: f64 = number
        .trim()
        .parse()
        .map_err(|_| format!("`{text}` is not a number followed by a unit (e.g. \"2 mm\")"))?;
    Ok(value * unit_factor(unit.trim())?)
}

/// SI factor of a unit expression: products and quotients of prefixed units with integer powers.
fn unit_factor(expr: &str) -> Result<f64, String> {
    if expr.is_empty() {
        return Ok(1.0);
    }
    let mut factor = 1.0;
    let mut dividing = false;
    let mut token = String::new();
    let flush = |token: &mut String, factor: &mut f64, dividing: bool| -> Result<(), String> {
        if token.is_empty() {
            return Ok(());
        }
        let f = power_factor(token)?;
        *factor = if dividing { *factor / f } else { *factor * f };
        token.clear();
        Ok(())
    };
    for c in expr.chars() {
        match c {
            '/' => {
                flush(&mut token, &mut factor, dividing)?;
                dividing = true;
            }
            '*' | '·' | ' ' => flush(&mut token, &mut factor, dividing)?,
            _ => token.push(c),
        }
    }
    flush(&mut token, &mut factor, dividing)?;
    Ok(factor)
}

fn power_factor(token: &str) -> Result<f64, String> {
    let (base, power) = match token.split_once('^') {
        Some((b, p)) => (
            b,
            p.parse::<i32>()
                .map_err(|_| format!("bad power `{p}` in unit `{token}`"))?,
        ),
        None => match token.strip_suffix(['2', '3']) {
            Some(b) if !b.is_empty() => (b, token[b.len()..].parse::<i32>().unwrap_or(1)),
            _ => (token, 1),
        },
    };
    Ok(single_unit(base)?.powi(power))
}

const BASE_UNITS: &[(&str, f64)] = &[
    ("m", 1.0),
    ("s", 1.0),
    ("g", 1e-3),
    ("t", 1e3),
    ("N", 1.0),
    ("Pa", 1.0),
    ("J", 1.0),
    ("W", 1.0),
    ("mol", 1.0),
    ("K", 1.0),
    ("C", 1.0),
    ("V", 1.0),
    ("A", 1.0),
    ("S", 1.0),
    ("h", 3600.0),
    ("min", 60.0),
    ("d", 86400.0),
    ("L", 1e-3),
];

const PREFIXES: &[(&str, f64)] = &[
    ("n", 1e-9),
    ("u", 1e-6),
    ("µ", 1e-6),
    ("m", 1e-3),
    ("c", 1e-2),
    ("d", 1e-1),
    ("k", 1e3),
    ("M", 1e6),
    ("G", 1e9),
    ("T", 1e12),
];

fn single_unit(name: &str) -> Result<f64, String> {
    if let Some(&(_, f)) = BASE_UNITS.iter().find(|(n, _)| *n == name) {
        return Ok(f);
    }
    for (prefix, pf) in PREFIXES {
        if let Some(rest) = name.strip_prefix(prefix)
            && let Some(&(_, f)) = BASE_UNITS.iter().find(|(n, _)| *n == rest)
        {
            return Ok(pf * f);
        }
    }
    Err(format!(
        "unknown unit `{name}` (known: m, s, g, t, N, Pa, J, mol, K, with prefixes n u µ m c k M G)"
    ))
}

#[cfg(test)]
mod tests {
    use super::parse_quantity;

    fn close(a: f64, b: f64) -> bool {
        (a - b).abs() <= 1e-12 * b.abs().max(1e-300)
    }

    #[test]
    fn parses_common_units() {
        assert!(close(parse_quantity("2 mm").unwrap(), 2e-3));
        assert!(close(parse_quantity("190 GPa").unwrap(), 190e9));
        assert!(close(parse_quantity("190e3 N/mm^2").unwrap(), 190e9));
        assert!(close(parse_quantity("8000 kg/m^3").unwrap(), 8000.0));
        assert!(close(parse_quantity("8e-9 t/mm^3").unwrap(), 8000.0));
        assert!(close(parse_quantity("22.17 N/mm").unwrap(), 22170.0));
        assert!(close(parse_quantity("0.02217 J/mm^2").unwrap(), 22170.0));
        assert!(close(parse_quantity("16.5 m/s").unwrap(), 16.5));
        assert!(close(parse_quantity("2 ns").unwrap(), 2e-9));
        assert!(close(parse_quantity("87 µs").unwrap(), 87e-6));
        assert!(close(parse_quantity("87us").unwrap(), 87e-6));
        assert!(close(parse_quantity("1.5e-3").unwrap(), 1.5e-3));
    }

    #[test]
    fn rejects_unknown_units() {
        assert!(parse_quantity("3 furlongs").is_err());
        assert!(parse_quantity("mm").is_err());
    }
}

/// What a relative amount is measured in.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Relative {
    /// "4 dx": multiples of the lattice spacing.
    Spacing,
    /// "0.5 stable": a fraction of the stable time step.
    StableStep,
    /// "2000 steps": a number of time steps.
    Steps,
    /// "1 horizon": multiples of the horizon δ.
    Horizon,
}

impl Relative {
    pub fn unit(self) -> &'static str {
        match self {
            Relative::Spacing => "dx",
            Relative::StableStep => "stable",
            Relative::Steps => "steps",
            Relative::Horizon => "horizon",
        }
    }
}

/// A quantity in SI units or relative to the discretization: "2 mm" or "8 dx"; "2 ns" or
/// "0.5 stable"; "87 us" or "2000 steps". One field per concept, so a variant can switch
/// between the two forms by overriding a single key.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Measure {
    Si(f64),
    Relative(f64, Relative),
}

impl<'de> Deserialize<'de> for Measure {
    fn deserialize<D: Deserializer<'de>>(deserializer: D) -> Result<Self, D::Error> {
        match Raw::deserialize(deserializer)? {
            Raw::Number(v) => Ok(Measure::Si(v)),
            Raw::Integer(v) => Ok(Measure::Si(v as f64)),
            Raw::Text(text) => parse_measure(&text).map_err(serde::de::Error::custom),
        }
    }
}

pub fn parse_measure(text: &str) -> Result<Measure, String> {
    for relative in [
        Relative::Spacing,
        Relative::StableStep,
        Relative::Steps,
        Relative::Horizon,
    ] {
        if let Some(number) = text.trim().strip_suffix(relative.unit()) {
            let value = number.trim().parse().map_err(|_| {
                format!("`{text}` is not a number followed by `{}`", relative.unit())
            })?;
            return Ok(Measure::Relative(value, relative));
        }
    }
    parse_quantity(text).map(Measure::Si)
}

#[cfg(test)]
mod measure_tests {
    use super::*;

    #[test]
    fn relative_and_absolute_measures() {
        assert_eq!(
            parse_measure("8 dx").unwrap(),
            Measure::Relative(8.0, Relative::Spacing)
        );
        assert_eq!(
            parse_measure("0.5 stable").unwrap(),
            Measure::Relative(0.5, Relative::StableStep)
        );
        assert_eq!(
            parse_measure("2000 steps").unwrap(),
            Measure::Relative(2000.0, Relative::Steps)
        );
        assert_eq!(parse_measure("2 ns").unwrap(), Measure::Si(2e-9));
        assert!(parse_measure("x steps").is_err());
    }
}
