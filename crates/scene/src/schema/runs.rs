//! `[[runs]]`: the named controller runs a scene compares, and the one way a controller is built from one.

use serde::{Deserialize, Serialize};

use super::Scene;
use crate::error::SceneError;
use crate::origin::Check;
pub use pneuflex_control::{AdaptiveParams, ImpedanceParams, PidParams};

/// One named controller run.
#[derive(Clone, Debug, Deserialize, Serialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct RunSpec {
    /// Run name: a directory `<out>/<name>/` and a legend entry.
    pub name: String,
    /// Which controller.
    pub controller: ControllerKind,
    /// Target impedance m_d, b_d, k_d (the control crate's parameters, as the file writes them).
    pub impedance: ImpedanceParams,
    /// Adaptive law gains (required for, and only allowed with, `controller = "adaptive"`).
    #[serde(default)]
    pub adaptive: Option<AdaptiveParams>,
    /// Inner position loop.
    pub inner: PidParams,
    /// Runs the adaptive controller of another run with its parameters held for the whole run (at that
    /// run's means, or at its projection bounds) instead of adapted: what the adaptation itself earns.
    /// The loader copies `controller`, `impedance`, `adaptive` and `inner` from that run.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub frozen: Option<FrozenSpec>,
}

/// `frozen = { run = "adaptive", at = "means" }`: the run whose law is held, and at which values.
#[derive(Clone, Debug, Deserialize, Serialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct FrozenSpec {
    /// The adaptive run whose controller is copied and whose trace gives the values.
    pub run: String,
    /// Which values the parameters are held at.
    pub at: FrozenAt,
}

/// Where a frozen run holds g, p, d.
#[derive(Clone, Copy, Debug, Deserialize, Serialize, PartialEq, Eq)]
#[serde(rename_all = "lowercase")]
pub enum FrozenAt {
    /// The means over the source run's trace of g, p and d.
    Means,
    /// p at p_max_m_per_n and d at its bound (-d_max_s with λd carried through from ė, +d_max_s as
    /// printed), g at its mean: what the projection bound alone would give.
    Bounds,
}

impl FrozenAt {
    /// `"means"` or `"bounds"`.
    pub fn name(self) -> &'static str {
        match self {
            FrozenAt::Means => "means",
            FrozenAt::Bounds => "bounds",
        }
    }
}

/// The values a frozen run holds, in SI: g in m, p in m/N, d in s.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
pub struct FrozenValues {
    /// Auxiliary term g, m.
    pub g_m: f64,
    /// Proportional factor p, m/N.
    pub p_m_per_n: f64,
    /// Differential factor d, s.
    pub d_s: f64,
}

/// Why a run's controller cannot be built: the key inside the run's table and what is wrong.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[error("{key}: {message}")]
pub struct RunSpecError {
    /// Key relative to the run (`adaptive`, `inner.kp_per_m`, ...).
    pub key: String,
    /// What is wrong.
    pub message: String,
}

impl RunSpec {
    /// The controller this run describes, with validated parameters: the one way every caller (the
    /// scene runner, the rig, Python, the cross-validation) builds a controller. A frozen run has no
    /// controller until its source has run: see [`RunSpec::build_frozen`].
    pub fn build(
        &self,
    ) -> Result<Box<dyn pneuflex_control::Controller + Send + Sync>, RunSpecError> {
        if let Some(f) = &self.frozen {
            return Err(RunSpecError {
                key: "frozen".into(),
                message: format!(
                    "a frozen run holds values that run `{}` reaches: it runs only after it, within the whole \
                     scene (`pneuflex run`)",
                    f.run
                ),
            });
        }
        self.build_with(None)
    }

    /// The controller of a frozen run, holding `values` (from [`crate::analysis::adaptation::frozen_values`]).
    pub fn build_frozen(
        &self,
        values: FrozenValues,
    ) -> Result<Box<dyn pneuflex_control::Controller + Send + Sync>, RunSpecError> {
        if self.frozen.is_none() {
            return Err(RunSpecError {
                key: "frozen".into(),
                message: "this run is not frozen: it has no values to hold".into(),
            });
        }
        self.build_with(Some(values))
    }

    /// What the board builds this run's controller from (`pneuflex rig pil`): its kind and parameters,
    /// checked here first as [`RunSpec::build`] checks them, so that a bad value is named by its key
    /// before anything is sent. A frozen run is refused: its values come from another run's trace.
    pub fn board_setup(&self) -> Result<pneuflex_control::ControllerSetup, RunSpecError> {
        use pneuflex_control::ControllerSetup;
        if let Some(f) = &self.frozen {
            return Err(RunSpecError {
                key: "frozen".into(),
                message: format!(
                    "holds the controller of `{}` with g, p, d fixed: the board runs the adapting controllers \
                     only; choose another run",
                    f.run
                ),
            });
        }
        self.build()?;
        // One arm per kind: a controller for the board is a compile error here until it has its setup.
        Ok(match self.controller {
            ControllerKind::Impedance => ControllerSetup::Impedance {
                impedance: self.impedance,
                pid: self.inner,
            },
            ControllerKind::Adaptive => ControllerSetup::Adaptive {
                impedance: self.impedance,
                adaptive: self.adaptive.ok_or_else(|| RunSpecError {
                    key: "adaptive".into(),
                    message: "missing".into(),
                })?,
                pid: self.inner,
            },
        })
    }

    fn build_with(
        &self,
        frozen: Option<FrozenValues>,
    ) -> Result<Box<dyn pneuflex_control::Controller + Send + Sync>, RunSpecError> {
        use pneuflex_control::{AdaptiveImpedanceController, ImpedanceController, ParamError};
        let bad = |table: &str| {
            let table = table.to_string();
            move |e: ParamError| RunSpecError {
                key: match e.field() {
                    Some(f) => format!("{table}.{f}"),
                    None => table.clone(),
                },
                message: e.reason().to_string(),
            }
        };
        // The kind and its tables first, then each table by the control crate's own checks, in the order a
        // reader of the run meets them. One arm per kind: a new kind is a compile error here until it is
        // built.
        let shared = || -> Result<(), RunSpecError> {
            self.impedance.validate().map_err(bad("impedance"))?;
            self.inner.validate().map_err(bad("inner"))
        };
        Ok(match self.controller {
            ControllerKind::Impedance => {
                if self.adaptive.is_some() {
                    return Err(RunSpecError {
                        key: "adaptive".into(),
                        message: "only allowed with controller = \"adaptive\"".into(),
                    });
                }
                shared()?;
                Box::new(
                    ImpedanceController::new(self.impedance, self.inner)
                        .map_err(bad("impedance"))?,
                )
            }
            ControllerKind::Adaptive => {
                let Some(a) = self.adaptive else {
                    return Err(RunSpecError {
                        key: "adaptive".into(),
                        message: "missing: controller = \"adaptive\" needs the adaptive gains"
                            .into(),
                    });
                };
                a.validate().map_err(bad("adaptive"))?;
                shared()?;
                match frozen {
                    Some(v) => Box::new(
                        AdaptiveImpedanceController::frozen(
                            self.impedance,
                            a,
                            self.inner,
                            v.g_m,
                            v.p_m_per_n,
                            v.d_s,
                        )
                        .map_err(bad("frozen"))?,
                    ),
                    None => Box::new(
                        AdaptiveImpedanceController::new(self.impedance, a, self.inner)
                            .map_err(bad("adaptive"))?,
                    ),
                }
            }
        })
    }
}

/// The controller of a run.
#[derive(Clone, Copy, Debug, Deserialize, Serialize, PartialEq, Eq)]
#[serde(rename_all = "lowercase")]
// Non-exhaustive: beyond this crate, a host that serves some kinds only (the Gymnasium environment) refuses
// the others by name, so that a new controller touches the scene and control crates only.
#[non_exhaustive]
pub enum ControllerKind {
    /// Position-based impedance control, eqs. (19)–(24), with the inner position PID.
    Impedance,
    /// Model-reference adaptive impedance control, eqs. (25)–(36), with the inner position PID.
    Adaptive,
}

impl ControllerKind {
    /// `"impedance"` or `"adaptive"`.
    pub fn name(self) -> &'static str {
        match self {
            ControllerKind::Impedance => "impedance",
            ControllerKind::Adaptive => "adaptive",
        }
    }
}

/// Checks `[[runs]]`: names, and each controller's parameters by the control crate's own checks.
pub(crate) fn validate(scene: &Scene, v: &Check<'_>) -> Result<(), SceneError> {
    if scene.runs.is_empty() {
        return Err(v.err("runs", "needs at least one run".into()));
    }
    for (i, run) in scene.runs.iter().enumerate() {
        let at = |k: &str| format!("runs[{i}].{k}");
        if run.name.trim().is_empty()
            || run.name.contains(['/', '\\'])
            || run.name == "."
            || run.name == ".."
        {
            return Err(v.err(
                &at("name"),
                format!("must be a non-empty directory name, got {:?}", run.name),
            ));
        }
        if scene.runs[..i].iter().any(|r| r.name == run.name) {
            return Err(v.err(&at("name"), format!("duplicate run name {:?}", run.name)));
        }
        // The one check of a run's controller: building it.
        run.build_with(run.frozen.as_ref().map(|_| FrozenValues::default()))
            .map_err(|e| v.err(&at(&e.key), e.message))?;
        if let Some(f) = &run.frozen {
            validate_frozen(scene, v, i, f)?;
        } else if let Some(j) = scene.runs[..i].iter().position(|r| r.frozen.is_some()) {
            // Frozen runs run after every adapting one (they need its trace): keep them last.
            return Err(v.err(
                &at("name"),
                format!(
                    "an adapting run must come before the frozen runs: move it above `{}`",
                    scene.runs[j].name
                ),
            ));
        }
    }
    Ok(())
}

/// A frozen run: its source is an earlier adaptive run that is not frozen, its controller is that run's
/// (the loader copied it; a key the frozen run sets itself must leave it the same), and `at = "bounds"`
/// has bounds to hold.
fn validate_frozen(
    scene: &Scene,
    v: &Check<'_>,
    i: usize,
    f: &FrozenSpec,
) -> Result<(), SceneError> {
    let at = |k: &str| format!("runs[{i}].{k}");
    let Some(src) = scene.runs[..i].iter().find(|r| r.name == f.run) else {
        let earlier: Vec<&str> = scene.runs[..i].iter().map(|r| r.name.as_str()).collect();
        return Err(v.err(
            &at("frozen.run"),
            format!(
                "no earlier run named {:?}, expected one of {earlier:?}",
                f.run
            ),
        ));
    };
    if src.frozen.is_some() || src.controller != ControllerKind::Adaptive {
        return Err(v.err(
            &at("frozen.run"),
            format!(
                "`{}` must be an adapting run with controller = \"adaptive\" (it has nothing to freeze)",
                f.run
            ),
        ));
    }
    let same = [
        ("controller", src.controller == scene.runs[i].controller),
        ("impedance", src.impedance == scene.runs[i].impedance),
        ("adaptive", src.adaptive == scene.runs[i].adaptive),
        ("inner", src.inner == scene.runs[i].inner),
    ];
    if let Some((key, _)) = same.iter().find(|(_, same)| !same) {
        return Err(v.err(
            &at(key),
            format!(
                "a frozen run runs the controller of `{}`, and this makes `{key}` differ from it: remove the \
                 key here, or set it on `{}` too",
                f.run, f.run
            ),
        ));
    }
    if f.at == FrozenAt::Bounds
        && let Some(a) = src.adaptive
        && !(a.p_max_m_per_n.is_finite() && a.d_max_s.is_finite())
    {
        return Err(v.err(
            &at("frozen.at"),
            format!(
                "\"bounds\" holds p and d at the projection bounds of `{}`, which has none (p_max_m_per_n = \
                 {}, d_max_s = {}): set both there, or use at = \"means\"",
                f.run, a.p_max_m_per_n, a.d_max_s
            ),
        ));
    }
    Ok(())
}

impl Scene {
    /// The controller of run `index` (the one way a scene's controller is built: the runner, the rig, PIL,
    /// Python); an error names the key of the run it is about.
    pub fn controller(
        &self,
        index: usize,
    ) -> Result<Box<dyn pneuflex_control::Controller + Send + Sync>, SceneError> {
        self.run_controller(index, None)
    }

    /// The controller of run `index`, holding `frozen` when it is a frozen run (the values its source
    /// reached: [`crate::analysis::adaptation::frozen_values`]); [`Scene::controller`] for the others.
    pub fn run_controller(
        &self,
        index: usize,
        frozen: Option<FrozenValues>,
    ) -> Result<Box<dyn pneuflex_control::Controller + Send + Sync>, SceneError> {
        let run = &self.runs[index];
        match frozen {
            Some(v) => run.build_frozen(v),
            None => run.build(),
        }
        .map_err(|e| self.invalid(&format!("runs[{index}].{}", e.key), e.message))
    }

    /// Whether any run holds another's adaptive parameters (and so runs after it).
    pub fn has_frozen_runs(&self) -> bool {
        self.runs.iter().any(|r| r.frozen.is_some())
    }
}

/// The loader's pre-pass over the parsed file: a run with `frozen = { run = "X", .. }` gets X's
/// `controller`, `impedance`, `adaptive` and `inner`, with the keys it writes itself merged over them (a
/// sweep's `runs[*].inner.kp_per_m` edits every run; validation checks the result is still X's controller).
/// An error is the key path and what is wrong.
pub(crate) fn copy_frozen_controllers(doc: &mut toml::Table) -> Result<(), (String, String)> {
    let Some(toml::Value::Array(runs)) = doc.get_mut("runs") else {
        return Ok(());
    };
    let name = |t: &toml::Value| t.get("name").and_then(|n| n.as_str()).map(str::to_string);
    for i in 0..runs.len() {
        let Some(source) = runs[i]
            .get("frozen")
            .and_then(|f| f.get("run"))
            .and_then(|r| r.as_str())
            .map(str::to_string)
        else {
            continue;
        };
        let Some(j) = runs
            .iter()
            .position(|r| name(r).as_deref() == Some(&source))
        else {
            let names: Vec<String> = runs.iter().filter_map(name).collect();
            return Err((
                format!("runs[{i}].frozen.run"),
                format!("no run named {source:?}, expected one of {names:?}"),
            ));
        };
        if runs[j].get("frozen").is_some() {
            return Err((
                format!("runs[{i}].frozen.run"),
                format!("`{source}` is itself frozen: freeze the adapting run it copies"),
            ));
        }
        for key in ["controller", "impedance", "adaptive", "inner"] {
            let Some(from) = runs[j].get(key).cloned() else {
                continue;
            };
            let Some(own) = runs[i].as_table_mut() else {
                break;
            };
            let merged = match (from, own.remove(key)) {
                (toml::Value::Table(mut base), Some(toml::Value::Table(mine))) => {
                    base.extend(mine);
                    toml::Value::Table(base)
                }
                (_, Some(mine)) => mine,
                (from, None) => from,
            };
            own.insert(key.to_string(), merged);
        }
    }
    Ok(())
}

/// Whether the parsed file has a frozen run (and needs [`copy_frozen_controllers`]).
pub(crate) fn copy_frozen_controllers_needed(doc: &toml::Table) -> bool {
    doc.get("runs")
        .and_then(|r| r.as_array())
        .is_some_and(|runs| runs.iter().any(|r| r.get("frozen").is_some()))
}
