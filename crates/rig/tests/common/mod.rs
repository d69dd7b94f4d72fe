//! What the rig's tests and benches share: the shipped emulated rig and the paper's controller for it.

#![allow(dead_code)]

use std::path::{Path, PathBuf};

use pneuflex_control::{ImpedanceController, ImpedanceParams, PidParams};

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
