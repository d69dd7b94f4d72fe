//! The controllers of `pneuflex-control` in Python, built from parameter dicts (the scene file's keys) or
//! from a scene file's run entry, and the scene's setpoint schedule.

use pneuflex_control::{Controller, Sensors, Setpoint, SetpointSchedule};
use pneuflex_scene::Scene;
use pneuflex_scene::schema::{ControllerKind, RunSpec};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::{PyAny, PyDict};

use crate::errors;
use crate::model::{check_finite, check_positive};

fn build(run: &RunSpec, what: &str) -> PyResult<Box<dyn Controller + Send + Sync>> {
    run.build()
        .map_err(|e| errors::other(format!("{what}: {e}")))
}

/// Index of a run given by name (str) or index (int).
pub fn run_index(scene: &Scene, run: &Bound<'_, PyAny>) -> PyResult<usize> {
    if let Ok(i) = run.extract::<usize>() {
        if i < scene.runs.len() {
            return Ok(i);
        }
        return Err(errors::other(format!(
            "{}: runs: index {i} out of range, the scene has {} runs",
            scene.source.display(),
            scene.runs.len()
        )));
    }
    let name: String = run.extract()?;
    scene.run_index(&name).map_err(errors::scene)
}

/// An impedance or adaptive impedance controller with its inner position PID (Section III).
#[pyclass(name = "Controller", module = "pneuflex")]
pub struct PyController {
    ctl: Box<dyn Controller + Send + Sync>,
    kind: ControllerKind,
}

#[pymethods]
impl PyController {
    /// A controller from parameter dicts with the scene file's keys: `kind` = "impedance" | "adaptive";
    /// `impedance` = {m_d_kg, b_d_ns_per_m, k_d_n_per_m}; `inner` = {kp_per_m, ki_per_m_s, kd_s_per_m,
    /// derivative_filter_s, u_min, u_max, tracking_time_s}; `adaptive` = {lambda_p, lambda_d, mu1..3,
    /// sigma1..3, force_unit_n, position_unit_m, lambda_d_sign, sigma1_sign} (docs/scenes.md).
    #[new]
    #[pyo3(signature = (kind, impedance, inner, adaptive = None))]
    fn new(
        py: Python<'_>,
        kind: &str,
        impedance: &Bound<'_, PyDict>,
        inner: &Bound<'_, PyDict>,
        adaptive: Option<&Bound<'_, PyDict>>,
    ) -> PyResult<Self> {
        // The dicts go through the scene schema (serde, unknown keys rejected, defaults applied).
        let d = PyDict::new(py);
        d.set_item("name", "python")?;
        d.set_item("controller", kind)?;
        d.set_item("impedance", impedance)?;
        d.set_item("inner", inner)?;
        if let Some(a) = adaptive {
            d.set_item("adaptive", a)?;
        }
        let json: String = py.import("json")?.call_method1("dumps", (d,))?.extract()?;
        let run: RunSpec = serde_json::from_str(&json)
            .map_err(|e| errors::other(format!("controller parameters: {e}")))?;
        Ok(Self {
            ctl: build(&run, "controller parameters")?,
            kind: run.controller,
        })
    }

    /// The controller of run `run` (name or index) of the scene file at `scene_path`.
    #[staticmethod]
    fn from_scene(scene_path: crate::shipped::ScenePath, run: &Bound<'_, PyAny>) -> PyResult<Self> {
        let scene = Scene::load(&scene_path).map_err(errors::scene)?;
        let i = run_index(&scene, run)?;
        let what = format!("{}: runs[{i}]", scene_path.display());
        Ok(Self {
            ctl: build(&scene.runs[i], &what)?,
            kind: scene.runs[i].controller,
        })
    }

    /// One control tick: sensors (t s, x m, x_dot m/s, f_e N, p_a and p_b Pa absolute, NaN for a plant
    /// without chambers), setpoint (f_ref N, x_d m), period dt (s); returns the valve command u in [-1, 1].
    /// Any other non-finite input, or dt <= 0, is a ValueError naming it (a NaN force was read as a
    /// command of 0, a dt of 0 gave 0).
    #[allow(clippy::too_many_arguments)]
    fn update(
        &mut self,
        t: f64,
        x: f64,
        x_dot: f64,
        f_e: f64,
        p_a: f64,
        p_b: f64,
        f_ref: f64,
        x_d: f64,
        dt: f64,
    ) -> PyResult<f64> {
        for (name, v) in [
            ("t", t),
            ("x", x),
            ("x_dot", x_dot),
            ("f_e", f_e),
            ("f_ref", f_ref),
            ("x_d", x_d),
        ] {
            check_finite(name, v)?;
        }
        for (name, p) in [("p_a", p_a), ("p_b", p_b)] {
            if p.is_infinite() {
                return Err(PyValueError::new_err(format!(
                    "{name} must be finite (or NaN: no chambers), got {p}"
                )));
            }
        }
        check_positive("dt", dt)?;
        let s = Sensors {
            t,
            x,
            x_dot,
            f_e,
            p_a,
            p_b,
        };
        let sp = Setpoint { f_ref, x_d };
        Ok(self.ctl.update(&s, &sp, dt).u)
    }

    /// Internal signals of the last update: x_r, x_f, dx_f (m), e (N), then the controller's own signals by
    /// name (the adaptive law's g in m, p in m/N, d in s).
    fn telemetry<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let t = self.ctl.telemetry();
        let d = PyDict::new(py);
        d.set_item("x_r", t.x_r)?;
        d.set_item("x_f", t.x_f)?;
        d.set_item("dx_f", t.dx_f)?;
        d.set_item("e", t.e)?;
        // Then the controller's own signals under their declared names (g, p, d for adaptive).
        for (s, v) in self.ctl.signals().iter().zip(self.record()) {
            d.set_item(s.name, v)?;
        }
        Ok(d)
    }

    /// Reference position x_r of the last update, m (the hot-loop shortcut for telemetry()["x_r"]).
    #[getter]
    fn x_r(&self) -> f64 {
        self.ctl.telemetry().x_r
    }

    /// Names of the controller's own recorded signals (beyond the loop's), as the controller declares them.
    #[getter]
    fn signals(&self) -> Vec<&'static str> {
        self.ctl.signals().iter().map(|s| s.name).collect()
    }

    /// Values of `signals` after the last update, in the same order.
    fn record(&self) -> Vec<f64> {
        let mut out = vec![0.0; self.ctl.signals().len()];
        self.ctl.record(&mut out);
        out
    }

    /// The adaptive law's (g, p, d) of the last update in SI: its declared signals of those names, zeros
    /// for a controller that declares none (impedance).
    fn gpd(&self) -> (f64, f64, f64) {
        let values = self.record();
        let by_name = |n: &str| {
            self.ctl
                .signals()
                .iter()
                .position(|s| s.name == n)
                .map_or(0.0, |i| values[i])
        };
        (by_name("g"), by_name("p"), by_name("d"))
    }

    /// "impedance" or "adaptive".
    #[getter]
    fn kind(&self) -> &'static str {
        self.kind.name()
    }

    /// Back to the initial state (filters, integrators, adaptive parameters).
    fn reset(&mut self) {
        self.ctl.reset();
    }
}

/// The force and position reference schedule of a scene.
#[pyclass(name = "Setpoints", module = "pneuflex", frozen)]
pub struct PySetpoints {
    schedule: SetpointSchedule,
}

#[pymethods]
impl PySetpoints {
    /// The schedule of the scene file at `scene_path`.
    #[new]
    fn new(scene_path: crate::shipped::ScenePath) -> PyResult<Self> {
        let scene = Scene::load(&scene_path).map_err(errors::scene)?;
        Ok(Self {
            schedule: scene.setpoints().map_err(errors::scene)?,
        })
    }

    /// (f_ref N, x_d m) at time `t` (s); a non-finite `t` is a ValueError.
    fn at(&self, t: f64) -> PyResult<(f64, f64)> {
        check_finite("t", t)?;
        let s = self.schedule.at(t);
        Ok((s.f_ref, s.x_d))
    }
}
