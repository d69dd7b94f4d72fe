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

/// An output directory being written; it appears under its final name only on commit.
#[derive(Debug)]
pub struct OutputDir {
    dest: PathBuf,
    tmp: PathBuf,
    done: bool,
    recoverable: Recoverable,
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

/// Reads the manifest of an existing output directory, if it has one.
pub fn read_manifest(dir: &Path) -> Option<Manifest> {
    let path = dir.join(MANIFEST);
    let meta = fs::symlink_metadata(&path).ok()?;
    if !meta.is_file() || meta.len() > (16 << 20) {
        return None;
    }
    serde_json::from_slice(&fs::read(&path).ok()?).ok()
}

/// Checks that `dest` may be replaced: absent, an empty directory, or a pneuflex output whose manifest
/// lists every file in it.
pub fn check_replaceable(dest: &Path) -> Result<(), OutputError> {
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
    match read_manifest(dest) {
        Some(m) if m.tool == "pneuflex" => {
            if let Some(f) = files.iter().find(|f| !m.files.contains(f)) {
                return Err(OutputError::Foreign {
                    dest: dest.to_path_buf(),
                    foreign: dest.join(f),
                    why: "not listed in its .pneuflex-output.json",
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
    for f in &m.files {
        let p = dir.join(f);
        if fs::symlink_metadata(&p).is_ok_and(|m| m.is_file() || m.file_type().is_symlink()) {
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
    pub fn create(
        dest: &Path,
        protect: &[&Path],
        recoverable: Recoverable,
    ) -> Result<Self, OutputError> {
        check_not_protected(dest, protect)?;
        check_replaceable(dest)?;
        let parent = parent_of(dest);
        fs::create_dir_all(&parent).map_err(io(&parent, "create"))?;
        let name = name_of(dest);
        let recovered = clean_stale(&parent, &name);
        let tmp = parent.join(format!(".{name}.partial-{}", std::process::id()));
        if tmp.exists() {
            fs::remove_dir_all(&tmp).map_err(io(&tmp, "remove"))?;
        }
        fs::create_dir_all(&tmp).map_err(io(&tmp, "create"))?;
        let mark = match recoverable {
            Recoverable::Regenerable => "regenerable",
            Recoverable::Irreplaceable => "irreplaceable",
        };
        let mark_path = tmp.join(STAGING_MARK);
        fs::write(&mark_path, mark).map_err(io(&mark_path, "write"))?;
        Ok(Self {
            dest: dest.to_path_buf(),
            tmp,
            done: false,
            recoverable,
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

    /// Where a partial (interrupted) output goes: `<dest>.partial`.
    pub fn partial_dest(&self) -> PathBuf {
        parent_of(&self.dest).join(format!("{}.partial", name_of(&self.dest)))
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
        manifest.files = list_files(&self.tmp)?;
        let mpath = self.tmp.join(MANIFEST);
        let text = serde_json::to_string_pretty(&manifest).map_err(|e| OutputError::Io {
            path: mpath.clone(),
            op: "write",
            os_error: std::io::Error::other(e),
        })? + "\n";
        fs::write(&mpath, text).map_err(io(&mpath, "write"))?;
        // Checked again: the destination may have changed while the command ran.
        check_replaceable(&to)?;
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
        if !self.done && (self.recoverable == Recoverable::Regenerable || nothing_written()) {
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
        let o = OutputDir::create(dest, &[], Recoverable::Regenerable)?;
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
        let o = OutputDir::create(&dest, &[], Recoverable::Regenerable).unwrap();
        fs::write(o.path().join("summary.json"), "{}").unwrap();
        let p = o
            .commit_partial(
                Manifest::new("test", "0", vec![]),
                Partial {
                    reason: "SIGINT".into(),
                    time_reached_s: 1.5,
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
        let o = OutputDir::create(&dest, &[], Recoverable::Irreplaceable).unwrap();
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
        let o = OutputDir::create(&d.join("r"), &[], Recoverable::Irreplaceable).unwrap();
        assert_eq!(o.recovered, vec![d.join(format!("r.unfinished-{dead}"))]);
        assert!(d.join(format!("r.unfinished-{dead}/trace.csv")).exists());
    }
}
