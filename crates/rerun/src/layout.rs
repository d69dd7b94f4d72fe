//! The viewer layout sent with every recording, made active when the recording starts and kept as its
//! default; it is built from the run's signals, so a run shows the plots it has and no empty one.

use rerun::blueprint::components::{PanelState, PlayState};
use rerun::blueprint::{
    Blueprint, BlueprintActivation, BlueprintPanel, ContainerLike, Horizontal, SelectionPanel,
    Spatial3DView, TextLogView, TimePanel, TimeSeriesView, Vertical,
};
use rerun::external::re_log_types::BlueprintActivationCommand;
use rerun::log::LogMsg;
use rerun::{ApplicationId, EntityPath, RecordingStream, RecordingStreamBuilder};

use crate::paths;
use crate::paths::Clock;
use crate::units;

/// A time-series plot: its title and the entity it shows with everything below it.
#[derive(Debug, Clone, PartialEq)]
pub struct Plot {
    /// Title, with the unit (`force [N]`).
    pub title: String,
    /// Entity path shown (`signals/force`).
    pub origin: String,
}

/// What the layout shows beside the 3D view and the event log.
#[derive(Debug, Clone, PartialEq)]
pub struct Layout {
    /// Stacked beside the 3D view: force over position.
    pub side: Vec<Plot>,
    /// The row below: pressure, valve, any other group.
    pub bottom: Vec<Plot>,
    /// One plot per signal, stacked in a column of the row below (the adaptive parameters, each on its
    /// own axis); empty for a run without them (no column).
    pub stacked: Vec<Plot>,
    /// Entities recorded but left out of the 3D view, so that it frames the actuator and the
    /// environment (the platform and the carriage: large, and not what the experiment is about).
    pub hidden_in_3d: Vec<String>,
    /// Where the 3D view's camera starts (world frame); None: the viewer's own choice.
    pub eye: Option<Eye>,
    /// Whether there is a 3D view (false for a recording with nothing in the world, e.g. a rig run's
    /// signals: then the side plots take the top row).
    pub world_view: bool,
}

/// A camera of the 3D view: where it is and what it looks at (world frame, m; z up).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Eye {
    /// Camera position, m.
    pub position_m: [f64; 3],
    /// The point it looks at (and orbits around), m.
    pub look_at_m: [f64; 3],
}

/// Groups drawn beside the 3D view.
const SIDE_GROUPS: [&str; 2] = ["force", "position"];
/// The group whose signals get a plot each.
const OWN_AXIS_GROUP: &str = "adaptive";

impl Layout {
    /// The layout of a run recording `signals` as (name, SI unit, group), in the order declared; the
    /// `time` group is not plotted.
    pub fn for_signals<'a>(signals: impl IntoIterator<Item = (&'a str, &'a str, &'a str)>) -> Self {
        let mut groups: Vec<(&str, Vec<&str>)> = Vec::new();
        let mut stacked = Vec::new();
        for (name, unit, group) in signals {
            if group == "time" {
                continue;
            }
            if group == OWN_AXIS_GROUP {
                stacked.push(Plot {
                    title: units::series_name(name, unit),
                    origin: format!("signals/{group}/{name}"),
                });
                continue;
            }
            match groups.iter_mut().find(|(g, _)| *g == group) {
                Some((_, u)) => u.push(unit),
                None => groups.push((group, vec![unit])),
            }
        }
        let plot = |(group, units): &(&str, Vec<&str>)| Plot {
            title: units::plot_title(group, units),
            origin: format!("signals/{group}"),
        };
        let mut side = Vec::new();
        for g in SIDE_GROUPS {
            if let Some(entry) = groups.iter().find(|(name, _)| *name == g) {
                side.push(plot(entry));
            }
        }
        let bottom = groups
            .iter()
            .filter(|(g, _)| !SIDE_GROUPS.contains(g))
            .map(plot)
            .collect();
        Self {
            side,
            bottom,
            stacked,
            hidden_in_3d: Vec::new(),
            eye: None,
            world_view: true,
        }
    }
}

impl Default for Layout {
    /// Every signal of [`paths::SIGNALS`] (the pneumatic plant under adaptive control), titled in the
    /// display units of [`crate::units`] — the units `SceneRecorder` logs in; a `RunRecorder` fed SI
    /// values sets its own layout.
    fn default() -> Self {
        Self::for_signals(paths::SIGNALS.iter().map(|p| {
            let (group, name) = p
                .strip_prefix("signals/")
                .and_then(|s| s.split_once('/'))
                .unwrap_or(("other", p));
            (name, paths::unit_of(p), group)
        }))
    }
}

fn plots(list: &[Plot]) -> Vec<ContainerLike> {
    list.iter()
        .map(|p| {
            TimeSeriesView::new(p.title.as_str())
                .with_origin(p.origin.as_str())
                .into()
        })
        .collect()
}

/// The layout of [`Layout::default`] (every signal of [`paths::SIGNALS`]).
pub fn default_blueprint(clock: Clock) -> Blueprint {
    blueprint(clock, &Layout::default())
}

/// 3D scene on the left, the side plots (force over position) on the right; the bottom plots, the
/// stacked plots (if any) and the event log in a row below. The blueprint and selection panels start
/// collapsed, the time panel shows the recording's clock and follows the latest data.
pub fn blueprint(clock: Clock, layout: &Layout) -> Blueprint {
    build(clock, layout).0
}

/// The blueprint and the blueprint path of its 3D view.
fn build(clock: Clock, layout: &Layout) -> (Blueprint, EntityPath) {
    let contents = std::iter::once("+ $origin/**".to_owned()).chain(
        layout
            .hidden_in_3d
            .iter()
            .map(|p| format!("- /{}/**", p.trim_matches('/'))),
    );
    let rig: ContainerLike = Spatial3DView::new("rig")
        .with_origin(paths::WORLD)
        .with_contents(contents)
        .into();
    let rig_path = match &rig {
        ContainerLike::View(v) => v.blueprint_path(),
        _ => unreachable!("a view converts to ContainerLike::View"),
    };
    let top: ContainerLike = if layout.world_view {
        let mut top: Vec<ContainerLike> = vec![rig];
        if !layout.side.is_empty() {
            top.push(Vertical::new(plots(&layout.side)).into());
        }
        Horizontal::new(top)
            .with_column_shares(if layout.side.is_empty() {
                vec![1.0]
            } else {
                vec![3.0, 2.0]
            })
            .into()
    } else {
        // No world to draw: the side plots side by side.
        Horizontal::new(plots(&layout.side)).into()
    };
    let mut bottom = plots(&layout.bottom);
    if !layout.stacked.is_empty() {
        bottom.push(Vertical::new(plots(&layout.stacked)).into());
    }
    bottom.push(TextLogView::new("events").with_origin(paths::EVENTS).into());
    let n = bottom.len();
    // The event log gets more room: its lines are sentences.
    let shares: Vec<f32> = (0..n).map(|i| if i + 1 == n { 1.6 } else { 1.0 }).collect();
    let bottom = Horizontal::new(bottom).with_column_shares(shares);
    let bp = Blueprint::new(Vertical::new([top, bottom.into()]).with_row_shares([3.0, 2.0]))
        .with_blueprint_panel(BlueprintPanel::new().with_state(PanelState::Collapsed))
        .with_selection_panel(SelectionPanel::new().with_state(PanelState::Collapsed))
        .with_time_panel(
            TimePanel::new()
                .with_state(PanelState::Collapsed)
                .with_timeline(clock.timeline())
                .with_play_state(PlayState::Following),
        );
    (bp, rig_path)
}

/// Sends the layout to `rec`, active and the default, with the 3D view's camera at `eye`. The SDK's
/// blueprint API has no camera for a 3D view: the blueprint is rendered to messages in memory, the
/// view's `EyeControls3D` property added to the same blueprint store, then all are sent as one
/// blueprint followed by its activation command (as `RecordingStreamBuilder::with_blueprint` does).
pub(crate) fn send_with_eye(
    rec: &RecordingStream,
    app: &ApplicationId,
    clock: Clock,
    layout: &Layout,
    eye: Eye,
) -> Result<(), String> {
    let (bp, view) = build(clock, layout);
    let (mem, storage) = RecordingStreamBuilder::new(app.clone())
        .memory()
        .map_err(|e| e.to_string())?;
    bp.send(
        &mem,
        BlueprintActivation {
            make_active: true,
            make_default: true,
        },
    )
    .map_err(|e| e.to_string())?;
    let mut msgs = Vec::new();
    let mut cmd: Option<BlueprintActivationCommand> = None;
    for m in storage.take() {
        match m {
            LogMsg::BlueprintActivationCommand(c) => cmd = Some(c),
            m if m.store_id().is_blueprint() => msgs.push(m),
            _ => {}
        }
    }
    drop(mem);
    let cmd = cmd.ok_or("the blueprint rendered without an activation command")?;
    let (eye_rec, eye_storage) = RecordingStreamBuilder::new(app.clone())
        .recording_id(cmd.blueprint_id.recording_id().clone())
        .blueprint()
        .memory()
        .map_err(|e| e.to_string())?;
    // The blueprint store's own timeline, as the SDK's blueprint messages use it.
    eye_rec.set_time_sequence("blueprint", 0);
    let f = |v: [f64; 3]| v.map(|c| c as f32);
    eye_rec
        .log(
            format!("{view}/EyeControls3D"),
            &re_sdk_types::blueprint::archetypes::EyeControls3D::new()
                .with_position(f(eye.position_m))
                .with_look_target(f(eye.look_at_m))
                .with_eye_up([0.0f32, 0.0, 1.0]),
        )
        .map_err(|e| e.to_string())?;
    msgs.extend(
        eye_storage
            .take()
            .into_iter()
            .filter(|m| matches!(m, LogMsg::ArrowMsg(..))),
    );
    drop(eye_rec);
    rec.send_blueprint(msgs, cmd);
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_impedance_run_has_no_adaptive_plot_and_an_adaptive_run_one_per_parameter() {
        let loop_signals = [
            ("t", "s", "time"),
            ("f_ref", "N", "force"),
            ("f_e", "N", "force"),
            ("x", "m", "position"),
            ("x_r", "m", "position"),
            ("p_a", "Pa", "pressure"),
            ("p_b", "Pa", "pressure"),
            ("u", "1", "valve"),
        ];
        let imp = Layout::for_signals(loop_signals);
        assert!(imp.stacked.is_empty());
        let titles: Vec<&str> = imp
            .side
            .iter()
            .chain(&imp.bottom)
            .map(|p| p.title.as_str())
            .collect();
        assert_eq!(
            titles,
            [
                "force [N]",
                "position [mm]",
                "pressure [kPa abs]",
                "valve [-]"
            ]
        );
        let adaptive = [
            ("g", "m", "adaptive"),
            ("p", "m/N", "adaptive"),
            ("d", "s", "adaptive"),
        ];
        let ada = Layout::for_signals(loop_signals.into_iter().chain(adaptive));
        let stacked: Vec<(&str, &str)> = ada
            .stacked
            .iter()
            .map(|p| (p.title.as_str(), p.origin.as_str()))
            .collect();
        assert_eq!(
            stacked,
            [
                ("g [mm]", "signals/adaptive/g"),
                ("p [mm/N]", "signals/adaptive/p"),
                ("d [s]", "signals/adaptive/d")
            ]
        );
        assert_eq!(Layout::default().stacked.len(), 3);
    }
}
