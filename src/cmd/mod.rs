//! One module per subcommand; each returns `anyhow::Result` and leaves printing of errors to `main`.
//!
//! Commands print through [`outln!`] and [`errln!`], never `println!`: a closed or full stdout (`| head`,
//! `> /dev/full`, `>&-`) is a clean exit with a message, not a panic, and a closed stderr is ignored.

/// Writes one line to stdout; a write error ends the command (`?` inside).
macro_rules! outln {
    ($($arg:tt)*) => {
        $crate::cmd::write_stdout(format_args!($($arg)*))?
    };
}

/// Writes one line to stderr; an error writing it is ignored (there is nowhere left to say it).
macro_rules! errln {
    ($($arg:tt)*) => {
        $crate::cmd::write_stderr(format_args!($($arg)*))
    };
}

/// The exit code of a command whose stdout was closed by its reader (`| head`): 128 + SIGPIPE, as a
/// shell reports a process that SIGPIPE ended.
pub const EXIT_BROKEN_PIPE: u8 = 128 + 13;

/// Writes `args` and a newline to stdout and flushes. A reader that went away (broken pipe) ends the
/// command quietly with [`EXIT_BROKEN_PIPE`]; any other error (a full disk, a closed descriptor) ends it
/// with a message. Outputs on disk are committed before a command prints its summary, so they stay.
pub fn write_stdout(args: std::fmt::Arguments) -> anyhow::Result<()> {
    use std::io::Write;
    let mut out = std::io::stdout().lock();
    let r = out
        .write_fmt(args)
        .and_then(|()| out.write_all(b"\n"))
        .and_then(|()| out.flush());
    r.map_err(|e| {
        if e.kind() == std::io::ErrorKind::BrokenPipe {
            Exit {
                code: EXIT_BROKEN_PIPE,
                message: String::new(),
            }
            .into()
        } else {
            anyhow::anyhow!("stdout: cannot write: {e}")
        }
    })
}

/// Writes `args` and a newline to stderr, ignoring errors.
pub fn write_stderr(args: std::fmt::Arguments) {
    use std::io::Write;
    let mut err = std::io::stderr().lock();
    let _ = err.write_fmt(args).and_then(|()| err.write_all(b"\n"));
}

/// Installs SIGINT, SIGTERM and SIGHUP handlers that store the signal number in the returned flag (0 while
/// none came); a second signal while the flag is set exits at once (code 128 + the signal). Commands check
/// the flag at their next tick, point or iteration, and commit what they have as a marked partial.
pub fn stop_flag() -> anyhow::Result<std::sync::Arc<std::sync::atomic::AtomicUsize>> {
    use anyhow::Context as _;
    use signal_hook::consts::{SIGHUP, SIGINT, SIGTERM};
    let flag = std::sync::Arc::new(std::sync::atomic::AtomicUsize::new(0));
    let armed = std::sync::Arc::new(std::sync::atomic::AtomicBool::new(false));
    for sig in [SIGINT, SIGTERM, SIGHUP] {
        // Order matters: the conditional shutdown sees the flag set by a previous signal only.
        signal_hook::flag::register_conditional_shutdown(sig, 128 + sig, armed.clone())
            .context("installing the signal handler")?;
        signal_hook::flag::register(sig, armed.clone()).context("installing the signal handler")?;
        signal_hook::flag::register_usize(sig, flag.clone(), sig as usize)
            .context("installing the signal handler")?;
    }
    Ok(flag)
}

/// The error that ends an interrupted command: exit code 128 + the signal, and what was kept where.
pub fn interrupted(signal: usize, what: String) -> anyhow::Error {
    Exit {
        code: 128 + signal.clamp(1, 64) as u8,
        message: format!("{}: {what}", pneuflex_scene::signal_name(signal.max(1))),
    }
    .into()
}

mod bag;
pub mod compare;
pub mod emulated;
pub mod excitation;
pub mod excite;
pub mod identify;
pub mod live;
pub mod mechanism;
pub mod new_rig;
pub mod perturb;
pub mod pil;
pub mod pil_mechanism;
pub mod progress;
mod recording;
pub mod rig;
pub mod rig_mechanism;
pub mod ros2;
pub mod run;
pub mod seal;
pub mod sweep;
mod tables;
pub mod tf;
pub mod tune;

/// An error that ends the process with a given exit code (128 + signal for an interrupted command).
#[derive(Debug)]
pub struct Exit {
    /// The process exit code.
    pub code: u8,
    /// What to print.
    pub message: String,
}

impl std::fmt::Display for Exit {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.message)
    }
}

impl std::error::Error for Exit {}

/// Ends a command whose outputs are committed with one error naming every run that diverged (its
/// summary.json marks them), so that a script sees a non-zero exit.
pub fn fail_on_divergence<'a>(
    runs: impl IntoIterator<Item = (&'a str, Option<&'a str>)>,
    dest: &std::path::Path,
) -> anyhow::Result<()> {
    let diverged: Vec<String> = runs
        .into_iter()
        .filter_map(|(name, why)| why.map(|why| format!("run `{name}` diverged: {why}")))
        .collect();
    if !diverged.is_empty() {
        anyhow::bail!(
            "{} (marked in {})",
            diverged.join("; "),
            dest.join("summary.json").display()
        );
    }
    Ok(())
}
