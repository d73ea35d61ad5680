//! The first view of every recording and live stream, made here rather than by a script: the
//! scene's main field large, the masks of its adaptive scheme beside it, its figures of merit
//! (energies or volume loss or the error, and the adaptive fraction) as plots, the events; the
//! timing series and the preset text in tabs out of the way. Sent as the recording's default
//! blueprint, so a viewer opening the file or the stream starts on it (and returns to it on
//! reset) instead of an automatic grid of every entity.

use rerun::blueprint::components::{PanelState, PlayState};
use rerun::blueprint::{
    Blueprint, BlueprintPanel, ContainerLike, Horizontal, SelectionPanel, Spatial2DView,
    Spatial3DView, Tabs, TextDocumentView, TextLogView, TimePanel, TimeSeriesView, Vertical,
};

use crate::scene::{Physics, Scene};

/// The entities a scene's frames carry, by role.
struct Roles {
    /// The field shown large.
    main: &'static str,
    /// The class masks shown beside it.
    masks: Vec<&'static str>,
    /// (title, entity query) of the figure-of-merit plots.
    plots: Vec<(&'static str, &'static str)>,
}

fn roles(scene: &Scene) -> Roles {
    let hybrid = scene.hybrid.is_some();
    let mut masks = Vec::new();
    let mut plots = Vec::new();
    let main = match scene.physics {
        Physics::Dynamics => {
            plots.push(("energies", "/metrics/energy/**"));
            plots.push(("broken bonds", "/metrics/bonds/**"));
            "damage"
        }
        Physics::Static => {
            plots.push(("error", "/metrics/error/**"));
            "displacement"
        }
        Physics::Diffusion => {
            plots.push(("error", "/metrics/error/**"));
            "concentration"
        }
        Physics::ScalarWave => {
            plots.push(("energy", "/metrics/energy/**"));
            "displacement"
        }
        Physics::NernstPlanck => {
            masks.push("phase");
            plots.push(("species totals", "/metrics/species/**"));
            plots.push(("residuals", "/metrics/residual/**"));
            "potential"
        }
        Physics::Corrosion => {
            masks.push("phase");
            plots.push(("volume loss", "/metrics/corrosion/volume_loss"));
            "concentration"
        }
    };
    if hybrid {
        masks.push("scheme");
        plots.push(("Ω_s fraction", "/metrics/hybrid/omega_s_fraction"));
    }
    if scene.absorbing.is_some() {
        masks.push("boundary");
        if scene.physics != Physics::ScalarWave {
            plots.push(("near-field energy", "/metrics/energy/**"));
        }
    }
    if scene.multigrid.is_some() {
        masks.push("grid");
        plots.push(("grid levels", "/metrics/grid/**"));
    }
    Roles { main, masks, plots }
}

/// A point-cloud view of one `nodes/<name>` entity, 3D for 3D scenes.
fn nodes_view(dim: usize, title: String, name: &str) -> ContainerLike {
    let query = [format!("/nodes/{name}")];
    if dim == 3 {
        Spatial3DView::new(title).with_contents(query).into()
    } else {
        Spatial2DView::new(title).with_contents(query).into()
    }
}

/// The default blueprint of a scene's recordings.
pub fn of_scene(scene: &Scene) -> Blueprint {
    let roles = roles(scene);
    let title = match &scene.variant {
        Some(v) => format!("{} — {} [{v}]", roles.main, scene.name),
        None => format!("{} — {}", roles.main, scene.name),
    };
    let mut fields = vec![nodes_view(scene.dim, title, roles.main)];
    fields.extend(
        roles
            .masks
            .iter()
            .map(|m| nodes_view(scene.dim, format!("{m} mask"), m)),
    );
    let shares: Vec<f32> = std::iter::once(3.0)
        .chain(roles.masks.iter().map(|_| 2.0))
        .collect();
    let mut side: Vec<ContainerLike> = roles
        .plots
        .iter()
        .map(|(title, query)| TimeSeriesView::new(*title).with_contents([*query]).into())
        .collect();
    side.push(TextLogView::new("events").with_contents(["/log/**"]).into());
    side.push(
        Tabs::new([
            TimeSeriesView::new("timing")
                .with_contents(["/metrics/timing/**"])
                .into(),
            TextDocumentView::new("preset")
                .with_contents(["/scene/preset", "/control/run"])
                .into(),
        ])
        .into(),
    );
    let root = Horizontal::new([
        Vertical::new(fields).with_row_shares(shares).into(),
        Vertical::new(side).into(),
    ])
    .with_column_shares([2.0, 1.0]);
    // The side panels start collapsed: the scene gets the window. The time line follows the
    // latest frame (a live run as it goes; a file opens on its last frame).
    Blueprint::new(root)
        .with_auto_views(false)
        .with_auto_layout(false)
        .with_blueprint_panel(BlueprintPanel::from_state(PanelState::Collapsed))
        .with_selection_panel(SelectionPanel::from_state(PanelState::Collapsed))
        .with_time_panel(
            TimePanel::new()
                .with_state(PanelState::Collapsed)
                .with_timeline("step")
                .with_play_state(PlayState::Following),
        )
}
