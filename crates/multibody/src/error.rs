//! Errors of the URDF reader, the world builder and the scene events.

use std::path::PathBuf;

/// Everything that can go wrong while building or driving a rig world. Each variant names the file
/// (where one is involved) and the URDF element at fault.
#[derive(Debug, thiserror::Error)]
pub enum MultibodyError {
    /// The URDF file does not parse (XML syntax: with its line; or urdf-rs' message).
    #[error("{file}: URDF does not parse: {reason}")]
    Parse {
        /// The URDF file.
        file: PathBuf,
        /// The parser's message.
        reason: String,
    },
    /// The URDF file could not be read: missing, not a regular file (a FIFO, a device), over the size
    /// limit, or not UTF-8. The OS error is printed once.
    #[error(transparent)]
    Input(#[from] pneuflex_files::InputError),
    /// A URDF element is malformed: a numeric attribute that is not the right count of finite numbers,
    /// or nesting too deep. Names the file, the line and the element as written.
    #[error("{file}:{line}: {element}: {reason}")]
    Element {
        /// The URDF file.
        file: PathBuf,
        /// Line of the element's start tag, from 1.
        line: usize,
        /// The start tag, e.g. `<mass value="heavy">`.
        element: String,
        /// What was expected and what was found (and the link or joint it is in).
        reason: String,
    },
    /// The configuration names a link that the URDF does not contain.
    #[error("{file}: no link named '{link}' (configuration field `{field}`)")]
    MissingLink {
        /// The URDF file.
        file: PathBuf,
        /// The configuration field that names it.
        field: &'static str,
        /// The missing link name.
        link: String,
    },
    /// The configuration names a joint that the URDF does not contain.
    #[error("{file}: no joint named '{joint}' (configuration field `{field}`)")]
    MissingJoint {
        /// The URDF file.
        file: PathBuf,
        /// The configuration field that names it.
        field: &'static str,
        /// The missing joint name.
        joint: String,
    },
    /// A named joint exists but has the wrong type or connects the wrong links.
    #[error("{file}: joint '{joint}': {reason}")]
    BadJoint {
        /// The URDF file.
        file: PathBuf,
        /// The joint at fault.
        joint: String,
        /// What was expected.
        reason: String,
    },
    /// A link's inertial element is not physical.
    #[error("{file}: link '{link}' <inertial>: {reason}")]
    BadInertial {
        /// The URDF file.
        file: PathBuf,
        /// The link at fault.
        link: String,
        /// What was expected.
        reason: String,
    },
    /// A link's collision geometry cannot be turned into a collider.
    #[error("{file}: link '{link}' <collision>: {reason}")]
    BadGeometry {
        /// The URDF file.
        file: PathBuf,
        /// The link at fault.
        link: String,
        /// What was expected.
        reason: String,
    },
    /// A link's `<visual>` mesh cannot be read.
    #[error("{file}: link '{link}' <visual>: {reason}")]
    BadVisual {
        /// The URDF file.
        file: PathBuf,
        /// The link at fault.
        link: String,
        /// What was expected.
        reason: String,
    },
    /// The link/joint tree is not a tree with one root.
    #[error("{file}: kinematic tree: {reason}")]
    BadTree {
        /// The URDF file.
        file: PathBuf,
        /// What was expected.
        reason: String,
    },
    /// A configuration value is out of range (non-finite, non-positive, ...).
    #[error("multibody configuration `{field}`: {reason}")]
    BadConfig {
        /// The configuration field at fault.
        field: &'static str,
        /// What was expected.
        reason: String,
    },
    /// A mechanism's actuator, contact or sensor is configured wrongly (a name the URDF lacks, a mount
    /// the geometry cannot have, a value out of range).
    #[error("{file}: {item}: `{key}`: {reason}")]
    BadMechanism {
        /// The URDF file the mechanism is built from.
        file: PathBuf,
        /// What is at fault, e.g. `actuator 'left'` or `contact 'pad'`.
        item: String,
        /// Its configuration key, e.g. `link_a`.
        key: &'static str,
        /// What was expected and what was found.
        reason: String,
    },
    /// A scene event refers to an unknown material.
    #[error("unknown material '{name}' (known: {known})")]
    UnknownMaterial {
        /// The name asked for.
        name: String,
        /// The names configured.
        known: String,
    },
}
