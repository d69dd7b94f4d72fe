//! Either kind of scene file, for the commands that take every scene (`sweep`, `tune`, Python's sweeps): a
//! one-actuator scene (`[plant]`) or a mechanism with `[[actuators]]`. What such a command asks of a scene —
//! its runs, its metric columns and their values, running it, writing a point's traces — is answered here
//! once for both kinds, so a command written against [`AnyScene`] takes every scene.

use std::path::{Path, PathBuf};
use std::sync::atomic::AtomicUsize;

use pneuflex_control::Setpoint;

use crate::error::SceneError;
use crate::mechanism::MechanismScene;
use crate::plants::Plant;
use crate::run::{RunResult, Sink, WindowMetrics};
use crate::schema::{Limits, RunSpec, Scene, WindowKind};

/// A scene file of either kind.
#[derive(Clone, Debug)]
pub enum AnyScene {
    /// One actuator on a `[plant]`.
    One(Box<Scene>),
    /// Several actuators on a URDF mechanism (`[[actuators]]`).
    Mechanism(Box<MechanismScene>),
}

/// A metric column of a scene's table: a window's metric, and for a mechanism the actuator it is of.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct MetricColumn {
    /// Window name.
    pub window: String,
    /// The actuator (mechanism scenes; None for a one-actuator scene and for `force_imbalance_n`).
    pub actuator: Option<String>,
    /// Metric, as summary.json names it.
    pub metric: &'static str,
}

impl MetricColumn {
    /// `window.metric`, or `window.actuator.metric`: the table's header.
    pub fn name(&self) -> String {
        match &self.actuator {
            Some(a) => format!("{}.{a}.{}", self.window, self.metric),
            None => format!("{}.{}", self.window, self.metric),
        }
    }
}

/// The metrics each window kind of a one-actuator scene has, in column order.
pub fn window_metrics(kind: WindowKind) -> &'static [&'static str] {
    match kind {
        WindowKind::Sine => &["rms_force_error_n", "phase_lag_deg", "amplitude_ratio"],
        WindowKind::Step => &["rms_force_error_n", "steady_state_error_n"],
        WindowKind::Event => &[
            "rms_force_error_n",
            "peak_force_n",
            "jump_n",
            "recovery_overshoot_n",
            "recovery_overshoot_pct",
            "settling_time_s",
            "settling_fragile",
            "tracking_error_n",
        ],
    }
}

/// A metric of a one-actuator scene's window; a settling time of a run that did not settle is infinite.
pub fn metric_of(w: &WindowMetrics, metric: &str) -> Option<f64> {
    let ev = w.event.as_ref();
    match metric {
        "rms_force_error_n" => Some(w.rms_force_error_n),
        "phase_lag_deg" => w.phase_lag_deg,
        "amplitude_ratio" => w.amplitude_ratio,
        "steady_state_error_n" => w.steady_state_error_n,
        "peak_force_n" => ev.map(|e| e.peak_force_n),
        "jump_n" => ev.map(|e| e.jump_n),
        "recovery_overshoot_n" => ev.map(|e| e.recovery_overshoot_n),
        "recovery_overshoot_pct" => ev.map(|e| e.recovery_overshoot_pct),
        "settling_time_s" => ev.map(|e| e.settling_time_s.unwrap_or(f64::INFINITY)),
        // 1 when the settling time hangs on where the band is drawn (docs/scenes.md), else 0.
        "settling_fragile" => ev.map(|e| f64::from(u8::from(e.settling_fragile))),
        "tracking_error_n" => ev.map(|e| e.tracking_error_n),
        _ => None,
    }
}

/// The per-actuator metrics of a mechanism window, in column order (`force_imbalance_n` follows them).
const ACTUATOR_METRICS: [&str; 3] = ["rms_force_error_n", "max_abs_force_error_n", "mean_force_n"];

impl AnyScene {
    /// Reads a scene file of either kind.
    pub fn load(path: &Path) -> Result<AnyScene, SceneError> {
        let text = pneuflex_files::read_text(path, pneuflex_files::InputKind::Scene)?;
        let base = path.parent().map(Path::to_path_buf).unwrap_or_default();
        Self::from_toml_str(&text, path, &base)
    }

    /// Parses scene text of either kind; `file` names it in errors, `base_dir` resolves a one-actuator
    /// scene's relative paths (a mechanism resolves them against `file`'s folder).
    pub fn from_toml_str(text: &str, file: &Path, base_dir: &Path) -> Result<AnyScene, SceneError> {
        if MechanismScene::is_mechanism(text) {
            MechanismScene::from_toml_str(text, file).map(|m| AnyScene::Mechanism(Box::new(m)))
        } else {
            Scene::from_toml_str(text, file, base_dir).map(|s| AnyScene::One(Box::new(s)))
        }
    }

    /// The one-actuator scene, if it is one.
    pub fn one(&self) -> Option<&Scene> {
        match self {
            AnyScene::One(s) => Some(s),
            AnyScene::Mechanism(_) => None,
        }
    }

    /// Scene name.
    pub fn name(&self) -> &str {
        match self {
            AnyScene::One(s) => &s.name,
            AnyScene::Mechanism(m) => &m.name,
        }
    }

    /// The controller runs compared.
    pub fn runs(&self) -> &[RunSpec] {
        match self {
            AnyScene::One(s) => &s.runs,
            AnyScene::Mechanism(m) => &m.runs,
        }
    }

    /// Simulated time, s.
    pub fn duration_s(&self) -> f64 {
        match self {
            AnyScene::One(s) => s.duration_s,
            AnyScene::Mechanism(m) => m.duration_s,
        }
    }

    /// Control period, s.
    pub fn dt_s(&self) -> f64 {
        match self {
            AnyScene::One(s) => s.dt_s,
            AnyScene::Mechanism(m) => m.dt_s,
        }
    }

    /// The scene's text as read (errors point into it).
    pub fn text(&self) -> &str {
        match self {
            AnyScene::One(s) => &s.text,
            AnyScene::Mechanism(m) => &m.text,
        }
    }

    /// Puts back the text of the file as the user wrote it (a sweep parses an edited copy; its errors and
    /// summaries point at the original).
    pub fn set_text(&mut self, text: String) {
        match self {
            AnyScene::One(s) => s.text = text,
            AnyScene::Mechanism(m) => m.text = text,
        }
    }

    /// The index of the run named `name`; the error lists the scene's runs.
    pub fn run_index(&self, name: &str) -> Result<usize, SceneError> {
        match self {
            AnyScene::One(s) => s.run_index(name),
            AnyScene::Mechanism(m) => m.runs.iter().position(|r| r.name == name).ok_or_else(|| {
                let names: Vec<&str> = m.runs.iter().map(|r| r.name.as_str()).collect();
                m.invalid(
                    "runs",
                    format!("no run named {name:?}, expected one of {names:?}"),
                )
            }),
        }
    }

    /// Keeps only run `run` and no claims (a tuner's candidate runs the tuned run alone).
    pub fn keep_only_run(&mut self, run: usize) {
        match self {
            AnyScene::One(s) => {
                s.runs = vec![s.runs[run].clone()];
                s.claims.clear();
            }
            AnyScene::Mechanism(m) => {
                m.runs = vec![m.runs[run].clone()];
                m.claims.clear();
            }
        }
    }

    /// Every scene key that names a file, with the file resolved (a copy of the scene written elsewhere
    /// names them relative to its new folder): `plant.actuator` and `plant.urdf`, or `urdf` and each
    /// `actuators[i].sheet`.
    pub fn named_files(&self) -> Vec<(String, PathBuf)> {
        match self {
            AnyScene::One(s) => s
                .plant
                .files()
                .into_iter()
                .map(|(key, p)| (key.to_string(), s.resolve(p)))
                .collect(),
            AnyScene::Mechanism(m) => std::iter::once(("urdf".to_string(), m.resolve(&m.urdf)))
                .chain(
                    m.actuators
                        .iter()
                        .enumerate()
                        .map(|(i, a)| (format!("actuators[{i}].sheet"), m.resolve(&a.sheet))),
                )
                .collect(),
        }
    }

    /// Whether the scene loads whole: a one-actuator scene's plant builds, a mechanism's sheets and URDF
    /// read.
    pub fn check_builds(&self) -> Result<(), SceneError> {
        match self {
            AnyScene::One(s) => crate::build_plant(s).map(drop),
            AnyScene::Mechanism(m) => crate::mechanism::MechanismPlant::new(m).map(drop),
        }
    }

    /// The metric column `WINDOW.METRIC` (one actuator) or `WINDOW.ACTUATOR.METRIC` / `WINDOW.force_imbalance_n`
    /// (a mechanism); the error lists the scene's.
    pub fn metric_column(&self, name: &str) -> Result<MetricColumn, String> {
        let columns = self.metric_columns();
        columns
            .iter()
            .find(|c| c.name() == name)
            .cloned()
            .ok_or_else(|| {
                let known: Vec<String> = columns.iter().map(MetricColumn::name).collect();
                format!(
                    "no metric column {name:?}; the scene's are {}",
                    known.join(", ")
                )
            })
    }

    /// The files the scene reads, the scene file first.
    pub fn input_files(&self, scene_path: &Path) -> Vec<PathBuf> {
        let mut inputs = vec![scene_path.to_path_buf()];
        match self {
            AnyScene::One(s) => inputs.extend(s.input_files().into_iter().skip(1).map(|(_, p)| p)),
            AnyScene::Mechanism(m) => {
                inputs.extend(m.input_files().into_iter().skip(1).map(|(_, p)| p))
            }
        }
        inputs
    }

    /// The digests of the files the scene reads, for a manifest.
    pub fn input_digests(&self) -> Vec<pneuflex_files::InputDigest> {
        match self {
            AnyScene::One(s) => crate::scene_inputs(s),
            AnyScene::Mechanism(m) => m
                .input_files()
                .iter()
                .filter_map(|(role, p)| pneuflex_files::InputDigest::of_file(p, role).ok())
                .collect(),
        }
    }

    /// Refuses a run that would cost more than `limits` (steps or trace size), naming the key.
    pub fn check_budget(&self, limits: &Limits) -> Result<(), SceneError> {
        match self {
            AnyScene::One(s) => s.check_budget(limits).map(drop),
            AnyScene::Mechanism(m) => m.check_budget(limits),
        }
    }

    /// The metric columns of the scene's table: each window's metrics (a one-actuator scene's by its
    /// window kind; a mechanism's per actuator, then the window's force imbalance).
    pub fn metric_columns(&self) -> Vec<MetricColumn> {
        match self {
            AnyScene::One(s) => s
                .metrics
                .iter()
                .flat_map(|w| {
                    window_metrics(w.kind).iter().map(|m| MetricColumn {
                        window: w.name.clone(),
                        actuator: None,
                        metric: m,
                    })
                })
                .collect(),
            AnyScene::Mechanism(m) => m
                .metrics
                .iter()
                .flat_map(|w| {
                    let per = m.actuators.iter().flat_map(move |a| {
                        ACTUATOR_METRICS.iter().map(move |metric| MetricColumn {
                            window: w.name.clone(),
                            actuator: Some(a.name.clone()),
                            metric,
                        })
                    });
                    per.chain(std::iter::once(MetricColumn {
                        window: w.name.clone(),
                        actuator: None,
                        metric: "force_imbalance_n",
                    }))
                })
                .collect(),
        }
    }

    /// Sets the simulated time, s (`pneuflex ros2 --duration`): the runs last this long, the events and the
    /// reference keep their times.
    pub fn set_duration(&mut self, duration_s: f64) {
        match self {
            AnyScene::One(s) => s.duration_s = duration_s,
            AnyScene::Mechanism(m) => m.duration_s = duration_s,
        }
    }

    /// Run `run` alone on this thread, actuator `i`'s setpoint at `t` being `reference(i, t, scheduled)`
    /// with `scheduled` the scene's own (`pneuflex ros2`: the force a ROS 2 system commands while it
    /// commands one); `observer` sees every tick and its `end`; a non-zero `stop` ends the run at the next
    /// tick, marked interrupted. The result has no window metrics: its reference need not be the scene's.
    pub fn run_referenced(
        &self,
        run: usize,
        reference: &mut dyn FnMut(usize, f64, Setpoint) -> Setpoint,
        observer: &mut dyn Sink<dyn Plant>,
        stop: Option<&AtomicUsize>,
    ) -> Result<RunResult, SceneError> {
        match self {
            AnyScene::One(s) => {
                let mut plant = crate::build_plant(s)?;
                let mut controller = s.controller(run)?;
                let setpoints = s.setpoints()?;
                let r = crate::run::simulate_referenced(
                    s,
                    run,
                    plant.as_mut(),
                    controller.as_mut(),
                    &mut |i, t| reference(i, t, setpoints.at(t)),
                    &mut |_| {},
                    observer,
                    stop,
                )?;
                observer.end(r.diverged.as_deref().or(r.interrupted.as_deref()));
                Ok(r)
            }
            AnyScene::Mechanism(m) => {
                crate::mechanism::run::run_one(m, run, reference, &mut |_| {}, observer, stop)
            }
        }
    }

    /// Every run of the scene, one after another on this thread; `progress` gets the fraction done.
    pub fn run(&self, progress: &mut dyn FnMut(f64)) -> Result<Vec<RunResult>, SceneError> {
        match self {
            AnyScene::One(s) => crate::run_scene(s, progress),
            AnyScene::Mechanism(m) => crate::mechanism::run_all(m, progress, None, &mut ()),
        }
    }

    /// The value of every column in `columns` for one run (None: not measured, or the run diverged).
    pub fn values(&self, r: &RunResult, columns: &[MetricColumn]) -> Vec<Option<f64>> {
        if r.diverged.is_some() {
            return vec![None; columns.len()];
        }
        match self {
            AnyScene::One(_) => columns
                .iter()
                .map(|c| r.window(&c.window).and_then(|w| metric_of(w, c.metric)))
                .collect(),
            AnyScene::Mechanism(m) => {
                let windows: Vec<crate::mechanism::summary::WindowMetrics> = m
                    .metrics
                    .iter()
                    .map(|w| crate::mechanism::summary::window_metrics(m, r, w))
                    .collect();
                columns
                    .iter()
                    .map(|c| {
                        let w = windows.iter().find(|w| w.window == c.window)?;
                        let value = match &c.actuator {
                            None if c.metric == "force_imbalance_n" => w.force_imbalance_n,
                            None => return None,
                            Some(a) => {
                                let (_, am) = w.actuators.iter().find(|(n, _)| n == a)?;
                                match c.metric {
                                    "rms_force_error_n" => am.rms_force_error_n,
                                    "max_abs_force_error_n" => am.max_abs_force_error_n,
                                    "mean_force_n" => am.mean_force_n,
                                    _ => return None,
                                }
                            }
                        };
                        // A window with no sample (NaN) is not measured.
                        (!value.is_nan()).then_some(value)
                    })
                    .collect()
            }
        }
    }

    /// The event windows of a run that did not settle, with why (`window: reason`); a mechanism's windows
    /// have no settling.
    pub fn unsettled(&self, r: &RunResult) -> Vec<String> {
        r.windows
            .iter()
            .filter_map(|w| {
                let e = w.event.as_ref()?;
                (!e.settled).then(|| {
                    format!(
                        "{}: {}",
                        w.name,
                        e.not_settled.as_deref().unwrap_or("not settled")
                    )
                })
            })
            .collect()
    }

    /// Writes the runs' traces and summary.json into `dir`, as `run` writes them.
    pub fn write_results(&self, dir: &Path, runs: &[RunResult]) -> Result<(), SceneError> {
        match self {
            AnyScene::One(s) => crate::write_results(dir, s, runs),
            AnyScene::Mechanism(m) => {
                crate::mechanism::write(dir, &crate::mechanism::summarise(m, runs), runs)
            }
        }
    }
}
