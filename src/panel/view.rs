//! The control panel's widgets: they render a `ControlState` and turn what the user does into
//! `Command`s. Nothing here steps a simulation; the caller sends the commands on.

use eframe::egui;

use crate::control::state::ControlState;
use crate::control::{Command, DtValue};
use crate::scene::builtin;

/// The panel's edit buffers (what the user is typing), refreshed from the state when it moves.
#[derive(Debug, Clone, Default)]
pub struct PanelInputs {
    pub chi: f64,
    /// φ_c and α of a scene that splits particles.
    pub split_damage: f64,
    pub split_strain: f64,
    /// φ_applied of an NNPP scene with reactions, in mV.
    pub applied_potential_mv: f64,
    pub dt_text: String,
    pub dt_override: bool,
    pub m: f64,
    pub dx_mm_text: String,
    pub scheme: String,
    /// The grid ratio of a multi-grid scene.
    pub ratio: usize,
    /// Ω⁻ of a multi-grid scene as typed: a band length ("8 mm", "2 horizon") or a region
    /// shape as an inline TOML table ("{ box = … }"); empty keeps the preset's.
    pub fine_text: String,
    pub every: u64,
    pub save_path: String,
    /// The preset and variant picked for `Load` ("" for the preset's base).
    pub preset: String,
    pub variant: String,
    /// The folder whose recordings are listed, and the list (refreshed by "List").
    pub folder: String,
    pub recordings: Vec<std::path::PathBuf>,
    /// A parse error of the panel's own fields (the state's `message` shows refusals).
    pub error: Option<String>,
    /// The state values the buffers were last filled from.
    seen: Option<SeenState>,
    /// The session the picker was last filled from.
    seen_session: Option<String>,
}

/// The state values the edit buffers mirror (floats by their bits, so equality is exact).
#[derive(Debug, Clone, PartialEq)]
struct SeenState {
    run: u32,
    chi: u64,
    split: Option<(u64, u64)>,
    dt: u64,
    m: u64,
    dx: u64,
    scheme: String,
    every: u64,
    ratio: Option<usize>,
}

/// Schemes offered by the picker (the preset schema's names).
pub const SCHEMES: &[&str] = &[
    "standard",
    "hybrid-fixed",
    "hybrid-adaptive",
    "wls-2",
    "wls-4",
    "wls-6",
];

impl PanelInputs {
    /// Refills the buffers whose state value changed (a command applied, a restart).
    pub fn sync(&mut self, state: &ControlState) {
        // The picker shows the loaded preset and variant until the user picks another.
        if self.seen_session.as_ref() != Some(&state.session) {
            self.preset = state.preset.clone();
            self.variant = state.variant.clone().unwrap_or_default();
            self.seen_session = Some(state.session.clone());
        }
        let d = &state.discretization;
        let now = SeenState {
            run: state.run,
            chi: state.chi.to_bits(),
            split: state
                .split
                .map(|r| (r.damage.to_bits(), r.strain_factor.to_bits())),
            dt: state.dt.to_bits(),
            m: d.m.to_bits(),
            dx: d.dx.to_bits(),
            scheme: d.scheme.clone(),
            every: state.every,
            ratio: d.ratio,
        };
        if self.seen.as_ref() == Some(&now) {
            return;
        }
        self.chi = state.chi;
        if let Some(rule) = state.split {
            self.split_damage = rule.damage;
            self.split_strain = rule.strain_factor;
        }
        if let Some(v) = state.applied_potential {
            self.applied_potential_mv = v * 1e3;
        }
        self.dt_text = format!("{:.4} ns", state.dt * 1e9);
        self.m = d.m;
        self.dx_mm_text = format!("{}", d.dx * 1e3);
        self.scheme = d.scheme.clone();
        self.ratio = d.ratio.unwrap_or(0);
        self.fine_text = d
            .region
            .clone()
            .or_else(|| d.band.clone())
            .unwrap_or_default();
        self.every = state.every;
        if self.save_path.is_empty() {
            self.save_path = format!("{}.rrd", state.recording_id());
        }
        self.seen = Some(now);
    }
}

/// Draws the panel; returns the commands the user gave this frame.
pub fn show(ui: &mut egui::Ui, state: &ControlState, inputs: &mut PanelInputs) -> Vec<Command> {
    inputs.sync(state);
    let mut out = Vec::new();
    ui.heading("peridyn");
    ui.label(format!(
        "recording {} — {} nodes, {} bonds",
        state.recording_id(),
        state.nodes,
        state.bonds
    ));
    preset_picker(ui, inputs, &mut out);
    ui.separator();
    run_controls(ui, state, &mut out);
    ui.separator();
    live_parameters(ui, state, inputs, &mut out);
    ui.separator();
    rebuild_parameters(ui, state, inputs, &mut out);
    ui.separator();
    saving(ui, state, inputs, &mut out);
    ui.separator();
    recordings(ui, inputs, &mut out);
    ui.separator();
    metrics(ui, state);
    for message in [&inputs.error, &state.message].into_iter().flatten() {
        ui.colored_label(egui::Color32::from_rgb(220, 80, 60), message.as_str());
    }
    if !out.is_empty() {
        inputs.error = None;
    }
    out
}

/// The variants of a built-in preset, from its text.
fn variants_of(preset: &str) -> Vec<String> {
    builtin::text(preset)
        .and_then(|t| toml::from_str::<crate::scene::Preset>(t).ok())
        .map(|p| p.variants.keys().cloned().collect())
        .unwrap_or_default()
}

fn preset_picker(ui: &mut egui::Ui, inputs: &mut PanelInputs, out: &mut Vec<Command>) {
    ui.horizontal(|ui| {
        let label = ui.label("preset");
        let before = inputs.preset.clone();
        egui::ComboBox::from_id_salt("preset")
            .selected_text(inputs.preset.clone())
            .show_ui(ui, |ui| {
                for name in builtin::names() {
                    ui.selectable_value(&mut inputs.preset, name.to_string(), name);
                }
            })
            .response
            .labelled_by(label.id);
        if inputs.preset != before {
            inputs.variant.clear();
        }
    });
    ui.horizontal_wrapped(|ui| {
        ui.label("variant");
        if ui
            .selectable_label(inputs.variant.is_empty(), "base")
            .clicked()
        {
            inputs.variant.clear();
        }
        for v in variants_of(&inputs.preset) {
            if ui.selectable_label(inputs.variant == v, &v).clicked() {
                inputs.variant = v;
            }
        }
        if ui.button("Load").clicked() {
            out.push(Command::Load {
                preset: inputs.preset.clone(),
                variant: (!inputs.variant.is_empty()).then(|| inputs.variant.clone()),
            });
        }
    });
}

fn run_controls(ui: &mut egui::Ui, state: &ControlState, out: &mut Vec<Command>) {
    ui.horizontal(|ui| {
        if state.running {
            if ui.button("Pause").clicked() {
                out.push(Command::Pause);
            }
        } else if ui.button("Play").clicked() {
            out.push(Command::Play);
        }
        if ui.button("Step").clicked() {
            out.push(Command::Step(1));
        }
        if ui.button("Reset").clicked() {
            out.push(Command::Reset);
        }
        ui.label(if state.running { "running" } else { "paused" });
    });
    let m = &state.metrics;
    let fraction = if m.total_steps > 0 {
        m.step as f32 / m.total_steps as f32
    } else {
        0.0
    };
    ui.add(egui::ProgressBar::new(fraction).text(format!(
        "step {} / {}   t = {:.3} µs",
        m.step,
        m.total_steps,
        m.time * 1e6
    )));
}

/// A slider's value is final: released after a drag, or changed by keyboard or click.
fn settled(slider: &egui::Response) -> bool {
    slider.drag_stopped() || (slider.changed() && !slider.dragged())
}

fn live_parameters(
    ui: &mut egui::Ui,
    state: &ControlState,
    inputs: &mut PanelInputs,
    out: &mut Vec<Command>,
) {
    egui::Grid::new("live").num_columns(2).show(ui, |ui| {
        let label = ui.label("χ");
        let slider = ui
            .add(egui::Slider::new(&mut inputs.chi, 0.01..=1.0).fixed_decimals(2))
            .labelled_by(label.id);
        if settled(&slider) && inputs.chi != state.chi {
            out.push(Command::SetChi(inputs.chi));
        }
        ui.end_row();

        if let Some(rule) = state.split {
            // zeng2024 (15) and (16): the ranges the scene loader accepts.
            let label = ui.label("φ_c (split damage)");
            let slider = ui
                .add(egui::Slider::new(&mut inputs.split_damage, 0.0..=0.99).fixed_decimals(2))
                .labelled_by(label.id);
            if settled(&slider) && inputs.split_damage != rule.damage {
                out.push(Command::SetSplitDamage(inputs.split_damage));
            }
            ui.end_row();
            let label = ui.label("α (split strain / s_c)");
            let slider = ui
                .add(egui::Slider::new(&mut inputs.split_strain, 0.01..=0.99).fixed_decimals(2))
                .labelled_by(label.id);
            if settled(&slider) && inputs.split_strain != rule.strain_factor {
                out.push(Command::SetSplitStrain(inputs.split_strain));
            }
            ui.end_row();
        }

        if let Some(v) = state.applied_potential {
            // Table 3.7's φ_applied is −300 mV (SHE); a few hundred mV either way.
            let label = ui.label("φ_applied (mV)");
            let slider = ui
                .add(
                    egui::Slider::new(&mut inputs.applied_potential_mv, -1000.0..=1000.0)
                        .fixed_decimals(0),
                )
                .labelled_by(label.id);
            if settled(&slider) && inputs.applied_potential_mv != v * 1e3 {
                out.push(Command::SetAppliedPotential(
                    inputs.applied_potential_mv * 1e-3,
                ));
            }
            ui.end_row();
        }

        let label = ui.label("Δt");
        ui.horizontal(|ui| {
            let edit = ui
                .add(egui::TextEdit::singleline(&mut inputs.dt_text).desired_width(110.0))
                .labelled_by(label.id);
            ui.checkbox(&mut inputs.dt_override, "above bound");
            let entered = edit.lost_focus() && ui.input(|i| i.key_pressed(egui::Key::Enter));
            if ui.button("Apply Δt").clicked() || entered {
                let text = format!(
                    "set dt {}{}",
                    inputs.dt_text.trim(),
                    if inputs.dt_override { " override" } else { "" }
                );
                match Command::parse(&text) {
                    Ok(c @ Command::SetDt { .. }) => out.push(c),
                    Ok(_) => {}
                    Err(e) => inputs.error = Some(format!("Δt not applied: {e}")),
                }
            }
        });
        ui.end_row();
        ui.label("");
        ui.label(format!(
            "stable bound {:.4} ns (Δt = {:.2}× bound)",
            state.stable.sharp * 1e9,
            state.dt / state.stable.sharp
        ));
        ui.end_row();
        if ui.small_button("Δt = 0.5 × bound").clicked() {
            out.push(Command::SetDt {
                value: DtValue::Stable(0.5),
                allow_unstable: false,
            });
        }
        ui.label("");
        ui.end_row();

        let label = ui.label("frame every");
        let every = ui
            .add(
                egui::DragValue::new(&mut inputs.every)
                    .range(1..=100_000)
                    .suffix(" steps"),
            )
            .labelled_by(label.id);
        if (every.drag_stopped() || every.lost_focus() || (every.changed() && !every.dragged()))
            && inputs.every != state.every
        {
            out.push(Command::SetEvery(inputs.every));
        }
        ui.end_row();
    });
}

fn rebuild_parameters(
    ui: &mut egui::Ui,
    state: &ControlState,
    inputs: &mut PanelInputs,
    out: &mut Vec<Command>,
) {
    ui.label("Discretization (applying restarts as a new recording)");
    egui::Grid::new("rebuild").num_columns(2).show(ui, |ui| {
        let label = ui.label("m = δ/Δx");
        ui.add(
            egui::DragValue::new(&mut inputs.m)
                .range(1.0..=16.0)
                .speed(0.1),
        )
        .labelled_by(label.id);
        ui.end_row();
        let label = ui.label("Δx [mm]");
        ui.add(egui::TextEdit::singleline(&mut inputs.dx_mm_text).desired_width(80.0))
            .labelled_by(label.id);
        ui.end_row();
        ui.label("scheme");
        egui::ComboBox::from_id_salt("scheme")
            .selected_text(inputs.scheme.clone())
            .show_ui(ui, |ui| {
                for s in SCHEMES {
                    ui.selectable_value(&mut inputs.scheme, s.to_string(), *s);
                }
            });
        ui.end_row();
        if state.discretization.ratio.is_some() {
            let label = ui.label("grid ratio Δx⁺/Δx⁻");
            ui.add(egui::DragValue::new(&mut inputs.ratio).range(2..=16))
                .labelled_by(label.id);
            ui.end_row();
            let label = ui.label("Ω⁻: band or {region}");
            ui.add(egui::TextEdit::singleline(&mut inputs.fine_text).hint_text("preset's"))
                .labelled_by(label.id);
            ui.end_row();
        }
    });
    if ui.button("Rebuild").clicked() {
        let d = &state.discretization;
        if inputs.m != d.m {
            out.push(Command::SetHorizonFactor(inputs.m));
        }
        match inputs.dx_mm_text.trim().parse::<f64>() {
            Ok(mm) if mm * 1e-3 != d.dx => out.push(Command::SetSpacing(mm * 1e-3)),
            Ok(_) => {}
            Err(_) => {
                inputs.error = Some(format!(
                    "Δx not applied: `{}` is not a number of millimetres",
                    inputs.dx_mm_text
                ))
            }
        }
        if inputs.scheme != d.scheme {
            out.push(Command::SetScheme(inputs.scheme.clone()));
        }
        if d.ratio.is_some_and(|r| r != inputs.ratio) {
            out.push(Command::SetGridRatio(inputs.ratio));
        }
        let fine = inputs.fine_text.trim();
        let current = d.region.as_deref().or(d.band.as_deref()).unwrap_or("");
        if d.ratio.is_some() && !fine.is_empty() && fine != current {
            match Command::parse(&format!(
                "set {} {fine}",
                if fine.starts_with('{') {
                    "region"
                } else {
                    "band"
                }
            )) {
                Ok(command) => out.push(command),
                Err(e) => inputs.error = Some(format!("Ω⁻ not applied: {e}")),
            }
        }
    }
}

fn saving(
    ui: &mut egui::Ui,
    state: &ControlState,
    inputs: &mut PanelInputs,
    out: &mut Vec<Command>,
) {
    ui.horizontal(|ui| match &state.saving {
        Some(path) => {
            ui.label(format!("saving to {}", path.display()));
            if ui.button("Stop saving").clicked() {
                out.push(Command::StopSaving);
            }
        }
        None => {
            let label = ui.label("save to");
            ui.add(egui::TextEdit::singleline(&mut inputs.save_path).desired_width(200.0))
                .labelled_by(label.id);
            if ui.button("Start saving").clicked() {
                out.push(Command::StartSaving(inputs.save_path.trim().into()));
            }
        }
    });
}

fn recordings(ui: &mut egui::Ui, inputs: &mut PanelInputs, out: &mut Vec<Command>) {
    ui.horizontal(|ui| {
        let label = ui.label("recordings in");
        ui.add(egui::TextEdit::singleline(&mut inputs.folder).desired_width(200.0))
            .labelled_by(label.id);
        if ui.button("List").clicked() {
            let folder = if inputs.folder.trim().is_empty() {
                "."
            } else {
                inputs.folder.trim()
            };
            match list_recordings(std::path::Path::new(folder)) {
                Ok(list) => inputs.recordings = list,
                Err(e) => inputs.error = Some(format!("cannot list `{folder}`: {e}")),
            }
        }
    });
    for path in &inputs.recordings {
        let name = path
            .file_name()
            .map(|n| n.to_string_lossy().to_string())
            .unwrap_or_default();
        if ui.button(format!("Replay {name}")).clicked() {
            out.push(Command::Replay(path.clone()));
        }
    }
}

/// The `.rrd` files of a folder, sorted by name.
pub fn list_recordings(folder: &std::path::Path) -> std::io::Result<Vec<std::path::PathBuf>> {
    let mut list: Vec<_> = std::fs::read_dir(folder)?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.extension().is_some_and(|e| e == "rrd") && p.is_file())
        .collect();
    list.sort();
    Ok(list)
}

fn metrics(ui: &mut egui::Ui, state: &ControlState) {
    let m = &state.metrics;
    egui::Grid::new("metrics").num_columns(2).show(ui, |ui| {
        let rows = [
            ("steps/s", format!("{:.1}", m.steps_per_second)),
            (
                "bond evaluations/s",
                format!("{:.3e}", m.bond_evaluations_per_second),
            ),
            ("kinetic energy", format!("{:.4e} J", m.kinetic)),
            ("strain energy", format!("{:.4e} J", m.strain)),
            ("total energy", format!("{:.4e} J", m.kinetic + m.strain)),
            ("damaged nodes (φ ≥ 0.35)", format!("{}", m.damaged_nodes)),
            ("broken bonds", format!("{}", m.broken_bonds)),
            (
                "Ω_s fraction",
                match m.standard_fraction {
                    Some(f) => format!("{:.1} % (the rest WLS)", 100.0 * f),
                    None => "100 % (standard scheme everywhere)".into(),
                },
            ),
        ];
        for (name, value) in rows {
            ui.label(name);
            ui.label(value);
            ui.end_row();
        }
    });
}
