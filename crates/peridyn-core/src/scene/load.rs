//! Loading a scene: a preset by built-in name or file, its variant (and the variants it
//! extends) and `--set` overrides merged onto it, then parsed and validated.

use std::path::Path;

use super::builtin;
use super::error::{ErrorContext, SceneError, line_of};
use super::schema::Preset;
use super::validate::validate;
use super::validated::Scene;

impl Scene {
    /// Loads a preset by built-in name or file path.
    pub fn load(name_or_path: &str, variant: Option<&str>) -> Result<Scene, SceneError> {
        Scene::load_with(name_or_path, variant, &[])
    }

    /// Loads a preset and applies `key.path=value` overrides after the variant (values in TOML
    /// syntax; a bare word is taken as a string), e.g. `discretization.scheme=wls-2`.
    pub fn load_with(
        name_or_path: &str,
        variant: Option<&str>,
        overrides: &[String],
    ) -> Result<Scene, SceneError> {
        let (file, text) = Scene::read(name_or_path)?;
        let table = override_table(&file, overrides)?;
        let mut scene = Scene::from_text_with(&file, &text, variant, &table)?;
        scene.overrides = overrides.to_vec();
        Ok(scene)
    }

    /// The preset text of a built-in name or a file, and the name to report it under.
    pub fn read(name_or_path: &str) -> Result<(String, String), SceneError> {
        if let Some(text) = builtin::text(name_or_path) {
            return Ok((format!("builtin:{name_or_path}"), text.to_string()));
        }
        let path = Path::new(name_or_path);
        let text = std::fs::read_to_string(path).map_err(|e| SceneError {
            file: name_or_path.to_string(),
            field: String::new(),
            line: None,
            message: if path.exists() {
                format!("cannot read: {e}")
            } else {
                format!(
                    "no such preset file or built-in preset (built-ins: {})",
                    builtin::names().join(", ")
                )
            },
        })?;
        Ok((name_or_path.to_string(), text))
    }

    /// Parses and validates preset text; `file` names it in errors.
    pub fn from_text(file: &str, text: &str, variant: Option<&str>) -> Result<Scene, SceneError> {
        Scene::from_text_with(file, text, variant, &toml::Table::new())
    }

    /// As `from_text`, with `overrides` merged after the variant.
    pub fn from_text_with(
        file: &str,
        text: &str,
        variant: Option<&str>,
        overrides: &toml::Table,
    ) -> Result<Scene, SceneError> {
        let base_ctx = ErrorContext {
            file,
            text,
            variant: None,
        };
        let toml_error = |e: toml::de::Error, ctx: &ErrorContext| SceneError {
            file: file.to_string(),
            field: String::new(),
            line: e.span().map(|s| line_of(text, s.start)),
            message: match ctx.variant {
                Some(v) => format!("{} (variant `{v}`)", e.message().trim()),
                None => e.message().trim().to_string(),
            },
        };
        let base: Preset = toml::from_str(text).map_err(|e| toml_error(e, &base_ctx))?;
        let preset = if variant.is_none() && overrides.is_empty() {
            base
        } else {
            let ctx = ErrorContext {
                variant,
                ..base_ctx.clone()
            };
            let mut merged: toml::Table = text.parse().map_err(|e| toml_error(e, &ctx))?;
            merged.remove("variants");
            if let Some(v) = variant {
                for table in variant_chain(&base.variants, v, &ctx)? {
                    merge_tables(&mut merged, &table);
                }
            }
            merge_tables(&mut merged, overrides);
            toml::Value::Table(merged)
                .try_into()
                .map_err(|e: toml::de::Error| {
                    if overrides.is_empty() {
                        toml_error(e, &ctx)
                    } else {
                        override_error(file, overrides, e)
                    }
                })?
        };
        let ctx = ErrorContext {
            file,
            text,
            variant,
        };
        validate(&preset, &ctx, text, variant)
    }
}

/// `a.b=value` strings as a nested table; values in TOML syntax, bare words as strings.
pub fn override_table(file: &str, overrides: &[String]) -> Result<toml::Table, SceneError> {
    let mut table = toml::Table::new();
    for o in overrides {
        let bad = |message: String| SceneError {
            file: file.to_string(),
            field: o.split('=').next().unwrap_or_default().trim().to_string(),
            line: None,
            message,
        };
        let Some((key, value)) = o.split_once('=') else {
            return Err(bad(format!(
                "override `{o}`: write KEY=VALUE, e.g. discretization.scheme=wls-2"
            )));
        };
        let value = value.trim();
        let parsed = format!("v = {value}")
            .parse::<toml::Table>()
            .ok()
            .and_then(|mut t| t.remove("v"))
            .unwrap_or_else(|| toml::Value::String(value.to_string()));
        let keys: Vec<&str> = key.trim().split('.').collect();
        if keys.iter().any(|k| k.is_empty()) {
            return Err(bad(format!("override `{o}`: empty key segment")));
        }
        let mut node = toml::Value::Table(table.clone());
        let mut cursor = &mut node;
        for k in &keys[..keys.len() - 1] {
            let t = cursor
                .as_table_mut()
                .ok_or_else(|| bad(format!("override `{o}`: `{k}` is not a table")))?;
            cursor = t
                .entry(k.to_string())
                .or_insert_with(|| toml::Value::Table(toml::Table::new()));
        }
        cursor
            .as_table_mut()
            .ok_or_else(|| bad(format!("override `{o}`: not a table")))?
            .insert(keys[keys.len() - 1].to_string(), parsed);
        if let toml::Value::Table(t) = node {
            table = t;
        }
    }
    Ok(table)
}

fn override_error(file: &str, overrides: &toml::Table, e: toml::de::Error) -> SceneError {
    SceneError {
        file: file.to_string(),
        field: String::new(),
        line: None,
        message: format!("{} (with overrides {overrides})", e.message().trim()),
    }
}

/// The tables a variant overlays, outermost first: a variant with `extends = "other"` is
/// `other`'s overlay followed by its own (the `extends` key itself dropped); an unknown name or
/// a cycle is an error naming the variant.
fn variant_chain(
    variants: &std::collections::BTreeMap<String, toml::Table>,
    name: &str,
    ctx: &ErrorContext,
) -> Result<Vec<toml::Table>, SceneError> {
    let mut chain: Vec<toml::Table> = Vec::new();
    let mut seen: Vec<String> = Vec::new();
    let mut current = name.to_string();
    loop {
        if seen.contains(&current) {
            seen.push(current);
            return Err(ctx.error(
                &format!("variants.{name}.extends"),
                format!(
                    "the variants extend each other in a cycle: {}",
                    seen.join(" → ")
                ),
            ));
        }
        let field = match seen.last() {
            None => "variants".to_string(),
            Some(child) => format!("variants.{child}.extends"),
        };
        let table = variants.get(&current).ok_or_else(|| {
            let known: Vec<&str> = variants.keys().map(String::as_str).collect();
            ctx.error(
                &field,
                format!(
                    "no variant `{current}`; this preset has: {}",
                    known.join(", ")
                ),
            )
        })?;
        let mut own = table.clone();
        let parent = own.remove("extends");
        chain.push(own);
        seen.push(current);
        current = match parent {
            None => break,
            Some(toml::Value::String(p)) => p,
            Some(other) => {
                return Err(ctx.error(
                    &format!("{}.extends", field_of(&seen)),
                    format!("write the name of another variant as a string, not {other}"),
                ));
            }
        };
    }
    chain.reverse();
    Ok(chain)
}

fn field_of(seen: &[String]) -> String {
    format!("variants.{}", seen.last().map_or("", String::as_str))
}

/// Overlays a variant (or `--set` overrides) on the base table: tables merge key by key,
/// other values replace; `key = false` over a table removes it (a variant without the base's
/// `[multigrid]`, say).
fn merge_tables(base: &mut toml::Table, overrides: &toml::Table) {
    for (key, value) in overrides {
        match (base.get_mut(key), value) {
            (Some(toml::Value::Table(b)), toml::Value::Table(o)) => merge_tables(b, o),
            (Some(toml::Value::Table(_)), toml::Value::Boolean(false)) => {
                base.remove(key);
            }
            _ => {
                base.insert(key.clone(), value.clone());
            }
        }
    }
}
