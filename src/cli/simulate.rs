//! The simulation commands' arguments: `tf`, `run`, `sweep`, `tune`, each handed to its `cmd` module.

use std::path::PathBuf;

use clap::Args;

use super::FigureFormat;
use crate::cmd;

/// Linearised transfer function (eqs. 16-17) of an actuator sheet, or of the sheet a scene names.
#[derive(Args)]
pub struct Tf {
    /// An actuator sheet (pneumatics/*.toml) or a scene file (scenes/*.toml).
    pub file: PathBuf,
    /// Print one JSON object (SI units) instead of a table.
    #[arg(long)]
    pub json: bool,
    /// For a scene: the inner position loop's margins for each run at every stiffness the scene meets,
    /// the largest kp with `--margin-db` of gain margin, and the predicted limit-cycle onset.
    #[arg(long = "loop")]
    pub loop_analysis: bool,
    /// With --loop: the gain margin the largest kp is computed for, dB (default 6).
    #[arg(long)]
    pub margin_db: Option<f64>,
    /// With --loop: also draw the Bode plot of every run's inner loop at every stiffness, with the margins
    /// marked (PNG; SVG or PDF for a FILE ending in .svg or .pdf).
    #[arg(long, value_name = "FILE.png")]
    pub bode: Option<PathBuf>,
}

/// What one simulation of a scene may cost before it is refused, before anything runs (`run`; for `sweep`
/// one point, for `tune` one candidate).
#[derive(Args)]
pub struct RunLimits {
    /// Largest number of integration steps a run may take (default 1e9); refused beyond it.
    #[arg(long, value_name = "N")]
    pub max_steps: Option<u64>,
    /// Largest memory the traces of a scene's runs may take, MiB (default 2048); refused beyond it.
    #[arg(long, value_name = "MIB")]
    pub max_trace_mb: Option<u64>,
}

impl RunLimits {
    /// The limits, the defaults where a flag is absent.
    pub fn limits(&self) -> pneuflex_scene::Limits {
        let mut limits = pneuflex_scene::Limits::default();
        if let Some(n) = self.max_steps {
            limits.max_steps_per_run = n;
        }
        if let Some(mb) = self.max_trace_mb {
            limits.max_trace_bytes = mb.saturating_mul(1 << 20);
        }
        limits
    }
}

/// Run every controller a scene lists; write traces, summary.json and figures.
#[derive(Args)]
pub struct Run {
    /// A scene file (scenes/*.toml).
    pub scene: PathBuf,
    /// Output directory (default: out/<scene name>/).
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// No progress bar and no metrics table.
    #[arg(long, short)]
    pub quiet: bool,
    /// Record every run to Rerun: `save <file.rrd>` (one file per run when the scene has several),
    /// `spawn` (start a viewer) or `connect <url>` (a running viewer). Needs the `rerun` feature.
    #[arg(long, num_args = 1..=2, value_names = ["MODE", "TARGET"])]
    pub rerun: Option<Vec<String>>,
    #[command(flatten)]
    pub limits: RunLimits,
    /// The figures' format: png (default), svg or pdf (vector, for a paper).
    #[arg(long, value_enum, default_value_t = FigureFormat::Png)]
    pub format: FigureFormat,
    /// Also write each run's trace as a rosbag2 recording (MCAP storage, CDR), `<run>/bag/`: joint
    /// states, chamber pressures, valve command, force reference, controller signals (docs/ros2.md).
    #[arg(long)]
    pub mcap: bool,
}

/// Run a scene at every point of a grid or sample of its keys, in parallel: one table of every point's
/// metrics per run (sweep.csv), and for two keys a heatmap per run and of adaptive - impedance
/// (docs/sweeps.md).
#[derive(Args)]
pub struct Sweep {
    /// A scene file (scenes/*.toml).
    pub scene: PathBuf,
    /// KEY=SPEC: a key path as the scene's errors spell it (`environment.stiffness_n_per_m`,
    /// `runs[adaptive].inner.kp_per_m`, `plant.actuator:mechanics.moving_mass_kg`) and its values:
    /// `a,b,c`, `lin:LO:HI:N`, `log:LO:HI:N`, or sampled `rand:LO:HI`, `lhs:LO:HI`, `rand-log:LO:HI`,
    /// `lhs-log:LO:HI` (with --samples). Several --set make a grid.
    #[arg(long = "set", value_name = "KEY=SPEC", required = true)]
    pub sets: Vec<String>,
    /// Output directory (default: out/<scene name>-sweep/), as `run --out`.
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Worker threads (default: one per core); the table is the same whatever the number.
    #[arg(long, default_value_t = 0)]
    pub threads: usize,
    /// The metric of the heatmaps, WINDOW.METRIC (default: the first sine window's rms_force_error_n);
    /// repeat for heatmaps of several metrics.
    #[arg(long, value_name = "WINDOW.METRIC")]
    pub metric: Vec<String>,
    /// The heatmaps' format: png (default), svg or pdf.
    #[arg(long, value_enum, default_value_t = FigureFormat::Png)]
    pub format: FigureFormat,
    /// Number of samples of the sampled keys (rand:, lhs:, ...).
    #[arg(long, value_name = "N")]
    pub samples: Option<usize>,
    /// Seed of the sampled keys.
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Also write every point's traces and summary.json (points/point-<i>/).
    #[arg(long)]
    pub traces: bool,
    /// No progress bar and no summary line.
    #[arg(long, short)]
    pub quiet: bool,
    /// Largest number of points (default 1,000,000; at most 100,000,000); the sweep is refused beyond.
    #[arg(long, value_name = "N", default_value_t = pneuflex_sweep::points::DEFAULT_MAX_POINTS)]
    pub max_points: u64,
    /// Largest output `--traces` may write, MiB (default 4096); the sweep is refused beyond.
    #[arg(long, value_name = "MIB", default_value_t = cmd::sweep::DEFAULT_MAX_OUTPUT_MB)]
    pub max_output_mb: u64,
    #[command(flatten)]
    pub limits: RunLimits,
}

/// Find the gains that minimise the worst case, over a list of environments, of a weighted sum of a
/// run's RMS error, phase lag and recovery overshoot (CMA-ES, in parallel, with a budget and a seed);
/// writes the tuned scene, convergence.png and report.md (docs/sweeps.md).
#[derive(Args)]
pub struct Tune {
    /// A scene file (scenes/*.toml).
    pub scene: PathBuf,
    /// KEY=[LO,HI]: a scene key the search moves within the box, e.g. `runs[adaptive].inner.kp_per_m=[2,20]`.
    #[arg(long = "free", value_name = "KEY=[LO,HI]", required = true)]
    pub free: Vec<String>,
    /// KEY=V1,V2,...: the environments (a list or lin:/log: range; several --over make a grid); the
    /// objective is the worst case over them. Default: the scene's own environment.
    #[arg(long = "over", value_name = "KEY=SPEC")]
    pub over: Vec<String>,
    /// The run whose metrics are the objective (default: the first adaptive run, else the first).
    #[arg(long)]
    pub run: Option<String>,
    /// WINDOW.METRIC=WEIGHT terms of J_e, replacing the default (every sine window's rms_force_error_n
    /// x 1 and phase_lag_deg x 0.1, every event window's recovery_overshoot_pct x 0.05).
    #[arg(long = "term", value_name = "WINDOW.METRIC=WEIGHT")]
    pub terms: Vec<String>,
    /// Largest number of candidates evaluated (each over every environment).
    #[arg(long, default_value_t = 200)]
    pub budget: usize,
    /// Seed of CMA-ES: the same seed and inputs give the same result, whatever the thread count.
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// CMA-ES population per generation (default 4 + 3 ln n).
    #[arg(long)]
    pub population: Option<usize>,
    /// CMA-ES initial step, as a fraction of each box.
    #[arg(long, default_value_t = 0.3)]
    sigma0: f64,
    /// Worker threads (default: one per core).
    #[arg(long, default_value_t = 0)]
    pub threads: usize,
    /// Output directory (default: out/<scene name>-tune/), as `run --out`.
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// No progress bar and no summary.
    #[arg(long, short)]
    pub quiet: bool,
    /// Largest number of scene runs (budget x environments; default 1,000,000, at most 100,000,000).
    #[arg(long, value_name = "N", default_value_t = pneuflex_sweep::points::DEFAULT_MAX_POINTS)]
    pub max_runs: u64,
    #[command(flatten)]
    pub limits: RunLimits,
    /// The convergence plot's format: png (default), svg or pdf.
    #[arg(long, value_enum, default_value_t = FigureFormat::Png)]
    pub format: FigureFormat,
}

impl Tf {
    pub fn call(self) -> anyhow::Result<()> {
        let text = if self.loop_analysis {
            cmd::tf::loop_margins(
                &self.file,
                self.margin_db.unwrap_or(6.0),
                self.json,
                self.bode.as_deref(),
            )?
        } else {
            cmd::tf::tf(&self.file, self.json, self.margin_db, self.bode.as_deref())?
        };
        cmd::write_stdout(format_args!("{text}"))
    }
}

impl Run {
    pub fn call(self) -> anyhow::Result<()> {
        cmd::run::run(
            &self.scene,
            self.out.as_deref(),
            &cmd::run::RunArgs {
                quiet: self.quiet,
                rerun: self.rerun,
                limits: self.limits.limits(),
                figures: self.format.into(),
                mcap: self.mcap,
            },
        )
    }
}

impl Sweep {
    pub fn call(self) -> anyhow::Result<()> {
        cmd::sweep::sweep(
            &self.scene,
            self.out.as_deref(),
            &cmd::sweep::SweepArgs {
                sets: self.sets,
                samples: self.samples,
                seed: self.seed,
                threads: self.threads,
                metric: self.metric,
                format: self.format.into(),
                traces: self.traces,
                quiet: self.quiet,
                max_points: self.max_points,
                max_output_mb: self.max_output_mb,
                limits: self.limits.limits(),
            },
        )
    }
}

impl Tune {
    pub fn call(self) -> anyhow::Result<()> {
        cmd::tune::tune(
            &self.scene,
            self.out.as_deref(),
            &cmd::tune::TuneArgs {
                free: self.free,
                over: self.over,
                run: self.run,
                terms: self.terms,
                options: pneuflex_sweep::tune::TuneOptions {
                    budget: self.budget,
                    seed: self.seed,
                    population: self.population,
                    sigma0: self.sigma0,
                    threads: self.threads,
                    max_runs: self.max_runs,
                },
                quiet: self.quiet,
                limits: self.limits.limits(),
                figures: self.format.into(),
            },
        )
    }
}

/// A rig's run against the simulation of the same scene and run: each window's metrics side by side with
/// the difference, figures of both, and the RMS difference of the traces (docs/your-rig.md).
#[derive(Args)]
pub struct Compare {
    /// The scene the rig ran (scenes/*.toml).
    pub scene: PathBuf,
    /// The trace.csv of a `rig run --scene` recording of this scene (checked: its manifest or trace names
    /// the scene by hash; the board's columns; finite; time from 0 on the scene's ticks; a simulation's
    /// trace or an excitation log is refused; a run that ended on a fault is compared up to the fault).
    /// Repeat it (RUN=TRACE.csv when its folder has no summary.json) for several runs, whose claims are then
    /// judged on the rig beside the simulation.
    #[arg(long, value_name = "[RUN=]TRACE.csv", required = true)]
    pub rig_log: Vec<String>,
    /// The scene's run a single --rig-log recorded (default: the one its summary.json names, else the first).
    #[arg(long)]
    pub run: Option<String>,
    /// Simulate with this actuator sheet instead of the scene's (an identified one: how much closer it comes).
    #[arg(long, value_name = "SHEET.toml")]
    pub actuator: Option<PathBuf>,
    /// Output directory (default: out/compare/<scene>/<run>/, out/compare/<scene>/<run>+<run>/ for several).
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// The figures' format: png (default), svg or pdf.
    #[arg(long, value_enum, default_value_t = FigureFormat::Png)]
    pub format: FigureFormat,
}

impl Compare {
    pub fn call(self) -> anyhow::Result<()> {
        cmd::compare::compare(&cmd::compare::CompareArgs {
            scene: &self.scene,
            rig_log: &self.rig_log,
            run: self.run.as_deref(),
            actuator: self.actuator.as_deref(),
            out: self.out.as_deref(),
            format: self.format.into(),
        })
    }
}
