//! Where a scene's values come from (its file, text, folder and overlay), and the checks of those values,
//! each blamed on its key (file, line and key path) in the one wording of `pneuflex_files::check`. Below
//! both the scene file's tables and the plants: each places its errors here.

use std::path::{Path, PathBuf};

use crate::error::SceneError;

/// Where a scene's values come from: its file, text, folder and overlay. An error is placed in it, a
/// relative path resolved against it and an actuator sheet read through it — by the scene and by the plants,
/// which see the origin and not the scene.
#[derive(Clone, Copy)]
pub struct SceneOrigin<'a> {
    /// The scene file.
    pub source: &'a Path,
    /// Its text (empty when unknown: errors then carry no line).
    pub text: &'a str,
    /// The folder relative paths are resolved against.
    pub base_dir: &'a Path,
    /// Texts standing in for the files they name.
    pub overlay: &'a pneuflex_pneumatics::FileOverlay,
}

impl SceneOrigin<'_> {
    /// An error about the value at `path` (a dotted key path), with the line of that key when the text of
    /// the file is known.
    pub fn invalid(&self, path: &str, message: String) -> SceneError {
        SceneError::Invalid {
            file: self.source.to_path_buf(),
            at: pneuflex_files::toml_key_position(self.text, path),
            key: path.to_string(),
            message,
        }
    }

    /// A path the scene names, resolved against the scene's folder.
    pub fn resolve(&self, p: &Path) -> PathBuf {
        if p.is_absolute() {
            p.to_path_buf()
        } else {
            self.base_dir.join(p)
        }
    }

    /// The actuator sheet at `resolved` (a path from [`SceneOrigin::resolve`]), with the overlay's texts
    /// standing in for the files they name.
    pub fn load_sheet(
        &self,
        resolved: &Path,
    ) -> Result<pneuflex_pneumatics::ActuatorSheet, pneuflex_pneumatics::ComponentError> {
        pneuflex_pneumatics::ActuatorSheet::load_overlaid(resolved, self.overlay)
    }

    /// An error of the plant that names no key.
    pub fn plant_error(&self, message: String) -> SceneError {
        SceneError::Plant {
            file: self.source.to_path_buf(),
            message,
        }
    }
}

/// Checks values of one scene, each error located at its key.
#[derive(Clone, Copy)]
pub struct Check<'a> {
    pub(crate) origin: SceneOrigin<'a>,
}

impl Check<'_> {
    /// An error about the value at `path`.
    pub fn err(&self, path: &str, message: String) -> SceneError {
        self.origin.invalid(path, message)
    }
    /// `x` is a finite number.
    pub fn finite(&self, path: &str, x: f64) -> Result<(), SceneError> {
        pneuflex_files::check::finite(x)
            .map(drop)
            .map_err(|m| self.err(path, m))
    }
    /// `x` is a finite number ≥ 0.
    pub fn non_negative(&self, path: &str, x: f64) -> Result<(), SceneError> {
        pneuflex_files::check::non_negative(x)
            .map(drop)
            .map_err(|m| self.err(path, m))
    }
    /// `x` is a finite number > 0.
    pub fn positive(&self, path: &str, x: f64) -> Result<(), SceneError> {
        pneuflex_files::check::positive(x)
            .map(drop)
            .map_err(|m| self.err(path, m))
    }
    /// A number in `[lo, hi]` (finite).
    pub fn within(&self, path: &str, x: f64, lo: f64, hi: f64) -> Result<(), SceneError> {
        pneuflex_files::check::within(x, lo, hi, "")
            .map(drop)
            .map_err(|m| self.err(path, m))
    }
}
