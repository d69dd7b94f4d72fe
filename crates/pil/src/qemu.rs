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
            check_executable(&p).map(|()| p)
        } else {
            Err(PilError::NoQemu(format!(
                "PNEUFLEX_QEMU={} is not a file; {INSTALL_HINT}",
                p.display()
            )))
        };
    }
    let path = std::env::var_os("PATH").unwrap_or_default();
    let found = std::env::split_paths(&path)
        .map(|d| d.join("qemu-system-arm"))
        .find(|p| p.is_file())
        .ok_or_else(|| {
            PilError::NoQemu(format!(
                "qemu-system-arm is not on the PATH; {INSTALL_HINT}"
            ))
        })?;
    check_executable(&found)?;
    Ok(found)
}

/// Checks that the QEMU binary can be run: an executable file.
fn check_executable(p: &Path) -> Result<(), PilError> {
    #[cfg(unix)]
    {
        use std::os::unix::fs::PermissionsExt;
        let mode = std::fs::metadata(p)
            .map(|m| m.permissions().mode())
            .unwrap_or(0);
        if mode & 0o111 == 0 {
            return Err(PilError::NoQemu(format!(
                "{}: not executable; {INSTALL_HINT}",
                p.display()
            )));
        }
    }
    Ok(())
}

/// ELF `e_machine` of 32-bit ARM.
const EM_ARM: u16 = 40;
/// ELF `e_flags` bit of the hard-float ABI (thumbv7em-none-eabihf).
const EF_ARM_ABI_FLOAT_HARD: u32 = 0x400;

/// Checks, before QEMU starts, that `elf` is a firmware image for the board: a regular file, an ELF
/// executable, 32-bit little-endian ARM with the hard-float ABI (what `cargo build --release` in firmware/
/// makes for thumbv7em-none-eabihf). Each refusal names the file and what it is instead.
pub fn check_firmware(elf: &Path) -> Result<(), PilError> {
    use std::io::Read;
    let hint = "build it with `cargo build --release` in firmware/ (docs/firmware.md), or pass the ELF that build makes";
    let bad = |what: String| PilError::Firmware(format!("{}: {what}; {hint}", elf.display()));
    let meta = std::fs::metadata(elf).map_err(|e| bad(format!("cannot read it: {e}")))?;
    if !meta.is_file() {
        return Err(bad("not a regular file".into()));
    }
    let mut head = [0u8; 52];
    let n = std::fs::File::open(elf)
        .and_then(|f| f.take(52).read(&mut head))
        .map_err(|e| bad(format!("cannot read it: {e}")))?;
    if n < 52 || &head[..4] != b"\x7fELF" {
        return Err(bad("not an ELF file".into()));
    }
    // e_type and e_machine sit at the same offsets in 32- and 64-bit ELF files.
    let u16_at = |i: usize| {
        if head[5] == 2 {
            u16::from_be_bytes([head[i], head[i + 1]])
        } else {
            u16::from_le_bytes([head[i], head[i + 1]])
        }
    };
    let (e_type, e_machine) = (u16_at(16), u16_at(18));
    if e_machine != EM_ARM {
        let name = match e_machine {
            3 => " (x86)",
            62 => " (x86-64)",
            183 => " (AArch64)",
            243 => " (RISC-V)",
            _ => "",
        };
        return Err(bad(format!(
            "an ELF for machine {e_machine}{name}, not ARM ({EM_ARM}): built for another target"
        )));
    }
    if head[4] != 1 || head[5] != 1 {
        return Err(bad(format!(
            "a {}-bit {} ARM ELF; the board runs 32-bit little-endian ARM",
            if head[4] == 2 { 64 } else { 32 },
            if head[5] == 2 {
                "big-endian"
            } else {
                "little-endian"
            }
        )));
    }
    let e_flags = u32::from_le_bytes([head[36], head[37], head[38], head[39]]);
    if e_type != 2 {
        return Err(bad(format!(
            "an ELF of type {e_type}, not an executable (2): an object or a library, not a firmware image"
        )));
    }
    if e_flags & EF_ARM_ABI_FLOAT_HARD == 0 {
        return Err(bad(format!(
            "an ARM ELF without the hard-float ABI (e_flags {e_flags:#x}); the board's firmware is built for \
             thumbv7em-none-eabihf"
        )));
    }
    Ok(())
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
        check_firmware(elf)?;
        let qemu = qemu_binary()?;
        let mut cmd = Command::new(&qemu);
        // Its own process group: a Ctrl-C at the terminal reaches pneuflex, which stops the run and then
        // ends the board (Drop), instead of killing QEMU under a run in progress.
        #[cfg(unix)]
        std::os::unix::process::CommandExt::process_group(&mut cmd, 0);
        let mut child = cmd
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
