//! The control panel's real widgets, driven headless with egui_kittest: clicks, a slider drag
//! and typed values emit the expected commands, and the panel shows the resulting state and
//! the refusals.

use egui_kittest::Harness;
use egui_kittest::kittest::Queryable;
use peridyn::control::state::Discretization;
use peridyn::control::{Command, ControlState, DtValue};
use peridyn::panel::view::{self, PanelInputs};
use peridyn::solver::SimInfo;

/// What the harness holds: the state the panel shows (commands applied to it as the
/// simulation thread would) and every command the panel emitted.
struct Model {
    state: ControlState,
    inputs: PanelInputs,
    emitted: Vec<Command>,
}

fn model() -> Model {
    // A real simulation's facts with round numbers (no literal: `SimInfo` grows fields).
    let scene = peridyn::scene::Scene::load("vibrating-plate", Some("small")).unwrap();
    let mut info: SimInfo = peridyn::sim::build(&scene).unwrap().info();
    info.nodes = 20301;
    info.bonds = 1_000_000;
    info.dt = 1e-7;
    info.stable_dt = 2e-7;
    info.total_steps = 870;
    info.frame_every = 20;
    let mut state = ControlState::new(
        "test",
        &info,
        Discretization {
            m: 4.0,
            dx: 1e-3,
            scheme: "standard".into(),
            ratio: None,
            region: None,
            band: None,
        },
        peridyn::scene::DEFAULT_CHI,
    );
    state.preset = "vibrating-plate".into();
    state.variant = Some("small".into());
    Model {
        state,
        inputs: PanelInputs::default(),
        emitted: Vec::new(),
    }
}

fn harness() -> Harness<'static, Model> {
    harness_of(model())
}

fn harness_of(model: Model) -> Harness<'static, Model> {
    Harness::builder()
        .with_size(egui::vec2(460.0, 760.0))
        .build_ui_state(
            |ui, m: &mut Model| {
                for command in view::show(ui, &m.state, &mut m.inputs) {
                    m.emitted.push(command.clone());
                    let _ = m.state.apply(command);
                }
            },
            model,
        )
}

use eframe::egui;

/// Replaces the text of the field labelled `label`, as a user would (select all, type).
fn type_into(h: &mut Harness<'static, Model>, label: &str, text: &str) {
    h.get_by_label(label).focus();
    h.run();
    h.key_press_modifiers(egui::Modifiers::COMMAND, egui::Key::A);
    h.run();
    h.get_by_label(label).type_text(text);
    h.run();
}

#[test]
fn play_pause_step_and_reset_buttons_emit_their_commands() {
    let mut h = harness();
    h.run();
    h.get_by_label("running");
    h.get_by_label("Pause").click();
    h.run();
    assert_eq!(h.state().emitted, [Command::Pause]);
    h.get_by_label("paused");
    h.get_by_label("Play").click();
    h.run();
    h.get_by_label("Step").click();
    h.run();
    h.get_by_label("Reset").click();
    h.run();
    assert_eq!(
        h.state().emitted,
        [
            Command::Pause,
            Command::Play,
            Command::Step(1),
            Command::Reset
        ]
    );
    assert_eq!(h.state().state.run, 2, "reset starts a new recording");
    h.get_by_label_contains("test-run2");
}

#[test]
fn dragging_the_chi_slider_emits_one_set_chi() {
    let mut h = harness();
    h.run();
    let rect = h.get_by_label("χ").rect();
    h.drag_at(rect.right_center() - egui::vec2(2.0, 0.0));
    h.run();
    h.hover_at(rect.center());
    h.run();
    h.drop_at(rect.center());
    h.run();
    let emitted = &h.state().emitted;
    assert_eq!(emitted.len(), 1, "{emitted:?}");
    let Command::SetChi(chi) = emitted[0] else {
        panic!("{emitted:?}")
    };
    assert!((0.4..0.65).contains(&chi), "dragged to the middle: {chi}");
    assert_eq!(h.state().state.chi, chi);
}

#[test]
fn typing_a_time_step_emits_set_dt_and_a_refusal_is_shown() {
    let mut h = harness();
    h.run();
    type_into(&mut h, "Δt", "150 ns");
    h.get_by_label("Apply Δt").click();
    h.run();
    assert_eq!(
        h.state().emitted,
        [Command::SetDt {
            value: DtValue::Seconds(150.0 * 1e-9),
            allow_unstable: false
        }]
    );
    assert_eq!(h.state().state.dt, 150.0 * 1e-9);
    h.get_by_label_contains("0.75× bound");

    // Above the bound: emitted, refused by the state, and the refusal is on the panel.
    type_into(&mut h, "Δt", "300 ns");
    h.get_by_label("Apply Δt").click();
    h.run();
    assert_eq!(h.state().emitted.len(), 2);
    assert_eq!(h.state().state.dt, 150.0 * 1e-9, "unchanged");
    h.get_by_label_contains("stable bound 2.0000e-7 s");
    h.get_by_label_contains("override");

    // Nonsense is caught by the panel itself.
    type_into(&mut h, "Δt", "fast");
    h.get_by_label("Apply Δt").click();
    h.run();
    assert_eq!(h.state().emitted.len(), 2, "nothing emitted");
    h.get_by_label_contains("Δt not applied");
}

#[test]
fn rebuild_emits_only_the_changed_discretization() {
    let mut h = harness();
    h.run();
    type_into(&mut h, "Δx [mm]", "0.5");
    h.get_by_label("Rebuild").click();
    h.run();
    assert_eq!(h.state().emitted, [Command::SetSpacing(0.5e-3)]);
    assert_eq!(h.state().state.run, 2);
}

#[test]
fn saving_starts_and_stops() {
    let mut h = harness();
    h.run();
    let path = std::env::temp_dir().join("peridyn-panel-test.rrd");
    type_into(&mut h, "save to", path.to_str().unwrap());
    h.get_by_label("Start saving").click();
    h.run();
    h.get_by_label_contains("saving to");
    h.get_by_label("Stop saving").click();
    h.run();
    assert_eq!(
        h.state().emitted,
        [Command::StartSaving(path), Command::StopSaving]
    );
}

/// The panel rendered with wgpu (lavapipe on machines without a GPU) and compared with
/// `tests/snapshots/panel.png`; `UPDATE_SNAPSHOTS=1` rewrites it (scripts/screenshots.sh).
#[test]
fn panel_snapshot() {
    let mut m = model();
    m.state.metrics.step = 312;
    m.state.metrics.time = 312.0 * 1e-7;
    m.state.metrics.steps_per_second = 412.0;
    m.state.metrics.bond_evaluations_per_second = 4.12e8;
    m.state.metrics.kinetic = 1.03;
    m.state.metrics.strain = 0.41;
    m.state.metrics.damaged_nodes = 187;
    m.state.metrics.broken_bonds = 2904.0;
    m.state.apply(Command::SetChi(0.9)).unwrap();
    m.state
        .apply(Command::SetDt {
            value: DtValue::Seconds(3e-7),
            allow_unstable: false,
        })
        .unwrap_err();
    let mut h = Harness::builder()
        .wgpu()
        .with_size(egui::vec2(460.0, 680.0))
        .build_ui_state(
            |ui, m: &mut Model| {
                for command in view::show(ui, &m.state, &mut m.inputs) {
                    m.emitted.push(command);
                }
            },
            m,
        );
    h.run();
    h.snapshot("panel");
}

#[test]
fn the_recordings_of_a_folder_are_listed_and_replayed() {
    let dir = std::env::temp_dir().join(format!("peridyn-panel-rec-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    for name in ["b.rrd", "a.rrd", "notes.txt"] {
        std::fs::write(dir.join(name), "x").unwrap();
    }
    let mut h = harness();
    h.run();
    type_into(&mut h, "recordings in", dir.to_str().unwrap());
    h.get_by_label("List").click();
    h.run();
    assert!(h.query_by_label("Replay notes.txt").is_none());
    h.get_by_label("Replay a.rrd");
    h.get_by_label("Replay b.rrd").click();
    h.run();
    assert_eq!(h.state().emitted, [Command::Replay(dir.join("b.rrd"))]);
}

#[test]
fn picking_a_preset_and_variant_emits_load() {
    let mut h = harness();
    h.run();
    h.get_by_label("preset").click();
    h.run();
    h.get_by_label("abc-wave-1d").click();
    h.run();
    h.get_by_label("small").click();
    h.run();
    h.get_by_label("Load").click();
    h.run();
    assert_eq!(
        h.state().emitted,
        [Command::Load {
            preset: "abc-wave-1d".into(),
            variant: Some("small".into())
        }]
    );
}

/// The panel opens on the preset's χ, variant and preset, not defaults of its own: the state the
/// simulation thread publishes comes from the scene.
#[test]
fn the_panel_starts_at_the_presets_chi() {
    use egui_kittest::kittest::NodeT;
    let scene = peridyn::scene::Scene::load_with(
        "kalthoff-winkler",
        Some("small-hybrid"),
        &["hybrid.chi=0.9".into()],
    )
    .unwrap();
    let file = std::env::temp_dir().join(format!("peridyn-panel-chi-{}.rrd", std::process::id()));
    let outlet =
        peridyn::record::Outlet::open(&peridyn::record::RecordTarget::File(file.clone())).unwrap();
    let spec = peridyn::control::runspec::RunSpec::new(&scene, None, Some(1));
    let driver = peridyn::control::Driver::start(spec, outlet, "chi").unwrap();
    assert_eq!(driver.state.chi, 0.9);
    let mut h = harness_of(Model {
        state: driver.state.clone(),
        inputs: PanelInputs::default(),
        emitted: Vec::new(),
    });
    h.run();
    assert_eq!(h.state().inputs.chi, 0.9);
    let shown = h.get_by_label("χ").accesskit_node().numeric_value();
    assert_eq!(shown, Some(0.9), "the χ slider shows the preset's value");
    assert!(h.state().emitted.is_empty(), "showing it gives no command");
    // The picker shows the loaded preset and variant, and the Ω_s line no claim of the standard
    // scheme everywhere.
    let toggled = |label: &str| format!("{:?}", h.get_by_label(label).accesskit_node().toggled());
    let picked = h
        .get_by_label("preset")
        .accesskit_node()
        .value()
        .map(|v| v.to_string());
    assert_eq!(picked.as_deref(), Some("kalthoff-winkler"));
    assert_eq!(toggled("small-hybrid"), "Some(True)");
    assert_eq!(toggled("small"), "Some(False)");
    assert!(
        h.query_by_label_contains("standard scheme everywhere")
            .is_none()
    );
    driver.finish(false, None).unwrap();
    let _ = std::fs::remove_file(file);
}

/// A scene that splits particles shows φ_c and α (zeng2024 (15), (16)) at the preset's values;
/// dragging φ_c emits one `set phi_c` that the state then shows. Scenes without splitting show
/// neither slider.
#[test]
fn the_split_sliders_show_the_presets_rule_and_emit_set_phi_c() {
    use egui_kittest::kittest::NodeT;
    let scene = peridyn::scene::Scene::load("branching", Some("small")).unwrap();
    let file = std::env::temp_dir().join(format!("peridyn-panel-split-{}.rrd", std::process::id()));
    let outlet =
        peridyn::record::Outlet::open(&peridyn::record::RecordTarget::File(file.clone())).unwrap();
    let spec = peridyn::control::runspec::RunSpec::new(&scene, None, Some(1));
    let driver = peridyn::control::Driver::start(spec, outlet, "split").unwrap();
    let rule = driver.state.split.expect("branching splits particles");
    assert_eq!((rule.damage, rule.strain_factor), (0.4, 0.5));
    let mut h = harness_of(Model {
        state: driver.state.clone(),
        inputs: PanelInputs::default(),
        emitted: Vec::new(),
    });
    h.run();
    let shown = |h: &Harness<'static, Model>, label: &str| {
        h.get_by_label(label).accesskit_node().numeric_value()
    };
    assert_eq!(shown(&h, "φ_c (split damage)"), Some(0.4));
    assert_eq!(shown(&h, "α (split strain / s_c)"), Some(0.5));
    assert!(
        h.state().emitted.is_empty(),
        "showing them gives no command"
    );
    let rect = h.get_by_label("φ_c (split damage)").rect();
    h.drag_at(rect.left_center() + egui::vec2(2.0, 0.0));
    h.run();
    h.hover_at(rect.center());
    h.run();
    h.drop_at(rect.center());
    h.run();
    let emitted = h.state().emitted.clone();
    assert_eq!(emitted.len(), 1, "{emitted:?}");
    let Command::SetSplitDamage(phi) = emitted[0] else {
        panic!("{emitted:?}")
    };
    assert!((0.35..0.65).contains(&phi), "dragged to the middle: {phi}");
    assert_eq!(h.state().state.split.map(|r| r.damage), Some(phi));
    drop(driver);
    let _ = std::fs::remove_file(&file);
    // The vibrating plate does not split: no slider.
    let mut h = harness();
    h.run();
    assert!(h.query_by_label("φ_c (split damage)").is_none());
}
