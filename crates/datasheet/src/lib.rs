//! Your own rig from datasheet values (`pneuflex new rig`, docs/your-rig.md): the numbers a catalogue gives
//! — bore, rod, stroke, supply, the valve's QN, Kv, Cv or C and b, the sensors' ranges — become a consistent,
//! commented sheet set, a scene running the paper's experiment on that rig, and a rig file, with every
//! assumption listed and gains checked on the linearised loop and in simulation.
//!
//! - `units`: quantities with unit suffixes;
//! - `iso6358`: flow ratings to the sonic conductance and critical pressure ratio;
//! - `limits`: each option's own range, checked before anything is derived;
//! - `series`: the ISO 15552 / ISO 6432 bores, rods and ports;
//! - `design`: the datasheet resolved into every value, with its assumptions;
//! - `checks`: whether the rig can run the experiment, each finding naming its option;
//! - `gains`: inner-loop gains from the loop analysis, confirmed by simulation;
//! - `write`: the files.

pub mod checks;
pub mod design;
pub mod gains;
pub mod iso6358;
pub mod limits;
pub mod series;
pub mod units;
pub mod write;

use std::fmt::Write as _;

use std::path::{Path, PathBuf};

pub use checks::{Finding, Severity};
pub use design::{Datasheet, Design, FlowRating, ValveKind};
pub use gains::Gains;

/// Why `new rig` wrote nothing.
#[derive(Debug, thiserror::Error)]
pub enum DesignError {
    #[error("{key} {value}: {why}")]
    Value {
        key: String,
        value: String,
        why: String,
    },
    #[error("{key}: does not apply: {why}")]
    NotApplying { key: String, why: String },
    #[error("{key}: missing: {why}")]
    Missing { key: String, why: String },
    #[error("the rig cannot run the experiment as given:\n{}", .0.iter().map(|f| format!("  {f}")).collect::<Vec<_>>().join("\n"))]
    Checks(Vec<Finding>),
    #[error("{}: {what}: {source}", .path.display())]
    Io {
        path: PathBuf,
        what: &'static str,
        source: std::io::Error,
    },
    #[error("{}: exists; new rig writes a fresh directory and replaces nothing: give another name, or move it away yourself", .0.display())]
    Exists(PathBuf),
    #[error("the written scene: {0}")]
    Scene(String),
    #[error("gains: {0}")]
    Gains(String),
    #[error("interrupted: nothing written")]
    Interrupted,
}

/// What `new rig` did.
#[derive(Clone, Debug)]
pub struct Report {
    /// The directory written.
    pub dir: PathBuf,
    pub design: Design,
    /// The warnings (errors stop before anything is written).
    pub warnings: Vec<Finding>,
    pub gains: Gains,
}

/// The control tick of the generated scene, s.
pub const DT_S: f64 = 0.001;

/// Resolves and checks `ds`, chooses gains, and writes the rig directory `dir` whole (staged beside it,
/// renamed in at the end; nothing is left if anything fails). `command` is the command line, for the report.
pub fn new_rig(ds: &Datasheet, dir: &Path, command: &str) -> Result<Report, DesignError> {
    new_rig_until(ds, dir, command, &|| false)
}

/// [`new_rig`], stopping with [`DesignError::Interrupted`] (and nothing written) at the first simulation
/// step after `stop` says so: a Ctrl-C during the gains' search leaves no staging folder behind.
pub fn new_rig_until(
    ds: &Datasheet,
    dir: &Path,
    command: &str,
    stop: &dyn Fn() -> bool,
) -> Result<Report, DesignError> {
    // The rig is named after its directory unless a name is given (or the directory's name is no rig name:
    // then from its sizes).
    let named = Datasheet {
        name: ds.name.clone().or_else(|| {
            dir.file_name()
                .map(|n| n.to_string_lossy().into_owned())
                .filter(|n| design::valid_name(n))
        }),
        ..ds.clone()
    };
    let design = design::resolve(&named)?;
    let findings = checks::check(&design);
    if findings.iter().any(|f| f.severity == Severity::Error) {
        return Err(DesignError::Checks(
            findings
                .into_iter()
                .filter(|f| f.severity == Severity::Error)
                .collect(),
        ));
    }
    if std::fs::symlink_metadata(dir).is_ok() {
        return Err(DesignError::Exists(dir.to_path_buf()));
    }
    if dir.file_name().is_none() {
        return Err(DesignError::Value {
            key: "DIR".into(),
            value: dir.display().to_string(),
            why: "name a directory to create, e.g. my-rig".into(),
        });
    }
    let parent = match dir.parent() {
        Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
        _ => PathBuf::from("."),
    };
    // The folders above DIR this run creates, removed again (when empty) if it fails.
    let created = Created(
        parent
            .ancestors()
            .take_while(|a| !a.as_os_str().is_empty() && std::fs::symlink_metadata(a).is_err())
            .map(Path::to_path_buf)
            .collect(),
    );
    std::fs::create_dir_all(&parent).map_err(|source| DesignError::Io {
        path: parent.clone(),
        what: "create",
        source,
    })?;
    let (stage, staged) = stage_beside(&parent)?;
    let result = (|| {
        std::fs::create_dir(stage.join("pneumatics")).map_err(|source| DesignError::Io {
            path: stage.clone(),
            what: "create",
            source,
        })?;
        let mut write = |g: &Gains| -> Result<PathBuf, DesignError> {
            if stop() {
                return Err(DesignError::Interrupted);
            }
            for (rel, text) in write::files(&design, g) {
                let p = stage.join(rel);
                std::fs::write(&p, text).map_err(|source| DesignError::Io {
                    path: p.clone(),
                    what: "write",
                    source,
                })?;
            }
            Ok(stage.join(write::SCENE))
        };
        // RK4 resolves the fastest chamber pole λ when λh ≤ 0.8 (pneuflex_scene's advice warns above 1).
        write(&Gains::start(10, design.m_d_kg, design.b_d_ns_per_m))?;
        let sheet = pneuflex_pneumatics::ActuatorSheet::load(stage.join(write::ACTUATOR))
            .map_err(|e| DesignError::Scene(e.to_string()))?;
        let pole = pneuflex_scene::analysis::advice::fastest_chamber_pole(&sheet.model());
        let substeps = ((pole * DT_S / 0.8).ceil() as usize).max(10);
        if substeps > MAX_SUBSTEPS {
            return Err(DesignError::Checks(vec![oversized_valve(
                &design, substeps,
            )]));
        }
        let gains = gains::choose(
            Gains::start(substeps, design.m_d_kg, design.b_d_ns_per_m),
            &mut write,
        )?;
        // A kp whose full-stroke error opens the valve 1 % is no position loop (the analysis returns
        // such when the valve or the load is too slow for the experiment).
        if gains.kp_per_m * design.stroke_m < MIN_KP_STROKE {
            return Err(DesignError::Gains(format!(
                "the loop settles only with kp = {} /m, which opens the valve by {:.2e} for an error of the whole \
                 {} mm stroke: no position loop at all; the valve's timing (--response-time, --switching-delay, \
                 --pwm-frequency) or the load (--mass) is too slow for the experiment's force loop",
                limits::num(gains.kp_per_m),
                gains.kp_per_m * design.stroke_m,
                design::fmt_mm(design.stroke_m)
            )));
        }
        write(&gains)?;
        let report = Report {
            dir: dir.to_path_buf(),
            design: design.clone(),
            warnings: findings.clone(),
            gains,
        };
        let p = stage.join(write::REPORT);
        std::fs::write(&p, report.markdown(command)).map_err(|source| DesignError::Io {
            path: p.clone(),
            what: "write",
            source,
        })?;
        Ok(report)
    })();
    // Nothing is named inside the staging folder, which is gone when the user reads the message.
    let report = result.map_err(|e| unstaged(e, &stage, dir))?;
    if stop() {
        return Err(DesignError::Interrupted);
    }
    if std::fs::symlink_metadata(dir).is_ok() {
        return Err(DesignError::Exists(dir.to_path_buf()));
    }
    std::fs::rename(&stage, dir).map_err(|source| DesignError::Io {
        path: dir.to_path_buf(),
        what: "rename the staged directory to",
        source,
    })?;
    std::mem::forget(staged);
    std::mem::forget(created);
    Ok(report)
}

/// The least kp times the stroke: the valve command a full-stroke position error gives.
pub const MIN_KP_STROKE: f64 = 0.01;

/// The most RK4 steps a control tick the generated scene may take: beyond it a run takes minutes, and the
/// valve is far larger than the chamber it fills.
pub const MAX_SUBSTEPS: usize = 100;

/// A valve whose chamber pole needs `substeps` steps a tick: the finding, with a flow that would work.
fn oversized_valve(d: &Design, substeps: usize) -> Finding {
    let c_ok = d.sonic_conductance_m3_per_s_pa * MAX_SUBSTEPS as f64 / substeps as f64;
    let qn_ok = iso6358::qn_from_c(c_ok, d.critical_pressure_ratio) * 6e4;
    // A dead volume given with the valve assumed is the value to change; otherwise the valve's rating.
    let key = if !d.assumed("--dead-volume") && d.assumed("--valve-flow") {
        "--dead-volume"
    } else {
        d.flow_key
    };
    Finding {
        severity: Severity::Error,
        key,
        message: format!(
            "the valve (C = {:.3e} m³/(s Pa)) fills the cap side's {:.2} cm³ dead volume so fast that the simulation \
             needs {substeps} RK4 steps a 1 ms tick (at most {MAX_SUBSTEPS}): the valve is far larger than the \
             chamber; QN ≤ {:.0} l/min would work (--valve-flow {:.0}l/min), or a larger --dead-volume",
            d.sonic_conductance_m3_per_s_pa,
            d.dead_volume_a_m3 * 1e6,
            qn_ok.floor(),
            qn_ok.floor()
        ),
    }
}

/// A staging folder beside DIR, made by this call (a name already taken, by anyone, is skipped).
fn stage_beside(parent: &Path) -> Result<(PathBuf, Staged), DesignError> {
    for n in 0..100 {
        // Not after DIR's name: a name near the file system's 255 bytes would leave no room for a suffix.
        let stage = parent.join(format!(".new-rig-{}-{n}.partial", std::process::id()));
        match std::fs::create_dir(&stage) {
            Ok(()) => return Ok((stage.clone(), Staged(stage))),
            Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists => continue,
            Err(source) => {
                return Err(DesignError::Io {
                    path: parent.to_path_buf(),
                    what: "create a folder in",
                    source,
                });
            }
        }
    }
    Err(DesignError::Io {
        path: parent.to_path_buf(),
        what: "create a folder in",
        source: std::io::Error::other("100 staging names beside the directory are taken"),
    })
}

/// `e` with the staging folder's paths given as the files of `dir` they stand for; an error from loading
/// a file new rig itself wrote is new rig's fault, and says so.
fn unstaged(e: DesignError, stage: &Path, dir: &Path) -> DesignError {
    let swap = |s: &str| s.replace(&stage.display().to_string(), &dir.display().to_string());
    match e {
        DesignError::Scene(m) => DesignError::Scene(format!(
            "{}: new rig wrote a file its own loader refuses (an option's range is missing a check: please report \
             the command line)",
            swap(&m)
        )),
        DesignError::Io { path, what, source } => DesignError::Io {
            path: path
                .strip_prefix(stage)
                .map(|rel| dir.join(rel))
                .unwrap_or(path),
            what,
            source,
        },
        DesignError::Gains(m) => DesignError::Gains(swap(&m)),
        e => e,
    }
}

/// Removes the folders above DIR this run created (deepest first, only when empty), on any early return.
struct Created(Vec<PathBuf>);
impl Drop for Created {
    fn drop(&mut self) {
        for d in &self.0 {
            let _ = std::fs::remove_dir(d);
        }
    }
}

/// Removes the staging directory this process made, on any early return.
struct Staged(PathBuf);
impl Drop for Staged {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

impl Report {
    /// The report `new rig` leaves in the directory (README.md) and prints.
    pub fn markdown(&self, command: &str) -> String {
        let d = &self.design;
        let mut s = String::new();
        let _ = writeln!(s, "# {}\n\nWritten by `{command}`.\n", d.name);
        let _ = writeln!(
            s,
            "A {} mm bore, {} mm rod, {} mm stroke cylinder at {:.2} MPa gauge supply, {} valve (C = {:.3e} m³/(s Pa), \
             b = {}; {}), force range {:.1} N, a chamber at mid stroke filled in {:.0} ms.\n",
            design::fmt_mm(d.bore_m),
            design::fmt_mm(d.rod_m),
            design::fmt_mm(d.stroke_m),
            (d.supply_abs_pa - d.atmosphere_pa) * 1e-6,
            match d.valve {
                ValveKind::Pwm => format!("a {} Hz PWM on/off", d.pwm_frequency_hz),
                ValveKind::Proportional => "a proportional".into(),
            },
            d.sonic_conductance_m3_per_s_pa,
            d.critical_pressure_ratio,
            d.flow_source,
            d.force_range_n(),
            d.fill_time_s() * 1e3
        );
        let _ = writeln!(
            s,
            "The experiment (`scene.toml`): a {} N contact force with a {} N, 1 Hz sine from 3 s, on an environment of \
             {} N/m at {} mm that stiffens to {} N/m at 6 s; impedance m_d = {} kg, b_d = {} N s/m.\n",
            d.force_n,
            d.sine_amplitude_n,
            d.stiffness_n_per_m,
            design::fmt_mm(d.surface_m),
            d.stiffness_after_n_per_m,
            self.gains.m_d_kg,
            self.gains.b_d_ns_per_m
        );
        let _ = writeln!(
            s,
            "## Gains\n\nkp = {} /m, ki = {} /(m s): {}.",
            self.gains.kp_per_m, self.gains.ki_per_m_s, self.gains.note
        );
        let db = |g: &Option<f64>| {
            g.map_or("none (the phase never crosses -180°)".into(), |g| {
                format!("{g:.1} dB")
            })
        };
        for (k, inner, outer) in &self.gains.gain_margins_db {
            let _ = writeln!(
                s,
                "- k_e = {k} N/m: inner-loop gain margin {}, outer force loop {}",
                db(inner),
                db(outer)
            );
        }
        let _ = writeln!(s, "\n## Assumed (each option replaces its value)\n");
        for a in &d.assumptions {
            let _ = writeln!(s, "- `{}`: {}", a.key, a.text);
        }
        if !self.warnings.is_empty() {
            let _ = writeln!(s, "\n## Warnings\n");
            for w in &self.warnings {
                let _ = writeln!(s, "- `{}`: {}", w.key, w.message);
            }
        }
        let dir = self.dir.display();
        let _ = writeln!(
            s,
            "\n## Next\n\n```sh\npneuflex run {dir}/scene.toml            # the experiment, out/{}/\n\
             pneuflex tf {dir}/scene.toml --loop      # the loop's margins at each stiffness\n\
             pneuflex rig emulate --rig {dir}/rig.toml    # an emulated rig (blocks: rig run connects from a second terminal)\n\
             pneuflex rig run --rig {dir}/rig.toml --scene {dir}/scene.toml --lockstep-truth {dir}/pneumatics/actuator.toml\n\
             # ^ the scene's first run on the emulated rig in lockstep, without a second terminal: out/rig/{}/\n```\n\n\
             docs/your-rig.md walks through the rest (rig run, compare, identify).",
            d.name, d.name
        );
        s
    }
}
