//! The entity layout of a recording: the scene header, and each frame's nodes (points colored
//! by field, raw values, class masks with annotation contexts), events and metrics.

use std::sync::Arc;

use rerun::external::arrow::array::{ArrayRef, Float32Array};
use rerun::{AsComponents, ComponentIdentifier, RecordingStream};

use crate::frame::Frame;
use crate::scene::Scene;
use crate::solver::SimInfo;

pub(super) fn log_scene(
    stream: &RecordingStream,
    scene: &Scene,
    info: &SimInfo,
) -> rerun::RecordingStreamResult<()> {
    let header = format!(
        "# {}{}\n\nsource: `{}`; {}D, {} nodes, {} directed bonds, Δt = {:.4e} s (stable bound {:.4e} s), {} steps.\n\n```toml\n{}\n```\n",
        scene.name,
        scene
            .variant
            .as_deref()
            .map(|v| format!(" — variant `{v}`"))
            .unwrap_or_default(),
        scene.source,
        info.dim,
        info.nodes,
        info.bonds,
        info.dt,
        info.stable_dt,
        info.total_steps,
        scene.preset_text
    );
    stream.log_static("scene/preset", &rerun::TextDocument::from_markdown(header))
}

pub(super) fn log_frame(
    stream: &RecordingStream,
    frame: &Frame,
    radius: f32,
    annotated: &mut Vec<&'static str>,
) -> rerun::RecordingStreamResult<()> {
    stream.set_time_sequence("step", frame.step as i64);
    stream.set_duration_secs("sim_time", frame.time);
    let dim = frame.dim;
    // Positions converted once, shared by every field's entity.
    let positions: Vec<[f32; 3]> = frame
        .positions
        .chunks_exact(dim)
        .map(|p| std::array::from_fn(|k| p.get(k).map_or(0.0, |&v| v as f32)))
        .collect();
    let radii: Vec<rerun::components::Radius> = if frame.radii.is_empty() {
        vec![radius.into()]
    } else {
        frame.radii.iter().map(|&r| r.into()).collect()
    };
    let palette = palette();
    for field in &frame.fields {
        let scale = 255.0 / (field.range.1 - field.range.0);
        let colors: Vec<rerun::Color> = field
            .values
            .iter()
            .map(|&v| {
                let t = ((v - field.range.0) * scale).clamp(0.0, 255.0);
                palette[if t.is_finite() { t as usize } else { 0 }]
            })
            .collect();
        let raw: ArrayRef = Arc::new(Float32Array::from_iter_values(
            field.values.iter().map(|&v| v as f32),
        ));
        let values = rerun::AnyValues::default().with_component_from_data(
            ComponentIdentifier::try_new(field.name.as_ref()).unwrap_or("value".into()),
            raw,
        );
        let path = format!("nodes/{}", field.name);
        let points: Box<dyn AsComponents> = if dim == 3 {
            Box::new(
                rerun::Points3D::new(positions.iter().copied())
                    .with_colors(colors)
                    .with_radii(radii.iter().copied()),
            )
        } else {
            Box::new(
                rerun::Points2D::new(positions.iter().map(|p| [p[0], p[1]]))
                    .with_colors(colors)
                    .with_radii(radii.iter().copied()),
            )
        };
        stream.log(path, &[points.as_ref(), &values as &dyn AsComponents])?;
    }
    for class in &frame.classes {
        let path = format!("nodes/{}", class.name);
        if !annotated.contains(&class.name) {
            let context =
                rerun::AnnotationContext::new(class.classes.iter().map(|&(id, label, rgb)| {
                    (id, label, rerun::Rgba32::from_rgb(rgb[0], rgb[1], rgb[2]))
                }));
            stream.log_static(path.as_str(), &context)?;
            annotated.push(class.name);
        }
        let ids = class
            .ids
            .iter()
            .map(|&c| rerun::components::ClassId::from(c));
        if dim == 3 {
            stream.log(
                path,
                &rerun::Points3D::new(positions.iter().copied())
                    .with_class_ids(ids)
                    .with_radii(radii.iter().copied()),
            )?;
        } else {
            stream.log(
                path,
                &rerun::Points2D::new(positions.iter().map(|p| [p[0], p[1]]))
                    .with_class_ids(ids)
                    .with_radii(radii.iter().copied()),
            )?;
        }
    }
    for event in &frame.events {
        stream.log(
            "log/events",
            &rerun::TextLog::new(event.as_str()).with_level(rerun::TextLogLevel::INFO),
        )?;
    }
    for (name, value) in &frame.scalars {
        stream.log(format!("metrics/{name}"), &rerun::Scalars::single(*value))?;
    }
    Ok(())
}

/// The colormap sampled at 256 levels.
fn palette() -> &'static [rerun::Color; 256] {
    static PALETTE: std::sync::OnceLock<[rerun::Color; 256]> = std::sync::OnceLock::new();
    PALETTE.get_or_init(|| std::array::from_fn(|i| colormap(i as f64 / 255.0)))
}

/// Viridis, sampled at nine points and interpolated linearly; t is clamped to [0, 1].
pub fn colormap(t: f64) -> rerun::Color {
    const VIRIDIS: [[f64; 3]; 9] = [
        [68.0, 1.0, 84.0],
        [71.0, 44.0, 122.0],
        [59.0, 81.0, 139.0],
        [44.0, 113.0, 142.0],
        [33.0, 144.0, 141.0],
        [39.0, 173.0, 129.0],
        [92.0, 200.0, 99.0],
        [170.0, 220.0, 50.0],
        [253.0, 231.0, 37.0],
    ];
    let t = if t.is_finite() {
        t.clamp(0.0, 1.0)
    } else {
        0.0
    };
    let x = t * 8.0;
    let i = (x.floor() as usize).min(7);
    let f = x - i as f64;
    let channel = |k: usize| (VIRIDIS[i][k] * (1.0 - f) + VIRIDIS[i + 1][k] * f).round() as u8;
    rerun::Color::from_rgb(channel(0), channel(1), channel(2))
}
