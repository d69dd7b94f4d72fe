//! A PIL run seen live: the scene runner's rows plus the link's quality and the board's update cost,
//! handed to a [`RowObserver`] (Rerun's `RowRecorder` on the simulated timeline in `rig pil --rerun`). The
//! extra columns go to observers only; trace.csv and the comparison hold the run's own columns.

use std::cell::Cell;
use std::rc::Rc;

use pneuflex_control::{RowObserver, Signal};
use pneuflex_scene::run::trace::Row;
use pneuflex_scene::{Plant, RunResult, StepObserver};

use crate::link::LinkStats;

/// What the firmware controller publishes after each tick for observers.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Live {
    /// The link's counters so far.
    pub link: LinkStats,
    /// The last update's cost on the board clock, ns (= instructions under -icount shift=0).
    pub update_ns: u32,
}

/// The columns added for observers: the rig's link-quality signals (same names and groups as `rig run`'s)
/// and the board's update cost.
pub const PIL_SIGNALS: [Signal; 4] = [
    pneuflex_rig::serial::LINK_SIGNALS[0],
    pneuflex_rig::serial::LINK_SIGNALS[1],
    pneuflex_rig::serial::LINK_SIGNALS[2],
    Signal::new(
        "update_ns",
        "ns",
        "board",
        "the controller update's duration on the board clock (1 ns = 1 instruction under QEMU -icount shift=0)",
    ),
];

/// A StepObserver forwarding each row, with [`PIL_SIGNALS`] appended, to a RowObserver.
pub struct LinkRows<'a> {
    inner: &'a mut dyn RowObserver,
    live: Rc<Cell<Live>>,
    values: Vec<f64>,
}

impl<'a> LinkRows<'a> {
    /// Watches through `live` (shared with the FirmwareController).
    pub fn new(inner: &'a mut dyn RowObserver, live: Rc<Cell<Live>>) -> Self {
        Self {
            inner,
            live,
            values: Vec::new(),
        }
    }
}

impl StepObserver for LinkRows<'_> {
    fn columns(&mut self, columns: &[Signal]) {
        let all: Vec<Signal> = columns.iter().chain(&PIL_SIGNALS).copied().collect();
        self.inner.begin(&all);
    }

    fn on_step(&mut self, row: &Row, _plant: &dyn Plant) {
        let l = self.live.get();
        self.values.clear();
        self.values.extend_from_slice(row.values);
        self.values.extend([
            l.link.frames_in as f64,
            l.link.crc_errors as f64,
            l.link.seq_gaps as f64,
            f64::from(l.update_ns),
        ]);
        self.inner.row(&self.values);
    }

    fn end_run(&mut self, result: &RunResult) {
        if let (Some(why), Some(&t)) = (&result.diverged, result.trace.t().last()) {
            self.inner.event(t, &format!("run stopped: {why}"));
        }
        self.inner.end();
    }
}
