//! The default viewer layout sent with every recording.

use rerun::blueprint::{
    Blueprint, Horizontal, Spatial3DView, TextLogView, TimePanel, TimeSeriesView, Vertical,
};

use crate::paths;
use crate::recorder::Clock;

/// 3D scene on the left, force above position on the right; pressure, valve, adaptive gains and
/// events in a row below. The time panel follows the recording's clock.
pub fn default_blueprint(clock: Clock) -> Blueprint {
    let plot = |name: &str, origin: &str| TimeSeriesView::new(name).with_origin(origin);
    let top = Horizontal::new([
        Spatial3DView::new("scene").with_origin(paths::WORLD).into(),
        Vertical::new([
            plot("force", "signals/force").into(),
            plot("position", "signals/position").into(),
        ])
        .into(),
    ])
    .with_column_shares([3.0, 2.0]);
    let bottom = Horizontal::new([
        plot("pressure", "signals/pressure").into(),
        plot("valve", "signals/valve").into(),
        plot("adaptive", "signals/adaptive").into(),
        TextLogView::new("events").with_origin(paths::EVENTS).into(),
    ]);
    Blueprint::new(Vertical::new([top.into(), bottom.into()]).with_row_shares([2.0, 1.0]))
        .with_time_panel(TimePanel::new().with_timeline(clock.timeline()))
}
