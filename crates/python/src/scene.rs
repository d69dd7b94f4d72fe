//! Scenes in Python: load a scene file, run it through the scene crate's runner (traces as numpy arrays),
//! compute summary.json metrics of any traces (e.g. from MuJoCo), draw figures, and probe Rapier's step rate.

use std::path::{Path, PathBuf};
use std::time::Instant;

use numpy::{IntoPyArray, PyReadonlyArray1};
use pneuflex_multibody::{CarriageRig, RigConfig};
use pneuflex_scene::analysis::{adaptation::lyapunov_summary, windows::compute_windows};
use pneuflex_scene::schema::ControllerKind;
use pneuflex_scene::{RunResult, Scene, Trace, build_plant, run_scene, summary};
use pyo3::exceptions::{PyKeyError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::{PyAny, PyDict};

use crate::errors;

fn load(path: &Path) -> PyResult<Scene> {
    Scene::load(path).map_err(|e| {
        // A scene with [[actuators]] fails here on its first key ("unknown field `actuators`"): its own
        // loader's error, or where to run it.
        if !is_mechanism(path) {
            return errors::scene(e);
        }
        match pneuflex_scene::mechanism::MechanismScene::load(path) {
            Ok(_) => errors::other(format!(
                "{}: {}",
                path.display(),
                pneuflex_scene::schema::SEVERAL_ACTUATORS
            )),
            Err(e) => errors::scene(e),
        }
    })
}

/// Whether the file is a scene with `[[actuators]]` (as `pneuflex run` tells them apart).
fn is_mechanism(path: &Path) -> bool {
    std::fs::read_to_string(path)
        .is_ok_and(|t| pneuflex_scene::mechanism::MechanismScene::is_mechanism(&t))
}

/// A JSON-serialisable Rust value as Python objects (via the json module).
pub(crate) fn to_py<'py, T: serde::Serialize>(
    py: Python<'py>,
    v: &T,
) -> PyResult<Bound<'py, PyAny>> {
    let text = serde_json::to_string(v).map_err(errors::other)?;
    py.import("json")?.call_method1("loads", (text,))
}

/// The scene file at `path`, parsed and validated, as a dict of its keys (defaults filled in), plus
/// `source` (the file), `base_dir` (where relative paths resolve) and `n_steps` (control ticks).
#[pyfunction]
pub fn load_scene<'py>(
    py: Python<'py>,
    path: crate::shipped::ScenePath,
) -> PyResult<Bound<'py, PyAny>> {
    let scene = load(&path)?;
    let d = to_py(py, &scene)?;
    d.set_item("source", scene.source.display().to_string())?;
    d.set_item("base_dir", scene.base_dir.display().to_string())?;
    d.set_item("n_steps", scene.n_steps())?;
    Ok(d)
}

/// The signals every control loop records, in order: [(name, unit, group)], as `pneuflex-control` declares
/// them (`LOOP_SIGNALS`); a trace's further columns are the controller's `Controller.signals`.
#[pyfunction]
pub fn loop_signals() -> Vec<(&'static str, &'static str, &'static str)> {
    pneuflex_control::LOOP_SIGNALS
        .iter()
        .map(|s| (s.name, s.unit, s.group))
        .collect()
}

pub(crate) fn trace_to_dict<'py>(py: Python<'py>, tr: Trace) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    for (c, v) in tr.into_columns() {
        d.set_item(c.name, v.into_pyarray(py))?;
    }
    Ok(d)
}

fn column(d: &Bound<'_, PyDict>, key: &str, what: &str) -> PyResult<Option<Vec<f64>>> {
    let Some(v) = d.get_item(key)? else {
        return Ok(None);
    };
    if let Ok(a) = v.extract::<PyReadonlyArray1<'_, f64>>() {
        return Ok(Some(a.as_array().to_vec()));
    }
    v.extract::<Vec<f64>>().map(Some).map_err(|_| {
        PyValueError::new_err(format!("{what}: column `{key}` must be a 1-D float array"))
    })
}

/// A trace from a dict of arrays: the loop's columns (t, f_ref, f_e, x, x_r, p_a, p_b, u) required, any
/// other column (g, p, d, ...) kept in the dict's order.
fn trace_from_dict(d: &Bound<'_, PyDict>, what: &str) -> PyResult<Trace> {
    let mut cols = Vec::with_capacity(d.len());
    for s in pneuflex_control::LOOP_SIGNALS.iter() {
        let v = column(d, s.name, what)?
            .ok_or_else(|| PyKeyError::new_err(format!("{what}: missing column `{}`", s.name)))?;
        cols.push((pneuflex_scene::run::trace::Column::from(s), v));
    }
    for key in d.keys() {
        let key: String = key.extract()?;
        if pneuflex_control::LOOP_SIGNALS.iter().any(|s| s.name == key) {
            continue;
        }
        let v = column(d, &key, what)?.unwrap_or_default();
        cols.push((
            pneuflex_scene::run::trace::Column {
                name: key,
                unit: String::new(),
                group: String::new(),
            },
            v,
        ));
    }
    Trace::from_columns(cols).map_err(|e| PyValueError::new_err(format!("{what}: {e}")))
}

fn run_all(py: Python<'_>, scene: &Scene) -> PyResult<(Vec<RunResult>, f64)> {
    // The GIL is released while the Rust runner works.
    let (r, secs) = py.detach(|| {
        let t0 = Instant::now();
        let r = run_scene(scene, &mut |_| {});
        (r, t0.elapsed().as_secs_f64())
    });
    Ok((r.map_err(errors::scene)?, secs))
}

/// Runs every controller of the scene file with the scene crate's runner and returns
/// {run name: {column: numpy array}} with the trace.csv columns (t, f_ref, f_e, x, x_r, p_a, p_b, u and,
/// for adaptive runs, g, p, d). A diverged run's arrays stop where it diverged.
#[pyfunction]
pub fn run<'py>(
    py: Python<'py>,
    scene_path: crate::shipped::ScenePath,
) -> PyResult<Bound<'py, PyDict>> {
    let scene = load(&scene_path)?;
    let (results, _) = run_all(py, &scene)?;
    let out = PyDict::new(py);
    for r in results {
        out.set_item(r.name.clone(), trace_to_dict(py, r.trace)?)?;
    }
    Ok(out)
}

/// Like `run`, and also returns the summary.json content and the wall time of the runner (s):
/// `(traces, summary, wall_s)`.
#[pyfunction]
pub fn run_with_summary<'py>(
    py: Python<'py>,
    scene_path: crate::shipped::ScenePath,
) -> PyResult<(Bound<'py, PyDict>, Bound<'py, PyAny>, f64)> {
    // Every scene kind: one with [[actuators]] runs through the same loop, its summary per actuator.
    if is_mechanism(&scene_path) {
        return run_mechanism(py, scene_path);
    }
    let scene = load(&scene_path)?;
    let (results, wall) = run_all(py, &scene)?;
    let s = to_py(py, &summary(&scene, &results))?;
    let out = PyDict::new(py);
    for r in results {
        out.set_item(r.name.clone(), trace_to_dict(py, r.trace)?)?;
    }
    Ok((out, s, wall))
}

/// Like `run_with_summary`, and also each column's unit: `(traces, summary, wall_s, units)` with
/// `units = {run: {column: unit}}` as the trace declares them (trace.csv's header, `loop_signals()` and the
/// controller's and plant's own signals); `pneuflex.run` puts them in each DataFrame's `attrs["units"]`.
#[pyfunction]
#[allow(clippy::type_complexity)]
pub fn run_results<'py>(
    py: Python<'py>,
    scene_path: crate::shipped::ScenePath,
) -> PyResult<(
    Bound<'py, PyDict>,
    Bound<'py, PyAny>,
    f64,
    Bound<'py, PyDict>,
)> {
    let units = PyDict::new(py);
    let out = PyDict::new(py);
    let (summary, wall, runs) = if is_mechanism(&scene_path) {
        use pneuflex_scene::mechanism::{self, MechanismScene};
        let scene = MechanismScene::load(&scene_path).map_err(errors::scene)?;
        let start = Instant::now();
        let runs = py
            .detach(|| mechanism::run_all(&scene, &mut |_| {}, None, &mut ()))
            .map_err(errors::scene)?;
        let wall = start.elapsed().as_secs_f64();
        let s = to_py(py, &mechanism::summarise(&scene, &runs))?;
        (
            s,
            wall,
            runs.into_iter()
                .map(|r| (r.name, r.trace))
                .collect::<Vec<_>>(),
        )
    } else {
        let scene = load(&scene_path)?;
        let (results, wall) = run_all(py, &scene)?;
        let s = to_py(py, &summary(&scene, &results))?;
        (
            s,
            wall,
            results.into_iter().map(|r| (r.name, r.trace)).collect(),
        )
    };
    for (name, trace) in runs {
        let d = PyDict::new(py);
        let u = PyDict::new(py);
        for (c, v) in trace.into_columns() {
            u.set_item(&c.name, &c.unit)?;
            d.set_item(c.name, v.into_pyarray(py))?;
        }
        out.set_item(&name, d)?;
        units.set_item(name, u)?;
    }
    Ok((out, summary, wall, units))
}

/// summary.json content for traces produced elsewhere (e.g. MuJoCo): `traces` maps run names of the scene
/// to dicts of arrays; `diverged` optionally maps run names to the reason they stopped. The metrics are the
/// scene crate's own (same windows, same formulas as `pneuflex run`).
#[pyfunction]
#[pyo3(signature = (scene_path, traces, diverged = None))]
pub fn summarize<'py>(
    py: Python<'py>,
    scene_path: crate::shipped::ScenePath,
    traces: &Bound<'py, PyDict>,
    diverged: Option<&Bound<'py, PyDict>>,
) -> PyResult<Bound<'py, PyAny>> {
    let scene = load(&scene_path)?;
    let mut results = Vec::new();
    for (k, v) in traces.iter() {
        let name: String = k.extract()?;
        let i = crate::controller::run_index(&scene, &k)?;
        let d = v.cast::<PyDict>().map_err(|_| {
            PyValueError::new_err(format!("traces[{name:?}] must be a dict of arrays"))
        })?;
        let trace = trace_from_dict(d, &format!("traces[{name:?}]"))?;
        let reason: Option<String> = match diverged {
            Some(dv) => dv.get_item(&name)?.map(|r| r.extract()).transpose()?,
            None => None,
        };
        let run = &scene.runs[i];
        let pwm_period_s = scene_pwm_period(&scene);
        let windows = if reason.is_none() {
            compute_windows(&scene, &trace, pwm_period_s)
        } else {
            Vec::new()
        };
        let lyapunov = (run.controller == ControllerKind::Adaptive)
            .then(|| lyapunov_summary(&scene, run))
            .flatten();
        results.push(RunResult {
            name,
            controller: run.controller,
            trace,
            windows,
            lyapunov,
            diverged: reason,
            interrupted: None,
            warnings: Vec::new(),
            pwm_period_s,
        });
    }
    to_py(py, &summary(&scene, &results))
}

#[cfg(feature = "figures")]
/// Runs every controller of the scene file and writes the output directory `pneuflex run --out OUT_DIR`
/// writes (each run's trace, summary.json, the figures, the manifest), through the same pipeline
/// (pneuflex-outputs); returns the directory. A directory pneuflex did not write is never replaced.
#[pyfunction]
pub fn run_to(
    py: Python<'_>,
    scene_path: crate::shipped::ScenePath,
    out_dir: PathBuf,
) -> PyResult<String> {
    use pneuflex_outputs::{Outcome, Outputs, Simulate, simulate_into};
    let scene = load(&scene_path)?;
    let outputs =
        Outputs::stage(&scene, &scene_path, &out_dir, "run", &[]).map_err(errors::other)?;
    let simulated = py
        .detach(|| simulate_into(&scene, outputs, Simulate::default(), &mut |_| {}, &mut ()))
        .map_err(errors::other)?;
    match simulated.outcome {
        Outcome::Committed(dest) => Ok(dest.display().to_string()),
        // No stop flag is given: a run is never cut.
        Outcome::Partial(s) => Err(errors::other(format!("stopped: {}", s.reason))),
    }
}

#[cfg(feature = "figures")]
/// Draws force.<fmt>, position.<fmt> and event-<i>.<fmt> of the scene into `out_dir` with one line per
/// entry of `runs` ({legend label: dict of arrays}); returns the files written. `fmt` is "png" or "svg".
#[pyfunction]
#[pyo3(signature = (scene_path, out_dir, runs, fmt = "png"))]
pub fn write_figures<'py>(
    py: Python<'py>,
    scene_path: crate::shipped::ScenePath,
    out_dir: PathBuf,
    runs: &Bound<'py, PyDict>,
    fmt: &str,
) -> PyResult<Bound<'py, pyo3::types::PyList>> {
    let scene = load(&scene_path)?;
    let format = match fmt {
        "png" => pneuflex_viz::Format::Png,
        "svg" => pneuflex_viz::Format::Svg,
        other => {
            return Err(PyValueError::new_err(format!(
                "fmt must be \"png\" or \"svg\", got {other:?}"
            )));
        }
    };
    let mut results = Vec::new();
    for (k, v) in runs.iter() {
        let name: String = k.extract()?;
        let d = v.cast::<PyDict>().map_err(|_| {
            PyValueError::new_err(format!("runs[{name:?}] must be a dict of arrays"))
        })?;
        let trace = trace_from_dict(d, &format!("runs[{name:?}]"))?;
        let controller = if !trace.has("g") {
            ControllerKind::Impedance
        } else {
            ControllerKind::Adaptive
        };
        results.push(RunResult {
            name,
            controller,
            trace,
            windows: Vec::new(),
            lyapunov: None,
            diverged: None,
            interrupted: None,
            warnings: Vec::new(),
            pwm_period_s: scene_pwm_period(&scene),
        });
    }
    std::fs::create_dir_all(&out_dir).map_err(|e| {
        pyo3::exceptions::PyOSError::new_err(format!("{}: cannot create: {e}", out_dir.display()))
    })?;
    let files =
        pneuflex_viz::write_figures(&out_dir, &scene, &results, format).map_err(errors::other)?;
    pyo3::types::PyList::new(py, files.iter().map(|p| p.display().to_string()))
}

/// The plant's initial sensor reading for the scene (x m, x_dot m/s, f_e N, p_a and p_b Pa absolute), the
/// state every run starts from.
#[pyfunction]
pub fn initial_state<'py>(
    py: Python<'py>,
    scene_path: crate::shipped::ScenePath,
) -> PyResult<Bound<'py, PyDict>> {
    let scene = load(&scene_path)?;
    let plant = build_plant(&scene).map_err(errors::scene)?;
    let s = plant.sense();
    let d = PyDict::new(py);
    d.set_item("x", s.x)?;
    d.set_item("x_dot", s.x_dot)?;
    d.set_item("f_e", s.f_e)?;
    d.set_item("p_a", s.p_a)?;
    d.set_item("p_b", s.p_b)?;
    Ok(d)
}

/// Steps per second of the Rapier rig world (`urdf_path`, the paper rig's roles and materials) at physics
/// step `dt_s` with a constant push `force_n` on the flange, `n_steps` steps, incline `alpha_deg`:
/// {steps_per_s, x, f_e} (x and f_e at the end, for a sanity check of the steady contact).
#[pyfunction]
#[pyo3(signature = (urdf_path, dt_s = 1e-3, n_steps = 10000, force_n = 10.0, alpha_deg = 0.0, solver_iterations = 4))]
pub fn bench_rapier<'py>(
    py: Python<'py>,
    urdf_path: PathBuf,
    dt_s: f64,
    n_steps: usize,
    force_n: f64,
    alpha_deg: f64,
    solver_iterations: usize,
) -> PyResult<Bound<'py, PyDict>> {
    let config = RigConfig {
        dt_s,
        alpha_rad: alpha_deg.to_radians(),
        solver_iterations,
        ..RigConfig::paper_rig()
    };
    let mut world = CarriageRig::from_urdf(&urdf_path, &config).map_err(errors::other)?;
    let t0 = Instant::now();
    let mut m = world.measurements();
    for _ in 0..n_steps {
        m = world.step_with_force(force_n);
    }
    let secs = t0.elapsed().as_secs_f64();
    let d = PyDict::new(py);
    d.set_item("steps_per_s", n_steps as f64 / secs)?;
    d.set_item("x", m.x)?;
    d.set_item("f_e", m.f_e)?;
    Ok(d)
}

/// Wall time of the scene runner's control tick without Python in the loop (scripts/bench): run `run` (name
/// or index) of the scene on a fresh plant, first `settle_s` of ticks untimed (steady contact), then `ticks`
/// timed ticks of sense → controller update → actuate → advance(dt), the runner's tick without events,
/// recording or checks (for a multibody scene: the Rapier step(s), the chamber substeps and the controller).
/// Returns {wall_s, ticks, dt_s, x, f_e} (x and f_e at the end, for a sanity check).
#[pyfunction]
#[pyo3(signature = (scene_path, run, ticks = 10000, settle_s = 1.0))]
pub fn bench_scene_ticks<'py>(
    py: Python<'py>,
    scene_path: crate::shipped::ScenePath,
    run: &Bound<'py, PyAny>,
    ticks: usize,
    settle_s: f64,
) -> PyResult<Bound<'py, PyDict>> {
    let scene = load(&scene_path)?;
    let index = crate::controller::run_index(&scene, run)?;
    // The product's loop (host, trace, checks), as `pneuflex run` runs it; the GIL stays held (a scene's
    // plant need not be Send) and no Python runs in the loop.
    let timing = pneuflex_scene::time_ticks(&scene, index, ticks as u64, settle_s.max(0.0))
        .map_err(errors::scene)?;
    let (secs, dt) = (timing.wall.as_secs_f64(), scene.dt_s);
    use pneuflex_control::signal::index as col;
    let (x, f_e) = (timing.last_row[col::X], timing.last_row[col::F_E]);
    let d = PyDict::new(py);
    d.set_item("wall_s", secs)?;
    d.set_item("ticks", ticks)?;
    d.set_item("dt_s", dt)?;
    d.set_item("x", x)?;
    d.set_item("f_e", f_e)?;
    Ok(d)
}

/// The PWM period of the scene's valve as its own (Rust) plant reports it: for traces made elsewhere
/// (MuJoCo, a plant written in Python), whose metrics average over the same period as `pneuflex run`'s.
pub(crate) fn scene_pwm_period(scene: &pneuflex_scene::Scene) -> Option<f64> {
    pneuflex_scene::build_plant(scene).ok()?.pwm_period_s()
}

/// Runs a scene with `[[actuators]]` (any URDF, several cylinders; docs/multibody.md) and returns
/// `(traces, summary, wall_s)`: per run a dict of its columns (`t`, `<actuator>.f_e`, ...) as numpy arrays,
/// the summary.json content, and the runner's wall time (s).
#[pyfunction]
pub fn run_mechanism<'py>(
    py: Python<'py>,
    scene_path: crate::shipped::ScenePath,
) -> PyResult<(Bound<'py, PyDict>, Bound<'py, PyAny>, f64)> {
    use pneuflex_scene::mechanism::{self, MechanismScene};
    let scene = MechanismScene::load(&scene_path).map_err(|e| {
        if !is_mechanism(&scene_path) && Scene::load(&scene_path).is_ok() {
            errors::other(format!(
                "{}: a scene with one [plant], not [[actuators]]: run it with pneuflex.run",
                scene_path.display()
            ))
        } else {
            errors::scene(e)
        }
    })?;
    let start = Instant::now();
    let runs = py
        .detach(|| mechanism::run_all(&scene, &mut |_| {}, None, &mut ()))
        .map_err(errors::scene)?;
    let wall = start.elapsed().as_secs_f64();
    let s = to_py(py, &mechanism::summarise(&scene, &runs))?;
    let out = PyDict::new(py);
    for r in runs {
        let d = PyDict::new(py);
        for (c, v) in r.trace.into_columns() {
            d.set_item(c.name, v.into_pyarray(py))?;
        }
        out.set_item(r.name.clone(), d)?;
    }
    Ok((out, s, wall))
}
