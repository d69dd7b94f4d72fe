//! Signals as data: whoever produces a recorded signal declares it once — name, unit, plot group — and
//! fills a slice of values per tick. Trace columns, CSV headers, Rerun entity paths (`signals/<group>/<name>`)
//! and Python dict keys are all derived from these declarations.

/// One recorded signal.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Signal {
    /// Column name in trace.csv, key in Python dicts, last part of the Rerun entity path.
    pub name: &'static str,
    /// SI unit (`N`, `m`, `Pa`, `s`, `m/N`, `1` for a dimensionless value).
    pub unit: &'static str,
    /// The plot it belongs on: `time`, `force`, `position`, `pressure`, `valve`, `adaptive`, ...
    pub group: &'static str,
    /// What it is, in one line.
    pub description: &'static str,
}

impl Signal {
    /// A signal declaration.
    pub const fn new(
        name: &'static str,
        unit: &'static str,
        group: &'static str,
        description: &'static str,
    ) -> Self {
        Self {
            name,
            unit,
            group,
            description,
        }
    }
}

/// The signals every control loop records, in this order, before the controller's and the plant's own:
/// time, the setpoint, what the plant senses, the inner loop's reference and the command.
pub const LOOP_SIGNALS: [Signal; 8] = [
    Signal::new("t", "s", "time", "time of the tick"),
    Signal::new("f_ref", "N", "force", "reference contact force f_r"),
    Signal::new(
        "f_e",
        "N",
        "force",
        "measured contact force f_e (flange pushes > 0)",
    ),
    Signal::new("x", "m", "position", "flange position x (extension > 0)"),
    Signal::new(
        "x_r",
        "m",
        "position",
        "reference position of the inner loop x_r",
    ),
    Signal::new(
        "p_a",
        "Pa",
        "pressure",
        "chamber A pressure, absolute (empty without chambers)",
    ),
    Signal::new(
        "p_b",
        "Pa",
        "pressure",
        "chamber B pressure, absolute (empty without chambers)",
    ),
    Signal::new("u", "1", "valve", "valve command in [-1, 1]"),
];

/// What watches a run of the control loop without changing it — a live viewer, a progress display, a
/// recorder — in every loop alike: the simulation host and the rig's real-time host call it with the same
/// columns (`LOOP_SIGNALS`, then the controller's own, then the plant's or the link's) and one row of
/// values per tick. `W` is what the host shows of the world beside the row: the simulated plant on the
/// simulation host (a viewer draws its bodies), `()` on the rig. A sink of rows alone implements it for
/// every `W` and watches a simulated run and a run on the real rig alike.
pub trait Sink<W: ?Sized = ()> {
    /// Run `run` starts: its columns as their producers declare them, the world at its initial state.
    fn begin(&mut self, _run: &str, _columns: &[Signal], _world: &W) {}
    /// One tick was recorded: its values in the order of the columns, the world in the state they were
    /// read from.
    fn row(&mut self, _values: &[f64], _world: &W) {}
    /// Something happened at `t_s` that a reader of the run should see (a fault, an event), in a sentence.
    fn event(&mut self, _t_s: f64, _text: &str) {}
    /// The run ended; `why` when it was cut short (diverged, a fault, a signal).
    fn end(&mut self, _why: Option<&str>) {}
    /// Whether it watches anything: a host may run unwatched runs in parallel.
    fn watches(&self) -> bool {
        true
    }
}

/// The sink that watches nothing.
impl<W: ?Sized> Sink<W> for () {
    fn watches(&self) -> bool {
        false
    }
}

/// Index of each loop signal in a row.
pub mod index {
    /// Time.
    pub const T: usize = 0;
    /// Reference force.
    pub const F_REF: usize = 1;
    /// Contact force.
    pub const F_E: usize = 2;
    /// Position.
    pub const X: usize = 3;
    /// Reference position.
    pub const X_R: usize = 4;
    /// Chamber A pressure.
    pub const P_A: usize = 5;
    /// Chamber B pressure.
    pub const P_B: usize = 6;
    /// Valve command.
    pub const U: usize = 7;
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_index_constants_match_the_declarations() {
        let names = [
            (index::T, "t"),
            (index::F_REF, "f_ref"),
            (index::F_E, "f_e"),
            (index::X, "x"),
            (index::X_R, "x_r"),
            (index::P_A, "p_a"),
            (index::P_B, "p_b"),
            (index::U, "u"),
        ];
        for (i, n) in names {
            assert_eq!(LOOP_SIGNALS[i].name, n);
        }
    }
}
