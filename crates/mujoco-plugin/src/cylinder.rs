//! One MuJoCo step of one cylinder, on state kept outside (MuJoCo's plugin_state), with no MuJoCo types.
//!
//! The coupling is the one crossval/couple.py makes from Python, so that the two agree: over a step of h
//! from the step-start extension x and velocity v, the force element integrates valve and chambers and
//! returns the mean piston force, and the actuator force for the step is that minus the sheet's Coulomb
//! friction at v. MuJoCo calls `compute` (which needs the force) before the step and `advance` (which
//! moves the state on) after it; both call [`Cylinder::step`], and a [`Memo`] makes the second a lookup.
//! Under `command="pressure"` the element runs behind a pressure regulator in front of each chamber and the
//! two controls are the chambers' set-points (`pneuflex_pneumatics::regulator`); the state is the same.

use pneuflex_pneumatics::{Actuator, ChamberState, Friction, PneumaticForceElement};

use crate::config::{Command, Config};

/// Numbers of plugin_state per cylinder.
pub const STATE_LEN: usize = PneumaticForceElement::STATE_LEN;

/// The state of one cylinder in plugin_state.
pub type State = [f64; STATE_LEN];

/// A cylinder's parameters.
#[derive(Clone, Debug)]
pub struct Cylinder {
    actuator: Actuator,
    friction: Friction,
    substeps: u32,
    initial: ChamberState,
    command: Command,
}

/// The result of one step for its inputs: what `compute` worked out, for `advance` to commit.
#[derive(Clone, Debug)]
pub struct Memo {
    /// The inputs' bits: state, x, v, the two controls, h.
    key: [u64; STATE_LEN + 5],
    /// The state after the step.
    pub next: State,
    /// The actuator force for the step, N.
    pub force: f64,
}

/// A step that could not be taken: the state is not one the element can be in (corrupted, or set by the
/// host to numbers the plugin never writes), or an input is not finite.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Refused {
    /// plugin_state holds impossible numbers.
    State,
    /// Length, velocity or timestep not finite (or the timestep not positive).
    Input,
}

impl Cylinder {
    /// The cylinder a configuration describes.
    pub fn new(c: &Config) -> Self {
        Self {
            actuator: c.actuator,
            friction: c.friction,
            substeps: c.chamber_substeps,
            initial: c.initial,
            command: c.command,
        }
    }

    /// The state at reset: the configured chambers, the valve at rest, the clock at 0.
    pub fn initial_state(&self) -> State {
        PneumaticForceElement::new(self.actuator, self.initial, self.substeps).state()
    }

    /// One step of `h` (s) from `state` at extension `x` (m) and velocity `v` (m/s) under the controls
    /// `ctrl`: the valve command `ctrl[0]` (clamped to [-1, 1]; NaN closes the valve; `ctrl[1]` unused), or
    /// under `command="pressure"` the set-points of chambers A and B, Pa absolute (clamped to [atmosphere,
    /// supply]; NaN closes the chamber); reusing `memo` when it was made for these inputs.
    pub fn step(
        &self,
        state: &State,
        x: f64,
        v: f64,
        ctrl: [f64; 2],
        h: f64,
        memo: &mut Option<Memo>,
    ) -> Result<(State, f64), Refused> {
        let mut key = [0u64; STATE_LEN + 5];
        for (k, s) in key
            .iter_mut()
            .zip(state.iter().chain(&[x, v, ctrl[0], ctrl[1], h]))
        {
            *k = s.to_bits();
        }
        if let Some(m) = memo.as_ref().filter(|m| m.key == key) {
            return Ok((m.next, m.force));
        }
        if !(x.is_finite() && v.is_finite() && h.is_finite() && h > 0.0) {
            return Err(Refused::Input);
        }
        let mut el = PneumaticForceElement::new(self.actuator, self.initial, self.substeps);
        if !el.set_state(state) {
            return Err(Refused::State);
        }
        match self.command {
            Command::Valve => el.set_command(ctrl[0]),
            Command::Pressure(regulator) => {
                el.set_regulator(Some(regulator));
                el.set_pressure_command(ctrl[0], ctrl[1]);
            }
        }
        let f = el.step(x, v, h);
        // As crossval: the drive argument matters only to stick-slip friction, which the plugin refuses.
        let force = f - self.friction.force(v, f);
        let next = el.state();
        *memo = Some(Memo { key, next, force });
        Ok((next, force))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::config;

    fn cylinder(extra: &[(&str, &str)]) -> Cylinder {
        let sheet = format!(
            "{}/../../pneumatics/paper-actuator.toml",
            env!("CARGO_MANIFEST_DIR")
        );
        let mut kv = vec![("sheet".to_string(), sheet)];
        kv.extend(extra.iter().map(|(k, v)| (k.to_string(), v.to_string())));
        let c = config::parse(|k| kv.iter().find(|(a, _)| a == k).map(|(_, v)| v.clone())).unwrap();
        Cylinder::new(&c)
    }

    /// The plugin's step is the force element's step (the same calls crossval makes through the
    /// bindings) minus the sheet's friction, and the memo returns the same numbers without stepping.
    #[test]
    fn a_step_is_the_force_element_step_minus_friction() {
        let cyl = cylinder(&[("chamber_substeps", "3")]);
        let sheet = pneuflex_pneumatics::ActuatorSheet::load(format!(
            "{}/../../pneumatics/paper-actuator.toml",
            env!("CARGO_MANIFEST_DIR")
        ))
        .unwrap();
        let mut el = PneumaticForceElement::new(sheet.actuator(), cyl.initial, 3);
        let mut state = cyl.initial_state();
        assert_eq!(state, el.state());
        let h = 25e-6;
        let mut memo = None;
        for k in 0..4000 {
            let t = k as f64 * h;
            let (x, v, u) = (
                0.02 + 0.005 * (9.0 * t).sin(),
                0.045 * (9.0 * t).cos(),
                (3.0 * t).sin(),
            );
            let (next, force) = cyl.step(&state, x, v, [u, 0.0], h, &mut memo).unwrap();
            el.set_command(u);
            let f = el.step(x, v, h);
            assert_eq!(force, f - sheet.mechanics.friction.force(v, f), "step {k}");
            assert_eq!(next, el.state(), "step {k}");
            // The same inputs again: the memo's answer, bit for bit; then the step is committed.
            let again = cyl.step(&state, x, v, [u, 0.0], h, &mut memo).unwrap();
            assert_eq!(again, (next, force));
            state = next;
        }
        // Both chambers moved through the run (the valve was driven both ways).
        let (p_a, p_b) = (state[0], state[1]);
        assert!(p_a != cyl.initial.p_a && p_b != cyl.initial.p_b);
    }

    #[test]
    fn a_changed_input_is_not_answered_from_the_memo() {
        let cyl = cylinder(&[]);
        let state = cyl.initial_state();
        let mut memo = None;
        let a = cyl
            .step(&state, 0.02, 0.0, [0.5, 0.0], 1e-3, &mut memo)
            .unwrap();
        let b = cyl
            .step(&state, 0.02, 0.0, [-0.5, 0.0], 1e-3, &mut memo)
            .unwrap();
        assert_ne!(a.0, b.0, "another command must give another state");
        let c = cyl
            .step(&state, 0.02, 0.0, [0.5, 0.0], 1e-3, &mut memo)
            .unwrap();
        assert_eq!(a, c);
    }

    /// Under `command="pressure"` the step is the force element behind the regulators at the two set-points
    /// (minus the sheet's friction), the valve left at rest; held, the chambers reach the set-points.
    #[test]
    fn a_pressure_step_is_the_regulated_force_element_step() {
        let cyl = cylinder(&[("command", "pressure"), ("chamber_substeps", "2")]);
        let Command::Pressure(reg) = cyl.command else {
            panic!("pressure command expected")
        };
        let mut el = PneumaticForceElement::new(cyl.actuator, cyl.initial, 2);
        el.set_regulator(Some(reg));
        let mut state = cyl.initial_state();
        let mut memo = None;
        let (set, h) = ([3.2e5, 2.1e5], 1e-4);
        for k in 0..2000 {
            let x = 0.02 + 1e-3 * (k as f64 * 1e-3).sin();
            let (next, force) = cyl.step(&state, x, 0.01, set, h, &mut memo).unwrap();
            el.set_pressure_command(set[0], set[1]);
            let f = el.step(x, 0.01, h);
            assert_eq!(force, f - cyl.friction.force(0.01, f), "step {k}");
            assert_eq!(next, el.state(), "step {k}");
            state = next;
        }
        assert!(
            (state[0] - set[0]).abs() < 1.0 && (state[1] - set[1]).abs() < 1.0,
            "{state:?}"
        );
        assert_eq!(state[4], 0.0, "the spool stays at rest");
    }

    #[test]
    fn impossible_state_and_inputs_are_refused() {
        let cyl = cylinder(&[]);
        let mut s = cyl.initial_state();
        let mut memo = None;
        assert_eq!(
            cyl.step(&s, f64::NAN, 0.0, [0.0; 2], 1e-3, &mut memo),
            Err(Refused::Input)
        );
        assert_eq!(
            cyl.step(&s, 0.0, 0.0, [0.0; 2], 0.0, &mut memo),
            Err(Refused::Input)
        );
        s[0] = -5.0;
        assert_eq!(
            cyl.step(&s, 0.0, 0.0, [0.0; 2], 1e-3, &mut memo),
            Err(Refused::State)
        );
        assert!(memo.is_none());
    }
}
