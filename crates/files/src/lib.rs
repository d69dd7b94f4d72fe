//! Safe file handling shared by every pneuflex command: a leaf crate (it depends on nothing of ours).
//!
//! - [`input`]: read a text input only if it is a regular file within a size limit per kind (a FIFO, a
//!   device or a directory is a clear error, never a hang or an unbounded read);
//! - [`position`]: the line and column of a TOML key path, so that every error names file, line and key;
//! - [`output`]: output directories written beside and renamed into place, marked by a manifest, never
//!   replacing what pneuflex did not create; interrupted outputs kept under a name that says so;
//! - [`provenance`]: content hashes of the inputs that produced a result;
//! - [`path`]: a file's path as seen from another folder.

pub mod check;
pub mod input;
pub mod output;
pub mod path;
pub mod position;
pub mod provenance;

pub use input::{InputError, InputKind, read_bytes, read_text};
pub use output::{OutputDir, OutputError};
pub use position::{Position, line_col, toml_key_position};
pub use provenance::{InputDigest, sha256_hex};
