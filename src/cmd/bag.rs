//! `--mcap` (`run`, `rig excite`): each run's trace also as a rosbag2 folder `<run>/bag/` (crates/ros2,
//! docs/ros2.md), written into the staged output directory before it is committed, so a bag is never in
//! a directory marked complete unless it is whole.

use std::path::Path;

use anyhow::Context;
use pneuflex_ros2::{BagSummary, TraceColumns, write_trace_bag};
use pneuflex_scene::{RunResult, Trace};

/// The bag's folder beside a run's trace.
pub const BAG_DIR: &str = "bag";

/// Writes `trace` as the bag `dir`; `actuators` names the `<actuator>.` column prefixes of a trace of
/// several (empty: one actuator).
pub fn write_trace(dir: &Path, trace: &Trace, actuators: &[String]) -> anyhow::Result<BagSummary> {
    let columns = trace
        .columns()
        .iter()
        .filter_map(|c| Some((c.name.as_str(), trace.column(&c.name)?)))
        .collect();
    let table = TraceColumns {
        columns,
        actuators: actuators.to_vec(),
    };
    write_trace_bag(dir, &table)
        .with_context(|| format!("--mcap: writing the bag {}", dir.display()))
}

/// Every run's bag, `<stage>/<run>/bag/`, in parallel (one run a core).
pub fn write_runs(
    stage: &Path,
    runs: &[RunResult],
    actuators: &[String],
) -> anyhow::Result<Vec<BagSummary>> {
    use rayon::prelude::*;
    runs.par_iter()
        .map(|r| write_trace(&stage.join(&r.name).join(BAG_DIR), &r.trace, actuators))
        .collect()
}

/// The bag of a rig recording: `<dir>/bag/` from `<dir>/trace.csv`, the board's record on its clock
/// (crates/ros2 trace_bag), the host's wall time left out, and the rows from the first fault on (the valve
/// was then in its safe state, not at `u`; `identify` leaves them out of a trace too). On an error the
/// bag's folder is removed again (the recording stays as it was).
pub fn write_recording(dir: &Path) -> Result<BagSummary, String> {
    let path = dir.join("trace.csv");
    let bag = dir.join(BAG_DIR);
    let written = (|| {
        let text = std::fs::read_to_string(&path)
            .map_err(|e| format!("--mcap: {}: cannot read: {e}", path.display()))?;
        let trace = Trace::from_csv(&text, &["wall_time", "fault"])
            .map_err(|e| format!("--mcap: {}: {e}", path.display()))?;
        let trace = match first_fault_row(&text) {
            Some(k) => Trace::from_columns(
                trace
                    .into_columns()
                    .into_iter()
                    .map(|(c, mut v)| {
                        v.truncate(k);
                        (c, v)
                    })
                    .collect(),
            )
            .map_err(|e| format!("--mcap: {}: {e}", path.display()))?,
            None => trace,
        };
        write_trace(&bag, &trace, &[]).map_err(|e| format!("{e:#}"))
    })();
    if written.is_err() && bag.is_dir() {
        let _ = std::fs::remove_dir_all(&bag);
    }
    written
}

/// The index of the first data row of a rig trace whose `fault` cell is not empty.
fn first_fault_row(text: &str) -> Option<usize> {
    let mut rows = text
        .lines()
        .filter(|l| !l.starts_with('#') && !l.trim().is_empty());
    let column = rows.next()?.split(',').position(|n| n.trim() == "fault")?;
    rows.position(|r| {
        r.split(',')
            .nth(column)
            .is_some_and(|c| !c.trim().is_empty())
    })
}
