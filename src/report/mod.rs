//! Speed-against-error sweeps: run a preset over a grid of values and schemes, then write a
//! CSV, a Markdown table and PNG plots (error against nodes, error against wall time).

pub mod plot;
mod sweep;

pub use sweep::{Axis, SweepRow, SweepSpec};

use std::fmt::Write as _;
use std::path::Path;
use std::sync::Arc;
use std::sync::atomic::AtomicBool;
use std::time::Instant;

use crate::runner::{self, NullSink};
use crate::scene::{Scene, override_table};
use crate::sim;

/// Every combination of the axes' values, in order (the last axis varies fastest).
fn combinations(axes: &[Axis]) -> Vec<Vec<String>> {
    axes.iter().fold(vec![Vec::new()], |acc, axis| {
        acc.iter()
            .flat_map(|prefix| {
                axis.values.iter().map(move |v| {
                    let mut next = prefix.clone();
                    next.push(v.clone());
                    next
                })
            })
            .collect()
    })
}

/// Runs the sweep; `progress` is told each run's label before it starts. Bad input (a preset
/// or override that does not validate) stops the sweep with the scene's error; a run that
/// fails numerically is kept as a row with its failure.
pub fn run(spec: &SweepSpec, progress: &mut dyn FnMut(&str)) -> Result<Vec<SweepRow>, String> {
    let (file, text) = Scene::read(&spec.preset).map_err(|e| e.to_string())?;
    let mut rows = Vec::new();
    let stop = Arc::new(AtomicBool::new(false));
    for values in combinations(&spec.axes) {
        for &scheme in &spec.schemes {
            let mut overrides = spec.set.clone();
            overrides.extend(
                spec.axes
                    .iter()
                    .zip(&values)
                    .map(|(a, v)| format!("{}={v}", a.key)),
            );
            overrides.push(format!("discretization.scheme=\"{}\"", scheme.name()));
            let label = format!("{} {}", scheme.name(), values.join(" "));
            progress(&label);
            let table = override_table(&file, &overrides).map_err(|e| e.to_string())?;
            let scene = Scene::from_text_with(&file, &text, spec.variant.as_deref(), &table)
                .map_err(|e| e.to_string())?;
            let started = Instant::now();
            let mut stepper = sim::build(&scene).map_err(|e| e.to_string())?;
            let setup_seconds = started.elapsed().as_secs_f64();
            let info = stepper.info();
            let summary = runner::run(stepper.as_mut(), &mut NullSink, &stop, None, &mut |_, _| {});
            rows.push(SweepRow {
                scheme,
                values: values.clone(),
                nodes: info.nodes,
                stencil: info.stencil,
                steps: summary.steps,
                setup_seconds,
                run_seconds: summary.wall_seconds - summary.frame_seconds,
                error: summary.relative_error,
                failure: summary.error.map(|e| e.to_string()),
            });
        }
    }
    Ok(rows)
}

fn error_text(row: &SweepRow) -> String {
    match (&row.failure, row.error) {
        (Some(_), _) => "failed".into(),
        (None, Some(e)) => format!("{e:.4e}"),
        (None, None) => String::new(),
    }
}

pub fn csv(spec: &SweepSpec, rows: &[SweepRow]) -> String {
    let mut out = String::from("scheme");
    for a in &spec.axes {
        let _ = write!(out, ",{}", a.key);
    }
    out.push_str(",nodes,stencil,steps,setup_s,run_s,error,failure\n");
    for r in rows {
        let _ = write!(out, "{}", r.scheme.name());
        for v in &r.values {
            let _ = write!(out, ",{}", csv_field(v));
        }
        let _ = writeln!(
            out,
            ",{},{:.2},{},{:.6},{:.6},{},{}",
            r.nodes,
            r.stencil,
            r.steps,
            r.setup_seconds,
            r.run_seconds,
            r.error.map_or(String::new(), |e| format!("{e:.6e}")),
            csv_field(r.failure.as_deref().unwrap_or(""))
        );
    }
    out
}

fn csv_field(v: &str) -> String {
    if v.contains([',', '"', '\n']) {
        format!("\"{}\"", v.replace('"', "\"\""))
    } else {
        v.to_string()
    }
}

pub fn markdown(spec: &SweepSpec, rows: &[SweepRow]) -> String {
    let mut out = String::from("| scheme |");
    for a in &spec.axes {
        let _ = write!(out, " {} |", a.key);
    }
    out.push_str(" nodes | stencil | steps | setup (s) | run (s) | rel. ℓ² error |\n|---|");
    for _ in &spec.axes {
        out.push_str("---|");
    }
    out.push_str("---:|---:|---:|---:|---:|---:|\n");
    for r in rows {
        let _ = write!(out, "| {} |", r.scheme.name());
        for v in &r.values {
            let _ = write!(out, " {v} |");
        }
        let _ = writeln!(
            out,
            " {} | {:.1} | {} | {:.3} | {:.3} | {} |",
            r.nodes,
            r.stencil,
            r.steps,
            r.setup_seconds,
            r.run_seconds,
            error_text(r)
        );
    }
    out
}

/// Writes sweep.csv, sweep.md, error-vs-nodes.png and error-vs-wall.png into `dir`.
pub fn write(dir: &Path, spec: &SweepSpec, rows: &[SweepRow]) -> Result<Vec<String>, String> {
    std::fs::create_dir_all(dir).map_err(|e| format!("{}: {e}", dir.display()))?;
    let put = |name: &str, text: String| {
        let path = dir.join(name);
        std::fs::write(&path, text).map_err(|e| format!("{}: {e}", path.display()))?;
        Ok::<_, String>(path.display().to_string())
    };
    let mut written = vec![
        put("sweep.csv", csv(spec, rows))?,
        put("sweep.md", markdown(spec, rows))?,
    ];
    let title = match &spec.variant {
        Some(v) => format!("{} [{v}]", spec.preset),
        None => spec.preset.clone(),
    };
    for (name, axis) in [
        ("error-vs-nodes.png", plot::XAxis::Nodes),
        ("error-vs-wall.png", plot::XAxis::WallTime),
    ] {
        let path = dir.join(name);
        plot::error_plot(&path, &title, rows, axis)?;
        written.push(path.display().to_string());
    }
    Ok(written)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_axes_and_combines_them() {
        let a = Axis::parse("discretization.spacing = 1, 0.5,0.25").unwrap();
        assert_eq!(a.key, "discretization.spacing");
        assert_eq!(a.values, ["1", "0.5", "0.25"]);
        assert!(Axis::parse("spacing").is_err());
        assert!(Axis::parse("spacing=").is_err());
        let b = Axis::parse("x=a,b").unwrap();
        let c = combinations(&[a, b]);
        assert_eq!(c.len(), 6);
        assert_eq!(c[1], ["1", "b"]);
    }
}
