//! What `rig excite` runs, for one channel or several: its options and the checked excitation of one actuator
//! (pneuflex_identify::excite), its centre within that channel's position limits.

use std::path::Path;

use anyhow::{anyhow, bail};
use pneuflex_rig::rtloop::check_duration;

/// The options of `pneuflex rig excite`.
#[derive(Clone, Debug)]
pub struct ExciteArgs {
    /// `prbs`, `chirp` or `steps`.
    pub signal: String,
    /// Amplitude, command units.
    pub amplitude: f64,
    /// Length, s.
    pub duration_s: f64,
    /// Centring position, m.
    pub centre_m: f64,
    /// Centring gain, 1/m.
    pub centring_per_m: f64,
    /// Command bias.
    pub bias: f64,
    /// PRBS bit / step hold time, s.
    pub hold_s: f64,
    /// Seed.
    pub seed: u64,
    /// Instead of a port: the rig file's emulator in lockstep with a simulated clock (not real time, no
    /// pty), hiding this actuator sheet, sensor noise seeded with `seed` (for CI and worked examples).
    pub lockstep_truth: Option<std::path::PathBuf>,
    /// `--mcap`: the recording also as a rosbag2 folder `bag/` beside trace.csv (docs/ros2.md).
    pub mcap: bool,
    /// A scene of several actuators: every actuator excited at once, each its own signal (seed + its index),
    /// on the rig file's board of as many channels (rig_mechanism.rs).
    pub scene: Option<std::path::PathBuf>,
}

/// The experiment `a` describes with `seed` for its signal, checked (the centre within `limits`, the
/// position limits at `key` of `rig_file`).
pub fn excitation(
    a: &ExciteArgs,
    seed: u64,
    limits: [f64; 2],
    rig_file: &Path,
    key: &str,
) -> anyhow::Result<pneuflex_identify::excite::Excitation> {
    use pneuflex_identify::excite::{Excitation, Signal};
    // The length first: the other checks (the ramp is a quarter of it) follow from it.
    check_duration(a.duration_s).map_err(|e| anyhow!("--duration: {}", e.message))?;
    if !(a.hold_s.is_finite() && a.hold_s > 0.0) {
        bail!("--hold: must be > 0 s, got {}", a.hold_s);
    }
    if a.signal != "chirp" && a.hold_s > a.duration_s {
        bail!(
            "--hold {} s: longer than --duration {} s: the {} would hold one level for the whole run and excite nothing",
            a.hold_s,
            a.duration_s,
            a.signal
        );
    }
    if !(a.amplitude.is_finite() && a.amplitude > 0.0 && a.amplitude <= 1.0) {
        bail!(
            "--amplitude: must be in (0, 1] (a zero amplitude excites nothing), got {}",
            a.amplitude
        );
    }
    // Full command for 1 mm off centre: a stiffer centring only chatters the valve.
    if !(a.centring_per_m.is_finite() && (0.0..=1000.0).contains(&a.centring_per_m)) {
        bail!(
            "--centring: in [0, 1000] 1/m (1000: the full command 1 mm off the centre), got {}",
            a.centring_per_m
        );
    }
    // The centre must lie inside the supervisor's position limits, with room to move both ways.
    let room = 0.1 * (limits[1] - limits[0]);
    if !(a.centre_m.is_finite() && a.centre_m >= limits[0] + room && a.centre_m <= limits[1] - room)
    {
        bail!(
            "--centre {} m: outside the rig's position limits [{}, {}] m less 10 % at each end ({}: \
             {key}); give a centre in [{}, {}] m",
            a.centre_m,
            limits[0],
            limits[1],
            rig_file.display(),
            limits[0] + room,
            limits[1] - room
        );
    }
    let signal = match a.signal.as_str() {
        "prbs" => Signal::Prbs {
            bit_s: a.hold_s,
            seed,
        },
        "steps" => Signal::Steps {
            hold_s: a.hold_s,
            seed,
        },
        "chirp" => Signal::Chirp {
            f0_hz: 0.2,
            f1_hz: 10.0,
            duration_s: a.duration_s,
        },
        other => bail!("--signal: `{other}`: expected prbs, chirp or steps"),
    };
    let excitation = Excitation {
        signal,
        amplitude: a.amplitude,
        bias: a.bias,
        centre_m: a.centre_m,
        centring_per_m: a.centring_per_m,
        ramp_s: 1.0_f64.min(0.25 * a.duration_s),
    };
    excitation.validate().map_err(|e| anyhow!(e))?;
    Ok(excitation)
}
