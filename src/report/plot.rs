//! Log–log PNG plots of a sweep's error, one series per scheme (plotters, bitmap backend, the
//! bundled DejaVu Sans so no system font is needed).

use std::path::Path;
use std::sync::Once;

use plotters::prelude::*;
use plotters::style::FontStyle;

use super::sweep::SweepRow;
use crate::scene::SchemeKind;

static FONT: Once = Once::new();

fn register_font() {
    FONT.call_once(|| {
        let bytes: &'static [u8] = include_bytes!("../../assets/fonts/DejaVuSans.ttf");
        // A bundled, valid font: registration cannot fail.
        let _ = plotters::style::register_font("sans-serif", FontStyle::Normal, bytes);
    });
}

#[derive(Debug, Clone, Copy)]
pub enum XAxis {
    Nodes,
    WallTime,
}

fn series_color(kind: SchemeKind) -> RGBColor {
    match kind {
        SchemeKind::Standard => RGBColor(31, 119, 180),
        SchemeKind::Wls2 => RGBColor(255, 127, 14),
        SchemeKind::Wls4 => RGBColor(44, 160, 44),
        SchemeKind::Wls6 => RGBColor(214, 39, 40),
        SchemeKind::HybridFixed => RGBColor(148, 103, 189),
        SchemeKind::HybridAdaptive => RGBColor(140, 86, 75),
    }
}

/// Error against nodes or wall time (setup + run), log–log; rows without an error are skipped.
pub fn error_plot(
    path: &Path,
    title: &str,
    rows: &[SweepRow],
    x_axis: XAxis,
) -> Result<(), String> {
    register_font();
    let x_of = |r: &SweepRow| match x_axis {
        XAxis::Nodes => r.nodes as f64,
        XAxis::WallTime => (r.setup_seconds + r.run_seconds).max(1e-6),
    };
    let points: Vec<(SchemeKind, f64, f64)> = rows
        .iter()
        .filter(|r| r.failure.is_none())
        .filter_map(|r| r.error.filter(|e| *e > 0.0).map(|e| (r.scheme, x_of(r), e)))
        .collect();
    if points.is_empty() {
        return Err(
            "nothing to plot: no run reported an error norm (does the preset have a [reference]?)"
                .into(),
        );
    }
    let range = |values: &mut dyn Iterator<Item = f64>| {
        let (lo, hi) = values.fold((f64::INFINITY, 0.0f64), |(lo, hi), v| {
            (lo.min(v), hi.max(v))
        });
        (lo / 1.5, hi * 1.5)
    };
    let (x_lo, x_hi) = range(&mut points.iter().map(|p| p.1));
    let (y_lo, y_hi) = range(&mut points.iter().map(|p| p.2));
    let draw = || -> Result<(), Box<dyn std::error::Error>> {
        let root = BitMapBackend::new(path, (900, 600)).into_drawing_area();
        root.fill(&WHITE)?;
        let x_label = match x_axis {
            XAxis::Nodes => "nodes",
            XAxis::WallTime => "wall time, setup + run (s)",
        };
        let mut chart = ChartBuilder::on(&root)
            .caption(title, ("sans-serif", 24))
            .margin(16)
            .x_label_area_size(48)
            .y_label_area_size(80)
            .build_cartesian_2d((x_lo..x_hi).log_scale(), (y_lo..y_hi).log_scale())?;
        chart
            .configure_mesh()
            .x_labels(6)
            .y_labels(8)
            .x_desc(x_label)
            .y_desc("relative l2 error (3.79)")
            .y_label_formatter(&|v| format!("{v:.0e}"))
            .x_label_formatter(&|v| match x_axis {
                XAxis::Nodes => format!("{v:.0}"),
                XAxis::WallTime => format!("{v:.2e}"),
            })
            .draw()?;
        for kind in SchemeKind::ALL {
            let mut series: Vec<(f64, f64)> = points
                .iter()
                .filter(|p| p.0 == kind)
                .map(|p| (p.1, p.2))
                .collect();
            if series.is_empty() {
                continue;
            }
            series.sort_by(|a, b| a.0.total_cmp(&b.0));
            let color = series_color(kind);
            chart
                .draw_series(LineSeries::new(series.clone(), color.stroke_width(2)))?
                .label(kind.name())
                .legend(move |(x, y)| {
                    PathElement::new(vec![(x, y), (x + 20, y)], color.stroke_width(2))
                });
            chart.draw_series(series.iter().map(|&p| Circle::new(p, 4, color.filled())))?;
        }
        chart
            .configure_series_labels()
            .background_style(WHITE.mix(0.8))
            .border_style(BLACK)
            .position(SeriesLabelPosition::UpperRight)
            .draw()?;
        root.present()?;
        Ok(())
    };
    draw().map_err(|e| format!("{}: {e}", path.display()))
}
