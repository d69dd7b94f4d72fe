//! What the rig's tests and benches share: the shipped emulated rig and the paper's controller for it.

#![allow(dead_code)]

use std::io;
use std::path::{Path, PathBuf};

use pneuflex_control::{ImpedanceController, ImpedanceParams, PidParams};
use pneuflex_rig::trace::TraceSink;

/// rigs/emulated.toml.
pub fn rig_path() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../rigs/emulated.toml")
}

/// The controller of scenes/paper-fig3.toml (impedance filter + PID tuned for the 40 Hz PWM valve).
pub fn paper_controller() -> ImpedanceController {
    ImpedanceController::new(
        ImpedanceParams::default(),
        PidParams {
            kp_per_m: 10.0,
            ki_per_m_s: 20.0,
            kd_s_per_m: 0.0,
            ..PidParams::default()
        },
    )
    .unwrap()
}

/// A disk that fills up after `room` bytes: the write that crosses it is short, the next one fails.
#[derive(Default)]
pub struct FullDisk {
    pub data: Vec<u8>,
    pub room: usize,
}

impl io::Write for FullDisk {
    fn write(&mut self, b: &[u8]) -> io::Result<usize> {
        let n = b.len().min(self.room - self.data.len());
        if n == 0 && !b.is_empty() {
            return Err(io::Error::new(
                io::ErrorKind::StorageFull,
                "No space left on device",
            ));
        }
        self.data.extend_from_slice(&b[..n]);
        Ok(n)
    }
    fn flush(&mut self) -> io::Result<()> {
        Ok(())
    }
}

impl TraceSink for FullDisk {
    fn truncate_to(&mut self, len: u64) -> io::Result<()> {
        self.data.truncate(len as usize);
        Ok(())
    }
}
