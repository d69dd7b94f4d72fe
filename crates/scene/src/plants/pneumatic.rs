//! The 1-DOF pneumatic plant: the actuator model of `pneuflex-pneumatics` (chambers, valve, eq. (1)
//! mechanics, fixed-step RK4) pushing a linear-spring environment, f_e = k_e (x - x_e), contact lost
//! when x <= x_e. The flange feels f_ext = -f_e.

use pneuflex_control::{Sensors, Telemetry, ValveCommand};
use pneuflex_pneumatics::{ChamberState, OneDofModel, OneDofState, PressureRegulator};

use crate::error::SceneError;
use crate::plants::{ActuatorGeometry, LinearSpring, Plant};
use crate::plants::{EventSpec, PlantSite, PlantSpec};

/// The pneumatic actuator against a linear spring, integrated with `substeps` RK4 steps per control period.
#[derive(Clone, Debug, PartialEq)]
pub struct OneDofPneumatic {
    model: OneDofModel,
    alpha0_rad: f64,
    initial: OneDofState,
    state: OneDofState,
    env0: LinearSpring,
    env: LinearSpring,
    u: f64,
    substeps: u32,
    /// G_alpha = m g sin(alpha) of eq. (1), N: computed when the incline changes, not at every tick.
    gravity_n: f64,
    /// A pressure regulator in front of each chamber in place of the valve ([`Plant::set_regulators`]).
    regulator: Option<PressureRegulator>,
    /// The regulators' set-points (p_a, p_b), Pa absolute.
    set_pa: (f64, f64),
}

impl OneDofPneumatic {
    /// A plant from a model, at rest at `x0_m` against `env`.
    ///
    /// Initial chambers: chamber B at the mean of supply and atmosphere (where a valve chattering around
    /// its centre leaves it) and chamber A at the static balance of eq. (1) with the contact force at x0.
    pub fn new(model: OneDofModel, x0_m: f64, env: LinearSpring, substeps: u32) -> Self {
        let s = &model.actuator.supply;
        let p_b = 0.5 * (s.supply_pressure_pa + s.atmosphere_pressure_pa);
        let p_a = model.static_balance(p_b, -env.force(x0_m));
        let initial = OneDofState::at_rest(x0_m, ChamberState::new(p_a, p_b), 0.0);
        let gravity_n = model.mechanics.gravity_force();
        Self {
            alpha0_rad: model.mechanics.alpha_rad,
            model,
            initial,
            state: initial,
            env0: env,
            env,
            u: 0.0,
            substeps: substeps.max(1),
            gravity_n,
            regulator: None,
            set_pa: (p_a, p_b),
        }
    }

    /// The plant a pneumatic scene describes (actuator sheet resolved against the scene's directory).
    pub fn from_spec(
        spec: &PlantSpec,
        site: &PlantSite<'_>,
        env: LinearSpring,
    ) -> Result<Self, SceneError> {
        let origin = site.origin;
        let PlantSpec::Pneumatic {
            actuator,
            substeps,
            alpha_deg,
            x0_m,
        } = spec
        else {
            return Err(origin.plant_error("not a pneumatic plant".into()));
        };
        let path = origin.resolve(actuator);
        let sheet = origin
            .load_sheet(&path)
            .map_err(|e| origin.invalid("plant.actuator", e.to_string()))?;
        let mut model = sheet.model();
        if let Some(a) = alpha_deg {
            model.mechanics.alpha_rad = a.to_radians();
        }
        let stroke = model.actuator.cylinder.stroke_m;
        // Default start: touching the environment surface.
        let x0 = x0_m.unwrap_or(env.x_e_m);
        if !(0.0..=stroke).contains(&x0) {
            return Err(origin.invalid(
                if x0_m.is_some() {
                    "plant.x0_m"
                } else {
                    "environment.x_e_m"
                },
                format!(
                    "initial position {x0} m is outside the stroke [0, {stroke}] m of {}",
                    path.display()
                ),
            ));
        }
        Ok(Self::new(model, x0, env, *substeps))
    }

    /// The actuator model (pneumatics and eq. (1) mechanics).
    pub fn model(&self) -> &OneDofModel {
        &self.model
    }

    /// The full model state.
    pub fn state(&self) -> &OneDofState {
        &self.state
    }

    /// The current environment.
    pub fn environment(&self) -> LinearSpring {
        self.env
    }

    /// RK4 steps per control period.
    pub fn substeps(&self) -> u32 {
        self.substeps
    }

    /// [`Plant::advance`] of [`pneuflex_pneumatics::PACK`] plants by `dt`, bit for bit the calls one by one,
    /// with each RK4 stage taken for every plant at once ([`pneuflex_pneumatics::advance_together`]: packed
    /// arithmetic). A batch of environments steps its plants so. Plants behind pressure regulators, or with
    /// different substeps, are advanced one by one.
    pub fn advance_together(plants: [&mut Self; pneuflex_pneumatics::PACK], dt: f64) {
        let substeps = plants[0].substeps;
        if plants
            .iter()
            .any(|p| p.regulator.is_some() || p.substeps != substeps)
        {
            for p in plants {
                p.advance(dt);
            }
            return;
        }
        let parts = plants.map(|p| {
            let Self {
                model,
                state,
                u,
                gravity_n,
                env,
                ..
            } = p;
            (&*model, state, *u, *gravity_n, *env)
        });
        let models = parts.each_ref().map(|p| p.0);
        let u = parts.each_ref().map(|p| p.2);
        let gravity_n = parts.each_ref().map(|p| p.3);
        let envs = parts.each_ref().map(|p| p.4);
        let plants = pneuflex_pneumatics::Together {
            models,
            states: parts.map(|p| p.1),
            u,
            gravity_n,
        };
        // The contact force held over each substep, as `advance` holds it.
        pneuflex_pneumatics::advance_together(plants, dt, substeps, &mut |i, x| -envs[i].force(x));
    }
}

impl crate::plants::Linearisable for OneDofPneumatic {
    fn boxed_clone(&self) -> Box<dyn crate::plants::Linearisable> {
        Box::new(self.clone())
    }
    fn has_valve_and_friction(&self) -> bool {
        true
    }
    fn state_vector(&self) -> Vec<f64> {
        let s = &self.state;
        let c = &s.chambers;
        vec![s.x, s.x_dot, c.p_a, c.p_b, c.t_a, c.t_b, s.valve.spool]
    }
    fn set_state_vector(&mut self, v: &[f64]) {
        let s = &mut self.state;
        (s.x, s.x_dot) = (v[0], v[1]);
        (
            s.chambers.p_a,
            s.chambers.p_b,
            s.chambers.t_a,
            s.chambers.t_b,
        ) = (v[2], v[3], v[4], v[5]);
        s.valve.spool = v[6];
    }
    fn perturbation_scales(&self) -> Vec<f64> {
        // m, m/s, Pa, Pa, K, K, 1: small against each state's range, large against rounding.
        vec![1e-7, 1e-6, 1.0, 1.0, 1e-3, 1e-3, 1e-6]
    }
    fn coulomb_n(&self) -> f64 {
        self.model.mechanics.friction.coulomb_n()
    }
    fn add_viscous(&mut self, c: f64) {
        self.model.mechanics.viscous_n_s_per_m += c;
    }
    fn without_coulomb_friction(&mut self) {
        use pneuflex_pneumatics::Friction;
        self.model.mechanics.friction = match self.model.mechanics.friction {
            Friction::Smooth {
                smooth_velocity_m_per_s,
                ..
            } => Friction::Smooth {
                coulomb_n: 0.0,
                smooth_velocity_m_per_s,
            },
            Friction::StickSlip {
                stribeck_velocity_m_per_s,
                stick_velocity_m_per_s,
                ..
            } => Friction::StickSlip {
                coulomb_n: 0.0,
                static_n: 0.0,
                stribeck_velocity_m_per_s,
                stick_velocity_m_per_s,
            },
            // LuGre without Coulomb friction has no bristle force left: no friction at all.
            Friction::LuGre {
                stribeck_velocity_m_per_s,
                ..
            } => Friction::Smooth {
                coulomb_n: 0.0,
                smooth_velocity_m_per_s: stribeck_velocity_m_per_s,
            },
        };
        // The seal's pressure term is Coulomb friction too.
        self.model.effects.coulomb_pressure_n_per_pa = None;
    }
    fn average_switching(&mut self) {
        let v = &mut self.model.actuator.valve;
        if let pneuflex_pneumatics::ValveKind::OnOffPwm {
            pwm_frequency_hz,
            switching_delay_s,
        } = v.kind
        {
            v.kind = pneuflex_pneumatics::ValveKind::Proportional {
                response_time_s: switching_delay_s + 0.5 / pwm_frequency_hz,
            };
            v.underlap = 1.0;
        }
    }
    fn hold_switching(&mut self) -> Option<(f64, f64)> {
        let v = &mut self.model.actuator.valve;
        let pneuflex_pneumatics::ValveKind::OnOffPwm {
            pwm_frequency_hz,
            switching_delay_s,
        } = v.kind
        else {
            return None;
        };
        v.kind = pneuflex_pneumatics::ValveKind::Proportional {
            response_time_s: 0.0,
        };
        v.underlap = 1.0;
        Some((1.0 / pwm_frequency_hz, switching_delay_s))
    }
    fn switching(&self) -> bool {
        matches!(
            self.model.actuator.valve.kind,
            pneuflex_pneumatics::ValveKind::OnOffPwm { .. }
        )
    }
}

impl Plant for OneDofPneumatic {
    fn signals(&self) -> &'static [pneuflex_control::Signal] {
        &crate::plants::VALVE_SIGNALS
    }

    fn record(&self, out: &mut [f64]) {
        out[0] = self.state.valve.spool;
    }

    fn sense(&self) -> Sensors {
        let s = &self.state;
        Sensors {
            t: 0.0,
            x: s.x,
            x_dot: s.x_dot,
            f_e: self.env.force(s.x),
            p_a: s.chambers.p_a,
            p_b: s.chambers.p_b,
        }
    }

    fn actuate(&mut self, command: ValveCommand, _telemetry: &Telemetry) {
        self.u = command.u;
    }

    fn set_regulators(
        &mut self,
        _i: usize,
        regulator: Option<PressureRegulator>,
    ) -> Result<(f64, f64), crate::plants::PlantError> {
        if regulator.is_some() && !self.model.is_paper_model() {
            return Err(crate::plants::PlantError::unsupported(
                "the pressure regulators replace the valve of the paper's model only: this actuator's sheet \
                 gives effects beyond it (leaks, lines, spool dynamics, wall heat, seal or LuGre friction)",
            ));
        }
        self.regulator = regulator;
        self.set_pa = (self.state.chambers.p_a, self.state.chambers.p_b);
        let s = &self.model.actuator.supply;
        Ok((s.atmosphere_pressure_pa, s.supply_pressure_pa))
    }

    fn actuate_pressures(&mut self, _i: usize, p_a_pa: f64, p_b_pa: f64) {
        self.set_pa = (p_a_pa, p_b_pa);
    }

    fn advance(&mut self, dt: f64) {
        let (gravity_n, env) = (self.gravity_n, self.env);
        if let Some(reg) = &self.regulator {
            self.model.advance_regulated(
                &mut self.state,
                reg,
                self.set_pa,
                gravity_n,
                dt,
                self.substeps,
                |x| -env.force(x),
            );
            return;
        }
        // The contact force is held over a substep: the spring's own time scale (≥ 20 ms at 1400 N/m on
        // 0.6 kg) is far longer than a substep.
        self.model
            .advance(&mut self.state, self.u, gravity_n, dt, self.substeps, |x| {
                -env.force(x)
            });
    }

    fn apply(&mut self, event: &EventSpec) -> Result<(), crate::plants::PlantError> {
        match *event {
            EventSpec::Stiffness {
                stiffness_n_per_m, ..
            } => {
                self.env.stiffness_n_per_m = stiffness_n_per_m;
                Ok(())
            }
            EventSpec::SwapEnvironment { .. } => Err(crate::plants::PlantError::unsupported(
                "swap_environment needs the multibody plant: the 1-DOF pneumatic plant has one linear-spring environment and no carriage",
            )),
            EventSpec::Alpha { alpha_deg, .. } => {
                // eq. (1): G_alpha = m g sin(alpha) from the next step on.
                self.model.mechanics.alpha_rad = alpha_deg.to_radians();
                self.gravity_n = self.model.mechanics.gravity_force();
                Ok(())
            }
        }
    }

    fn check_invariants(&self) -> Result<(), crate::plants::PlantError> {
        let a = &self.model.actuator;
        let stroke = a.cylinder.stroke_m;
        crate::plants::chamber_invariants(&self.state.chambers, &a.supply, self.state.x, stroke)?;
        // Energy has one source, the supply: the flange's kinetic energy plus the spring's can never exceed
        // the spring charged across the whole stroke plus the largest piston and gravity force working
        // over it (twice that, for margin). Beyond, the integrator is creating energy.
        let m = &self.model.mechanics;
        let f_max = a.supply.supply_pressure_pa * a.cylinder.area_a() + m.gravity_force().abs();
        let k = self.env.stiffness_n_per_m.max(self.env0.stiffness_n_per_m);
        let e_max = 2.0 * (0.5 * k * stroke * stroke + f_max * stroke);
        let d = (self.state.x - self.env.x_e_m).max(0.0);
        let e = 0.5 * m.moving_mass_kg * self.state.x_dot.powi(2)
            + 0.5 * self.env.stiffness_n_per_m * d * d;
        if e > e_max {
            return Err(crate::plants::PlantError::invariant(format!(
                "mechanical energy {e:.3e} J (flange and environment spring) above the {e_max:.3e} J the supply \
                 can have put in over the stroke: energy grows without a source"
            )));
        }
        Ok(())
    }

    fn actuator_geometry(&self) -> Option<ActuatorGeometry> {
        let c = &self.model.actuator.cylinder;
        Some(ActuatorGeometry {
            stroke_m: c.stroke_m,
            bore_m: c.bore_m,
            alpha_rad: self.alpha0_rad,
            x_e_m: self.env0.x_e_m,
            pwm_period_s: self.model.actuator.valve.pwm_period_s(),
        })
    }

    fn reset(&mut self) {
        self.state = self.initial;
        self.model.mechanics.alpha_rad = self.alpha0_rad;
        self.gravity_n = self.model.mechanics.gravity_force();
        self.env = self.env0;
        self.u = 0.0;
        self.set_pa = (self.state.chambers.p_a, self.state.chambers.p_b);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::schema::Scene;

    fn plant() -> OneDofPneumatic {
        let path =
            std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scenes/paper-fig3.toml");
        let scene = Scene::load(&path).unwrap();
        let env = LinearSpring {
            stiffness_n_per_m: scene.environment.stiffness_n_per_m,
            x_e_m: scene.environment.x_e_m,
        };
        OneDofPneumatic::from_scene(&scene, env).unwrap()
    }

    #[test]
    fn the_actuator_geometry_is_the_sheets() {
        let p = plant();
        let g = p.actuator_geometry().unwrap();
        let c = &p.model.actuator.cylinder;
        assert_eq!((g.stroke_m, g.bore_m), (c.stroke_m, c.bore_m));
        assert_eq!(g.alpha_rad, p.model.mechanics.alpha_rad);
        assert_eq!(g.x_e_m, 0.02);
    }

    #[test]
    fn the_initial_state_satisfies_the_invariants() {
        plant().check_invariants().unwrap();
    }

    #[test]
    fn a_flange_faster_than_the_supply_can_drive_it_breaks_the_energy_invariant() {
        let mut p = plant();
        let a = &p.model.actuator;
        // Independent bound: the supply's largest force over the stroke, twice, and the spring at full stroke.
        let stroke = a.cylinder.stroke_m;
        let bound = 2.0
            * (0.5 * 700.0 * stroke * stroke
                + (a.supply.supply_pressure_pa * a.cylinder.area_a()
                    + p.model.mechanics.gravity_force().abs())
                    * stroke);
        let m = p.model.mechanics.moving_mass_kg;
        let v_limit = (2.0 * bound / m).sqrt();
        p.state.x_dot = 0.9 * v_limit;
        p.check_invariants().unwrap();
        p.state.x_dot = 1.1 * v_limit;
        let e = p.check_invariants().unwrap_err();
        assert_eq!(e.kind, crate::plants::PlantErrorKind::Invariant);
        assert!(e.message.contains("energy grows without a source"), "{e}");
    }

    #[test]
    fn the_valve_spool_is_recorded_and_under_pwm_is_one_side_or_the_other() {
        let path =
            std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scenes/paper-fig3.toml");
        let mut scene = Scene::load(&path).unwrap();
        scene.duration_s = 0.5;
        scene.metrics.clear();
        scene.claims.clear();
        scene.events.clear();
        let r = &crate::run_scene(&scene, &mut |_| {}).unwrap()[0];
        let spool = r.trace.column("spool").expect("the plant declares spool");
        assert_eq!(spool.len(), r.trace.len());
        // The 40 Hz on/off valve: after the first tick every sample is fully on one side.
        assert!(
            spool[1..].iter().all(|&s| s == 1.0 || s == -1.0),
            "{spool:?}"
        );
        assert!(spool.contains(&1.0) && spool.contains(&-1.0));
    }

    #[test]
    fn a_negative_absolute_pressure_is_named() {
        let mut p = plant();
        p.state.chambers.p_b = -1.0;
        let e = p.check_invariants().unwrap_err();
        assert!(e.message.starts_with("chamber pressure p_b = -1"), "{e}");
    }
}
