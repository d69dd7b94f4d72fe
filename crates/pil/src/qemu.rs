//! The emulated board: `qemu-system-arm -M mps2-an386` running the firmware ELF with UART0 on its stdio and
//! virtual time from the instruction count (`-icount shift=0`: one instruction per virtual nanosecond).

use std::path::{Path, PathBuf};
use std::process::{Child, ChildStdin, ChildStdout, Command, Stdio};

use crate::PilError;

/// How QEMU is installed where it is missing (Debian/Ubuntu; the CI image is Debian).
pub const INSTALL_HINT: &str = "install it with `sudo apt-get install qemu-system-arm` (Debian/Ubuntu), \
     `brew install qemu` (macOS) or your distribution's qemu-system-arm package, or point PNEUFLEX_QEMU at the binary";

/// The QEMU binary: `PNEUFLEX_QEMU` if set, else `qemu-system-arm` on the PATH.
pub fn qemu_binary() -> Result<PathBuf, PilError> {
    if let Some(p) = std::env::var_os("PNEUFLEX_QEMU") {
        let p = PathBuf::from(p);
        return if p.is_file() {
            Ok(p)
        } else {
            Err(PilError::NoQemu(format!(
                "PNEUFLEX_QEMU={} is not a file; {INSTALL_HINT}",
                p.display()
            )))
        };
    }
    let path = std::env::var_os("PATH").unwrap_or_default();
    std::env::split_paths(&path)
        .map(|d| d.join("qemu-system-arm"))
        .find(|p| p.is_file())
        .ok_or_else(|| {
            PilError::NoQemu(format!(
                "qemu-system-arm is not on the PATH; {INSTALL_HINT}"
            ))
        })
}

/// The firmware image shipped with the source tree, once built (`cargo build --release` in firmware/).
pub fn default_firmware(repo_root: &Path) -> PathBuf {
    repo_root.join("firmware/target/thumbv7em-none-eabihf/release/pneuflex-firmware")
}

/// A running emulated board; killed when dropped.
pub struct Board {
    child: Child,
}

impl Board {
    /// Boots `elf` on the emulated mps2-an386. Its UART0 is the returned pipes.
    pub fn start(elf: &Path) -> Result<(Board, ChildStdin, ChildStdout), PilError> {
        let meta = std::fs::metadata(elf).map_err(|e| {
            PilError::Firmware(format!(
                "{}: {e}; build it with `cargo build --release` in firmware/ (docs/firmware.md)",
                elf.display()
            ))
        })?;
        if !meta.is_file() {
            return Err(PilError::Firmware(format!("{}: not a file", elf.display())));
        }
        let qemu = qemu_binary()?;
        let mut child = Command::new(&qemu)
            .args(["-M", "mps2-an386", "-display", "none", "-monitor", "none"])
            .args(["-serial", "stdio"])
            // Virtual time from the instruction count, 1 ns each: the board clock, the per-update cost and
            // the watchdog's trip time are instruction counts, whatever this machine's speed. The firmware
            // never sleeps (it spins on RAM waiting for its interrupts), so `sleep` plays no part.
            .args(["-icount", "shift=0,align=off,sleep=off"])
            .arg("-kernel")
            .arg(elf)
            .stdin(Stdio::piped())
            .stdout(Stdio::piped())
            .stderr(Stdio::inherit())
            .spawn()
            .map_err(|e| PilError::NoQemu(format!("{}: {e}; {INSTALL_HINT}", qemu.display())))?;
        let (Some(stdin), Some(stdout)) = (child.stdin.take(), child.stdout.take()) else {
            let _ = child.kill();
            return Err(PilError::Link("QEMU's stdio pipes are missing".into()));
        };
        Ok((Board { child }, stdin, stdout))
    }

    /// Whether QEMU has exited, with its status.
    pub fn exited(&mut self) -> Option<std::process::ExitStatus> {
        self.child.try_wait().ok().flatten()
    }
}

impl Drop for Board {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}
