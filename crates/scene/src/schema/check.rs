//! The checks of a scene's values, blamed on the key they are about (file, line and key path), in the one
//! wording of `pneuflex_files::check`.

use super::Scene;
use crate::error::SceneError;

/// Checks values of one scene, each error located at its key.
pub(crate) struct Check<'a> {
    pub(crate) scene: &'a Scene,
}

impl Check<'_> {
    /// An error about the value at `path`.
    pub(crate) fn err(&self, path: &str, message: String) -> SceneError {
        self.scene.invalid(path, message)
    }
    /// `x` is a finite number.
    pub(crate) fn finite(&self, path: &str, x: f64) -> Result<(), SceneError> {
        pneuflex_files::check::finite(x)
            .map(drop)
            .map_err(|m| self.err(path, m))
    }
    pub(crate) fn non_negative(&self, path: &str, x: f64) -> Result<(), SceneError> {
        pneuflex_files::check::non_negative(x)
            .map(drop)
            .map_err(|m| self.err(path, m))
    }
    pub(crate) fn positive(&self, path: &str, x: f64) -> Result<(), SceneError> {
        pneuflex_files::check::positive(x)
            .map(drop)
            .map_err(|m| self.err(path, m))
    }
    /// A number in `[lo, hi]` (finite).
    pub(crate) fn within(&self, path: &str, x: f64, lo: f64, hi: f64) -> Result<(), SceneError> {
        pneuflex_files::check::within(x, lo, hi, "")
            .map(drop)
            .map_err(|m| self.err(path, m))
    }
}
