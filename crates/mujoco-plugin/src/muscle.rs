//! `pneuflex.muscle`'s configuration and one MuJoCo step of one muscle, on state kept outside (MuJoCo's
//! plugin_state), with no MuJoCo types.
//!
//! The muscle is `pneuflex_muscle::MuscleForceElement`, the element the engine's mechanism steps (the
//! antagonist scene's muscles): over a step of h from the step-start length L (the actuator length: a
//! spatial tendon's length with gear 1) and rate L', it integrates its chamber and valve or regulator in
//! `chamber_substeps` RK4 substeps along L + L' tau and returns the mean tension; the actuator force is
//! minus that (a muscle pulls its anchors together: MuJoCo's tendon force is + along a lengthening
//! tendon). Braid friction (M7) is inside the tension. `compute` (before the step) and `advance` (after
//! it) both call [`Muscle::step`]; a [`Memo`] makes the second a lookup, as for the cylinder.
//!
//! Configuration keys (`<config key=... value=.../>`): `sheet` (a muscle sheet, pneumatics/*-muscle.toml,
//! docs/muscles.md), `chamber_substeps`, `initial_pressure_pa`, `initial_temperature_k`.

use std::ffi::CStr;
use std::path::PathBuf;

use pneuflex_muscle::{ChamberState, MuscleForceElement, MuscleSheet};

use crate::config::ConfigError;
use crate::cylinder::Refused;

/// The keys `pneuflex.muscle` declares to MuJoCo (its compiler rejects any other, naming it).
pub const KEYS: &[&CStr] = &[
    c"sheet",
    c"chamber_substeps",
    c"initial_pressure_pa",
    c"initial_temperature_k",
];

/// Numbers of plugin_state per muscle: p, T, the valve's state, the element's clock.
pub const STATE_LEN: usize = MuscleForceElement::STATE_LEN;

/// The state of one muscle in plugin_state.
pub type State = [f64; STATE_LEN];

/// Most chamber substeps per MuJoCo step (a 1 ms step in 1 us substeps), as the cylinder's.
const MAX_SUBSTEPS: u32 = 1000;

/// Initial muscle pressure, Pa absolute: the supply sheet's bounds, as the cylinder's chambers.
const PRESSURE_PA: (f64, f64) = (1e3, 10e6);

/// Initial gas temperature, K, as the cylinder's.
const TEMPERATURE_K: (f64, f64) = (200.0, 400.0);

fn err(key: &str, message: impl Into<String>) -> ConfigError {
    ConfigError {
        key: key.to_string(),
        message: message.into(),
    }
}

/// A muscle's parameters: the element at reset (its sheet's muscle, gas, supply, feed; the chamber
/// substeps; the initial gas), cloned for each step.
#[derive(Clone, Debug)]
pub struct Muscle {
    initial: MuscleForceElement,
}

/// The result of one step for its inputs: what `compute` worked out, for `advance` to commit.
#[derive(Clone, Debug)]
pub struct Memo {
    /// The inputs' bits: state, L, L', u, h.
    key: [u64; STATE_LEN + 4],
    /// The state after the step.
    pub next: State,
    /// The actuator force for the step (-tension), N.
    pub force: f64,
}

/// Reads the configuration through `get` (a key's value, `None` or "" when absent).
pub fn parse(get: impl Fn(&str) -> Option<String>) -> Result<Muscle, ConfigError> {
    let given = |k: &str| get(k).filter(|v| !v.trim().is_empty());
    let Some(sheet) = given("sheet") else {
        return Err(err(
            "sheet",
            "required: the path of a muscle sheet (pneumatics/*-muscle.toml, docs/muscles.md), absolute \
             or relative to the working directory",
        ));
    };
    let path = PathBuf::from(sheet.trim());
    let sheet = MuscleSheet::load(&path).map_err(|e| {
        if path.is_relative() && !path.exists() {
            // MuJoCo gives a plugin no model folder: say where a relative path was looked for.
            let cwd =
                std::env::current_dir().map_or_else(|_| "?".into(), |d| d.display().to_string());
            err(
                "sheet",
                format!(
                    "{e} (a relative sheet is read from the working directory, {cwd}, not the model's \
                     folder: give an absolute path)"
                ),
            )
        } else {
            err("sheet", e.to_string())
        }
    })?;
    let chamber_substeps = match given("chamber_substeps") {
        None => 1,
        Some(v) => match v.trim().parse::<u32>() {
            Ok(n) if (1..=MAX_SUBSTEPS).contains(&n) => n,
            _ => {
                return Err(err(
                    "chamber_substeps",
                    format!("expected a whole number in [1, {MAX_SUBSTEPS}], got '{v}'"),
                ));
            }
        },
    };
    let within = |key: &str, (lo, hi): (f64, f64), what: &str| match given(key) {
        None => Ok(None),
        Some(v) => match v.trim().parse::<f64>() {
            Ok(x) if (lo..=hi).contains(&x) => Ok(Some(x)),
            _ => Err(err(key, format!("expected {what}, got '{v}'"))),
        },
    };
    let s = &sheet.chamber.supply;
    // As the engine's mechanism starts a muscle: unpressurised, the gas at the atmosphere's temperature.
    let gas = ChamberState {
        pressure_pa: within(
            "initial_pressure_pa",
            PRESSURE_PA,
            "an absolute pressure in [1e3, 1e7] Pa (gauge + atmosphere)",
        )?
        .unwrap_or(s.atmosphere_pressure_pa),
        temperature_k: within(
            "initial_temperature_k",
            TEMPERATURE_K,
            "a temperature in [200, 400] K",
        )?
        .unwrap_or(s.atmosphere_temperature_k),
    };
    Ok(Muscle {
        initial: MuscleForceElement::new(sheet.chamber, sheet.plant_feed(), gas, chamber_substeps),
    })
}

impl Muscle {
    /// The state at reset: the configured gas, the valve at rest, the clock at 0.
    pub fn initial_state(&self) -> State {
        self.initial.state()
    }

    /// One step of `h` (s) from `state` at length `length_m` (m) and rate `rate` (m/s) under command `u`
    /// (clamped to [-1, 1]; NaN closes the valve): the state after it and the actuator force (-mean
    /// tension, N), reusing `memo` when it was made for these inputs.
    pub fn step(
        &self,
        state: &State,
        length_m: f64,
        rate: f64,
        u: f64,
        h: f64,
        memo: &mut Option<Memo>,
    ) -> Result<(State, f64), Refused> {
        let mut key = [0u64; STATE_LEN + 4];
        for (k, s) in key
            .iter_mut()
            .zip(state.iter().chain(&[length_m, rate, u, h]))
        {
            *k = s.to_bits();
        }
        if let Some(m) = memo.as_ref().filter(|m| m.key == key) {
            return Ok((m.next, m.force));
        }
        if !(length_m.is_finite() && rate.is_finite() && h.is_finite() && h > 0.0) {
            return Err(Refused::Input);
        }
        let mut el = self.initial.clone();
        if !el.set_state(state) {
            return Err(Refused::State);
        }
        el.set_command(u);
        let force = -el.step_length(length_m, rate, h);
        let next = el.state();
        *memo = Some(Memo { key, next, force });
        Ok((next, force))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sheet() -> String {
        format!(
            "{}/../../pneumatics/festo-dmsp-10-muscle.toml",
            env!("CARGO_MANIFEST_DIR")
        )
    }

    fn with<'a>(kv: &'a [(&'a str, &'a str)]) -> impl Fn(&str) -> Option<String> + 'a {
        move |k| kv.iter().find(|(a, _)| *a == k).map(|(_, v)| v.to_string())
    }

    /// The plugin's step is the engine's element stepped over the same length and rate, its force minus
    /// the tension; the memo returns the same numbers without stepping.
    #[test]
    fn a_step_is_the_engines_muscle_element_step() {
        let s = sheet();
        let muscle = parse(with(&[("sheet", &s), ("chamber_substeps", "2")])).unwrap();
        let m = MuscleSheet::load(&s).unwrap();
        let atm = m.chamber.supply.atmosphere_pressure_pa;
        let mut el = MuscleForceElement::new(
            m.chamber,
            m.plant_feed(),
            ChamberState {
                pressure_pa: atm,
                temperature_k: m.chamber.supply.atmosphere_temperature_k,
            },
            2,
        );
        let mut state = muscle.initial_state();
        assert_eq!(state, el.state());
        let h = 1e-4;
        let mut memo = None;
        let mut p_max: f64 = 0.0;
        for k in 0..20_000 {
            let t = k as f64 * h;
            let (l, rate, u) = (
                0.18 + 0.01 * (3.0 * t).sin(),
                0.03 * (3.0 * t).cos(),
                (2.0 * t).sin(),
            );
            let (next, force) = muscle.step(&state, l, rate, u, h, &mut memo).unwrap();
            el.set_command(u);
            let tension = el.step_length(l, rate, h);
            assert_eq!(force, -tension, "step {k}");
            assert_eq!(next, el.state(), "step {k}");
            let again = muscle.step(&state, l, rate, u, h, &mut memo).unwrap();
            assert_eq!(again, (next, force));
            state = next;
            p_max = p_max.max(state[0]);
        }
        // Filled (and vented again) through the run.
        assert!(p_max > atm + 1e5, "{p_max} Pa");
        assert!(state[0] < p_max - 1e5, "{} Pa", state[0]);
    }

    #[test]
    fn the_configuration_defaults_and_errors_name_their_key() {
        let s = sheet();
        let m = parse(with(&[("sheet", &s)])).unwrap();
        let s0 = m.initial_state();
        assert_eq!((s0[0], s0[1]), (101_325.0, 293.15));
        let m = parse(with(&[
            ("sheet", &s),
            ("initial_pressure_pa", "3e5"),
            ("initial_temperature_k", "300"),
        ]))
        .unwrap();
        assert_eq!(m.initial_state()[..2], [3e5, 300.0]);
        let bad = |kv: &[(&str, &str)]| parse(with(kv)).unwrap_err();
        assert_eq!(bad(&[]).key, "sheet");
        assert_eq!(
            bad(&[("sheet", &s), ("chamber_substeps", "0")]).key,
            "chamber_substeps"
        );
        assert_eq!(
            bad(&[("sheet", &s), ("initial_pressure_pa", "1e300")]).key,
            "initial_pressure_pa"
        );
        assert_eq!(
            bad(&[("sheet", &s), ("initial_temperature_k", "hot")]).key,
            "initial_temperature_k"
        );
        // A cylinder's sheet is not a muscle's: the sheet's own error, under `sheet`.
        let cyl = format!(
            "{}/../../pneumatics/paper-actuator.toml",
            env!("CARGO_MANIFEST_DIR")
        );
        let e = bad(&[("sheet", &cyl)]);
        assert_eq!(e.key, "sheet");
        assert!(e.message.contains("paper-actuator.toml"), "{e}");
        let e = bad(&[("sheet", "no/such-muscle.toml")]);
        assert!(e.message.contains("working directory"), "{e}");
    }

    #[test]
    fn impossible_state_and_inputs_are_refused() {
        let m = parse(with(&[("sheet", &sheet())])).unwrap();
        let mut s = m.initial_state();
        let mut memo = None;
        assert_eq!(
            m.step(&s, f64::NAN, 0.0, 0.0, 1e-3, &mut memo),
            Err(Refused::Input)
        );
        assert_eq!(
            m.step(&s, 0.18, 0.0, 0.0, 0.0, &mut memo),
            Err(Refused::Input)
        );
        s[0] = -5.0;
        assert_eq!(
            m.step(&s, 0.18, 0.0, 0.0, 1e-3, &mut memo),
            Err(Refused::State)
        );
        assert!(memo.is_none());
    }

    #[test]
    fn keys_are_unique_and_ascii() {
        for (i, k) in KEYS.iter().enumerate() {
            assert!(k.to_str().is_ok());
            assert!(!KEYS[..i].contains(k));
        }
    }
}
