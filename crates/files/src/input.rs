//! Bounded reads of input files: regular files only, with a size limit per kind of file.
//!
//! The file type is checked with `stat` before the file is opened, because opening a FIFO for reading blocks
//! until a writer appears; the read itself is capped at the limit plus one byte, so `/dev/zero` or a file that
//! grows while it is read cannot exhaust memory.

use std::io::Read;
use std::path::{Path, PathBuf};

/// What an input file is, which sets its size limit.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum InputKind {
    /// A scene file (scenes/*.toml).
    Scene,
    /// An actuator or component sheet (pneumatics/*.toml).
    Sheet,
    /// A URDF rig description.
    Urdf,
    /// A rig file (rigs/*.toml).
    RigFile,
    /// A recorded trace (CSV).
    Trace,
    /// A collision mesh of a URDF (STL or OBJ).
    Mesh,
}

impl InputKind {
    /// Largest accepted size, bytes. The shipped files are 1–12 kB; the limits leave two orders of magnitude.
    pub fn max_bytes(self) -> u64 {
        match self {
            InputKind::Scene | InputKind::Sheet | InputKind::RigFile => 1 << 20,
            InputKind::Urdf => 8 << 20,
            InputKind::Trace => 2 << 30,
            // A 1-million-triangle binary STL is 50 MB.
            InputKind::Mesh => 256 << 20,
        }
    }

    /// A word for messages.
    pub fn noun(self) -> &'static str {
        match self {
            InputKind::Scene => "scene file",
            InputKind::Sheet => "component sheet",
            InputKind::Urdf => "URDF file",
            InputKind::RigFile => "rig file",
            InputKind::Trace => "trace",
            InputKind::Mesh => "mesh file",
        }
    }
}

/// Why an input file was not read.
#[derive(Debug, thiserror::Error)]
pub enum InputError {
    /// The operating system refused (missing file, permissions, ...). Its message is printed once, here.
    #[error("{}: cannot read: {os_error}", path.display())]
    Io {
        /// The file.
        path: PathBuf,
        /// The OS error (in the message, not as a source, so that it is printed once).
        os_error: std::io::Error,
    },
    /// A directory, FIFO, socket or device where a file was expected.
    #[error("{}: not a regular file ({what}); a {noun} must be a regular file", path.display())]
    NotRegular {
        /// The path.
        path: PathBuf,
        /// What it is instead.
        what: &'static str,
        /// The kind of input expected.
        noun: &'static str,
    },
    /// Larger than the limit for its kind.
    #[error("{}: {size} bytes exceed the {limit}-byte limit of a {noun}", path.display())]
    TooLarge {
        /// The file.
        path: PathBuf,
        /// Its size (or the limit + 1 when it grew while read).
        size: u64,
        /// The limit.
        limit: u64,
        /// The kind of input.
        noun: &'static str,
    },
    /// Not UTF-8 text.
    #[error("{}: not UTF-8 text (byte {offset})", path.display())]
    NotText {
        /// The file.
        path: PathBuf,
        /// Offset of the first invalid byte.
        offset: usize,
    },
}

impl InputError {
    /// The file the error is about.
    pub fn path(&self) -> &Path {
        match self {
            InputError::Io { path, .. }
            | InputError::NotRegular { path, .. }
            | InputError::TooLarge { path, .. }
            | InputError::NotText { path, .. } => path,
        }
    }
}

fn file_type_name(ft: &std::fs::FileType) -> &'static str {
    #[cfg(unix)]
    {
        use std::os::unix::fs::FileTypeExt;
        if ft.is_fifo() {
            return "a FIFO";
        }
        if ft.is_char_device() {
            return "a character device";
        }
        if ft.is_block_device() {
            return "a block device";
        }
        if ft.is_socket() {
            return "a socket";
        }
    }
    if ft.is_dir() {
        "a directory"
    } else {
        "not a file"
    }
}

/// Checks that `path` is a regular file (following symlinks) of at most the kind's size limit.
pub fn check_regular(path: &Path, kind: InputKind) -> Result<u64, InputError> {
    let meta = std::fs::metadata(path).map_err(|os_error| InputError::Io {
        path: path.to_path_buf(),
        os_error,
    })?;
    if !meta.is_file() {
        return Err(InputError::NotRegular {
            path: path.to_path_buf(),
            what: file_type_name(&meta.file_type()),
            noun: kind.noun(),
        });
    }
    let limit = kind.max_bytes();
    if meta.len() > limit {
        return Err(InputError::TooLarge {
            path: path.to_path_buf(),
            size: meta.len(),
            limit,
            noun: kind.noun(),
        });
    }
    Ok(meta.len())
}

/// Reads a binary input: a regular file, at most `kind.max_bytes()`.
pub fn read_bytes(path: &Path, kind: InputKind) -> Result<Vec<u8>, InputError> {
    let size = check_regular(path, kind)?;
    let io = |os_error| InputError::Io {
        path: path.to_path_buf(),
        os_error,
    };
    let f = std::fs::File::open(path).map_err(io)?;
    let limit = kind.max_bytes();
    let mut bytes = Vec::with_capacity(size as usize);
    f.take(limit + 1).read_to_end(&mut bytes).map_err(io)?;
    if bytes.len() as u64 > limit {
        return Err(InputError::TooLarge {
            path: path.to_path_buf(),
            size: bytes.len() as u64,
            limit,
            noun: kind.noun(),
        });
    }
    Ok(bytes)
}

/// Reads a text input: a regular file, at most `kind.max_bytes()`, UTF-8.
pub fn read_text(path: &Path, kind: InputKind) -> Result<String, InputError> {
    let bytes = read_bytes(path, kind)?;
    let mut text = String::from_utf8(bytes).map_err(|e| InputError::NotText {
        path: path.to_path_buf(),
        offset: e.utf8_error().valid_up_to(),
    })?;
    // A byte-order mark (editors on Windows write one) is not part of the text: left in, it would make the
    // first key or column name start with an invisible character.
    if text.starts_with('\u{feff}') {
        text.drain(..'\u{feff}'.len_utf8());
    }
    Ok(text)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A fresh scratch directory, removed when the returned guard drops.
    fn tmp(name: &str) -> tempfile::TempDir {
        tempfile::Builder::new()
            .prefix(&format!("pneuflex-files-{name}-"))
            .tempdir()
            .unwrap()
    }

    #[test]
    fn a_directory_is_refused_by_name() {
        let d = tmp("dir");
        let d = d.path().to_path_buf();
        let e = read_text(&d, InputKind::Scene).unwrap_err();
        assert!(
            matches!(
                e,
                InputError::NotRegular {
                    what: "a directory",
                    ..
                }
            ),
            "{e}"
        );
        assert!(e.to_string().contains("not a regular file"));
    }

    #[cfg(unix)]
    #[test]
    fn a_device_is_refused_without_reading_it() {
        let e = read_text(Path::new("/dev/zero"), InputKind::Sheet).unwrap_err();
        assert!(
            e.to_string()
                .contains("/dev/zero: not a regular file (a character device)"),
            "{e}"
        );
    }

    #[test]
    fn a_file_over_the_limit_is_refused() {
        let d = tmp("big");
        let d = d.path().to_path_buf();
        let p = d.join("big.toml");
        std::fs::write(&p, vec![b'#'; (InputKind::Scene.max_bytes() + 1) as usize]).unwrap();
        let e = read_text(&p, InputKind::Scene).unwrap_err();
        assert!(matches!(e, InputError::TooLarge { .. }), "{e}");
    }

    #[test]
    fn a_missing_file_names_the_path_once() {
        let e = read_text(Path::new("no/such/file.toml"), InputKind::Scene).unwrap_err();
        let s = e.to_string();
        assert_eq!(s.matches("no/such/file.toml").count(), 1, "{s}");
    }

    #[test]
    fn text_is_read() {
        let d = tmp("ok");
        let d = d.path().to_path_buf();
        let p = d.join("a.toml");
        std::fs::write(&p, "a = 1\n").unwrap();
        assert_eq!(read_text(&p, InputKind::Scene).unwrap(), "a = 1\n");
    }

    #[test]
    fn a_byte_order_mark_is_not_part_of_the_text() {
        let d = tmp("bom");
        let p = d.path().join("a.toml");
        std::fs::write(&p, "\u{feff}name = \"x\"\n").unwrap();
        assert_eq!(read_text(&p, InputKind::Scene).unwrap(), "name = \"x\"\n");
    }
}
