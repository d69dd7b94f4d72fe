//! Rust errors as Python exceptions: unreadable files are `OSError` (`FileNotFoundError` when missing),
//! bad content is `pneuflex.PneuflexError` (a `ValueError`); every message names the file and the key.

use pyo3::exceptions::{PyFileNotFoundError, PyOSError, PyValueError};
use pyo3::prelude::*;

pyo3::create_exception!(
    pneuflex,
    PneuflexError,
    PyValueError,
    "A scene, actuator sheet, URDF or parameter set is invalid (the message names the file and the key)."
);

/// A scene-crate error as a Python exception.
pub fn scene(e: pneuflex_scene::SceneError) -> PyErr {
    use pneuflex_scene::SceneError as E;
    match &e {
        E::Input(pneuflex_files::InputError::Io { os_error, .. })
            if os_error.kind() == std::io::ErrorKind::NotFound =>
        {
            PyFileNotFoundError::new_err(e.to_string())
        }
        E::Input(pneuflex_files::InputError::Io { .. }) | E::Write { .. } | E::Output(_) => {
            PyOSError::new_err(e.to_string())
        }
        _ => PneuflexError::new_err(e.to_string()),
    }
}

/// A component-sheet error as a Python exception.
pub fn component(e: pneuflex_pneumatics::ComponentError) -> PyErr {
    match &e {
        _ if e
            .os_error()
            .is_some_and(|o| o.kind() == std::io::ErrorKind::NotFound) =>
        {
            PyFileNotFoundError::new_err(e.to_string())
        }
        _ if e.os_error().is_some() => PyOSError::new_err(e.to_string()),
        _ => PneuflexError::new_err(e.to_string()),
    }
}

/// Any other error of ours (controller parameters, multibody, figures) as `PneuflexError`.
pub fn other(e: impl std::fmt::Display) -> PyErr {
    PneuflexError::new_err(e.to_string())
}
