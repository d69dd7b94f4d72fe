//! `--rerun MODE [TARGET]` of the commands whose loop takes a row observer (`rig run`, `rig pil`): a live Rerun
//! view of each run's rows (`pneuflex_rerun::RowRecorder`), or nothing. Without the `rerun` feature the option
//! is a clear error that says how to rebuild.

use pneuflex_control::Sink;

/// The parsed `--rerun` option; parsed before anything runs.
pub struct LiveSink {
    #[cfg(feature = "rerun")]
    sink: Option<pneuflex_rerun::Sink>,
}

/// Which timeline a view's rows go on.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Timeline {
    /// The wall clock (a real or emulated rig).
    Wall,
    /// Simulated time (processor-in-the-loop).
    Sim,
}

/// `--rerun` given to a pneuflex built without Rerun: the error saying how to rebuild; `command` (`run`,
/// `rig run`, ...) names the command in the hint.
#[cfg(not(feature = "rerun"))]
pub fn without_rerun(words: &[String], command: &str) -> anyhow::Error {
    anyhow::anyhow!(
        "--rerun {}: this pneuflex was built without Rerun; rebuild with \
         `cargo run --release --features rerun -- {command} ...` (docs/rerun.md)",
        words.join(" ")
    )
}

impl LiveSink {
    /// Parses `--rerun` words; `command` (`rig run`, `rig pil`) names the command in the rebuild hint.
    pub fn parse(words: Option<&[String]>, command: &str) -> anyhow::Result<Self> {
        #[cfg(feature = "rerun")]
        {
            let _ = command;
            Ok(Self {
                sink: words.map(pneuflex_rerun::parse_sink).transpose()?,
            })
        }
        #[cfg(not(feature = "rerun"))]
        match words {
            Some(words) => Err(without_rerun(words, command)),
            None => Ok(Self {}),
        }
    }

    /// The view of run `run` (one of `n_runs`: `save` writes one file per run), recording `recording`, on
    /// `timeline`, for a loop of tick `dt_s` (and PWM period `pwm_period_s`, for the averaged series). A save
    /// path in a missing directory is refused here.
    pub fn view(
        &self,
        recording: &str,
        run: &str,
        n_runs: usize,
        timeline: Timeline,
        dt_s: f64,
        pwm_period_s: Option<f64>,
    ) -> anyhow::Result<LiveView> {
        #[cfg(feature = "rerun")]
        {
            let clock = match timeline {
                Timeline::Wall => pneuflex_rerun::Clock::Wall,
                Timeline::Sim => pneuflex_rerun::Clock::Sim,
            };
            let rec = match &self.sink {
                Some(sink) => Some(pneuflex_rerun::RowRecorder::new(
                    pneuflex_rerun::sink_for_run(sink, run, n_runs),
                    recording,
                    clock,
                    dt_s,
                    pwm_period_s,
                )?),
                None => None,
            };
            Ok(LiveView { rec, nothing: () })
        }
        #[cfg(not(feature = "rerun"))]
        {
            let _ = (recording, run, n_runs, timeline, dt_s, pwm_period_s);
            Ok(LiveView { nothing: () })
        }
    }
}

/// One run's live view (or none).
pub struct LiveView {
    #[cfg(feature = "rerun")]
    rec: Option<pneuflex_rerun::RowRecorder>,
    /// The observer that watches nothing, handed out without a view.
    nothing: (),
}

impl LiveView {
    /// The observer to hand the loop.
    pub fn observer(&mut self) -> &mut dyn Sink<()> {
        #[cfg(feature = "rerun")]
        return match self.rec.as_mut() {
            Some(r) => r,
            None => &mut self.nothing,
        };
        #[cfg(not(feature = "rerun"))]
        return &mut self.nothing;
    }

    /// Ends the view: the ticks logged (None without a view), or the first logging error.
    pub fn finish(self) -> anyhow::Result<Option<usize>> {
        #[cfg(feature = "rerun")]
        if let Some(r) = self.rec {
            return Ok(Some(r.finish()?));
        }
        Ok(None)
    }
}
