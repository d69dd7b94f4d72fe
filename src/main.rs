//! The `pneuflex` command line: argument parsing, progress and wiring only — no physics, no control law.

mod cmd;

use std::path::PathBuf;
use std::process::ExitCode;

use clap::{Parser, Subcommand};

/// Force and position control of pneumatic compliant actuators: model, controllers, scenes, real rig.
#[derive(Parser)]
#[command(name = "pneuflex", version, about, long_about = None)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Linearised transfer function (eqs. 16-17) of an actuator sheet, or of the sheet a scene names.
    Tf {
        /// An actuator sheet (pneumatics/*.toml) or a scene file (scenes/*.toml).
        file: PathBuf,
        /// Print one JSON object (SI units) instead of a table.
        #[arg(long)]
        json: bool,
        /// For a scene: the inner position loop's margins for each run at every stiffness the scene meets,
        /// the largest kp with `--margin-db` of gain margin, and the predicted limit-cycle onset.
        #[arg(long = "loop")]
        loop_analysis: bool,
        /// With --loop: the gain margin the largest kp is computed for, dB (default 6).
        #[arg(long)]
        margin_db: Option<f64>,
        /// With --loop: also draw the Bode plot of every run's inner loop at every stiffness (PNG).
        #[arg(long, value_name = "FILE.png")]
        bode: Option<PathBuf>,
    },
    /// Run every controller a scene lists; write traces, summary.json and figures.
    Run {
        /// A scene file (scenes/*.toml).
        scene: PathBuf,
        /// Output directory (default: out/<scene name>/).
        #[arg(long)]
        out: Option<PathBuf>,
        /// No progress bar and no metrics table.
        #[arg(long, short)]
        quiet: bool,
        /// Record every run to Rerun: `save <file.rrd>` (one file per run when the scene has several),
        /// `spawn` (start a viewer) or `connect <url>` (a running viewer). Needs the `rerun` feature.
        #[arg(long, num_args = 1..=2, value_names = ["MODE", "TARGET"])]
        rerun: Option<Vec<String>>,
        /// Largest number of integration steps a run may take (default 1e9); the scene is refused beyond it.
        #[arg(long, value_name = "N")]
        max_steps: Option<u64>,
        /// Largest memory all traces may take, MiB (default 2048); the scene is refused beyond it.
        #[arg(long, value_name = "MIB")]
        max_trace_mb: Option<u64>,
    },
    /// Run a scene at every point of a grid or sample of its keys, in parallel: one table of every point's
    /// metrics per run (sweep.csv), and for two keys a heatmap per run and of adaptive - impedance
    /// (docs/sweeps.md).
    Sweep {
        /// A scene file (scenes/*.toml).
        scene: PathBuf,
        /// KEY=SPEC: a key path as the scene's errors spell it (`environment.stiffness_n_per_m`,
        /// `runs[adaptive].inner.kp_per_m`, `plant.actuator:mechanics.moving_mass_kg`) and its values:
        /// `a,b,c`, `lin:LO:HI:N`, `log:LO:HI:N`, or sampled `rand:LO:HI`, `lhs:LO:HI`, `rand-log:LO:HI`,
        /// `lhs-log:LO:HI` (with --samples). Several --set make a grid.
        #[arg(long = "set", value_name = "KEY=SPEC", required = true)]
        sets: Vec<String>,
        /// Output directory (default: out/<scene name>-sweep/), as `run --out`.
        #[arg(long)]
        out: Option<PathBuf>,
        /// Worker threads (default: one per core); the table is the same whatever the number.
        #[arg(long, default_value_t = 0)]
        threads: usize,
        /// The metric of the heatmaps, WINDOW.METRIC (default: the first sine window's rms_force_error_n);
        /// repeat for heatmaps of several metrics.
        #[arg(long, value_name = "WINDOW.METRIC")]
        metric: Vec<String>,
        /// Number of samples of the sampled keys (rand:, lhs:, ...).
        #[arg(long, value_name = "N")]
        samples: Option<usize>,
        /// Seed of the sampled keys.
        #[arg(long, default_value_t = 0)]
        seed: u64,
        /// Also write every point's traces and summary.json (points/point-<i>/).
        #[arg(long)]
        traces: bool,
        /// No progress bar and no summary line.
        #[arg(long, short)]
        quiet: bool,
        /// Largest number of points (default 1,000,000; at most 100,000,000); the sweep is refused beyond.
        #[arg(long, value_name = "N", default_value_t = pneuflex_sweep::points::DEFAULT_MAX_POINTS)]
        max_points: u64,
        /// Largest output `--traces` may write, MiB (default 4096); the sweep is refused beyond.
        #[arg(long, value_name = "MIB", default_value_t = cmd::sweep::DEFAULT_MAX_OUTPUT_MB)]
        max_output_mb: u64,
        /// Largest number of integration steps one run of a point may take (default 1e9), as `run`'s.
        #[arg(long, value_name = "N")]
        max_steps: Option<u64>,
        /// Largest memory the traces of one point's runs may take, MiB (default 2048), as `run`'s.
        #[arg(long, value_name = "MIB")]
        max_trace_mb: Option<u64>,
    },
    /// Find the gains that minimise the worst case, over a list of environments, of a weighted sum of a
    /// run's RMS error, phase lag and recovery overshoot (CMA-ES, in parallel, with a budget and a seed);
    /// writes the tuned scene, convergence.png and report.md (docs/sweeps.md).
    Tune {
        /// A scene file (scenes/*.toml).
        scene: PathBuf,
        /// KEY=[LO,HI]: a scene key the search moves within the box, e.g. `runs[adaptive].inner.kp_per_m=[2,20]`.
        #[arg(long = "free", value_name = "KEY=[LO,HI]", required = true)]
        free: Vec<String>,
        /// KEY=V1,V2,...: the environments (a list or lin:/log: range; several --over make a grid); the
        /// objective is the worst case over them. Default: the scene's own environment.
        #[arg(long = "over", value_name = "KEY=SPEC")]
        over: Vec<String>,
        /// The run whose metrics are the objective (default: the first adaptive run, else the first).
        #[arg(long)]
        run: Option<String>,
        /// WINDOW.METRIC=WEIGHT terms of J_e, replacing the default (every sine window's rms_force_error_n
        /// x 1 and phase_lag_deg x 0.1, every event window's recovery_overshoot_pct x 0.05).
        #[arg(long = "term", value_name = "WINDOW.METRIC=WEIGHT")]
        terms: Vec<String>,
        /// Largest number of candidates evaluated (each over every environment).
        #[arg(long, default_value_t = 200)]
        budget: usize,
        /// Seed of CMA-ES: the same seed and inputs give the same result, whatever the thread count.
        #[arg(long, default_value_t = 0)]
        seed: u64,
        /// CMA-ES population per generation (default 4 + 3 ln n).
        #[arg(long)]
        population: Option<usize>,
        /// CMA-ES initial step, as a fraction of each box.
        #[arg(long, default_value_t = 0.3)]
        sigma0: f64,
        /// Worker threads (default: one per core).
        #[arg(long, default_value_t = 0)]
        threads: usize,
        /// Output directory (default: out/<scene name>-tune/), as `run --out`.
        #[arg(long)]
        out: Option<PathBuf>,
        /// No progress bar and no summary.
        #[arg(long, short)]
        quiet: bool,
        /// Largest number of scene runs (budget x environments; default 1,000,000, at most 100,000,000).
        #[arg(long, value_name = "N", default_value_t = pneuflex_sweep::points::DEFAULT_MAX_POINTS)]
        max_runs: u64,
        /// Largest number of integration steps one run of a candidate may take (default 1e9), as `run`'s.
        #[arg(long, value_name = "N")]
        max_steps: Option<u64>,
        /// Largest memory of one candidate's traces, MiB (default 2048), as `run`'s.
        #[arg(long, value_name = "MIB")]
        max_trace_mb: Option<u64>,
    },
    /// Fit actuator-sheet parameters to rig logs (docs/identification.md): replay the logged valve command
    /// through the 1-DOF model, Levenberg-Marquardt, 95 % intervals, report, fitted sheet.
    Identify {
        /// Rig traces (trace.csv of `rig run` / `rig excite`); repeat for several logs.
        #[arg(long = "log", required = true)]
        logs: Vec<PathBuf>,
        /// The actuator sheet to start from (pneumatics/*.toml).
        #[arg(long)]
        actuator: PathBuf,
        /// Parameters to fit, comma-separated dotted keys (valve.sonic_conductance_m3_per_s_pa, ...).
        #[arg(long, required = true)]
        free: Vec<String>,
        /// Bounds of a free parameter, KEY=[lo,hi]; repeat for several.
        #[arg(long)]
        bounds: Vec<String>,
        /// Output directory (default: out/identify/<folder of the first log>/).
        #[arg(long)]
        out: Option<PathBuf>,
        /// Fraction of each log held out at its end for validation.
        #[arg(long, default_value_t = 0.2)]
        validation: f64,
        /// Segment length of the replay, s (each segment restarts from the measured state).
        #[arg(long, default_value_t = 0.1)]
        segment: f64,
        /// Start of each segment left out of the comparison, s.
        #[arg(long, default_value_t = 0.015)]
        settle: f64,
        /// Largest number of data rows of one log (default 2,000,000); a longer log is refused.
        #[arg(long, value_name = "N", default_value_t = 2_000_000)]
        max_rows: usize,
        /// Longest time span of one log, s (default 3600); a longer log is refused.
        #[arg(long, value_name = "S", default_value_t = 3600.0)]
        max_log_s: f64,
    },
    /// Write a hidden truth for identification tests: the sheet with KEYS each moved 20-40 % (seeded).
    Perturb {
        /// The actuator sheet to perturb.
        #[arg(long)]
        actuator: PathBuf,
        /// Keys to perturb, comma-separated.
        #[arg(long, required = true)]
        keys: Vec<String>,
        /// Seed.
        #[arg(long, default_value_t = 1)]
        seed: u64,
        /// New directory for the sheets and truth.json.
        #[arg(long)]
        out: PathBuf,
    },
    /// Fit friction laws (constant Coulomb, and rising with the pressure) to a seal's bench tests at held
    /// pressures: force, pressure and position logs `circle_<P>bar.csv` (docs/identification.md, "Real data").
    Seal {
        /// Folder of the tests (or its parent with a `friction/` folder), e.g.
        /// data/zillen-2021-printed-cylinder.
        #[arg(long)]
        data: PathBuf,
        /// Piston bore, m.
        #[arg(long, default_value_t = 0.025)]
        bore_m: f64,
        /// Speed below which a sample is still and left out, m/s.
        #[arg(long, default_value_t = 0.002)]
        still_below: f64,
        /// Print one JSON object (SI units) instead of tables.
        #[arg(long)]
        json: bool,
    },
    /// Fit a choked ISO 6358 leak, as a conductance per volume, to closed-chamber pressure-decay logs
    /// (';'-separated, time in ms with '.' as the thousands separator) and rank the chambers.
    Leak {
        /// Decay logs; repeat for several chambers.
        #[arg(long = "log", required = true)]
        logs: Vec<PathBuf>,
        /// Gas temperature in the chamber, K.
        #[arg(long, default_value_t = pneuflex_pneumatics::T_DEFAULT)]
        temperature_k: f64,
        /// Atmospheric pressure, Pa absolute.
        #[arg(long, default_value_t = pneuflex_pneumatics::P_ATM)]
        atmosphere_pa: f64,
        /// Print JSON (SI units) instead of a table.
        #[arg(long)]
        json: bool,
    },
    /// Real-rig mode: the same controller on a real or emulated rig over the serial protocol (docs/rig.md).
    Rig {
        #[command(subcommand)]
        action: RigCommand,
    },
}

#[derive(Subcommand)]
enum RigCommand {
    /// Emulate the rig's I/O board: the 1-DOF pneumatic plant in real time behind a pseudo-terminal (or a port).
    Emulate {
        /// Rig file (rigs/*.toml): protocol, calibration, plant and fault injection.
        #[arg(long, default_value = "rigs/emulated.toml")]
        rig: PathBuf,
        /// Serve this serial port instead of a new pseudo-terminal.
        #[arg(long)]
        port: Option<String>,
        /// Stop after this many seconds (default: until Ctrl-C).
        #[arg(long)]
        duration: Option<f64>,
        /// Hide a truth: the plant runs this actuator sheet (and its supply), which the host does not know.
        #[arg(long)]
        truth: Option<PathBuf>,
        /// Sensor-noise seed (with --truth; default: the rig file's emulator.seed).
        #[arg(long)]
        seed: Option<u64>,
        /// Transport delay of valve commands in seconds, whole sample periods (with --truth).
        #[arg(long)]
        delay: Option<f64>,
    },
    /// Processor-in-the-loop: a scene's controllers in the firmware on an emulated Cortex-M4F (QEMU
    /// mps2-an386), the plant simulated in lockstep, compared tick by tick with the host (docs/firmware.md).
    Pil {
        /// Scene file (scenes/*.toml).
        #[arg(long)]
        scene: PathBuf,
        /// Name of the scene's run (default: every run).
        #[arg(long)]
        run: Option<String>,
        /// Firmware ELF (default: firmware/target/thumbv7em-none-eabihf/release/pneuflex-firmware).
        #[arg(long)]
        firmware: Option<PathBuf>,
        /// Output directory (default: out/pil/<scene name>/).
        #[arg(long)]
        out: Option<PathBuf>,
        /// Log each run live to Rerun on the simulated timeline: `save <file.rrd>` (one file per run),
        /// `spawn` or `connect <url>`. Needs the `rerun` feature.
        #[arg(long, num_args = 1..=2, value_names = ["MODE", "TARGET"])]
        rerun: Option<Vec<String>>,
    },
    /// Excite the valve for identification (docs/identification.md): a PRBS, chirp or steps plus a weak
    /// centring term, under the supervisor's limits, logged like `rig run`.
    Excite {
        /// Serial port of the I/O board (default: the rig file's link.port).
        #[arg(long)]
        port: Option<String>,
        /// Rig file (rigs/*.toml).
        #[arg(long, default_value = "rigs/emulated.toml")]
        rig: PathBuf,
        /// prbs, chirp or steps.
        #[arg(long, default_value = "steps")]
        signal: String,
        /// Amplitude of the signal, command units (0-1).
        #[arg(long, default_value_t = 0.05)]
        amplitude: f64,
        /// Length, s.
        #[arg(long, default_value_t = 10.0)]
        duration: f64,
        /// Centre position the centring term holds, m.
        #[arg(long, default_value_t = 0.025)]
        centre: f64,
        /// Centring gain, 1/m (0: none, the piston walks into a stop or rests on the block).
        #[arg(long, default_value_t = 15.0)]
        centring: f64,
        /// Command bias.
        #[arg(long, default_value_t = 0.0)]
        bias: f64,
        /// PRBS bit / step hold time, s (chirp: ignored).
        #[arg(long, default_value_t = 0.15)]
        hold: f64,
        /// Seed of the PRBS / step levels.
        #[arg(long, default_value_t = 1)]
        seed: u64,
        /// Output directory for trace.csv (default: out/rig/excite/<signal>/).
        #[arg(long)]
        out: Option<PathBuf>,
        /// Instead of --port: the rig file's emulator in lockstep with a simulated clock (not real time),
        /// hiding this actuator sheet; --seed also seeds its sensor noise. For CI and worked examples.
        #[arg(long, conflicts_with = "port")]
        lockstep_truth: Option<PathBuf>,
    },
    /// Run one of a scene's controllers on a rig, real or emulated, with the safety supervisor.
    Run {
        /// Serial port of the I/O board (default: the rig file's link.port).
        #[arg(long)]
        port: Option<String>,
        /// Scene whose controller and reference schedule to run.
        #[arg(long)]
        scene: PathBuf,
        /// Rig file (rigs/*.toml): port, calibration, limits, safe state, watchdog.
        #[arg(long, default_value = "rigs/emulated.toml")]
        rig: PathBuf,
        /// Name of the scene's run to use (default: the first).
        #[arg(long)]
        run: Option<String>,
        /// Run length in seconds (default: the scene's duration).
        #[arg(long)]
        duration: Option<f64>,
        /// Output directory for trace.csv (default: out/rig/<scene>/<run>/).
        #[arg(long)]
        out: Option<PathBuf>,
        /// Show the run live in Rerun on the wall-clock timeline, with the same entity paths as `run`
        /// plus the link's quality: `save <file.rrd>`, `spawn` (start a viewer) or `connect <url>`.
        /// Needs the `rerun` feature.
        #[arg(long, num_args = 1..=2, value_names = ["MODE", "TARGET"])]
        rerun: Option<Vec<String>>,
    },
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    let result = match cli.command {
        Command::Rig {
            action:
                RigCommand::Pil {
                    scene,
                    run,
                    firmware,
                    out,
                    rerun,
                },
        } => cmd::pil::pil(
            &scene,
            run.as_deref(),
            firmware.as_deref(),
            out.as_deref(),
            rerun.as_deref(),
        ),
        Command::Tf {
            file,
            json,
            loop_analysis: true,
            margin_db,
            bode,
        } => cmd::tf::loop_margins(&file, margin_db.unwrap_or(6.0), json, bode.as_deref())
            .and_then(|text| cmd::write_stdout(format_args!("{text}"))),
        Command::Tf {
            file,
            json,
            margin_db,
            bode,
            ..
        } => cmd::tf::tf(&file, json, margin_db, bode.as_deref())
            .and_then(|text| cmd::write_stdout(format_args!("{text}"))),
        Command::Run {
            scene,
            out,
            quiet,
            rerun,
            max_steps,
            max_trace_mb,
        } => cmd::run::run(
            &scene,
            out.as_deref(),
            &cmd::run::RunArgs {
                quiet,
                rerun,
                max_steps,
                max_trace_mb,
            },
        ),
        Command::Sweep {
            scene,
            sets,
            out,
            threads,
            metric,
            samples,
            seed,
            traces,
            quiet,
            max_points,
            max_output_mb,
            max_steps,
            max_trace_mb,
        } => cmd::sweep::sweep(
            &scene,
            out.as_deref(),
            &cmd::sweep::SweepArgs {
                sets,
                samples,
                seed,
                threads,
                metric,
                traces,
                quiet,
                max_points,
                max_output_mb,
                limits: cmd::run::limits(max_steps, max_trace_mb),
            },
        ),
        Command::Tune {
            scene,
            free,
            over,
            run,
            terms,
            budget,
            seed,
            population,
            sigma0,
            threads,
            out,
            quiet,
            max_runs,
            max_steps,
            max_trace_mb,
        } => cmd::tune::tune(
            &scene,
            out.as_deref(),
            &cmd::tune::TuneArgs {
                free,
                over,
                run,
                terms,
                options: pneuflex_sweep::tune::TuneOptions {
                    budget,
                    seed,
                    population,
                    sigma0,
                    threads,
                    max_runs,
                },
                quiet,
                limits: cmd::run::limits(max_steps, max_trace_mb),
            },
        ),
        Command::Rig {
            action:
                RigCommand::Emulate {
                    rig,
                    port,
                    duration,
                    truth,
                    seed,
                    delay,
                },
        } => cmd::rig::emulate(
            &rig,
            port.as_deref(),
            duration,
            &cmd::rig::Hidden {
                truth,
                seed,
                delay_s: delay,
            },
        ),
        Command::Identify {
            logs,
            actuator,
            free,
            bounds,
            out,
            validation,
            segment,
            settle,
            max_rows,
            max_log_s,
        } => cmd::identify::identify(
            logs,
            &actuator,
            out.as_deref(),
            cmd::identify::IdentifyArgs {
                free,
                bounds,
                validation,
                segment_s: segment,
                settle_s: settle,
                limits: pneuflex_identify::log::LogLimits {
                    max_rows,
                    max_span_s: max_log_s,
                },
            },
        ),
        Command::Perturb {
            actuator,
            keys,
            seed,
            out,
        } => cmd::identify::perturb(&actuator, &keys, seed, &out),
        Command::Seal {
            data,
            bore_m,
            still_below,
            json,
        } => cmd::seal::seal(
            &data,
            &pneuflex_identify::seal::SealOptions {
                bore_m,
                still_below_m_per_s: still_below,
                ..Default::default()
            },
            json,
        ),
        Command::Leak {
            logs,
            temperature_k,
            atmosphere_pa,
            json,
        } => cmd::seal::leak(
            &logs,
            &pneuflex_identify::leak::LeakOptions {
                atmosphere_pa,
                temperature_k,
                ..Default::default()
            },
            json,
        ),
        Command::Rig {
            action:
                RigCommand::Excite {
                    port,
                    rig,
                    signal,
                    amplitude,
                    duration,
                    centre,
                    centring,
                    bias,
                    hold,
                    seed,
                    out,
                    lockstep_truth,
                },
        } => cmd::rig::excite(
            &rig,
            port.as_deref(),
            &cmd::rig::ExciteArgs {
                signal,
                amplitude,
                duration_s: duration,
                centre_m: centre,
                centring_per_m: centring,
                bias,
                hold_s: hold,
                seed,
                lockstep_truth,
            },
            out.as_deref(),
        ),
        Command::Rig {
            action:
                RigCommand::Run {
                    port,
                    scene,
                    rig,
                    run,
                    duration,
                    out,
                    rerun,
                },
        } => cmd::rig::run_scene(
            &rig,
            port.as_deref(),
            &scene,
            run.as_deref(),
            duration,
            out.as_deref(),
            rerun.as_deref(),
        ),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(err) => {
            let exit = err.downcast_ref::<cmd::Exit>();
            // A reader that went away (`| head`) hears nothing more.
            if exit.is_none_or(|e| !e.message.is_empty()) {
                cmd::write_stderr(format_args!("error: {err:#}"));
            }
            match exit {
                Some(e) => ExitCode::from(e.code),
                None => ExitCode::FAILURE,
            }
        }
    }
}
