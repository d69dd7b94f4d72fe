//! `[[runs]]`: the named controller runs a scene compares, and the one way a controller is built from one.

use serde::{Deserialize, Serialize};

use super::Scene;
use super::check::Check;
use crate::error::SceneError;
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
    /// scene runner, the rig, Python, the cross-validation) builds a controller.
    pub fn build(
        &self,
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
        // reader of the run meets them.
        match (self.controller, self.adaptive) {
            (ControllerKind::Adaptive, None) => {
                return Err(RunSpecError {
                    key: "adaptive".into(),
                    message: "missing: controller = \"adaptive\" needs the adaptive gains".into(),
                });
            }
            (ControllerKind::Impedance, Some(_)) => {
                return Err(RunSpecError {
                    key: "adaptive".into(),
                    message: "only allowed with controller = \"adaptive\"".into(),
                });
            }
            (ControllerKind::Adaptive, Some(a)) => a.validate().map_err(bad("adaptive"))?,
            (ControllerKind::Impedance, None) => {}
        }
        self.impedance.validate().map_err(bad("impedance"))?;
        self.inner.validate().map_err(bad("inner"))?;
        Ok(match (self.controller, self.adaptive) {
            (ControllerKind::Adaptive, Some(a)) => Box::new(
                AdaptiveImpedanceController::new(self.impedance, a, self.inner)
                    .map_err(bad("adaptive"))?,
            ),
            _ => Box::new(
                ImpedanceController::new(self.impedance, self.inner).map_err(bad("impedance"))?,
            ),
        })
    }
}

/// The controller of a run.
#[derive(Clone, Copy, Debug, Deserialize, Serialize, PartialEq, Eq)]
#[serde(rename_all = "lowercase")]
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
        run.build().map_err(|e| v.err(&at(&e.key), e.message))?;
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
        self.runs[index]
            .build()
            .map_err(|e| self.invalid(&format!("runs[{index}].{}", e.key), e.message))
    }
}
