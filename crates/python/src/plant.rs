//! A plant implemented in Python (e.g. MuJoCo), driven by the scene crate's own loop: `run_plant` runs
//! `pneuflex_scene::simulate` — events, `sense → update → record → actuate → advance`, the divergence and
//! invariant checks, the trace columns the controller declares — with a Python object as the plant.
//!
//! The object's methods, called each tick with the GIL held:
//!
//! | method | when |
//! | --- | --- |
//! | `reset()` | once, before the run (the plant returns to its initial state) |
//! | `apply(event: dict)` | at the first tick at or after each event's time, before sensing; the dict is the scene's event entry (`kind`, `t_s`, ...) |
//! | `sense() -> (x, x_dot, f_e, p_a, p_b)` | each tick, SI, pressures absolute (NaN when the plant has no chambers) |
//! | `actuate(u, x_r)` | each tick but the last: the valve command in [-1, 1] and the controller's reference position x_r |
//! | `advance(dt)` | after `actuate`: integrate dt seconds with the command held |
//!
//! An exception in `sense`, `actuate` or `advance` stops the run as diverged, with the method, the plant's
//! time, the exception's type, message and the line that raised it as the reason; one in `apply` is the
//! scene runner's event error (`PneuflexError` naming `events[i]`, the exception as its `__cause__`); one in
//! `reset` is raised as it is. `KeyboardInterrupt` and `SystemExit` (not `Exception`s) are re-raised as they are.

use std::cell::RefCell;
use std::time::Instant;

use pneuflex_control::{Sensors, Telemetry, ValveCommand};
use pneuflex_scene::analysis::{adaptation::lyapunov_summary, windows::compute_windows};
use pneuflex_scene::plants::{PlantError, PlantErrorKind};
use pneuflex_scene::schema::{ControllerKind, EventSpec, Limits};
use pneuflex_scene::{Plant, Scene, simulate, summary};
use pyo3::exceptions::{PyException, PyTypeError};
use pyo3::intern;
use pyo3::prelude::*;
use pyo3::types::{PyAny, PyDict};

use crate::errors;
use crate::scene::{to_py, trace_to_dict};

/// The Python methods a plant object must have, in the order of the table above.
const METHODS: [&str; 5] = ["reset", "apply", "sense", "actuate", "advance"];

/// The first exception a Python plant raised, and what it was doing.
struct Failure {
    err: PyErr,
    message: String,
}

/// A Python object as a [`Plant`] of the scene crate: each trait method calls the object's method.
pub struct PyPlant<'py> {
    obj: Bound<'py, PyAny>,
    sense: Bound<'py, PyAny>,
    actuate: Bound<'py, PyAny>,
    advance: Bound<'py, PyAny>,
    /// Simulated time of the plant (sum of the `advance` steps since `reset`), s.
    t: f64,
    /// The first exception; once set, no further Python method is called and `sense` reads NaN.
    failure: RefCell<Option<Failure>>,
}

impl<'py> PyPlant<'py> {
    /// Wraps `obj`; a TypeError names the methods it lacks.
    pub fn new(obj: Bound<'py, PyAny>) -> PyResult<Self> {
        let missing: Vec<&str> = METHODS
            .iter()
            .copied()
            .filter(|m| !obj.getattr(*m).is_ok_and(|a| a.is_callable()))
            .collect();
        if !missing.is_empty() {
            let ty = obj.get_type().name()?;
            return Err(PyTypeError::new_err(format!(
                "a plant needs the methods reset(), apply(event), sense() -> (x, x_dot, f_e, p_a, p_b), \
                 actuate(u, x_r) and advance(dt); {ty} has no {}",
                missing.join(", ")
            )));
        }
        Ok(Self {
            sense: obj.getattr("sense")?,
            actuate: obj.getattr("actuate")?,
            advance: obj.getattr("advance")?,
            obj,
            t: 0.0,
            failure: RefCell::new(None),
        })
    }

    fn failed(&self) -> bool {
        self.failure.borrow().is_some()
    }

    /// Keeps the first exception, described as `<what> at t = <t> s raised <Type>: <message> (<file>:<line>)`.
    fn fail(&self, what: &str, err: PyErr) {
        let mut f = self.failure.borrow_mut();
        if f.is_none() {
            let message = format!(
                "Python plant: {what} at t = {:.4} s raised {}",
                self.t,
                describe(self.obj.py(), &err)
            );
            *f = Some(Failure { err, message });
        }
    }

    /// Why the run stopped, when the plant raised.
    pub fn failure_message(&self) -> Option<String> {
        self.failure.borrow().as_ref().map(|f| f.message.clone())
    }

    /// The exception the plant raised, if any (cloned: the plant keeps its record).
    pub fn exception(&self) -> Option<PyErr> {
        let py = self.obj.py();
        self.failure.borrow().as_ref().map(|f| f.err.clone_ref(py))
    }

    /// A raised `BaseException` that is not an `Exception` (KeyboardInterrupt, SystemExit): not the plant's
    /// failure but the user's, to be re-raised as it is.
    pub fn interrupt(&self) -> Option<PyErr> {
        let py = self.obj.py();
        self.failure
            .borrow()
            .as_ref()
            .filter(|f| !f.err.is_instance_of::<PyException>(py))
            .map(|f| f.err.clone_ref(py))
    }

    fn read(&self) -> PyResult<Sensors> {
        let (x, x_dot, f_e, p_a, p_b): (f64, f64, f64, f64, f64) =
            self.sense.call0()?.extract().map_err(|e: PyErr| {
                PyTypeError::new_err(format!(
                    "sense() must return a tuple of 5 floats (x, x_dot, f_e, p_a, p_b): {e}"
                ))
            })?;
        Ok(Sensors {
            t: self.t,
            x,
            x_dot,
            f_e,
            p_a,
            p_b,
        })
    }
}

/// `<Type>: <message> (<file>:<line>)` of an exception, the line being where it was raised.
fn describe(py: Python<'_>, err: &PyErr) -> String {
    let ty = err
        .get_type(py)
        .name()
        .map(|n| n.to_string())
        .unwrap_or_else(|_| "exception".into());
    let mut s = format!("{ty}: {}", err.value(py));
    if let Some(mut tb) = err.traceback(py) {
        while let Ok(next) = tb.getattr(intern!(py, "tb_next")) {
            match next.cast_into::<pyo3::types::PyTraceback>() {
                Ok(n) => tb = n,
                Err(_) => break,
            }
        }
        let file = tb
            .getattr(intern!(py, "tb_frame"))
            .and_then(|f| f.getattr(intern!(py, "f_code")))
            .and_then(|c| c.getattr(intern!(py, "co_filename")))
            .and_then(|n| n.extract::<String>());
        let line = tb
            .getattr(intern!(py, "tb_lineno"))
            .and_then(|l| l.extract::<u32>());
        if let (Ok(file), Ok(line)) = (file, line) {
            let name = std::path::Path::new(&file)
                .file_name()
                .map(|n| n.to_string_lossy().into_owned())
                .unwrap_or(file);
            s.push_str(&format!(" ({name}:{line})"));
        }
    }
    s
}

impl Plant for PyPlant<'_> {
    fn sense(&self) -> Sensors {
        let nan = Sensors {
            t: self.t,
            x: f64::NAN,
            x_dot: f64::NAN,
            f_e: f64::NAN,
            p_a: f64::NAN,
            p_b: f64::NAN,
        };
        if self.failed() {
            return nan;
        }
        self.read().unwrap_or_else(|e| {
            self.fail("sense()", e);
            nan
        })
    }

    fn actuate(&mut self, command: ValveCommand, telemetry: &Telemetry) {
        if self.failed() {
            return;
        }
        if let Err(e) = self.actuate.call1((command.u, telemetry.x_r)) {
            self.fail("actuate(u, x_r)", e);
        }
    }

    fn advance(&mut self, dt: f64) {
        if self.failed() {
            return;
        }
        match self.advance.call1((dt,)) {
            Ok(_) => self.t += dt,
            Err(e) => self.fail("advance(dt)", e),
        }
    }

    fn apply(&mut self, event: &EventSpec) -> Result<(), PlantError> {
        if let Some(m) = self.failure_message() {
            return Err(PlantError::new(PlantErrorKind::External, m));
        }
        let py = self.obj.py();
        let r = to_py(py, event).and_then(|ev| self.obj.call_method1(intern!(py, "apply"), (ev,)));
        match r {
            Ok(_) => Ok(()),
            Err(e) => {
                self.fail("apply(event)", e);
                Err(PlantError::new(
                    PlantErrorKind::External,
                    self.failure_message().unwrap_or_default(),
                ))
            }
        }
    }

    fn reset(&mut self) {
        *self.failure.borrow_mut() = None;
        self.t = 0.0;
        if let Err(e) = self.obj.call_method0(intern!(self.obj.py(), "reset")) {
            self.fail("reset()", e);
        }
    }

    /// The plant's exception, if it raised: the scene loop stops the run as diverged with it.
    fn check_invariants(&self) -> Result<(), PlantError> {
        self.failure_message().map_or(Ok(()), |m| {
            Err(PlantError::new(PlantErrorKind::External, m))
        })
    }
}

/// Runs run `run` (name or index) of the scene file with `plant`, a Python object with the methods
/// `reset()`, `apply(event)`, `sense() -> (x, x_dot, f_e, p_a, p_b)`, `actuate(u, x_r)` and `advance(dt)`,
/// in the scene crate's own loop (events, controller, divergence checks, trace columns as the controller
/// declares them). Returns `(trace, status, wall_s)`: the trace as {column: ndarray}; `status` the
/// summary.json content with this one run when it ran to its end, or the reason (str) it diverged —
/// including an exception of the plant, named with its type, message and line; `wall_s` the loop's wall
/// time. The GIL is held throughout (the plant is called each tick).
#[pyfunction]
pub fn run_plant<'py>(
    py: Python<'py>,
    scene_path: crate::shipped::ScenePath,
    run: &Bound<'py, PyAny>,
    plant: Bound<'py, PyAny>,
) -> PyResult<(Bound<'py, PyDict>, Bound<'py, PyAny>, f64)> {
    let scene = Scene::load(&scene_path).map_err(errors::scene)?;
    scene
        .check_budget(&Limits::default())
        .map_err(errors::scene)?;
    let index = crate::controller::run_index(&scene, run)?;
    let setpoints = scene.setpoints().map_err(errors::scene)?;
    let mut controller = scene.controller(index).map_err(errors::scene)?;
    let mut plant = PyPlant::new(plant)?;
    plant.reset();
    if let Some(e) = plant.exception() {
        return Err(e);
    }
    let t0 = Instant::now();
    let result = simulate(
        &scene,
        index,
        &mut plant,
        controller.as_mut(),
        &setpoints,
        &mut |_| {},
    );
    let wall = t0.elapsed().as_secs_f64();
    if let Some(e) = plant.interrupt() {
        return Err(e);
    }
    let mut r = match result {
        Ok(r) => r,
        Err(e) => {
            let err = errors::scene(e);
            err.set_cause(py, plant.exception());
            return Err(err);
        }
    };
    // The plant's exception is why the run stopped, whichever check saw its NaN reading first.
    if let Some(m) = plant.failure_message() {
        r.diverged = Some(m);
    }
    let status = match &r.diverged {
        Some(reason) => reason.clone().into_pyobject(py)?.into_any(),
        None => {
            // A plant written in Python reports no valve: the period is the scene's own valve's.
            if r.pwm_period_s.is_none() {
                r.pwm_period_s = crate::scene::scene_pwm_period(&scene);
            }
            r.windows = compute_windows(&scene, &r.trace, r.pwm_period_s);
            if r.controller == ControllerKind::Adaptive {
                r.lyapunov = lyapunov_summary(&scene, &scene.runs[index]);
            }
            to_py(py, &summary(&scene, std::slice::from_ref(&r)))?
        }
    };
    Ok((trace_to_dict(py, r.trace)?, status, wall))
}
