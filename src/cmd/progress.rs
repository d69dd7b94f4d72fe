//! The progress bar of long simulations: hidden unless the work lasts longer than a moment.

/// A progress bar that shows itself only when the simulation lasts longer than a moment.
pub struct Progress {
    bar: indicatif::ProgressBar,
    quiet: bool,
    start: std::time::Instant,
    shown: std::cell::Cell<bool>,
}

impl Progress {
    /// A bar for `message`, drawn on stderr once the work has lasted 300 ms (never when `quiet`).
    pub fn new(quiet: bool, message: String) -> Self {
        use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
        let bar = ProgressBar::with_draw_target(Some(1000), ProgressDrawTarget::hidden());
        bar.set_style(
            ProgressStyle::with_template(
                "{spinner} {msg} [{bar:40}] {percent:>3}% ({elapsed}, eta {eta})",
            )
            .unwrap_or_else(|_| ProgressStyle::default_bar())
            .progress_chars("=> "),
        );
        bar.set_message(message);
        Self {
            bar,
            quiet,
            start: std::time::Instant::now(),
            shown: std::cell::Cell::new(false),
        }
    }

    /// The fraction done, in [0, 1].
    pub fn set(&self, fraction: f64) {
        if !self.quiet && !self.shown.get() && self.start.elapsed().as_millis() > 300 {
            self.bar
                .set_draw_target(indicatif::ProgressDrawTarget::stderr());
            self.shown.set(true);
        }
        self.bar
            .set_position((fraction.clamp(0.0, 1.0) * 1000.0) as u64);
    }

    /// Removes the bar.
    pub fn finish(&self) {
        self.bar.finish_and_clear();
    }
}
