//! Watchers of a simulated run, tick by tick, that do not change it: the one sink trait of every loop
//! (`pneuflex_control::Sink`), seeing the simulated plant beside each row, and a fan-out to several.

pub use pneuflex_control::Sink;

use crate::plants::Plant;

/// Any number of sinks watching the same runs (Rerun, a live plot, a progress display …), each called in
/// order.
#[derive(Default)]
pub struct Sinks<'a, 'p>(pub Vec<&'a mut dyn Sink<dyn Plant + 'p>>);

impl<'p> Sink<dyn Plant + 'p> for Sinks<'_, 'p> {
    fn begin(&mut self, run: &str, columns: &[pneuflex_control::Signal], plant: &(dyn Plant + 'p)) {
        for o in &mut self.0 {
            o.begin(run, columns, plant);
        }
    }
    fn row(&mut self, values: &[f64], plant: &(dyn Plant + 'p)) {
        for o in &mut self.0 {
            o.row(values, plant);
        }
    }
    fn event(&mut self, t_s: f64, text: &str) {
        for o in &mut self.0 {
            o.event(t_s, text);
        }
    }
    fn end(&mut self, why: Option<&str>) {
        for o in &mut self.0 {
            o.end(why);
        }
    }
    fn watches(&self) -> bool {
        self.0.iter().any(|o| o.watches())
    }
}
