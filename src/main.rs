//! The `pneuflex` command line: argument parsing (cli/), progress and wiring (cmd/) only — no physics, no
//! control law.

mod cli;
mod cmd;

use std::process::ExitCode;

use clap::Parser;

fn main() -> ExitCode {
    match cli::Cli::parse().command.call() {
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
