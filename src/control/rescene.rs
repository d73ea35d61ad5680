//! The scene of a run: the preset as given, with the discretization the commands chose
//! (`Discretization`, defined here and held by `state`). The choices are merged into the preset
//! text (into the chosen variant's table) and the result goes through the full validation again
//! (units, sizes, memory), so a bad choice is refused with the same messages as a bad preset.

use crate::scene::{Scene, SceneError};

/// The discretization choices that need a rebuild.
#[derive(Debug, Clone, PartialEq)]
pub struct Discretization {
    /// Horizon factor m = δ/Δx.
    pub m: f64,
    /// Lattice spacing Δx (m).
    pub dx: f64,
    pub scheme: String,
    /// Grid ratio Δx⁺/Δx⁻ of a multi-grid scene (None: one grid).
    pub ratio: Option<usize>,
    /// A fine region Ω⁻ chosen live (`multigrid.region` as an inline TOML table; None: the
    /// preset's own).
    pub region: Option<String>,
    /// An initial fine band chosen live (`multigrid.band`; None: the preset's own).
    pub band: Option<String>,
}

/// The discretization a scene was built with (m = δ/Δx; the scheme by its preset name).
pub fn discretization_of(scene: &Scene) -> Discretization {
    let scheme = toml::from_str::<toml::Table>(&scene.preset_text)
        .ok()
        .and_then(|t| {
            let base = t
                .get("discretization")
                .and_then(|d| d.get("scheme"))
                .and_then(|s| s.as_str().map(String::from));
            let variant = scene.variant.as_ref().and_then(|v| {
                t.get("variants")?
                    .get(v)?
                    .get("discretization")?
                    .get("scheme")?
                    .as_str()
                    .map(String::from)
            });
            variant.or(base)
        })
        .unwrap_or_else(|| "standard".into());
    Discretization {
        m: scene.horizon / scene.spacing,
        dx: scene.spacing,
        scheme,
        ratio: scene.multigrid.as_ref().map(|g| g.ratio),
        region: None,
        band: None,
    }
}

/// `base` rebuilt with `choice` wherever it differs from `base`'s own discretization.
pub fn with_discretization(base: &Scene, choice: &Discretization) -> Result<Scene, SceneError> {
    let own = discretization_of(base);
    let mut overrides = toml::Table::new();
    if choice.dx != own.dx {
        overrides.insert("spacing".into(), toml::Value::Float(choice.dx));
    }
    if choice.m != own.m || choice.dx != own.dx {
        overrides.insert("horizon".into(), format!("{:?} dx", choice.m).into());
    }
    if choice.scheme != own.scheme {
        overrides.insert("scheme".into(), choice.scheme.clone().into());
    }
    let ratio = choice.ratio.filter(|_| choice.ratio != own.ratio);
    let mut multigrid_overrides = toml::Table::new();
    if let Some(r) = ratio {
        multigrid_overrides.insert("ratio".into(), toml::Value::Integer(r as i64));
    }
    if let Some(band) = &choice.band {
        multigrid_overrides.insert("band".into(), band.clone().into());
    }
    if let Some(shape) = &choice.region {
        let parsed = toml::from_str::<toml::Table>(&format!("region = {shape}")).map_err(|e| {
            SceneError {
                file: base.source.clone(),
                field: "multigrid.region".into(),
                line: None,
                message: format!("`{shape}` is not an inline table: {e}"),
            }
        })?;
        multigrid_overrides.extend(parsed);
    }
    if overrides.is_empty() && multigrid_overrides.is_empty() {
        return Ok(base.clone());
    }
    let invalid = |message: String| SceneError {
        file: base.source.clone(),
        field: "discretization".into(),
        line: None,
        message,
    };
    let mut table: toml::Table = base
        .preset_text
        .parse()
        .map_err(|e: toml::de::Error| invalid(e.to_string()))?;
    let target = match &base.variant {
        Some(v) => table
            .get_mut("variants")
            .and_then(|t| t.get_mut(v))
            .and_then(|t| t.as_table_mut())
            .ok_or_else(|| invalid(format!("no variant `{v}`")))?,
        None => &mut table,
    };
    let discretization = target
        .entry("discretization")
        .or_insert_with(|| toml::Value::Table(toml::Table::new()));
    let Some(discretization) = discretization.as_table_mut() else {
        return Err(invalid("`discretization` is not a table".into()));
    };
    let mut changed: Vec<String> = overrides
        .keys()
        .map(|k| format!("discretization.{k}"))
        .collect();
    discretization.extend(overrides);
    if !multigrid_overrides.is_empty() {
        let multigrid = target
            .entry("multigrid")
            .or_insert_with(|| toml::Value::Table(toml::Table::new()));
        let Some(multigrid) = multigrid.as_table_mut() else {
            return Err(invalid("`multigrid` is not a table".into()));
        };
        changed.extend(multigrid_overrides.keys().map(|k| format!("multigrid.{k}")));
        multigrid.extend(multigrid_overrides);
    }
    let text = toml::to_string(&table).map_err(|e| invalid(e.to_string()))?;
    // `--set` overrides still apply, except those of the values this rebuild changes.
    let kept: Vec<String> = base
        .overrides
        .iter()
        .filter(|o| {
            !changed
                .iter()
                .any(|k| o.split('=').next().map(str::trim) == Some(k))
        })
        .cloned()
        .collect();
    let extra = crate::scene::override_table(&base.source, &kept)?;
    let mut scene = Scene::from_text_with(&base.source, &text, base.variant.as_deref(), &extra)?;
    scene.overrides = kept;
    // The preset as the user wrote it stays the recording's preset; the choices are stated
    // in the run's command log.
    scene.preset_text = base.preset_text.clone();
    // Settings made outside the preset (`--every`) carry over.
    scene.output_every = base.output_every;
    Ok(scene)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn choices_override_the_variant_and_keep_the_rest() {
        let base = Scene::load("kalthoff-winkler", Some("small")).unwrap();
        let own = discretization_of(&base);
        assert_eq!(own.m, 4.0);
        assert_eq!(own.dx, 1e-3);
        assert_eq!(own.scheme, "standard");
        assert_eq!(
            with_discretization(&base, &own).unwrap().horizon,
            base.horizon
        );
        let m3 = with_discretization(
            &base,
            &Discretization {
                m: 3.0,
                ..own.clone()
            },
        )
        .unwrap();
        assert_eq!(m3.spacing, 1e-3);
        assert!((m3.horizon - 3e-3).abs() < 1e-15);
        assert_eq!(m3.precracks.len(), base.precracks.len());
        let fine = with_discretization(
            &base,
            &Discretization {
                dx: 5e-4,
                ..own.clone()
            },
        )
        .unwrap();
        assert_eq!(fine.spacing, 5e-4);
        assert!(
            (fine.horizon - 2e-3).abs() < 1e-15,
            "m kept: {}",
            fine.horizon
        );
    }

    #[test]
    fn a_grid_ratio_choice_rebuilds_the_fine_region() {
        let base = Scene::load("corrosion-1d", Some("multigrid")).unwrap();
        let own = discretization_of(&base);
        assert_eq!(own.ratio, Some(4));
        let two = with_discretization(
            &base,
            &Discretization {
                ratio: Some(2),
                ..own
            },
        )
        .unwrap();
        assert_eq!(two.multigrid.as_ref().unwrap().ratio, 2);
        assert_eq!(two.spacing, base.spacing);
        let plain = Scene::load("corrosion-1d", None).unwrap();
        assert_eq!(discretization_of(&plain).ratio, None);
    }

    #[test]
    fn a_fine_region_or_band_choice_rebuilds_the_fine_level() {
        use crate::scene::Refinement;
        let base = Scene::load("corrosion-1d", Some("multigrid")).unwrap();
        let own = discretization_of(&base);
        let narrow = with_discretization(
            &base,
            &Discretization {
                region: Some("{ box = { min = [-5.25], max = [5.25] } }".into()),
                ..own.clone()
            },
        )
        .unwrap();
        let Refinement::Region(region) = &narrow.multigrid.as_ref().unwrap().refinement else {
            panic!("corrosion refines a region");
        };
        assert!(region.contains(&[5.0], 0.0) && !region.contains(&[6.0], 0.0));
        // A band on a diffusion scene is refused by the preset validation, naming the field.
        let e = with_discretization(
            &base,
            &Discretization {
                band: Some("8 mm".into()),
                ..own
            },
        )
        .unwrap_err();
        assert!(e.to_string().contains("multigrid.band"), "{e}");
        let kw = Scene::load("kalthoff-winkler-multigrid", Some("small")).unwrap();
        let wide = with_discretization(
            &kw,
            &Discretization {
                band: Some("2 horizon".into()),
                ..discretization_of(&kw)
            },
        )
        .unwrap();
        let Refinement::Adaptive { band, .. } = wide.multigrid.as_ref().unwrap().refinement else {
            panic!("dynamics refines adaptively");
        };
        assert_eq!(band, 2.0 * kw.horizon);
    }

    #[test]
    fn a_choice_the_validation_refuses_gives_its_message() {
        let base = Scene::load("kalthoff-winkler", Some("small")).unwrap();
        let own = discretization_of(&base);
        let e = with_discretization(&base, &Discretization { dx: 1e-6, ..own }).unwrap_err();
        assert!(e.to_string().contains("discretization.spacing"), "{e}");
    }
}
