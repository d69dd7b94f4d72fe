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
    },
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    let result = match cli.command {
        Command::Tf { file, json } => cmd::tf::tf(&file, json).map(|text| println!("{text}")),
        Command::Run { scene, out, quiet } => cmd::run::run(&scene, out.as_deref(), quiet),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(err) => {
            eprintln!("error: {err:#}");
            ExitCode::FAILURE
        }
    }
}
