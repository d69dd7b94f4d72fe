//! `rig emulate --truth`: the emulated plant runs a hidden sheet (perturbed 20-40 % by seed), with sensor
//! noise from the seed and an optional transport delay.
mod common;

use common::{rms_of, shipped};
use pneuflex_identify::excite::{Excitation, Signal};
use pneuflex_identify::log::read_log;
use pneuflex_identify::params::{Key, Offsets};
use pneuflex_identify::perturb::perturb;
use pneuflex_identify::replay::{Prepared, ReplayOptions};
use pneuflex_pneumatics::ActuatorSheet;

const KEYS: [Key; 5] = [
    Key::SonicConductance,
    Key::CriticalRatio,
    Key::DeadVolumeA,
    Key::DeadVolumeB,
    Key::Coulomb,
];

fn steps() -> Excitation {
    Excitation {
        signal: Signal::Steps {
            hold_s: 0.15,
            seed: 5,
        },
        amplitude: 0.25,
        bias: 0.0,
        centre_m: 0.02,
        centring_per_m: 10.0,
        ramp_s: 1.0,
    }
}

/// Each perturbed key moves by 20-40 %, the others not at all; the same seed gives the same truth, another
/// seed another; the written sheet loads (same schema).
#[test]
fn perturbation_is_seeded_and_within_20_to_40_percent() {
    let dir = common::scratch("perturb");
    let dir = dir.path().to_path_buf();
    let (a, da) = perturb(&shipped(), &KEYS, 11, &dir.join("a")).unwrap();
    let (_, db) = perturb(&shipped(), &KEYS, 11, &dir.join("b")).unwrap();
    let (_, dc) = perturb(&shipped(), &KEYS, 12, &dir.join("c")).unwrap();
    assert_eq!(da, db);
    assert_ne!(da, dc);
    let truth = ActuatorSheet::load(&a).unwrap().model();
    let base = ActuatorSheet::load(shipped()).unwrap().model();
    let off = Offsets::default();
    for c in &da {
        let rel = (c.truth / c.shipped - 1.0).abs();
        assert!((0.2..=0.4).contains(&rel), "{}: {rel}", c.key.name());
        assert_eq!(c.key.get(&truth, &off), c.truth);
    }
    for k in [Key::MovingMass, Key::Viscous, Key::SwitchingDelay] {
        assert_eq!(k.get(&truth, &off), k.get(&base, &off), "{}", k.name());
    }
}

/// The polytropic exponent is perturbed towards isothermal (its distance from 1 down by 20-40 %), never out
/// of the sheet's range [1, 1.67]: for every seed the 1.4 of the shipped sheet becomes 1.24-1.32 in a sheet
/// that loads, and the written sheet carries it.
#[test]
fn the_polytropic_exponent_is_perturbed_towards_isothermal() {
    let dir = common::scratch("perturb-n");
    for seed in 0..12 {
        let out = dir.path().join(format!("s{seed}"));
        let (sheet, changes) = perturb(&shipped(), &[Key::PolytropicExponent], seed, &out).unwrap();
        let n = changes[0].truth;
        assert!((1.24..=1.32).contains(&n), "seed {seed}: n = {n}");
        let m = ActuatorSheet::load(&sheet).unwrap().model();
        assert_eq!(m.actuator.gas.polytropic_exponent, n);
    }
}

/// The log of an emulator hiding a truth is the truth's, not the shipped sheet's: replayed through the
/// truth it matches to near the sensor resolution, through the shipped sheet it does not.
#[test]
fn emulator_runs_the_hidden_truth() {
    let dir = common::scratch("truth");
    let dir = dir.path().to_path_buf();
    let (truth, _) = perturb(&shipped(), &KEYS, 21, &dir.join("truth")).unwrap();
    let trace = dir.join("trace.csv");
    common::record(&truth, 3, steps(), 2.0, None, &trace);
    let log = read_log(&trace).unwrap();
    let n = log.len();
    let p = Prepared::new(log, &ReplayOptions::default(), n - 1);
    let with_truth = rms_of(&p, &ActuatorSheet::load(&truth).unwrap().model());
    let with_shipped = rms_of(&p, &ActuatorSheet::load(shipped()).unwrap().model());
    eprintln!("pressure / position RMS: truth {with_truth:?}, shipped {with_shipped:?}");
    // 12-bit pressure channels resolve 270 / 540 Pa: the truth replays within a few counts.
    assert!(with_truth[0] < 2000.0, "{with_truth:?}");
    assert!(
        with_shipped[0] > 3.0 * with_truth[0],
        "{with_shipped:?} vs {with_truth:?}"
    );
}

/// A transport delay of 5 sample periods: the chambers leave atmosphere 5 rows later (30 ms of steps with
/// no centring: the piston is still far from the stops).
#[test]
fn transport_delay_shifts_the_response() {
    let dir = common::scratch("delay");
    let dir = dir.path().to_path_buf();
    let ex = Excitation {
        centring_per_m: 0.0,
        ..steps()
    };
    let first_move = |delay: Option<f64>, name: &str| {
        let trace = dir.join(name);
        common::record_delayed(&shipped(), 3, ex, 0.03, None, delay, &trace);
        let log = read_log(&trace).unwrap();
        let p0 = log.p_b[0].max(log.p_a[0]);
        (0..log.len())
            .find(|&k| log.p_a[k].max(log.p_b[k]) > p0 + 5e3)
            .expect("the chambers fill")
    };
    let k0 = first_move(None, "0.csv");
    let k5 = first_move(Some(0.005), "5.csv");
    assert_eq!(
        k5,
        k0 + 5,
        "first pressure rise at row {k0} without, {k5} with the delay"
    );
}
