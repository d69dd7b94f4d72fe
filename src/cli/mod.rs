//! The command line's grammar: one `Args` struct per command, grouped as the commands are (simulation,
//! identification, real rig); each hands its values to its `cmd` module and holds no logic of its own.

pub mod identify;
pub mod new;
pub mod rig;
pub mod ros2;
pub mod simulate;

use clap::{Parser, Subcommand};

/// A figure format on the command line (`--format` of every command that draws).
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum FigureFormat {
    /// Raster image.
    Png,
    /// Vector image.
    Svg,
    /// Vector document, from the SVG (for a paper).
    Pdf,
}

impl From<FigureFormat> for pneuflex_viz::Format {
    fn from(f: FigureFormat) -> Self {
        match f {
            FigureFormat::Png => pneuflex_viz::Format::Png,
            FigureFormat::Svg => pneuflex_viz::Format::Svg,
            FigureFormat::Pdf => pneuflex_viz::Format::Pdf,
        }
    }
}

/// Force and position control of pneumatic compliant actuators: model, controllers, scenes, real rig.
#[derive(Parser)]
#[command(name = "pneuflex", version, about, long_about = None)]
pub struct Cli {
    #[command(subcommand)]
    pub command: Command,
}

#[derive(Subcommand)]
pub enum Command {
    Tf(simulate::Tf),
    Run(simulate::Run),
    Sweep(simulate::Sweep),
    Tune(simulate::Tune),
    Compare(simulate::Compare),
    Identify(identify::Identify),
    Perturb(identify::Perturb),
    Seal(identify::Seal),
    Leak(identify::Leak),
    /// Make something new from a few values: `new rig DIR` from datasheet values (docs/your-rig.md).
    New {
        #[command(subcommand)]
        what: new::NewCommand,
    },
    /// Real-rig mode: the same controller on a real or emulated rig over the serial protocol (docs/rig.md).
    Rig {
        #[command(subcommand)]
        action: rig::RigCommand,
    },
    Ros2(ros2::Ros2),
}

impl Command {
    pub fn call(self) -> anyhow::Result<()> {
        match self {
            Command::Tf(a) => a.call(),
            Command::Run(a) => a.call(),
            Command::Sweep(a) => a.call(),
            Command::Tune(a) => a.call(),
            Command::Compare(a) => a.call(),
            Command::Identify(a) => a.call(),
            Command::Perturb(a) => a.call(),
            Command::Seal(a) => a.call(),
            Command::Leak(a) => a.call(),
            Command::New { what } => what.call(),
            Command::Rig { action } => action.call(),
            Command::Ros2(a) => a.call(),
        }
    }
}
