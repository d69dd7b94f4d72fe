//! The pneumatic model in Python: an actuator sheet, the 1-DOF model of eq. (1), and the axial force
//! element (chambers + valve, eqs. (2)-(11)) that an external rigid-body engine such as MuJoCo couples to.

use std::path::PathBuf;

use pneuflex_multibody::{AxialActuator, PneumaticForceElement};
use pneuflex_pneumatics::{ActuatorSheet, ChamberState, Friction, OneDofModel, OneDofState};
use pneuflex_scene::Scene;
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::PyDict;

use crate::errors;

pub(crate) fn check_finite(name: &str, v: f64) -> PyResult<f64> {
    if v.is_finite() {
        Ok(v)
    } else {
        Err(PyValueError::new_err(format!(
            "{name} must be finite, got {v}"
        )))
    }
}

pub(crate) fn check_positive(name: &str, v: f64) -> PyResult<f64> {
    if v.is_finite() && v > 0.0 {
        Ok(v)
    } else {
        Err(PyValueError::new_err(format!(
            "{name} must be finite and > 0, got {v}"
        )))
    }
}

/// A pneumatic actuator described by an actuator sheet (TOML): cylinder, valve, supply, gas, mechanics.
#[pyclass(name = "Actuator", module = "pneuflex", frozen)]
pub struct PyActuator {
    sheet: ActuatorSheet,
    model: OneDofModel,
}

impl PyActuator {
    /// The 1-DOF model (pneumatics + mechanics) with the incline in force.
    pub fn model(&self) -> OneDofModel {
        self.model
    }
}

#[pymethods]
impl PyActuator {
    /// Loads an actuator sheet and every component file it names; `alpha_deg` overrides the sheet's incline.
    #[new]
    #[pyo3(signature = (path, alpha_deg = None))]
    fn new(path: PathBuf, alpha_deg: Option<f64>) -> PyResult<Self> {
        let sheet = ActuatorSheet::load(&path).map_err(errors::component)?;
        let mut model = sheet.model();
        if let Some(a) = alpha_deg {
            let a = check_finite("alpha_deg", a)?;
            if !(-90.0..=90.0).contains(&a) {
                return Err(PyValueError::new_err(format!(
                    "alpha_deg must be in [-90, 90], got {a}"
                )));
            }
            model.mechanics.alpha_rad = a.to_radians();
        }
        Ok(Self { sheet, model })
    }

    /// The actuator of a pneumatic scene's plant (sheet path resolved against the scene, scene's alpha).
    #[staticmethod]
    fn from_scene(scene_path: crate::shipped::ScenePath) -> PyResult<Self> {
        let scene = Scene::load(&scene_path).map_err(errors::scene)?;
        let Some((actuator, alpha_deg)) = scene.plant.force_element() else {
            return Err(errors::other(format!(
                "{}: plant: the ideal and linear plants have no actuator model to couple (kind must be \"pneumatic\" or \"multibody\")",
                scene_path.display()
            )));
        };
        Self::new(scene.resolve(actuator), alpha_deg)
    }

    /// Path of the sheet.
    #[getter]
    fn path(&self) -> PathBuf {
        self.sheet.path.clone()
    }

    /// Every parameter of the model as a dict (SI units, pressures absolute).
    fn params<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let a = &self.model.actuator;
        let m = &self.model.mechanics;
        let c = &a.cylinder;
        let d = PyDict::new(py);
        d.set_item("name", &self.sheet.name)?;
        d.set_item("path", self.sheet.path.display().to_string())?;
        d.set_item("bore_m", c.bore_m)?;
        d.set_item("rod_m", c.rod_m)?;
        d.set_item("stroke_m", c.stroke_m)?;
        d.set_item("dead_volume_a_m3", c.dead_volume_a_m3)?;
        d.set_item("dead_volume_b_m3", c.dead_volume_b_m3)?;
        d.set_item("area_a_m2", c.area_a())?;
        d.set_item("area_b_m2", c.area_b())?;
        d.set_item("area_rod_m2", c.area_rod())?;
        d.set_item("gas_constant_j_per_kg_k", a.gas.gas_constant_j_per_kg_k)?;
        d.set_item("polytropic_exponent", a.gas.polytropic_exponent)?;
        d.set_item("supply_pressure_pa", a.supply.supply_pressure_pa)?;
        d.set_item("supply_temperature_k", a.supply.supply_temperature_k)?;
        d.set_item("atmosphere_pressure_pa", a.supply.atmosphere_pressure_pa)?;
        d.set_item(
            "atmosphere_temperature_k",
            a.supply.atmosphere_temperature_k,
        )?;
        d.set_item(
            "sonic_conductance_m3_per_s_pa",
            a.valve.orifice.sonic_conductance_m3_per_s_pa,
        )?;
        d.set_item(
            "critical_pressure_ratio",
            a.valve.orifice.critical_pressure_ratio,
        )?;
        d.set_item("underlap", a.valve.underlap)?;
        let (kind, keys) = a.valve.kind.sheet_keys();
        d.set_item("valve_kind", kind)?;
        for (key, value) in keys {
            d.set_item(key, value)?;
        }
        d.set_item("moving_mass_kg", m.moving_mass_kg)?;
        d.set_item("viscous_n_s_per_m", m.viscous_n_s_per_m)?;
        // The law's name, then its parameters under the sheet's keys (F_c, F_s, v_s, sigma0, sigma1).
        let (law, params) = match m.friction {
            Friction::Smooth {
                coulomb_n: f_c,
                smooth_velocity_m_per_s: v_s,
            } => (
                "smooth",
                vec![("coulomb_n", f_c), ("smooth_velocity_m_per_s", v_s)],
            ),
            Friction::StickSlip {
                coulomb_n: f_c,
                static_n: f_s,
                stribeck_velocity_m_per_s: v_s,
                stick_velocity_m_per_s: v_stick,
            } => (
                "stick_slip",
                vec![
                    ("coulomb_n", f_c),
                    ("static_n", f_s),
                    ("stribeck_velocity_m_per_s", v_s),
                    ("stick_velocity_m_per_s", v_stick),
                ],
            ),
            Friction::LuGre {
                coulomb_n: f_c,
                static_n: f_s,
                stribeck_velocity_m_per_s: v_s,
                bristle_stiffness_n_per_m: sigma0,
                bristle_damping_n_s_per_m: sigma1,
            } => (
                "lugre",
                vec![
                    ("coulomb_n", f_c),
                    ("static_n", f_s),
                    ("stribeck_velocity_m_per_s", v_s),
                    ("bristle_stiffness_n_per_m", sigma0),
                    ("bristle_damping_n_s_per_m", sigma1),
                ],
            ),
        };
        d.set_item("friction", law)?;
        for (key, value) in params {
            d.set_item(key, value)?;
        }
        d.set_item("alpha_rad", m.alpha_rad)?;
        d.set_item("alpha_deg", m.alpha_rad.to_degrees())?;
        d.set_item("gravity_m_per_s2", m.gravity_m_per_s2)?;
        Ok(d)
    }

    /// Net pneumatic force on the rod along +x, N: p_a S_a - p_b S_b - p_atm S_rod (eq. (1)'s F_1).
    fn piston_force(&self, p_a: f64, p_b: f64) -> f64 {
        self.model
            .actuator
            .piston_force(&ChamberState::new(p_a, p_b))
    }

    /// Chamber-A pressure (Pa absolute) that holds the flange at rest against `p_b`, gravity and `f_ext_n`.
    #[pyo3(signature = (p_b, f_ext_n = 0.0))]
    fn static_balance(&self, p_b: f64, f_ext_n: f64) -> f64 {
        self.model.static_balance(p_b, f_ext_n)
    }

    /// Gravity along +x, m g sin(alpha), N (eq. (1)'s G_alpha).
    fn gravity_force(&self) -> f64 {
        self.model.mechanics.gravity_force()
    }

    /// Coulomb friction opposing motion at velocity `x_dot` under net drive `drive_n` (eq. (1)'s f), N.
    #[pyo3(signature = (x_dot, drive_n = 0.0))]
    fn friction_force(&self, x_dot: f64, drive_n: f64) -> f64 {
        self.model.mechanics.friction.force(x_dot, drive_n)
    }

    /// Transfer function of eqs. (16)-(17) at the operating point holding `f_ext_n` at `x_m` (default:
    /// mid-stroke, no load): gains, natural frequency, damping, polynomial coefficients, operating point.
    #[pyo3(signature = (x_m = None, f_ext_n = 0.0))]
    fn transfer_function<'py>(
        &self,
        py: Python<'py>,
        x_m: Option<f64>,
        f_ext_n: f64,
    ) -> PyResult<Bound<'py, PyDict>> {
        let x = x_m.unwrap_or(0.5 * self.model.actuator.cylinder.stroke_m);
        let op = self
            .model
            .operating_point(x, f_ext_n)
            .map_err(errors::other)?;
        let tf = self.model.transfer_function(&op);
        let d = PyDict::new(py);
        d.set_item("k_n", tf.k_n)?;
        d.set_item("omega_n", tf.omega_n)?;
        d.set_item("xi_n", tf.xi_n)?;
        d.set_item("num", tf.num)?;
        d.set_item("den", tf.den.to_vec())?;
        let o = PyDict::new(py);
        o.set_item("x_m", op.x)?;
        o.set_item("u", op.u)?;
        o.set_item("f_ext_n", op.f_ext)?;
        o.set_item("p_a", op.p_a)?;
        o.set_item("p_b", op.p_b)?;
        o.set_item("temperature_k", op.temperature_k)?;
        d.set_item("operating_point", o)?;
        Ok(d)
    }

    fn __repr__(&self) -> String {
        format!(
            "Actuator({:?}, alpha_deg={})",
            self.sheet.path.display().to_string(),
            self.model.mechanics.alpha_rad.to_degrees()
        )
    }
}

/// Default initial chambers of the scene plant: B at the mean of supply and atmosphere, A at the static
/// balance of eq. (1) against `f_ext`.
fn default_chambers(model: &OneDofModel, f_ext: f64) -> (f64, f64) {
    let s = &model.actuator.supply;
    let p_b = 0.5 * (s.supply_pressure_pa + s.atmosphere_pressure_pa);
    (model.static_balance(p_b, f_ext), p_b)
}

/// The 1-DOF model of eq. (1): chambers, valve, mass, friction and incline, integrated with fixed-step RK4.
#[pyclass(name = "OneDof", module = "pneuflex")]
pub struct PyOneDof {
    model: OneDofModel,
    initial: OneDofState,
    state: OneDofState,
}

#[pymethods]
impl PyOneDof {
    /// A model at rest at `x0_m` with chamber pressures `p_a`, `p_b` (Pa absolute). Absent pressures: B at
    /// the mean of supply and atmosphere and A at the static balance against the external force `f_ext_n`.
    #[new]
    #[pyo3(signature = (actuator, x0_m, p_a = None, p_b = None, f_ext_n = 0.0))]
    fn new(
        actuator: &PyActuator,
        x0_m: f64,
        p_a: Option<f64>,
        p_b: Option<f64>,
        f_ext_n: f64,
    ) -> PyResult<Self> {
        let model = actuator.model();
        let x0 = check_finite("x0_m", x0_m)?;
        let stroke = model.actuator.cylinder.stroke_m;
        // The end stops hold the piston in [0, stroke]: a start beyond them is no state of the model.
        if !(0.0..=stroke).contains(&x0) {
            return Err(PyValueError::new_err(format!(
                "x0_m must be within the stroke [0, {stroke}] m, got {x0}"
            )));
        }
        check_finite("f_ext_n", f_ext_n)?;
        let (pa0, pb0) = default_chambers(&model, f_ext_n);
        let p_b = check_positive("p_b", p_b.unwrap_or(pb0))?;
        let p_a = match p_a {
            Some(p) => check_positive("p_a", p)?,
            None if p_b == pb0 => pa0,
            None => model.static_balance(p_b, f_ext_n),
        };
        let initial = OneDofState::at_rest(x0, ChamberState::new(p_a, p_b), 0.0);
        Ok(Self {
            model,
            initial,
            state: initial,
        })
    }

    /// One RK4 step of `dt_s` under valve command `u` and external force `f_ext_n` (N along +x).
    /// A NaN command or force is refused (it was read as some command); `u` outside [-1, 1] is clamped.
    fn step(&mut self, u: f64, f_ext_n: f64, dt_s: f64) -> PyResult<()> {
        check_positive("dt_s", dt_s)?;
        check_finite("u", u)?;
        check_finite("f_ext_n", f_ext_n)?;
        self.model.step(&mut self.state, u, f_ext_n, dt_s);
        Ok(())
    }

    /// Back to the initial state.
    fn reset(&mut self) {
        self.state = self.initial;
    }

    /// Net pneumatic force on the rod at the current chambers, N.
    fn piston_force(&self) -> f64 {
        self.model.actuator.piston_force(&self.state.chambers)
    }

    /// Simulated time, s.
    #[getter]
    fn t(&self) -> f64 {
        self.state.t
    }
    /// Piston extension, m.
    #[getter]
    fn x(&self) -> f64 {
        self.state.x
    }
    /// Piston velocity, m/s.
    #[getter]
    fn x_dot(&self) -> f64 {
        self.state.x_dot
    }
    /// Chamber A pressure, Pa absolute.
    #[getter]
    fn p_a(&self) -> f64 {
        self.state.chambers.p_a
    }
    /// Chamber B pressure, Pa absolute.
    #[getter]
    fn p_b(&self) -> f64 {
        self.state.chambers.p_b
    }
    /// Chamber A temperature, K.
    #[getter]
    fn t_a(&self) -> f64 {
        self.state.chambers.t_a
    }
    /// Chamber B temperature, K.
    #[getter]
    fn t_b(&self) -> f64 {
        self.state.chambers.t_b
    }
    /// Valve spool position in [-1, 1].
    #[getter]
    fn spool(&self) -> f64 {
        self.state.valve.spool
    }
}

/// The pneumatic force element between cylinder and flange (`pneuflex_pneumatics::PneumaticForceElement`, the
/// element the Rapier rig uses): chamber states and valve, advanced by `step(x, x_dot, u, dt)` along a flange
/// motion given by an external rigid-body engine.
#[pyclass(name = "ForceElement", module = "pneuflex")]
pub struct PyForceElement {
    model: OneDofModel,
    initial: ChamberState,
    element: PneumaticForceElement,
    substeps: u32,
    t: f64,
}

#[pymethods]
impl PyForceElement {
    /// A force element with chamber pressures `p_a`, `p_b` (Pa absolute; absent: the scene plant's default,
    /// B at the mean of supply and atmosphere and A at the static balance against `f_ext_n`), gas at
    /// `temperature_k` (default 293.15 K), `substeps` chamber RK4 substeps per `step`.
    #[new]
    #[pyo3(signature = (actuator, p_a = None, p_b = None, f_ext_n = 0.0, temperature_k = None, substeps = 1))]
    fn new(
        actuator: &PyActuator,
        p_a: Option<f64>,
        p_b: Option<f64>,
        f_ext_n: f64,
        temperature_k: Option<f64>,
        substeps: u32,
    ) -> PyResult<Self> {
        let model = actuator.model();
        let (pa0, pb0) = default_chambers(&model, f_ext_n);
        let p_b = check_positive("p_b", p_b.unwrap_or(pb0))?;
        let p_a = match p_a {
            Some(p) => check_positive("p_a", p)?,
            None if p_b == pb0 => pa0,
            None => model.static_balance(p_b, f_ext_n),
        };
        let t_k = check_positive(
            "temperature_k",
            temperature_k.unwrap_or(pneuflex_pneumatics::T_DEFAULT),
        )?;
        if substeps == 0 {
            return Err(PyValueError::new_err("substeps must be >= 1"));
        }
        let c = ChamberState::with_temperature(p_a, p_b, t_k);
        Ok(Self {
            model,
            initial: c,
            element: PneumaticForceElement::new(model.actuator, c, substeps),
            substeps,
            t: 0.0,
        })
    }

    /// Advances valve and chambers by `dt_s` while the flange moves at `x_dot` (m/s) from extension `x`
    /// (m) under valve command `u`; returns the substep-averaged pneumatic force on the flange over the
    /// step, N along +x (the reaction on the cylinder is its negative). Friction and viscosity (K_v) are
    /// not included.
    fn step(&mut self, x: f64, x_dot: f64, u: f64, dt_s: f64) -> PyResult<f64> {
        check_positive("dt_s", dt_s)?;
        check_finite("x", x)?;
        check_finite("x_dot", x_dot)?;
        check_finite("u", u)?;
        self.element.set_command(u);
        self.t += dt_s;
        Ok(self.element.force(x, x_dot, dt_s))
    }

    /// Times `n` steps of `dt_s` in a Rust loop (no Python per step; the GIL released), the flange at `x`
    /// moving at `x_dot` (the extension held: the chambers see the volume rate, not a new volume) under
    /// command `u`; the element's state moves on. Returns the wall time, s: the chamber model's own cost
    /// of a step, for scripts/bench against MuJoCo and the native plugin.
    fn bench_steps(
        &mut self,
        py: Python<'_>,
        n: u64,
        x: f64,
        x_dot: f64,
        u: f64,
        dt_s: f64,
    ) -> PyResult<f64> {
        check_positive("dt_s", dt_s)?;
        check_finite("x", x)?;
        check_finite("x_dot", x_dot)?;
        check_finite("u", u)?;
        self.element.set_command(u);
        let el = &mut self.element;
        let wall = py.detach(|| {
            let t0 = std::time::Instant::now();
            for _ in 0..n {
                std::hint::black_box(el.step(std::hint::black_box(x), x_dot, dt_s));
            }
            t0.elapsed().as_secs_f64()
        });
        self.t += dt_s * n as f64;
        Ok(wall)
    }

    /// Pneumatic force on the flange at the current chambers, N along +x.
    fn force(&self) -> f64 {
        self.element.piston_force()
    }

    /// Coulomb friction of piston and guide (eq. (1)'s f) at velocity `x_dot` under net drive `drive_n`, N.
    #[pyo3(signature = (x_dot, drive_n = 0.0))]
    fn friction_force(&self, x_dot: f64, drive_n: f64) -> f64 {
        self.model.mechanics.friction.force(x_dot, drive_n)
    }

    /// Back to the initial chambers, valve and time.
    fn reset(&mut self) {
        self.element = PneumaticForceElement::new(self.model.actuator, self.initial, self.substeps);
        self.t = 0.0;
    }

    /// Element time (sum of the steps), s.
    #[getter]
    fn t(&self) -> f64 {
        self.t
    }
    /// Chamber A pressure, Pa absolute.
    #[getter]
    fn p_a(&self) -> f64 {
        self.element.chambers.p_a
    }
    /// Chamber B pressure, Pa absolute.
    #[getter]
    fn p_b(&self) -> f64 {
        self.element.chambers.p_b
    }
    /// Chamber A temperature, K.
    #[getter]
    fn t_a(&self) -> f64 {
        self.element.chambers.t_a
    }
    /// Chamber B temperature, K.
    #[getter]
    fn t_b(&self) -> f64 {
        self.element.chambers.t_b
    }
    /// Valve spool position in [-1, 1].
    #[getter]
    fn spool(&self) -> f64 {
        self.element.valve.spool
    }
}
