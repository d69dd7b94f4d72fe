//! A Rerun view of any loop that hands its rows to a [`pneuflex_control::Sink`]: the real rig (`rig run --rerun`)
//! on the `wall_time` timeline, or a loop on simulated time. The signals go to the same entity paths as a
//! simulated run's (`signals/<group>/<name>`, in display units, with the same layout), so a rig run and
//! its simulation read the same in the viewer; the rig adds its link's quality (`signals/link/…`,
//! `signals/timing/period_error`) and its fault as an event.

use pneuflex_control::Signal;
use pneuflex_control::Sink as SinkTrait;
use pneuflex_scene::run::trace::{Column, Row};

use crate::error::RerunError;
use crate::layout::Layout;
use crate::recorder::{Clock, EventLevel, RecorderOptions, RunRecorder, wall_clock_s};
use crate::scene_observer::SignalLog;
use crate::sink::Sink;

/// Records the rows of one loop run to Rerun; the first error stops logging and is returned by
/// [`RowRecorder::finish`].
pub struct RowRecorder {
    sink: Sink,
    recording: String,
    options: RecorderOptions,
    dt_s: f64,
    pwm_period_s: Option<f64>,
    /// Where the row's `t` = 0 lies on the timeline: the wall clock when the run began (rig), 0 (sim).
    t0_s: f64,
    current: Option<Current>,
    error: Option<RerunError>,
    rows: usize,
}

struct Current {
    rec: RunRecorder,
    signals: SignalLog,
    columns: Vec<Column>,
}

impl RowRecorder {
    /// A recorder named `recording` sending to `sink`, on `clock`'s timeline. `dt_s` is the loop's tick;
    /// with `pwm_period_s` the chattering signals also get their mean over one PWM period, as in `run`.
    /// A save path whose directory does not exist and a malformed connect address are refused here,
    /// before the loop starts.
    pub fn new(
        sink: Sink,
        recording: &str,
        clock: Clock,
        dt_s: f64,
        pwm_period_s: Option<f64>,
    ) -> Result<Self, RerunError> {
        match &sink {
            Sink::Save(path) => crate::sink::check_save_path(path)?,
            Sink::Connect(addr) => {
                crate::sink::normalise_url(addr)?;
            }
            Sink::Spawn => {}
        }
        Ok(Self {
            sink,
            recording: recording.to_owned(),
            options: RecorderOptions {
                clock,
                // Live: a viewer shows the rig within ~0.1 s at 1 kHz.
                batch_rows: if clock == Clock::Wall { 100 } else { 1024 },
                ..RecorderOptions::default()
            },
            dt_s,
            pwm_period_s,
            t0_s: 0.0,
            current: None,
            error: None,
            rows: 0,
        })
    }

    /// Rows logged.
    pub fn rows(&self) -> usize {
        self.rows
    }

    /// Returns the first logging error, if any.
    pub fn finish(mut self) -> Result<usize, RerunError> {
        self.close();
        self.error.map_or(Ok(self.rows), Err)
    }

    fn start(&mut self, columns: &[Signal]) -> Result<Current, RerunError> {
        let columns: Vec<Column> = columns.iter().map(Column::from).collect();
        let mut options = self.options.clone();
        options.layout = Layout::for_signals(
            columns
                .iter()
                .map(|c| (c.name.as_str(), c.unit.as_str(), c.group.as_str())),
        );
        // The rows carry signals, no world: no empty 3D view.
        options.layout.world_view = false;
        let mut rec = RunRecorder::with_options("pneuflex", &self.recording, &self.sink, options)?;
        let shown = vec![true; columns.len()];
        let signals =
            SignalLog::register(&mut rec, &columns, &shown, self.pwm_period_s, self.dt_s)?;
        self.t0_s = match self.options.clock {
            Clock::Wall => wall_clock_s(),
            Clock::Sim => 0.0,
        };
        Ok(Current {
            rec,
            signals,
            columns,
        })
    }

    fn fail(&mut self, e: RerunError) {
        self.error.get_or_insert(e);
        self.current = None;
    }

    fn close(&mut self) {
        if let Some(mut c) = self.current.take() {
            let done = c.signals.flush(&mut c.rec).and_then(|()| c.rec.finish());
            if let Err(e) = done {
                self.error.get_or_insert(e);
            }
        }
    }
}

impl<W: ?Sized> SinkTrait<W> for RowRecorder {
    fn begin(&mut self, _run: &str, columns: &[Signal], _world: &W) {
        if self.error.is_some() {
            return;
        }
        self.close();
        match self.start(columns) {
            Ok(c) => self.current = Some(c),
            Err(e) => self.fail(e),
        }
    }

    fn row(&mut self, values: &[f64], _world: &W) {
        let Some(c) = self.current.as_mut() else {
            return;
        };
        let row = Row {
            columns: &c.columns,
            values,
        };
        match c.signals.log_at(&mut c.rec, self.t0_s, &row) {
            Ok(()) => self.rows += 1,
            Err(e) => self.fail(e),
        }
    }

    fn event(&mut self, t_s: f64, text: &str) {
        let Some(c) = self.current.as_mut() else {
            return;
        };
        if let Err(e) = c.rec.log_event(self.t0_s + t_s, EventLevel::Error, text) {
            self.fail(e);
        }
    }

    fn end(&mut self, _why: Option<&str>) {
        self.close();
    }
}
