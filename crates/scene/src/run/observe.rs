//! Watchers of a run, tick by tick, that do not change it: a viewer, a live plot, the rig's observers.

use super::result::RunResult;
use super::trace::Row;
use crate::plants::Plant;

/// Watches runs tick by tick without changing them (a viewer, a live plot). Called after each tick's
/// sample is recorded, with the plant in the state that sample was read from.
pub trait StepObserver {
    /// A run starts; the plant is at its initial state.
    fn begin_run(&mut self, _run: &crate::schema::RunSpec, _plant: &dyn Plant) {}
    /// The run's columns as their producers declare them (the loop's, the controller's, the plant's),
    /// before its first tick.
    fn columns(&mut self, _columns: &[pneuflex_control::Signal]) {}
    /// One control tick was recorded.
    fn on_step(&mut self, _row: &Row, _plant: &dyn Plant) {}
    /// A run ended (its metrics are not computed yet).
    fn end_run(&mut self, _result: &RunResult) {}
    /// Whether this observer watches anything. One that does not (every method a no-op) lets the runs of
    /// a scene execute in parallel; one that does sees them one after another, in the scene's order.
    fn watches(&self) -> bool {
        true
    }
}

/// The observer that watches nothing.
pub struct NoObserver;

impl StepObserver for NoObserver {
    fn watches(&self) -> bool {
        false
    }
}

/// A [`pneuflex_control::RowObserver`] — the row watcher the rig's loop takes too — as a [`StepObserver`]
/// of the simulation: the same observer watches a simulated run and a run on the real rig.
pub struct Rows<'a>(pub &'a mut dyn pneuflex_control::RowObserver);

impl StepObserver for Rows<'_> {
    fn columns(&mut self, columns: &[pneuflex_control::Signal]) {
        self.0.begin(columns);
    }
    fn on_step(&mut self, row: &Row, _plant: &dyn Plant) {
        self.0.row(row.values);
    }
    fn end_run(&mut self, _result: &RunResult) {
        self.0.end();
    }
}

/// Any number of observers watching the same runs (Rerun, a live plot, a progress display …), each
/// called in order.
#[derive(Default)]
pub struct Observers<'a>(pub Vec<&'a mut dyn StepObserver>);

impl StepObserver for Observers<'_> {
    fn begin_run(&mut self, run: &crate::schema::RunSpec, plant: &dyn Plant) {
        for o in &mut self.0 {
            o.begin_run(run, plant);
        }
    }
    fn columns(&mut self, columns: &[pneuflex_control::Signal]) {
        for o in &mut self.0 {
            o.columns(columns);
        }
    }
    fn on_step(&mut self, row: &Row, plant: &dyn Plant) {
        for o in &mut self.0 {
            o.on_step(row, plant);
        }
    }
    fn end_run(&mut self, result: &RunResult) {
        for o in &mut self.0 {
            o.end_run(result);
        }
    }
    fn watches(&self) -> bool {
        self.0.iter().any(|o| o.watches())
    }
}
