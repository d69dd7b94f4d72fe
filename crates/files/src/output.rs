//! Output directories that never destroy what pneuflex did not create.
//!
//! A command writes into a staging directory beside its destination (`.<name>.partial-<pid>`), then renames it
//! into place. The finished directory carries a manifest ([`MANIFEST`]) naming the tool, the command, the
//! inputs and every file it wrote. A destination may only be replaced when it does not exist, is empty, or
//! carries a manifest that lists every file in it; anything else is an error that names the foreign file,
//! and nothing is deleted. `.`, `/`, the home directory, the working directory and its ancestors, and the
//! folders of the command's inputs are refused outright.
//!
//! The old output is moved aside, the new one renamed in, then the old one removed: a failure at any point
//! leaves a complete output under the destination's name. An interrupted command commits what it has under
//! `<dest>.partial` (same rules), so the previous complete output stays untouched. Staging directories of
//! processes that died are removed by the next command that writes beside them, unless they hold data
//! that cannot be made again (a rig trace): those are renamed to `<dest>.unfinished-<pid>` and reported.

use std::fs;
use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

use crate::provenance::InputDigest;

/// Name of the manifest file in every output directory pneuflex writes.
pub const MANIFEST: &str = ".pneuflex-output.json";
/// Marker inside a staging directory while it is being written.
const STAGING_MARK: &str = ".pneuflex-staging";
/// Version of the manifest's layout.
pub const MANIFEST_SCHEMA: u32 = 1;

/// What went wrong with an output directory.
#[derive(Debug, thiserror::Error)]
pub enum OutputError {
    /// The destination is a place pneuflex never replaces.
    #[error("{}: refusing to use as an output directory: {why}", path.display())]
    Refused {
        /// The destination.
        path: PathBuf,
        /// Which rule refused it.
        why: String,
    },
    /// The destination holds files pneuflex did not write.
    #[error(
        "{}: not replaced: {} was not written by pneuflex ({}); move it away or choose another output directory",
        dest.display(), foreign.display(), why
    )]
    Foreign {
        /// The destination.
        dest: PathBuf,
        /// One file that is not pneuflex's.
        foreign: PathBuf,
        /// Why it counts as foreign.
        why: &'static str,
    },
    /// The destination holds a rig recording, which no command replaces.
    #[error(
        "{}: not replaced: it holds a rig recording ({why}); a recording cannot be made again and pneuflex \
         never replaces or deletes one; choose another output directory",
        dest.display()
    )]
    Recording {
        /// The destination.
        dest: PathBuf,
        /// How it was recognised as a recording.
        why: String,
    },
    /// The destination is the output of another pneuflex command.
    #[error(
        "{}: not replaced: it is the output of `pneuflex {other}`, and `pneuflex {command}` replaces only its \
         own outputs; choose another output directory",
        dest.display()
    )]
    OtherCommand {
        /// The destination.
        dest: PathBuf,
        /// The command that wrote it.
        other: String,
        /// The command that would replace it.
        command: String,
    },
    /// The destination exists and is not a directory.
    #[error("{}: exists and is not a directory; choose another output directory", path.display())]
    NotADirectory {
        /// The destination.
        path: PathBuf,
    },
    /// The operating system refused an operation (message printed once).
    #[error("{}: cannot {op}: {os_error}", path.display())]
    Io {
        /// The file or directory.
        path: PathBuf,
        /// What was attempted.
        op: &'static str,
        /// The OS error.
        os_error: std::io::Error,
    },
}

fn io<'a>(path: &'a Path, op: &'static str) -> impl FnOnce(std::io::Error) -> OutputError + 'a {
    move |os_error| OutputError::Io {
        path: path.to_path_buf(),
        op,
        os_error,
    }
}

/// Why an output is partial.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Partial {
    /// What stopped it (`SIGINT`, `SIGTERM`, ...).
    pub reason: String,
    /// Simulated (or rig) time reached, s.
    pub time_reached_s: f64,
    /// How much of the work was done, for commands that are not one run (`412 of 1000 points`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub done: Option<String>,
}

/// The manifest: what wrote an output directory, from which inputs, and which files are its own.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Manifest {
    /// Always `pneuflex`.
    pub tool: String,
    /// The tool's version.
    pub version: String,
    /// Layout version of this manifest.
    pub schema_version: u32,
    /// The command that wrote it (`run`, `rig run`, ...).
    pub command: String,
    /// Whether the command finished; false with `partial` set for an interrupted one.
    pub complete: bool,
    /// Set when the output is partial.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub partial: Option<Partial>,
    /// Whether the directory is a rig recording (it cannot be made again; never replaced).
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub recording: bool,
    /// The inputs, by content hash.
    pub inputs: Vec<InputDigest>,
    /// Every file written, relative to the directory, `/`-separated, sorted.
    pub files: Vec<String>,
}

impl Manifest {
    /// A manifest for `command` with the given inputs; `files` is filled at commit.
    pub fn new(command: &str, version: &str, inputs: Vec<InputDigest>) -> Self {
        Self {
            tool: "pneuflex".into(),
            version: version.into(),
            schema_version: MANIFEST_SCHEMA,
            command: command.into(),
            complete: true,
            partial: None,
            recording: false,
            inputs,
            files: Vec::new(),
        }
    }
}

/// Whether stale staging directories of this output may be deleted (a simulation can be rerun) or must
/// be kept (a rig trace cannot be recorded again).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Recoverable {
    /// Regenerable: a dead process's staging directory is removed.
    Regenerable,
    /// Irreplaceable: a dead process's staging directory is kept as `<dest>.unfinished-<pid>`.
    Irreplaceable,
}

/// Who writes an output: the command (as its manifest names it) and whether what it writes can be made
/// again. It decides what the output may replace: a simulation output replaces only an output of the same
/// command; a recording replaces nothing.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Writer {
    /// The command, as the manifest records it (`run`, `sweep`, `rig excite`, ...).
    pub command: &'static str,
    /// Regenerable (a simulation) or irreplaceable (a recording from a board).
    pub recoverable: Recoverable,
}

impl Writer {
    /// A command whose output can be made again.
    pub const fn simulation(command: &'static str) -> Self {
        Self {
            command,
            recoverable: Recoverable::Regenerable,
        }
    }

    /// A command that records a rig on the wall clock: its output is never replaced.
    pub const fn recording(command: &'static str) -> Self {
        Self {
            command,
            recoverable: Recoverable::Irreplaceable,
        }
    }
}

/// The commands whose outputs are rig recordings (also recognised without a manifest, by their trace).
const RECORDING_COMMANDS: [&str; 2] = ["rig run", "rig excite"];

/// An output directory being written; it appears under its final name only on commit.
#[derive(Debug)]
pub struct OutputDir {
    dest: PathBuf,
    tmp: PathBuf,
    /// Where an interrupted command commits what it has (see [`OutputDir::partial_dest`]).
    partial: PathBuf,
    done: bool,
    writer: Writer,
    /// Staging directories of dead processes that were kept (irreplaceable data), for the caller to report.
    pub recovered: Vec<PathBuf>,
}

fn absolute(p: &Path) -> PathBuf {
    let abs = if p.is_absolute() {
        p.to_path_buf()
    } else {
        std::env::current_dir()
            .unwrap_or_else(|_| PathBuf::from("/"))
            .join(p)
    };
    // Resolve symlinks where the path exists; lexically normalise the rest.
    if let Ok(c) = fs::canonicalize(&abs) {
        return c;
    }
    let mut out = PathBuf::new();
    for c in abs.components() {
        match c {
            std::path::Component::ParentDir => {
                out.pop();
            }
            std::path::Component::CurDir => {}
            other => out.push(other),
        }
    }
    match (out.parent(), out.file_name()) {
        (Some(parent), Some(name)) => fs::canonicalize(parent)
            .map(|p| p.join(name))
            .unwrap_or(out.clone()),
        _ => out,
    }
}

/// Refuses destinations that must never be replaced: `/`, `$HOME`, the working directory or one of its
/// ancestors, and the folders of the inputs (`protect`) or their ancestors.
pub fn check_not_protected(dest: &Path, protect: &[&Path]) -> Result<(), OutputError> {
    let abs = absolute(dest);
    let refuse = |why: String| {
        Err(OutputError::Refused {
            path: dest.to_path_buf(),
            why,
        })
    };
    if abs.parent().is_none() {
        return refuse("it is the root directory".into());
    }
    if let Some(home) = std::env::var_os("HOME").filter(|h| !h.is_empty())
        && absolute(Path::new(&home)) == abs
    {
        return refuse("it is the home directory".into());
    }
    if let Ok(cwd) = std::env::current_dir() {
        let cwd = absolute(&cwd);
        if cwd.starts_with(&abs) {
            return refuse(if cwd == abs {
                "it is the working directory".into()
            } else {
                "it contains the working directory".into()
            });
        }
    }
    for p in protect {
        let folder = absolute(p);
        let folder = if folder.is_dir() {
            folder
        } else {
            folder.parent().map(Path::to_path_buf).unwrap_or(folder)
        };
        if folder.starts_with(&abs) {
            return refuse(format!(
                "it holds an input of this command ({})",
                p.display()
            ));
        }
    }
    // Inside another output: writing there would add files its manifest does not list (and inside a
    // recording, mix a simulation into data that cannot be made again).
    for up in abs.ancestors().skip(1) {
        if let Some(m) = read_manifest(up) {
            let what = match recording_evidence(up, Some(&m)) {
                Some(_) => "the rig recording",
                None => "the output",
            };
            return refuse(format!(
                "it is inside {}, {what} of `pneuflex {}`; choose a directory outside it",
                up.display(),
                m.command
            ));
        }
    }
    Ok(())
}

/// Every file below `dir`, relative, `/`-separated, sorted (the manifest and staging mark excluded).
fn list_files(dir: &Path) -> Result<Vec<String>, OutputError> {
    fn walk(root: &Path, dir: &Path, out: &mut Vec<String>) -> Result<(), OutputError> {
        for entry in fs::read_dir(dir).map_err(io(dir, "list"))? {
            let entry = entry.map_err(io(dir, "list"))?;
            let path = entry.path();
            let ft = entry.file_type().map_err(io(&path, "inspect"))?;
            if ft.is_dir() {
                walk(root, &path, out)?;
            } else {
                let rel = path.strip_prefix(root).unwrap_or(&path);
                let rel = rel
                    .components()
                    .map(|c| c.as_os_str().to_string_lossy())
                    .collect::<Vec<_>>()
                    .join("/");
                if rel != MANIFEST && rel != STAGING_MARK {
                    out.push(rel);
                }
            }
        }
        Ok(())
    }
    let mut out = Vec::new();
    walk(dir, dir, &mut out)?;
    out.sort();
    Ok(out)
}

/// Whether a manifest's file entry is a plain relative path (no `..`, no root, no drive): the only kind
/// pneuflex writes, and the only kind it ever removes.
fn is_plain_entry(entry: &str) -> bool {
    let p = Path::new(entry);
    !entry.is_empty()
        && p.components()
            .all(|c| matches!(c, std::path::Component::Normal(_)))
}

/// Reads the manifest of an existing output directory, if it has one.
pub fn read_manifest(dir: &Path) -> Option<Manifest> {
    let path = dir.join(MANIFEST);
    let meta = fs::symlink_metadata(&path).ok()?;
    if !meta.is_file() || meta.len() > (16 << 20) {
        return None;
    }
    serde_json::from_slice(&fs::read(&path).ok()?).ok()
}

/// The columns a rig trace has after the loop's and the controller's signals (docs/rig.md, "Trace"): the
/// board's record, one sample it sent (its board time and readings) and one echo of a valve command it
/// applied (when, what) a row; then the host's wall clock and the fault. Readers that treat a trace's
/// columns as signals skip these.
pub const RIG_TRACE_COLUMNS: [&str; 9] = [
    "board_t",
    "board_x",
    "board_f_e",
    "board_p_a",
    "board_p_b",
    "applied_t",
    "applied_u",
    "wall_time",
    "fault",
];

/// Why a directory is a rig recording, if it is one: its manifest says so (or names a recording command),
/// or a `trace.csv` in it has the rig trace's `wall_time` column (recognised without the manifest, so that
/// a recording whose manifest was edited or lost is still never replaced).
pub fn recording_evidence(dir: &Path, manifest: Option<&Manifest>) -> Option<String> {
    if let Some(m) = manifest {
        if m.recording {
            return Some(format!(
                "its manifest marks it as recorded by `pneuflex {}`",
                m.command
            ));
        }
        if RECORDING_COMMANDS.contains(&m.command.as_str()) {
            return Some(format!("recorded by `pneuflex {}`", m.command));
        }
    }
    let mut traces = Vec::new();
    find_traces(dir, 0, &mut traces);
    traces
        .into_iter()
        .find(|t| has_wall_clock_header(t))
        .map(|t| {
            let rel = t.strip_prefix(dir).unwrap_or(&t).display().to_string();
            format!("{rel} has the wall_time column of a rig trace")
        })
}

/// Every `trace*.csv` below `dir`, to a depth of 3 folders.
fn find_traces(dir: &Path, depth: usize, out: &mut Vec<PathBuf>) {
    let Ok(entries) = fs::read_dir(dir) else {
        return;
    };
    for e in entries.flatten() {
        let Ok(ft) = e.file_type() else { continue };
        let name = e.file_name().to_string_lossy().into_owned();
        if ft.is_dir() && depth < 3 {
            find_traces(&e.path(), depth + 1, out);
        } else if ft.is_file() && name.starts_with("trace") && name.ends_with(".csv") {
            out.push(e.path());
        }
    }
}

/// Whether the first line that is not a comment names a `wall_time` column (read: the first 64 KiB).
fn has_wall_clock_header(path: &Path) -> bool {
    use std::io::Read;
    let Ok(f) = fs::File::open(path) else {
        return false;
    };
    let mut head = Vec::new();
    if f.take(64 << 10).read_to_end(&mut head).is_err() {
        return false;
    }
    let text = String::from_utf8_lossy(&head);
    text.lines()
        .map(|l| l.trim_start_matches('\u{feff}'))
        .find(|l| !l.starts_with('#') && !l.trim().is_empty())
        .is_some_and(|h| h.split(',').any(|c| c.trim() == "wall_time"))
}

/// Checks that `writer` may replace `dest`: absent, an empty directory, or an output of the same command
/// whose manifest lists every file in it. A rig recording is never replaceable.
pub fn check_replaceable(dest: &Path, writer: &Writer) -> Result<(), OutputError> {
    let meta = match fs::symlink_metadata(dest) {
        Ok(m) => m,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(()),
        Err(e) => return Err(io(dest, "inspect")(e)),
    };
    if meta.file_type().is_symlink() {
        return Err(OutputError::Refused {
            path: dest.to_path_buf(),
            why: "it is a symbolic link; name the directory itself".into(),
        });
    }
    if !meta.is_dir() {
        return Err(OutputError::NotADirectory {
            path: dest.to_path_buf(),
        });
    }
    let files = list_files(dest)?;
    let has_dirs_only = files.is_empty();
    let manifest = read_manifest(dest);
    if let Some(why) = recording_evidence(dest, manifest.as_ref()) {
        return Err(OutputError::Recording {
            dest: dest.to_path_buf(),
            why,
        });
    }
    match manifest {
        Some(m) if m.tool == "pneuflex" => {
            // A manifest that lists a path leaving its directory was not written by pneuflex: replacing
            // the directory would remove that file.
            if let Some(e) = m.files.iter().find(|e| !is_plain_entry(e)) {
                return Err(OutputError::Foreign {
                    dest: dest.to_path_buf(),
                    foreign: dest.join(MANIFEST),
                    why: if e.contains("..") || Path::new(e).is_absolute() {
                        "its manifest lists a file outside the directory"
                    } else {
                        "its manifest lists an entry that is not a plain file name"
                    },
                });
            }
            if let Some(f) = files.iter().find(|f| !m.files.contains(f)) {
                return Err(OutputError::Foreign {
                    dest: dest.to_path_buf(),
                    foreign: dest.join(f),
                    why: "not listed in its .pneuflex-output.json",
                });
            }
            if m.command != writer.command || writer.recoverable == Recoverable::Irreplaceable {
                return Err(OutputError::OtherCommand {
                    dest: dest.to_path_buf(),
                    other: m.command,
                    command: writer.command.to_string(),
                });
            }
            Ok(())
        }
        _ if has_dirs_only && dest.join(MANIFEST).symlink_metadata().is_err() => {
            // Empty (or only empty folders): nothing to lose. Anything else is somebody's.
            if fs::read_dir(dest)
                .map_err(io(dest, "list"))?
                .next()
                .is_none()
            {
                Ok(())
            } else {
                Err(OutputError::Foreign {
                    dest: dest.to_path_buf(),
                    foreign: dest.to_path_buf(),
                    why: "it holds folders and no .pneuflex-output.json",
                })
            }
        }
        _ => Err(OutputError::Foreign {
            dest: dest.to_path_buf(),
            foreign: dest.join(files.first().map(String::as_str).unwrap_or(MANIFEST)),
            why: "the directory has no valid .pneuflex-output.json",
        }),
    }
}

/// Checks that a single output file (a plot) may be written at `path`: not inside a pneuflex output
/// directory (a recording or another command's output, whose manifest would not list it) and not over an
/// existing file.
pub fn check_file_destination(path: &Path) -> Result<(), OutputError> {
    if fs::symlink_metadata(path).is_ok() {
        return Err(OutputError::Refused {
            path: path.to_path_buf(),
            why: "the file exists; choose another name (pneuflex does not overwrite it)".into(),
        });
    }
    let abs = absolute(path);
    for up in abs.ancestors().skip(1) {
        if let Some(m) = read_manifest(up) {
            let what = match recording_evidence(up, Some(&m)) {
                Some(_) => "the rig recording",
                None => "the output",
            };
            return Err(OutputError::Refused {
                path: path.to_path_buf(),
                why: format!(
                    "it is inside {}, {what} of `pneuflex {}`; choose a place outside it",
                    up.display(),
                    m.command
                ),
            });
        }
    }
    Ok(())
}

/// The first free destination for a recording made without `--out`: `default` when it is absent or an empty
/// directory, else `default-2`, `default-3`, ... (recordings are never replaced, so a second recording
/// with the same default goes beside the first).
pub fn fresh_destination(default: &Path) -> PathBuf {
    let empty = |p: &Path| match fs::symlink_metadata(p) {
        Err(e) => e.kind() == std::io::ErrorKind::NotFound,
        Ok(m) => m.is_dir() && fs::read_dir(p).is_ok_and(|mut d| d.next().is_none()),
    };
    if empty(default) {
        return default.to_path_buf();
    }
    let name = name_of(default);
    let parent = parent_of(default);
    (2..100_000)
        .map(|i| parent.join(format!("{name}-{i}")))
        .find(|p| empty(p))
        .unwrap_or_else(|| default.to_path_buf())
}

fn pid_alive(pid: u32) -> bool {
    // Linux: /proc/<pid> exists while the process does. Elsewhere, assume alive (never delete).
    if Path::new("/proc/self").exists() {
        Path::new(&format!("/proc/{pid}")).exists()
    } else {
        true
    }
}

/// The parent folder of a destination (`.` for a bare name).
fn parent_of(dest: &Path) -> PathBuf {
    match dest.parent() {
        Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
        _ => PathBuf::from("."),
    }
}

fn name_of(dest: &Path) -> String {
    dest.file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_else(|| "out".into())
}

/// Removes (or, for irreplaceable data, renames aside) the staging directories of dead processes.
fn clean_stale(parent: &Path, name: &str) -> Vec<PathBuf> {
    let mut kept = Vec::new();
    let Ok(entries) = fs::read_dir(parent) else {
        return kept;
    };
    for entry in entries.flatten() {
        let fname = entry.file_name().to_string_lossy().into_owned();
        let pid = [".partial-", ".old-"].iter().find_map(|tag| {
            fname
                .strip_prefix(&format!(".{name}{tag}"))
                .and_then(|p| p.parse::<u32>().ok())
        });
        let Some(pid) = pid else { continue };
        if pid == std::process::id() || pid_alive(pid) {
            continue;
        }
        let path = entry.path();
        // Only directories pneuflex marked as its own staging (or its moved-aside old outputs) are touched.
        let mark = fs::read_to_string(path.join(STAGING_MARK)).ok();
        let is_old = fname.contains(".old-") && read_manifest(&path).is_some();
        match mark.as_deref() {
            Some("irreplaceable") => {
                let to = parent.join(format!("{name}.unfinished-{pid}"));
                if fs::rename(&path, &to).is_ok() {
                    kept.push(to);
                }
            }
            Some(_) => {
                let _ = fs::remove_dir_all(&path);
            }
            None if is_old => {
                let _ = remove_listed(&path);
            }
            None => {}
        }
    }
    kept
}

/// Removes a pneuflex output directory: only the files its manifest lists, then its empty folders.
/// Anything else found in it is left where it is.
fn remove_listed(dir: &Path) -> Result<(), OutputError> {
    let Some(m) = read_manifest(dir) else {
        return Ok(());
    };
    // A manifest that names anything but plain files inside its directory is not one pneuflex wrote:
    // nothing of that directory is touched.
    if !m.files.iter().all(|f| is_plain_entry(f)) {
        return Ok(());
    }
    // Only plain relative entries, and only what resolves inside the directory (a listed folder that is
    // a link to elsewhere is not followed).
    let root = fs::canonicalize(dir).map_err(io(dir, "inspect"))?;
    for f in m.files.iter().filter(|f| is_plain_entry(f)) {
        let p = dir.join(f);
        let inside = p
            .parent()
            .and_then(|parent| fs::canonicalize(parent).ok())
            .is_some_and(|parent| parent.starts_with(&root));
        if inside
            && fs::symlink_metadata(&p).is_ok_and(|m| m.is_file() || m.file_type().is_symlink())
        {
            fs::remove_file(&p).map_err(io(&p, "remove"))?;
        }
    }
    let _ = fs::remove_file(dir.join(MANIFEST));
    let _ = fs::remove_file(dir.join(STAGING_MARK));
    remove_empty_dirs(dir);
    Ok(())
}

fn remove_empty_dirs(dir: &Path) {
    if let Ok(entries) = fs::read_dir(dir) {
        for e in entries.flatten() {
            if e.file_type().is_ok_and(|t| t.is_dir()) {
                remove_empty_dirs(&e.path());
            }
        }
    }
    let _ = fs::remove_dir(dir);
}

impl OutputDir {
    /// Prepares to write `dest`: refuses protected places and directories pneuflex did not write, cleans
    /// stale staging directories beside it, and creates a fresh staging directory.
    pub fn create(dest: &Path, protect: &[&Path], writer: Writer) -> Result<Self, OutputError> {
        check_not_protected(dest, protect)?;
        check_replaceable(dest, &writer)?;
        // Where an interrupted command keeps what it did, refused now rather than after the work. A
        // recording's goes beside an earlier interrupted recording (`.partial-2`, ...), never over it.
        let partial = match writer.recoverable {
            Recoverable::Regenerable => {
                let p = parent_of(dest).join(format!("{}.partial", name_of(dest)));
                check_replaceable(&p, &writer)?;
                p
            }
            Recoverable::Irreplaceable => {
                fresh_destination(&parent_of(dest).join(format!("{}.partial", name_of(dest))))
            }
        };
        let parent = parent_of(dest);
        fs::create_dir_all(&parent).map_err(io(&parent, "create"))?;
        let name = name_of(dest);
        let recovered = clean_stale(&parent, &name);
        let tmp = parent.join(format!(".{name}.partial-{}", std::process::id()));
        if tmp.exists() {
            fs::remove_dir_all(&tmp).map_err(io(&tmp, "remove"))?;
        }
        fs::create_dir_all(&tmp).map_err(io(&tmp, "create"))?;
        let mark = match writer.recoverable {
            Recoverable::Regenerable => "regenerable",
            Recoverable::Irreplaceable => "irreplaceable",
        };
        let mark_path = tmp.join(STAGING_MARK);
        fs::write(&mark_path, mark).map_err(io(&mark_path, "write"))?;
        Ok(Self {
            dest: dest.to_path_buf(),
            tmp,
            partial,
            done: false,
            writer,
            recovered,
        })
    }

    /// The directory to write into until commit.
    pub fn path(&self) -> &Path {
        &self.tmp
    }

    /// The final destination.
    pub fn dest(&self) -> &Path {
        &self.dest
    }

    /// Where a partial (interrupted) output goes: `<dest>.partial` (a recording: the first free of `<dest>.partial`, `<dest>.partial-2`, ...).
    pub fn partial_dest(&self) -> PathBuf {
        self.partial.clone()
    }

    /// Writes the manifest (listing every staged file) and renames the staged directory to `dest`,
    /// replacing a previous pneuflex output there. Returns the final path.
    pub fn commit(self, manifest: Manifest) -> Result<PathBuf, OutputError> {
        let dest = self.dest.clone();
        self.commit_to(dest, manifest)
    }

    /// Commits an interrupted command's output under `<dest>.partial`, leaving `dest` untouched.
    pub fn commit_partial(
        self,
        mut manifest: Manifest,
        partial: Partial,
    ) -> Result<PathBuf, OutputError> {
        manifest.complete = false;
        manifest.partial = Some(partial);
        let to = self.partial_dest();
        self.commit_to(to, manifest)
    }

    fn commit_to(mut self, to: PathBuf, mut manifest: Manifest) -> Result<PathBuf, OutputError> {
        // The manifest names the command that wrote the directory, whatever the caller built it with.
        manifest.command = self.writer.command.to_string();
        manifest.recording = self.writer.recoverable == Recoverable::Irreplaceable;
        manifest.files = list_files(&self.tmp)?;
        let mpath = self.tmp.join(MANIFEST);
        let text = serde_json::to_string_pretty(&manifest).map_err(|e| OutputError::Io {
            path: mpath.clone(),
            op: "write",
            os_error: std::io::Error::other(e),
        })? + "\n";
        fs::write(&mpath, text).map_err(io(&mpath, "write"))?;
        // Checked again: the destination may have changed while the command ran.
        check_replaceable(&to, &self.writer)?;
        let aside = parent_of(&to).join(format!(".{}.old-{}", name_of(&to), std::process::id()));
        let had_old = to.exists();
        if had_old {
            fs::rename(&to, &aside).map_err(io(&to, "move aside"))?;
        }
        if let Err(e) = fs::rename(&self.tmp, &to) {
            if had_old {
                let _ = fs::rename(&aside, &to);
            }
            return Err(io(&to, "rename into place")(e));
        }
        self.done = true;
        // The staging mark goes only now: a staging directory whose commit failed keeps it, so the next
        // command still knows it as pneuflex's.
        let _ = fs::remove_file(to.join(STAGING_MARK));
        if had_old {
            remove_listed(&aside)?;
        }
        Ok(to)
    }

    /// Keeps the staging directory as it is and returns its path; nothing is removed.
    pub fn keep(mut self) -> PathBuf {
        self.done = true;
        self.tmp.clone()
    }
}

impl Drop for OutputDir {
    /// An uncommitted staging directory is removed, unless it holds irreplaceable data (a rig trace whose
    /// commit failed): that one stays, and the next command renames it to `<dest>.unfinished-<pid>`.
    fn drop(&mut self) {
        let nothing_written = || list_files(&self.tmp).is_ok_and(|f| f.is_empty());
        if !self.done && (self.writer.recoverable == Recoverable::Regenerable || nothing_written())
        {
            let _ = fs::remove_dir_all(&self.tmp);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A fresh scratch directory, removed when the returned guard drops.
    fn scratch(name: &str) -> tempfile::TempDir {
        tempfile::Builder::new()
            .prefix(&format!("pneuflex-out-{name}-"))
            .tempdir()
            .unwrap()
    }

    fn write_one(dest: &Path, body: &str) -> Result<PathBuf, OutputError> {
        let o = OutputDir::create(dest, &[], Writer::simulation("test"))?;
        fs::create_dir_all(o.path().join("run")).unwrap();
        fs::write(o.path().join("run/trace.csv"), body).unwrap();
        o.commit(Manifest::new("test", "0", vec![]))
    }

    #[test]
    fn a_user_file_survives_and_is_named() {
        let d = scratch("user");
        let d = d.path().to_path_buf();
        let dest = d.join("d");
        fs::create_dir_all(&dest).unwrap();
        fs::write(dest.join("notes.txt"), "mine").unwrap();
        let e = write_one(&dest, "x").unwrap_err();
        assert!(e.to_string().contains("notes.txt"), "{e}");
        assert_eq!(fs::read_to_string(dest.join("notes.txt")).unwrap(), "mine");
        // No staging directory left behind.
        assert_eq!(fs::read_dir(&d).unwrap().count(), 1);
    }

    #[test]
    fn an_output_is_replaced_and_a_file_added_to_it_blocks_the_next() {
        let d = scratch("replace");
        let d = d.path().to_path_buf();
        let dest = d.join("d");
        write_one(&dest, "1").unwrap();
        write_one(&dest, "2").unwrap();
        assert_eq!(fs::read_to_string(dest.join("run/trace.csv")).unwrap(), "2");
        let m = read_manifest(&dest).unwrap();
        assert_eq!(m.files, vec!["run/trace.csv".to_string()]);
        fs::write(dest.join("run/plot.png"), "user").unwrap();
        let e = write_one(&dest, "3").unwrap_err();
        assert!(e.to_string().contains("plot.png"), "{e}");
        assert_eq!(fs::read_to_string(dest.join("run/trace.csv")).unwrap(), "2");
    }

    #[test]
    fn the_working_directory_and_root_are_refused() {
        let e = check_not_protected(Path::new("."), &[]).unwrap_err();
        assert!(e.to_string().contains("working directory"), "{e}");
        let e = check_not_protected(Path::new("/"), &[]).unwrap_err();
        assert!(e.to_string().contains("root"), "{e}");
        let e = check_not_protected(Path::new(".."), &[]).unwrap_err();
        assert!(
            e.to_string().contains("contains the working directory"),
            "{e}"
        );
    }

    #[test]
    fn the_folder_of_an_input_is_refused() {
        let d = scratch("input");
        let d = d.path().to_path_buf();
        let scene = d.join("scenes/a.toml");
        fs::create_dir_all(scene.parent().unwrap()).unwrap();
        fs::write(&scene, "").unwrap();
        let e = check_not_protected(&d.join("scenes"), &[&scene]).unwrap_err();
        assert!(e.to_string().contains("holds an input"), "{e}");
    }

    #[test]
    fn a_partial_output_leaves_the_complete_one_untouched() {
        let d = scratch("partial");
        let d = d.path().to_path_buf();
        let dest = d.join("d");
        write_one(&dest, "complete").unwrap();
        let o = OutputDir::create(&dest, &[], Writer::simulation("test")).unwrap();
        fs::write(o.path().join("summary.json"), "{}").unwrap();
        let p = o
            .commit_partial(
                Manifest::new("test", "0", vec![]),
                Partial {
                    reason: "SIGINT".into(),
                    time_reached_s: 1.5,
                    done: None,
                },
            )
            .unwrap();
        assert_eq!(p, d.join("d.partial"));
        assert_eq!(
            fs::read_to_string(dest.join("run/trace.csv")).unwrap(),
            "complete"
        );
        let m = read_manifest(&p).unwrap();
        assert!(!m.complete);
        assert_eq!(m.partial.unwrap().reason, "SIGINT");
    }

    #[test]
    fn a_failed_commit_keeps_irreplaceable_data() {
        let d = scratch("failedcommit");
        let d = d.path().to_path_buf();
        let dest = d.join("r");
        let o = OutputDir::create(&dest, &[], Writer::recording("rig run")).unwrap();
        let staged = o.path().to_path_buf();
        fs::write(staged.join("trace.csv"), "t\n0\n").unwrap();
        // Somebody's file appears in the destination while the run goes on: the commit is refused…
        fs::create_dir_all(&dest).unwrap();
        fs::write(dest.join("notes.txt"), "mine").unwrap();
        assert!(o.commit(Manifest::new("test", "0", vec![])).is_err());
        // …and the recording is still there.
        assert_eq!(
            fs::read_to_string(staged.join("trace.csv")).unwrap(),
            "t\n0\n"
        );
    }

    #[test]
    fn stale_staging_of_a_dead_process_is_removed_or_kept_by_kind() {
        let d = scratch("stale");
        let d = d.path().to_path_buf();
        // PIDs above the kernel's pid_max (4194304) never exist.
        let dead = 4_194_399u32;
        let regen = d.join(format!(".d.partial-{dead}"));
        fs::create_dir_all(&regen).unwrap();
        fs::write(regen.join(STAGING_MARK), "regenerable").unwrap();
        let rig = d.join(format!(".r.partial-{dead}"));
        fs::create_dir_all(&rig).unwrap();
        fs::write(rig.join(STAGING_MARK), "irreplaceable").unwrap();
        fs::write(rig.join("trace.csv"), "t\n0\n").unwrap();
        let foreign = d.join(format!(".d.partial-{}", dead + 1));
        fs::create_dir_all(&foreign).unwrap();
        write_one(&d.join("d"), "x").unwrap();
        assert!(!regen.exists());
        assert!(
            foreign.exists(),
            "a directory without pneuflex's mark is never removed"
        );
        let o = OutputDir::create(&d.join("r"), &[], Writer::recording("rig run")).unwrap();
        assert_eq!(o.recovered, vec![d.join(format!("r.unfinished-{dead}"))]);
        assert!(d.join(format!("r.unfinished-{dead}/trace.csv")).exists());
    }

    /// A recording as `rig run` leaves it: a trace with the wall-clock column and its manifest.
    fn record_one(dest: &Path) -> PathBuf {
        let o = OutputDir::create(dest, &[], Writer::recording("rig excite")).unwrap();
        fs::write(
            o.path().join("trace.csv"),
            "# pneuflex rig trace\nt,u,wall_time,fault\n0,0,1.7e9,\n",
        )
        .unwrap();
        o.commit(Manifest::new("rig run", "0", vec![])).unwrap()
    }

    #[test]
    fn a_recording_names_its_command_and_is_replaced_by_no_command() {
        let d = scratch("recording");
        let dest = d.path().join("rec");
        record_one(&dest);
        let m = read_manifest(&dest).unwrap();
        // The writer names the command, whatever the caller's manifest said.
        assert_eq!(m.command, "rig excite");
        assert!(m.recording);
        let trace = fs::read(dest.join("trace.csv")).unwrap();
        for w in [
            Writer::simulation("sweep"),
            Writer::simulation("rig excite"),
            Writer::recording("rig excite"),
            Writer::recording("rig run"),
        ] {
            let e = OutputDir::create(&dest, &[], w).unwrap_err();
            assert!(matches!(e, OutputError::Recording { .. }), "{e}");
            assert!(e.to_string().contains("rig recording"), "{e}");
        }
        // A manifest edited to say it is a sweep's, listing every file: still a recording by its trace.
        let mut m = read_manifest(&dest).unwrap();
        m.command = "sweep".into();
        m.recording = false;
        fs::write(dest.join(MANIFEST), serde_json::to_string(&m).unwrap()).unwrap();
        let e = OutputDir::create(&dest, &[], Writer::simulation("sweep")).unwrap_err();
        assert!(e.to_string().contains("wall_time"), "{e}");
        assert_eq!(fs::read(dest.join("trace.csv")).unwrap(), trace);
    }

    #[test]
    fn a_simulation_output_is_replaced_only_by_its_own_command() {
        let d = scratch("othercmd");
        let dest = d.path().join("o");
        write_one(&dest, "1").unwrap();
        let e = OutputDir::create(&dest, &[], Writer::simulation("sweep")).unwrap_err();
        assert!(
            e.to_string().contains("output of `pneuflex test`") && e.to_string().contains("sweep"),
            "{e}"
        );
        assert_eq!(fs::read_to_string(dest.join("run/trace.csv")).unwrap(), "1");
    }

    #[test]
    fn nothing_is_written_inside_another_output() {
        let d = scratch("inside");
        let rec = d.path().join("rec");
        record_one(&rec);
        let e =
            OutputDir::create(&rec.join("fit"), &[], Writer::simulation("identify")).unwrap_err();
        assert!(
            e.to_string().contains("inside") && e.to_string().contains("rig recording"),
            "{e}"
        );
        let sim = d.path().join("sim");
        write_one(&sim, "1").unwrap();
        let e = OutputDir::create(&sim.join("a/b"), &[], Writer::simulation("test")).unwrap_err();
        assert!(e.to_string().contains("inside"), "{e}");
        assert!(!sim.join("a").exists());
    }

    #[test]
    fn a_second_recording_without_out_goes_beside_the_first() {
        let d = scratch("fresh");
        let dest = d.path().join("adaptive");
        assert_eq!(fresh_destination(&dest), dest);
        record_one(&dest);
        assert_eq!(fresh_destination(&dest), d.path().join("adaptive-2"));
    }

    #[test]
    fn a_manifest_entry_outside_its_directory_deletes_nothing() {
        let d = scratch("escape");
        let dest = d.path().join("o");
        write_one(&dest, "1").unwrap();
        let victim = d.path().join("victim.txt");
        fs::write(&victim, "mine").unwrap();
        let abs_victim = d.path().join("victim2.txt");
        fs::write(&abs_victim, "mine too").unwrap();
        for entry in [
            "../victim.txt".to_string(),
            abs_victim.display().to_string(),
        ] {
            let mut m = read_manifest(&dest).unwrap();
            m.files.push(entry.clone());
            fs::write(dest.join(MANIFEST), serde_json::to_string(&m).unwrap()).unwrap();
            let e = write_one(&dest, "2").unwrap_err();
            assert!(
                e.to_string().contains("outside the directory"),
                "{entry}: {e}"
            );
            m.files.pop();
            fs::write(dest.join(MANIFEST), serde_json::to_string(&m).unwrap()).unwrap();
        }
        // A stale moved-aside output of a dead process whose manifest lists a file outside it.
        let dead = 4_194_399u32;
        let old = d.path().join(format!(".o.old-{dead}"));
        fs::create_dir_all(&old).unwrap();
        let mut m = Manifest::new("test", "0", vec![]);
        m.files = vec!["../victim.txt".into()];
        fs::write(old.join(MANIFEST), serde_json::to_string(&m).unwrap()).unwrap();
        write_one(&dest, "3").unwrap();
        assert!(
            old.join(MANIFEST).exists(),
            "a directory with a foreign manifest is left alone"
        );
        assert_eq!(fs::read_to_string(&victim).unwrap(), "mine");
        assert_eq!(fs::read_to_string(&abs_victim).unwrap(), "mine too");
    }

    #[test]
    fn a_foreign_partial_is_refused_before_the_work() {
        let d = scratch("partialfirst");
        let dest = d.path().join("o");
        fs::create_dir_all(d.path().join("o.partial")).unwrap();
        fs::write(d.path().join("o.partial/notes.txt"), "mine").unwrap();
        let e = OutputDir::create(&dest, &[], Writer::simulation("test")).unwrap_err();
        assert!(e.to_string().contains("notes.txt"), "{e}");
    }
}
