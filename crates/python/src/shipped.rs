//! Scene arguments: a path, or the name of a scene shipped inside the package ("paper-fig3" for
//! `pneuflex/data/scenes/paper-fig3.toml`). The lookup is the Python package's (`pneuflex._data.resolve`), so
//! that the wheel's layout is decided in one place.

use std::ops::Deref;
use std::path::{Path, PathBuf};

use pyo3::prelude::*;

/// A scene file argument: an existing path as given, else a shipped scene's name resolved to its file.
#[derive(Clone, Debug)]
pub struct ScenePath(PathBuf);

impl<'a, 'py> FromPyObject<'a, 'py> for ScenePath {
    type Error = PyErr;

    fn extract(obj: Borrowed<'a, 'py, PyAny>) -> PyResult<Self> {
        let py = obj.py();
        // A str / bytes / os.PathLike, as PathBuf takes it (anything else is its TypeError).
        let path: PathBuf = obj.extract()?;
        if path.exists() {
            return Ok(Self(path));
        }
        let resolved = py
            .import("pneuflex._data")?
            .getattr("resolve")?
            .call1((path.clone(),))?;
        Ok(Self(resolved.extract()?))
    }
}

impl Deref for ScenePath {
    type Target = Path;

    fn deref(&self) -> &Path {
        &self.0
    }
}

impl AsRef<Path> for ScenePath {
    fn as_ref(&self) -> &Path {
        &self.0
    }
}

impl From<ScenePath> for PathBuf {
    fn from(p: ScenePath) -> PathBuf {
        p.0
    }
}
