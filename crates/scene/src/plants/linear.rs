//! The paper's linear plant, eqs. (16)/(17): the flange position answers the load pressure through
//! Y(s)/P_L(s) = K_n / (s (s²/ω_n² + 2 ξ_n s/ω_n + 1)). The valve command is a load-pressure command,
//! p_L = u · p_range, and the contact force enters as the load-pressure disturbance -f_e/S_a, as in the paper's
//! own simulation of Figs. 3/4 (Section III-B). Integrated with fixed-step RK4 substeps; the spring force is
//! evaluated inside each stage.

use pneuflex_control::{Sensors, Signal, Telemetry, ValveCommand};

use crate::error::SceneError;
use crate::plants::{EventSpec, PlantSite, PlantSpec};
use crate::plants::{LinearSpring, Plant};

/// The load pressure the plant is driven with (its own recorded signal).
const LINEAR_SIGNALS: [Signal; 1] = [Signal::new(
    "p_l",
    "Pa",
    "pressure",
    "load pressure command p_L = u · load_pressure_range_pa (eq. 16's input)",
)];

/// The parameters of eq. (17) and the load-pressure scaling.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LinearModel {
    /// K_n, m/(Pa·s).
    pub k_n: f64,
    /// ω_n, rad/s.
    pub omega_n: f64,
    /// ξ_n, 1.
    pub zeta_n: f64,
    /// Piston area S_a, m².
    pub area_a: f64,
    /// Load pressure at u = 1, Pa.
    pub p_range: f64,
}

impl LinearModel {
    /// State derivative of [x, ẋ, ẍ] under load pressure p_L against `env`:
    /// x'''/ω² + 2ξ x''/ω + x' = K_n (p_L - f_e/S_a)  (eq. 17 written as an ODE).
    fn rates(&self, s: [f64; 3], p_l: f64, env: &LinearSpring) -> [f64; 3] {
        let p_in = p_l - env.force(s[0]) / self.area_a;
        let w = self.omega_n;
        [
            s[1],
            s[2],
            w * w * (self.k_n * p_in - s[1]) - 2.0 * self.zeta_n * w * s[2],
        ]
    }
}

/// The linear plant against a linear-spring environment.
#[derive(Clone, Debug, PartialEq)]
pub struct LinearPlant {
    model: LinearModel,
    state: [f64; 3],
    initial: [f64; 3],
    env: LinearSpring,
    env0: LinearSpring,
    u: f64,
    substeps: u32,
}

impl LinearPlant {
    /// A plant at rest at `x0` against `env`.
    pub fn new(model: LinearModel, x0: f64, env: LinearSpring, substeps: u32) -> Self {
        let initial = [x0, 0.0, 0.0];
        Self {
            model,
            state: initial,
            initial,
            env,
            env0: env,
            u: 0.0,
            substeps: substeps.max(1),
        }
    }

    /// The plant a `kind = "linear"` scene describes.
    pub fn from_spec(
        spec: &PlantSpec,
        site: &PlantSite<'_>,
        env: LinearSpring,
    ) -> Result<Self, SceneError> {
        let origin = site.origin;
        let PlantSpec::Linear {
            actuator,
            k_n_m_per_pa_s,
            omega_n_rad_per_s,
            zeta_n,
            area_a_m2,
            load_pressure_range_pa,
            substeps,
            x0_m,
        } = spec
        else {
            return Err(origin.plant_error("not a linear plant".into()));
        };
        let model = match actuator {
            Some(a) => {
                let sheet = origin
                    .load_sheet(&origin.resolve(a))
                    .map_err(|e| origin.invalid("plant.actuator", e.to_string()))?;
                let m = sheet.model();
                let (_, tf) = m.transfer_function_mid_stroke().map_err(|e| {
                    origin.invalid(
                        "plant.actuator",
                        format!("no operating point at mid-stroke to linearise at: {e}"),
                    )
                })?;
                let sp = &m.actuator.supply;
                LinearModel {
                    k_n: tf.k_n,
                    omega_n: tf.omega_n,
                    zeta_n: tf.xi_n,
                    area_a: m.actuator.cylinder.area_a(),
                    p_range: load_pressure_range_pa
                        .unwrap_or(sp.supply_pressure_pa - sp.atmosphere_pressure_pa),
                }
            }
            None => {
                // Validation requires every number without a sheet.
                let need = |x: Option<f64>, key: &str| {
                    x.ok_or_else(|| origin.invalid(key, "missing".into()))
                };
                LinearModel {
                    k_n: need(*k_n_m_per_pa_s, "plant.k_n_m_per_pa_s")?,
                    omega_n: need(*omega_n_rad_per_s, "plant.omega_n_rad_per_s")?,
                    zeta_n: need(*zeta_n, "plant.zeta_n")?,
                    area_a: need(*area_a_m2, "plant.area_a_m2")?,
                    p_range: need(*load_pressure_range_pa, "plant.load_pressure_range_pa")?,
                }
            }
        };
        Ok(Self::new(model, x0_m.unwrap_or(env.x_e_m), env, *substeps))
    }

    /// The model's parameters.
    pub fn model(&self) -> &LinearModel {
        &self.model
    }
}

impl crate::plants::Linearisable for LinearPlant {
    fn boxed_clone(&self) -> Box<dyn crate::plants::Linearisable> {
        Box::new(self.clone())
    }
    fn state_vector(&self) -> Vec<f64> {
        self.state.to_vec()
    }
    fn set_state_vector(&mut self, v: &[f64]) {
        self.state.copy_from_slice(&v[..3]);
    }
    fn perturbation_scales(&self) -> Vec<f64> {
        vec![1e-7, 1e-6, 1e-5]
    }
}

impl Plant for LinearPlant {
    fn sense(&self) -> Sensors {
        Sensors {
            t: 0.0,
            x: self.state[0],
            x_dot: self.state[1],
            f_e: self.env.force(self.state[0]),
            p_a: f64::NAN,
            p_b: f64::NAN,
        }
    }

    fn actuate(&mut self, command: ValveCommand, _telemetry: &Telemetry) {
        self.u = command.u;
    }

    fn advance(&mut self, dt: f64) {
        let h = dt / f64::from(self.substeps);
        let p_l = self.u * self.model.p_range;
        let (m, env) = (self.model, self.env);
        let axpy =
            |s: [f64; 3], a: f64, k: [f64; 3]| [s[0] + a * k[0], s[1] + a * k[1], s[2] + a * k[2]];
        for _ in 0..self.substeps {
            let s = self.state;
            let k1 = m.rates(s, p_l, &env);
            let k2 = m.rates(axpy(s, 0.5 * h, k1), p_l, &env);
            let k3 = m.rates(axpy(s, 0.5 * h, k2), p_l, &env);
            let k4 = m.rates(axpy(s, h, k3), p_l, &env);
            for i in 0..3 {
                self.state[i] += h / 6.0 * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i]);
            }
        }
    }

    fn apply(&mut self, event: &EventSpec) -> Result<(), crate::plants::PlantError> {
        match *event {
            EventSpec::Stiffness {
                stiffness_n_per_m, ..
            } => {
                self.env.stiffness_n_per_m = stiffness_n_per_m;
                Ok(())
            }
            _ => Err(crate::plants::PlantError::unsupported(format!(
                "the linear plant supports only stiffness events, not {}",
                event.kind()
            ))),
        }
    }

    fn reset(&mut self) {
        self.state = self.initial;
        self.env = self.env0;
        self.u = 0.0;
    }

    fn signals(&self) -> &'static [Signal] {
        &LINEAR_SIGNALS
    }

    fn record(&self, out: &mut [f64]) {
        out[0] = self.u * self.model.p_range;
    }
}
