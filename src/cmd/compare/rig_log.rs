//! What `compare` accepts as a rig log, checked before anything is simulated or written (docs/your-rig.md,
//! "The rig against its simulation"): the `trace.csv` of a `rig run --scene` recording of this scene (its
//! manifest, or the trace's own `# input scene` line, holds the scene's hash) and run (its summary.json, its
//! controller's columns), with the board's columns, finite and on the scene's ticks from t = 0. A
//! simulation's trace, an excitation log or another command's output is refused with what it is. A
//! recording that ended on a fault (or a signal) is kept up to the row before the fault.

use std::path::{Path, PathBuf};

use anyhow::bail;
use pneuflex_files::output::{MANIFEST, Manifest, RIG_TRACE_COLUMNS, read_manifest};
use pneuflex_rig::record::{COMMAND as RIG_RUN, EXCITE};
use pneuflex_rig::trace::END_MARKER;
use pneuflex_scene::{Scene, Trace};

/// A log that passed the checks.
pub(super) struct RigLog {
    /// Its rows up to (not including) the first faulty one.
    pub trace: Trace,
    /// How the recording ended early, when it did (a fault or a signal), in words.
    pub fault: Option<String>,
    /// What the checks could not confirm, in words (printed as warnings and kept in the report).
    pub notes: Vec<String>,
}

/// The output a log belongs to: the nearest manifest above it that lists it (its own folder's manifest
/// even when it does not: the file was then put into a recording by hand), and the log's path in it.
fn owner(path: &Path) -> Option<(PathBuf, Manifest, String)> {
    let abs = std::fs::canonicalize(path).ok()?;
    for (depth, dir) in abs.ancestors().skip(1).take(4).enumerate() {
        let Some(m) = read_manifest(dir) else {
            continue;
        };
        let rel = abs.strip_prefix(dir).ok()?;
        let rel = rel
            .components()
            .map(|c| c.as_os_str().to_string_lossy())
            .collect::<Vec<_>>()
            .join("/");
        if depth == 0 || m.files.contains(&rel) {
            return Some((dir.to_path_buf(), m, rel));
        }
    }
    None
}

/// The scene a rig trace's own comment lines name: `# input scene <path> sha256 <hex>`.
fn scene_line(comments: &[&str]) -> Option<(String, String)> {
    comments.iter().find_map(|c| {
        let rest = c.strip_prefix("# input scene ")?;
        let (path, hash) = rest.rsplit_once(" sha256 ")?;
        Some((path.to_string(), hash.trim().to_string()))
    })
}

/// The scene and run a recording's summary.json names (`rig run --scene` writes it beside the trace).
pub(super) fn summary_of(trace: &Path) -> Option<(String, String)> {
    let beside = trace
        .parent()
        .unwrap_or(Path::new("."))
        .join("summary.json");
    let text = std::fs::read_to_string(beside).ok()?;
    let s: serde_json::Value = serde_json::from_str(&text).ok()?;
    Some((
        s["scene"].as_str()?.to_string(),
        s["runs"][0]["name"].as_str()?.to_string(),
    ))
}

/// A file given as `--rig-log`: its text, what could not be confirmed, and the output it belongs to.
pub(super) struct Recording {
    /// The file's text.
    pub text: String,
    /// What the checks could not confirm, in words.
    pub notes: Vec<String>,
    /// The output it belongs to (its folder, manifest, and its path in it), when one lists it.
    pub owner: Option<(PathBuf, Manifest, String)>,
}

/// Reads `path` (given as `arg`) as a recording of `rig run`: a regular text file, not in a staging folder,
/// of an output whose manifest says `rig run` and lists it. Any other command's output is refused, saying
/// what it is. Shared by the one-actuator and the several-actuator checks.
pub(super) fn read_recording(arg: &str, path: &Path) -> anyhow::Result<Recording> {
    let shown = path.display().to_string();
    let meta = match std::fs::metadata(path) {
        Ok(m) => m,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => {
            bail!("--rig-log {arg}: no such file")
        }
        Err(e) => bail!("--rig-log {arg}: cannot read: {e}"),
    };
    if meta.is_dir() {
        let inside = path.join("trace.csv");
        if inside.is_file() {
            bail!(
                "--rig-log {arg}: is a directory; give the trace in it: --rig-log {}",
                inside.display()
            );
        }
        bail!("--rig-log {arg}: is a directory; give a recording's trace.csv");
    }
    // A pipe or a device would block or never end: only a file is read.
    if !meta.is_file() {
        bail!(
            "--rig-log {arg}: not a regular file (a pipe or a device); give a recording's trace.csv"
        );
    }
    // A recording still being written is staged in `.<dest>.partial-<pid>/` (crates/files output.rs).
    let folder = std::fs::canonicalize(path)
        .ok()
        .and_then(|p| {
            p.parent()
                .and_then(|d| d.file_name())
                .map(|n| n.to_string_lossy().into_owned())
        })
        .unwrap_or_default();
    if folder.starts_with('.') && folder.contains(".partial-") {
        bail!(
            "--rig-log {arg}: in {folder}/, the staging folder of a recording still being made (or of a run \
             that died: the next `rig run` beside it keeps that as `<out>.unfinished-<pid>/`); compare a \
             finished recording"
        );
    }
    let mut notes = Vec::new();
    // What wrote it: a recording of `rig run`, or something else, said so.
    let owner = owner(path);
    match &owner {
        Some((dir, m, rel)) if m.command != RIG_RUN => {
            let what = if m.command == EXCITE {
                "an excitation log, written by `pneuflex rig excite` (a test signal on the valve, not the \
                 scene's controller: `identify` reads it)"
                    .to_string()
            } else if m.recording {
                format!("a recording of `pneuflex {}`", m.command)
            } else if rel.ends_with(".csv") {
                format!("a simulation's trace, written by `pneuflex {}`", m.command)
            } else {
                format!("a file of the output of `pneuflex {}`", m.command)
            };
            bail!(
                "--rig-log {arg}: {what} (manifest {}), not a recording of the scene's run on the rig; \
                 compare needs the trace.csv that `rig run --scene` recorded",
                dir.join(MANIFEST).display()
            );
        }
        Some((dir, m, rel)) if !m.files.contains(rel) => bail!(
            "--rig-log {arg}: {rel} is not a file of the recording in {} (its manifest does not list it): \
             added or renamed after the recording?",
            dir.display()
        ),
        Some(_) => {}
        None if path.with_file_name(MANIFEST).exists() => notes.push(format!(
            "{shown}: the manifest beside it ({MANIFEST}) cannot be read as one: its provenance is read \
             from the trace's own lines"
        )),
        None => notes.push(format!(
            "{shown}: no manifest ({MANIFEST}) beside it: its provenance is read from the trace's own lines"
        )),
    }
    let bytes =
        std::fs::read(path).map_err(|e| anyhow::anyhow!("--rig-log {arg}: cannot read: {e}"))?;
    let text = String::from_utf8(bytes).map_err(|e| {
        anyhow::anyhow!(
            "--rig-log {arg}: not a text file (not UTF-8 at byte {}); give a recording's trace.csv",
            e.utf8_error().valid_up_to()
        )
    })?;
    Ok(Recording { text, notes, owner })
}

/// Refuses a recording made with another scene file than `scene_path` (or this one since changed), by the
/// hash its manifest (or its trace's own line, `from_trace`) recorded; `scene_name` says which case it is.
pub(super) fn check_scene_hash(
    arg: &str,
    path: &Path,
    scene_name: &str,
    scene_path: &Path,
    owner: Option<&(PathBuf, Manifest, String)>,
    from_trace: Option<(String, String)>,
    notes: &mut Vec<String>,
) -> anyhow::Result<()> {
    let shown = path.display().to_string();
    // The scene it ran: by hash, from the manifest, else from the trace's own input line.
    let recorded = owner
        .and_then(|(_, m, _)| m.inputs.iter().find(|i| i.role == "scene"))
        .map(|i| (i.path.clone(), i.sha256.clone()))
        .or(from_trace);
    let given = pneuflex_files::InputDigest::of_file(scene_path, "scene")?;
    match recorded {
        Some((was, hash)) if hash != given.sha256 => {
            let same_name = summary_of(path).is_some_and(|(s, _)| s == scene_name);
            let head = |h: &str| h.chars().take(12).collect::<String>();
            if same_name {
                bail!(
                    "--rig-log {arg}: recorded with scene `{}` as it was then ({was}, sha256 {}…); {} is now \
                     sha256 {}…: the scene changed since the recording; compare with the scene as recorded",
                    scene_name,
                    head(&hash),
                    scene_path.display(),
                    head(&given.sha256)
                );
            }
            bail!(
                "--rig-log {arg}: recorded with {was} (sha256 {}…), and {} is sha256 {}…: another scene, or \
                 this one changed since the recording",
                head(&hash),
                scene_path.display(),
                head(&given.sha256)
            );
        }
        Some(_) => {}
        None if owner.is_some() => notes.push(format!(
            "{shown}: an older recording: its manifest does not name the scene it ran, so it is not \
             checked to be a recording of {}",
            scene_path.display()
        )),
        None => bail!(
            "--rig-log {arg}: names no scene among its inputs (no manifest, no `# input scene` line): an \
             excitation log (`rig excite`) or a trace from elsewhere; compare needs the trace.csv that `rig \
             run --scene` recorded"
        ),
    }
    Ok(())
}

/// Reads and checks `path` (given as `arg`) as a recording of `scene`'s run `run`.
pub(super) fn check(
    scene: &Scene,
    scene_path: &Path,
    run: usize,
    arg: &str,
    path: &Path,
) -> anyhow::Result<RigLog> {
    let shown = path.display().to_string();
    let Recording {
        text,
        mut notes,
        owner,
    } = read_recording(arg, path)?;
    // The lines: comments before the header, the header, the data rows with their line numbers, the end
    // marker.
    let mut comments = Vec::new();
    let mut header: Option<(usize, &str)> = None;
    let mut rows: Vec<(usize, &str)> = Vec::new();
    let mut end: Option<(usize, &str)> = None;
    for (i, line) in text.lines().enumerate() {
        let line = line.trim_start_matches('\u{feff}');
        let n = i + 1;
        if line.trim().is_empty() {
            continue;
        }
        if let Some((at, _)) = end {
            bail!(
                "--rig-log {arg}: line {n}: more after the end marker of line {at}: two traces joined, or edited?"
            );
        }
        if let Some(e) = line.strip_prefix(END_MARKER) {
            end = Some((n, e));
        } else if line.starts_with('#') {
            if header.is_none() {
                comments.push(line);
            }
        } else if header.is_none() {
            header = Some((n, line));
        } else {
            rows.push((n, line));
        }
    }
    let Some((header_line, header)) = header else {
        bail!("--rig-log {arg}: no header row: empty, or not a trace");
    };
    let names: Vec<&str> = header.split(',').map(str::trim).collect();
    let missing: Vec<&str> = RIG_TRACE_COLUMNS
        .iter()
        .copied()
        .filter(|c| !names.contains(c))
        .collect();
    let loop_names: Vec<&str> = pneuflex_control::LOOP_SIGNALS
        .iter()
        .map(|s| s.name)
        .collect();
    if !names.starts_with(&loop_names) {
        let shown_header: String = header.chars().take(40).collect();
        bail!(
            "--rig-log {arg}: line {header_line}: `{shown_header}` is not a trace's header (`{}`, ...): give a \
             recording's trace.csv",
            loop_names.join(",")
        );
    }
    if missing.len() == RIG_TRACE_COLUMNS.len() {
        bail!(
            "--rig-log {arg}: line {header_line}: none of the rig's columns ({}): a simulation's trace \
             (`pneuflex run` writes one), not a recording of the rig",
            RIG_TRACE_COLUMNS.join(", ")
        );
    }
    if !missing.is_empty() {
        bail!(
            "--rig-log {arg}: line {header_line}: the board's columns {} are missing: a rig trace from \
             before trace schema 2, or edited; record the run again with `rig run --scene`",
            missing.join(", ")
        );
    }
    check_scene_hash(
        arg,
        path,
        &scene.name,
        scene_path,
        owner.as_ref(),
        scene_line(&comments),
        &mut notes,
    )?;
    // The run: its controller's own columns sit between the loop's signals and the board's.
    let controller = scene.controller(run)?;
    let want: Vec<&str> = controller.signals().iter().map(|s| s.name).collect();
    let loop_n = pneuflex_control::LOOP_SIGNALS.len();
    let board = names
        .iter()
        .position(|n| *n == RIG_TRACE_COLUMNS[0])
        .unwrap_or(names.len());
    let got: Vec<&str> = names.get(loop_n..board).unwrap_or_default().to_vec();
    if got != want {
        bail!(
            "--rig-log {arg}: line {header_line}: the controller's columns are [{}], run `{}` records [{}]: a \
             recording of another run?",
            got.join(","),
            scene.runs[run].name,
            want.join(",")
        );
    }
    let trace = Trace::from_csv(&text, &RIG_TRACE_COLUMNS)
        .map_err(|e| anyhow::anyhow!("--rig-log {shown}: {e}"))?;
    // The end marker: its count is the rows written; without it the recording was cut.
    match end {
        Some((at, e)) => {
            let count = e
                .rsplit_once(", ")
                .and_then(|(_, n)| n.strip_suffix(" rows"))
                .and_then(|n| n.trim().parse::<usize>().ok());
            match count {
                Some(c) if c == rows.len() => {}
                Some(c) => bail!(
                    "--rig-log {arg}: line {at}: the end marker counts {c} rows, the file has {}: rows were \
                     removed or added",
                    rows.len()
                ),
                None => bail!("--rig-log {arg}: line {at}: the end marker `{END_MARKER}{e}` is not `<reason>, <n> rows`"),
            }
        }
        None => notes.push(format!(
            "{shown}: no end marker: the recording was cut (a crash, a kill or a full disk) after {} rows",
            rows.len()
        )),
    }
    // The first faulty row: the comparison stops before it.
    let fault_col = names.iter().position(|n| *n == "fault").unwrap_or(0);
    let faulty = rows.iter().position(|(_, r)| {
        r.split(',')
            .nth(fault_col)
            .is_some_and(|c| !c.trim().is_empty())
    });
    let keep = faulty.unwrap_or(rows.len());
    let t = trace.t();
    let fault = match faulty {
        Some(k) => {
            let (line, row) = rows[k];
            let why = row
                .split(',')
                .nth(fault_col)
                .unwrap_or("")
                .trim()
                .replace(';', ",");
            if k < 2 {
                bail!(
                    "--rig-log {arg}: line {line}: the recording ended on a fault at its row {} ({why}): \
                     fewer than two rows before it to compare",
                    k + 1
                );
            }
            let how = if why.starts_with("interrupted") {
                "was stopped by a signal"
            } else {
                "ended on a fault"
            };
            Some(format!(
                "the recording {how} at t = {} s (line {line}: {why}); compared up to t = {} s",
                t[k],
                t[k - 1]
            ))
        }
        None => None,
    };
    if keep < 2 {
        bail!("--rig-log {arg}: fewer than two rows");
    }
    let trace = cut(trace, keep);
    // On the scene's ticks from t = 0, every value finite.
    let dt = scene.dt_s;
    let t = trace.t();
    if t[0].abs() > 0.01 * dt || !t[0].is_finite() {
        bail!(
            "--rig-log {arg}: line {}: starts at t = {} s; a recording starts at 0 (cut from a longer one?)",
            rows[0].0,
            t[0]
        );
    }
    for i in 1..keep {
        let step = t[i] - t[i - 1];
        if step.is_nan() || step <= 0.0 {
            bail!(
                "--rig-log {arg}: line {}: t = {} s does not come after the previous row's {} s: time must increase",
                rows[i].0,
                t[i],
                t[i - 1]
            );
        }
        if (step - dt).abs() > 0.01 * dt {
            bail!(
                "--rig-log {arg}: line {}: t jumps from {} to {} s, the scene's dt_s is {dt} s: rows missing, \
                 or a log of another scene?",
                rows[i].0,
                t[i - 1],
                t[i]
            );
        }
    }
    for (col, v) in trace.columns().iter().zip(columns(&trace)) {
        // Chamber pressures are NaN throughout on a rig without pressure sensors.
        if matches!(col.name.as_str(), "p_a" | "p_b") && v.iter().all(|x| x.is_nan()) {
            continue;
        }
        if let Some(i) = v.iter().position(|x| !x.is_finite()) {
            bail!(
                "--rig-log {arg}: line {}: column `{}`: {} is not a measurement (every value before a fault \
                 must be finite)",
                rows[i].0,
                col.name,
                if v[i].is_nan() {
                    "an empty cell or NaN".to_string()
                } else {
                    v[i].to_string()
                }
            );
        }
    }
    // The reference the rig followed is the scene's, tick by tick (computed by the same code on the same t):
    // what no hash can say of an older recording or an edited manifest.
    let setpoints = scene.setpoints()?;
    let f_ref = trace.f_ref();
    for i in 0..keep {
        let want = setpoints.at(t[i]).f_ref;
        if (f_ref[i] - want).abs() > 1e-6 * want.abs().max(1.0) {
            bail!(
                "--rig-log {arg}: line {}: f_ref = {} N, the reference of scene `{}` at t = {} s is {want} N: a \
                 recording of another scene, or of this one before its reference changed",
                rows[i].0,
                f_ref[i],
                scene.name,
                t[i]
            );
        }
    }
    Ok(RigLog {
        trace,
        fault,
        notes,
    })
}

/// Each column's values.
fn columns(trace: &Trace) -> Vec<Vec<f64>> {
    trace
        .clone()
        .into_columns()
        .into_iter()
        .map(|(_, v)| v)
        .collect()
}

/// The first `n` rows of `trace`.
fn cut(trace: Trace, n: usize) -> Trace {
    let cols = trace
        .into_columns()
        .into_iter()
        .map(|(c, mut v)| {
            v.truncate(n);
            (c, v)
        })
        .collect();
    Trace::from_columns(cols).expect("the same columns, shortened alike")
}
