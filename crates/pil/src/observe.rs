//! A PIL run seen live: the scene runner's rows plus the link's quality and the board's update cost,
//! handed to a sink of rows (Rerun's `RowRecorder` on the simulated timeline in `rig pil --rerun`). The
//! extra columns go to observers only; trace.csv and the comparison hold the run's own columns.

use std::cell::Cell;
use std::rc::Rc;

use pneuflex_control::{Signal, Sink};
use pneuflex_scene::Plant;

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

/// A sink of the simulated run forwarding each row, with [`PIL_SIGNALS`] appended, to a sink of rows.
pub struct LinkRows<'a> {
    inner: &'a mut dyn Sink<()>,
    live: Rc<Cell<Live>>,
    values: Vec<f64>,
}

impl<'a> LinkRows<'a> {
    /// Watches through `live` (shared with the FirmwareController).
    pub fn new(inner: &'a mut dyn Sink<()>, live: Rc<Cell<Live>>) -> Self {
        Self {
            inner,
            live,
            values: Vec::new(),
        }
    }
}

impl<'p> Sink<dyn Plant + 'p> for LinkRows<'_> {
    fn begin(&mut self, run: &str, columns: &[Signal], _plant: &(dyn Plant + 'p)) {
        let all: Vec<Signal> = columns.iter().chain(&PIL_SIGNALS).copied().collect();
        self.inner.begin(run, &all, &());
    }

    fn row(&mut self, values: &[f64], _plant: &(dyn Plant + 'p)) {
        let l = self.live.get();
        self.values.clear();
        self.values.extend_from_slice(values);
        self.values.extend([
            l.link.frames_in as f64,
            l.link.crc_errors as f64,
            l.link.seq_gaps as f64,
            f64::from(l.update_ns),
        ]);
        self.inner.row(&self.values, &());
    }

    fn end(&mut self, why: Option<&str>) {
        if let (Some(why), Some(&t)) = (why, self.values.first()) {
            self.inner.event(t, &format!("run stopped: {why}"));
        }
        self.inner.end(why);
    }
}
