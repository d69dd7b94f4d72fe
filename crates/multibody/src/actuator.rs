//! The force element between the cylinder body and the flange.

/// An axial force element: given the flange state it returns the force along +x on the flange, N.
/// The world applies the same force with opposite sign on the cylinder body, every physics step.
pub trait AxialActuator {
    /// Advance the element's own state by `dt` (s) at flange extension `x` (m) and velocity `x_dot`
    /// (m/s) and return the force on the flange along +x, N (eq. (1)'s F_1 - F_2 term).
    fn force(&mut self, x: f64, x_dot: f64, dt: f64) -> f64;
}

/// A constant axial force, N: the "constant push" of the contact-stiffness tests.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ConstantForce {
    /// Force on the flange along +x, N.
    pub force_n: f64,
}

impl AxialActuator for ConstantForce {
    fn force(&mut self, _x: f64, _x_dot: f64, _dt: f64) -> f64 {
        self.force_n
    }
}

/// A linear spring-damper towards a set extension: F = k (x_set - x) - c x_dot.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SpringActuator {
    /// Spring rate, N/m.
    pub stiffness_n_per_m: f64,
    /// Damping, N s/m.
    pub damping_n_s_per_m: f64,
    /// Extension at which the spring is relaxed, m.
    pub set_x_m: f64,
}

impl AxialActuator for SpringActuator {
    fn force(&mut self, x: f64, x_dot: f64, _dt: f64) -> f64 {
        self.stiffness_n_per_m * (self.set_x_m - x) - self.damping_n_s_per_m * x_dot
    }
}

impl<T: AxialActuator + ?Sized> AxialActuator for &mut T {
    fn force(&mut self, x: f64, x_dot: f64, dt: f64) -> f64 {
        (**self).force(x, x_dot, dt)
    }
}

/// The pneumatic cylinder as a force element (chambers and valve over each physics step, the mean
/// piston force): `pneuflex_pneumatics::PneumaticForceElement`, the one implementation every engine uses
/// (this rig, MuJoCo from Python and the native MuJoCo plugin). Viscous friction K_v is the URDF joint
/// damping and is not added here.
pub use pneuflex_pneumatics::PneumaticForceElement;

impl AxialActuator for PneumaticForceElement {
    fn force(&mut self, x: f64, x_dot: f64, dt: f64) -> f64 {
        self.step(x, x_dot, dt)
    }
}

impl<T: AxialActuator + ?Sized> AxialActuator for Box<T> {
    fn force(&mut self, x: f64, x_dot: f64, dt: f64) -> f64 {
        (**self).force(x, x_dot, dt)
    }
}

/// What an engine and a scene ask of an actuator family (a cylinder, a muscle) beside its force: the
/// command, the named sensors, the state, the invariants and the travel its mount may take. A new family
/// implements this and is built from its sheet in the scene's `mechanism/build.rs`: nothing else changes.
pub trait ActuatorFamily: AxialActuator {
    /// The family's name as scenes and messages say it: `cylinder`, `muscle`.
    fn family(&self) -> &'static str;
    /// Set the command held from the next step on: the valve command u in [-1, 1] (clamped; NaN is 0).
    fn set_command(&mut self, u: f64);
    /// The family's sensors, in the order [`ActuatorFamily::read_sensors`] writes them (a cylinder's
    /// `p_a`, `p_b`; a muscle's `p_muscle`), each a trace column after the actuator's name.
    fn sensors(&self) -> &'static [SensorSpec];
    /// The sensors' values now, one per sensor (pressures in Pa absolute).
    fn read_sensors(&self, out: &mut [f64]);
    /// Whether the actuator pulls its anchors together (a muscle) rather than pushing them apart: its
    /// force is then `-tension` and a scene reports its contraction and tension, so that for both kinds a
    /// larger command gives a larger sensed position and force.
    fn pulls(&self) -> bool {
        false
    }
    /// Whether the mount's stroke `x_m` (m, from the retracted length) is one the family can take with a
    /// stroke of `stroke_m`: a cylinder only between its end stops (with 0.1 % slack for the explicit
    /// step), a muscle also slack (shorter than its fittings' distance allows).
    fn admits_stroke(&self, x_m: f64, stroke_m: f64) -> bool {
        let slack = 1e-3 * stroke_m;
        (-slack..=stroke_m + slack).contains(&x_m)
    }
    /// The evolving state as numbers (chambers, valve, clock), for a host that stores or restores it.
    fn state(&self) -> Vec<f64>;
    /// Restores [`ActuatorFamily::state`]'s numbers; `false` (nothing changed) when they are not a state
    /// the element can be in.
    fn set_state(&mut self, s: &[f64]) -> bool;
    /// The family's invariants at mount stroke `x_m` of `stroke_m`: its chambers' pressures within
    /// (0, 2 x supply], temperatures positive, its travel possible; Err says which and by how much.
    fn check_invariants(&self, x_m: f64, stroke_m: f64) -> Result<(), String>;
}

impl<T: ActuatorFamily + ?Sized> ActuatorFamily for Box<T> {
    fn family(&self) -> &'static str {
        (**self).family()
    }
    fn set_command(&mut self, u: f64) {
        (**self).set_command(u)
    }
    fn sensors(&self) -> &'static [SensorSpec] {
        (**self).sensors()
    }
    fn read_sensors(&self, out: &mut [f64]) {
        (**self).read_sensors(out)
    }
    fn pulls(&self) -> bool {
        (**self).pulls()
    }
    fn admits_stroke(&self, x_m: f64, stroke_m: f64) -> bool {
        (**self).admits_stroke(x_m, stroke_m)
    }
    fn state(&self) -> Vec<f64> {
        (**self).state()
    }
    fn set_state(&mut self, s: &[f64]) -> bool {
        (**self).set_state(s)
    }
    fn check_invariants(&self, x_m: f64, stroke_m: f64) -> Result<(), String> {
        (**self).check_invariants(x_m, stroke_m)
    }
}

/// One of a family's sensors: its trace column's name (after the actuator's), unit and meaning.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct SensorSpec {
    /// Column name after `<actuator>.`.
    pub name: &'static str,
    /// SI unit.
    pub unit: &'static str,
    /// What it reads, in one line.
    pub description: &'static str,
}

/// A cylinder's sensors: its two chambers' pressures, the control loop's own `p_a`, `p_b` columns.
pub const CHAMBER_PRESSURES: [SensorSpec; 2] = [
    SensorSpec {
        name: "p_a",
        unit: "Pa",
        description: "chamber A pressure, absolute",
    },
    SensorSpec {
        name: "p_b",
        unit: "Pa",
        description: "chamber B pressure, absolute",
    },
];

/// Chamber pressures may reach this multiple of the supply before a run is stopped as diverged (the
/// one-actuator plants' margin: a moving load compresses a closed chamber above the supply).
pub const PRESSURE_MARGIN: f64 = 2.0;

/// A pressure and a temperature within the invariants' bounds, or why not.
pub fn gas_invariant(
    (p_name, t_name): (&str, &str),
    p_pa: f64,
    t_k: f64,
    supply_pa: f64,
) -> Result<(), String> {
    let p_max = PRESSURE_MARGIN * supply_pa;
    if !(p_pa > 0.0 && p_pa <= p_max) {
        return Err(format!(
            "chamber pressure {p_name} = {p_pa:.6e} Pa (absolute) outside (0, {p_max:.3e}] Pa \
             ({PRESSURE_MARGIN} x supply)"
        ));
    }
    if !(t_k > 0.0 && t_k < 2000.0) {
        return Err(format!(
            "chamber temperature {t_name} = {t_k:.6e} K outside (0, 2000) K"
        ));
    }
    Ok(())
}

impl ActuatorFamily for PneumaticForceElement {
    fn family(&self) -> &'static str {
        "cylinder"
    }
    fn set_command(&mut self, u: f64) {
        PneumaticForceElement::set_command(self, u)
    }
    fn sensors(&self) -> &'static [SensorSpec] {
        &CHAMBER_PRESSURES
    }
    fn read_sensors(&self, out: &mut [f64]) {
        let (p_a, p_b) = self.pressures();
        out[0] = p_a;
        out[1] = p_b;
    }
    fn state(&self) -> Vec<f64> {
        PneumaticForceElement::state(self).to_vec()
    }
    fn set_state(&mut self, s: &[f64]) -> bool {
        <&[f64; Self::STATE_LEN]>::try_from(s)
            .is_ok_and(|s| PneumaticForceElement::set_state(self, s))
    }
    fn check_invariants(&self, x_m: f64, stroke_m: f64) -> Result<(), String> {
        let (c, s) = (&self.chambers, &self.actuator.supply);
        gas_invariant(("p_a", "T_a"), c.p_a, c.t_a, s.supply_pressure_pa)?;
        gas_invariant(("p_b", "T_b"), c.p_b, c.t_b, s.supply_pressure_pa)?;
        let tol = 1e-3 + 0.01 * stroke_m;
        if !(x_m >= -tol && x_m <= stroke_m + tol) {
            return Err(format!(
                "piston position x = {x_m:.6e} m outside the stroke [0, {stroke_m}] m (+/- {tol:.4} m)"
            ));
        }
        Ok(())
    }
}

/// The muscle crate the second family is built on (its sheet and chamber types, for whoever builds one).
pub use pneuflex_muscle;

/// The McKibben muscle as a force element between two anchors (the second family; docs/muscles.md): the
/// engine gives the anchors' distance over a physics step, the element integrates its chamber (M9, M10) and
/// valve or regulator over it in `substeps` RK4 substeps with the length moving at the step's rate (split
/// at a PWM valve's spool edges), and returns the mean of -tension (M5, M7, M8): it pulls the anchors
/// together. The mount's stroke x is L - L_min with L_min = L0 (1 - eps_max), the fully contracted length.
#[derive(Debug, Clone)]
pub struct MuscleForceElement {
    /// Muscle, gas and supply.
    pub chamber: pneuflex_muscle::MuscleChamber,
    /// Valve or regulator.
    pub feed: pneuflex_muscle::Feed,
    /// Gas in the muscle.
    pub gas: pneuflex_muscle::ChamberState,
    /// The valve's spool and PWM state (unused with a regulator).
    pub valve: pneuflex_pneumatics::ValveState,
    /// The command u in [-1, 1] held until changed.
    command: f64,
    substeps: u32,
    time_s: f64,
}

impl MuscleForceElement {
    /// How many numbers [`ActuatorFamily::state`] writes: p, T, the valve's state and the clock.
    pub const STATE_LEN: usize = 3 + pneuflex_pneumatics::ValveState::LEN;

    /// A muscle at gas state `gas`, its valve at rest at spool 0, `substeps` (0 is 1) per physics step.
    pub fn new(
        chamber: pneuflex_muscle::MuscleChamber,
        feed: pneuflex_muscle::Feed,
        gas: pneuflex_muscle::ChamberState,
        substeps: u32,
    ) -> Self {
        Self {
            chamber,
            feed,
            gas,
            valve: pneuflex_pneumatics::ValveState::default(),
            command: 0.0,
            substeps: substeps.max(1),
            time_s: 0.0,
        }
    }

    /// The fully contracted length L_min = L0 (1 - eps_max) (M6): the mount's retracted length, m.
    pub fn contracted_length_m(&self) -> f64 {
        let b = &self.chamber.muscle.braid;
        b.rest_length_m * (1.0 - b.max_contraction())
    }

    /// The mount's stroke L0 - L_min from full contraction to the rest length, m.
    pub fn stroke_m(&self) -> f64 {
        self.chamber.muscle.braid.rest_length_m - self.contracted_length_m()
    }

    /// What feeds the chamber under command `u`: the 3/2 valve at `spool`, or the regulator set from
    /// atmosphere (u = -1) to supply (u = +1), linearly.
    fn port(&self, spool: f64) -> pneuflex_muscle::Port {
        use pneuflex_muscle::{Feed, Port};
        match self.feed {
            Feed::Closed => Port::Closed,
            Feed::Valve(valve) => Port::Valve { valve, spool },
            Feed::Regulator { time_constant_s } => {
                let s = &self.chamber.supply;
                Port::Regulator {
                    time_constant_s,
                    set_pressure_pa: s.atmosphere_pressure_pa
                        + 0.5
                            * (self.command + 1.0)
                            * (s.supply_pressure_pa - s.atmosphere_pressure_pa),
                }
            }
        }
    }

    /// One RK4 step of the gas over `h` from length `l` moving at `l_dot`, the port held.
    fn rk4(&mut self, l: f64, l_dot: f64, h: f64, port: &pneuflex_muscle::Port) {
        use pneuflex_muscle::ChamberState as G;
        let c = &self.chamber;
        let d = |g: &G, l: f64| {
            let r = c.rates(g, l, l_dot, port);
            (r.pressure_pa_per_s, r.temperature_k_per_s)
        };
        let at = |g: &G, k: (f64, f64), s: f64| G {
            pressure_pa: g.pressure_pa + s * k.0,
            temperature_k: g.temperature_k + s * k.1,
        };
        let g = self.gas;
        let k1 = d(&g, l);
        let k2 = d(&at(&g, k1, 0.5 * h), l + 0.5 * h * l_dot);
        let k3 = d(&at(&g, k2, 0.5 * h), l + 0.5 * h * l_dot);
        let k4 = d(&at(&g, k3, h), l + h * l_dot);
        self.gas = G {
            pressure_pa: g.pressure_pa + h / 6.0 * (k1.0 + 2.0 * k2.0 + 2.0 * k3.0 + k4.0),
            temperature_k: g.temperature_k + h / 6.0 * (k1.1 + 2.0 * k2.1 + 2.0 * k3.1 + k4.1),
        };
    }

    /// Advances the chamber by `dt` (s) while the muscle's length goes from `length_m` at `rate` (m/s),
    /// and returns the mean tension over the step, N (trapezoid over each piece).
    pub fn step_length(&mut self, length_m: f64, rate: f64, dt: f64) -> f64 {
        let h = dt / f64::from(self.substeps);
        let mut t_sum = 0.0;
        for i in 0..self.substeps {
            let (t_sub, t_end) = (self.time_s, self.time_s + h);
            let (mut tau, mut rest) = (t_sub, h);
            loop {
                let (spool, edge) = match self.feed {
                    pneuflex_muscle::Feed::Valve(v) => {
                        v.segment(&mut self.valve, self.command, tau, rest)
                    }
                    _ => (0.0, None),
                };
                let len = edge.map_or(rest, |e| (e - tau).min(rest));
                let l = length_m + rate * (h * f64::from(i) + (tau - t_sub));
                let f0 = self.chamber.tension(&self.gas, l, rate);
                let port = self.port(spool);
                self.rk4(l, rate, len, &port);
                let f1 = self.chamber.tension(&self.gas, l + rate * len, rate);
                t_sum += 0.5 * (f0 + f1) * (len / h);
                match edge {
                    Some(e) if e < t_end => {
                        tau = e;
                        rest = t_end - e;
                    }
                    _ => break,
                }
            }
            self.time_s += h;
        }
        t_sum / f64::from(self.substeps)
    }

    /// The muscle's tension at rest at length `length_m` and the gas now, N (M5, M8).
    pub fn static_tension(&self, length_m: f64) -> f64 {
        self.chamber.tension(&self.gas, length_m, 0.0)
    }
}

impl AxialActuator for MuscleForceElement {
    fn force(&mut self, x: f64, x_dot: f64, dt: f64) -> f64 {
        -self.step_length(self.contracted_length_m() + x, x_dot, dt)
    }
}

impl ActuatorFamily for MuscleForceElement {
    fn family(&self) -> &'static str {
        "muscle"
    }
    fn set_command(&mut self, u: f64) {
        self.command = if u.is_nan() { 0.0 } else { u.clamp(-1.0, 1.0) };
    }
    /// `p_muscle`, not `p`: the adaptive law's own `p` takes that column name.
    fn sensors(&self) -> &'static [SensorSpec] {
        &[SensorSpec {
            name: "p_muscle",
            unit: "Pa",
            description: "muscle pressure, absolute",
        }]
    }
    fn read_sensors(&self, out: &mut [f64]) {
        out[0] = self.gas.pressure_pa;
    }
    fn pulls(&self) -> bool {
        true
    }
    /// Any length from slack (down to the anchors meeting) to the fibres lying straight, L = b.
    fn admits_stroke(&self, x_m: f64, _stroke_m: f64) -> bool {
        let l = self.contracted_length_m() + x_m;
        l > 0.0 && l <= self.chamber.muscle.braid.fibre_length_m()
    }
    fn state(&self) -> Vec<f64> {
        let mut v = vec![self.gas.pressure_pa, self.gas.temperature_k];
        v.extend(self.valve.to_array());
        v.push(self.time_s);
        v
    }
    fn set_state(&mut self, s: &[f64]) -> bool {
        if s.len() != Self::STATE_LEN {
            return false;
        }
        let mut va = [0.0; pneuflex_pneumatics::ValveState::LEN];
        va.copy_from_slice(&s[2..2 + pneuflex_pneumatics::ValveState::LEN]);
        let Some(valve) = pneuflex_pneumatics::ValveState::from_array(&va) else {
            return false;
        };
        if !(s[..2].iter().all(|v| v.is_finite() && *v > 0.0) && s[Self::STATE_LEN - 1].is_finite())
        {
            return false;
        }
        self.gas = pneuflex_muscle::ChamberState {
            pressure_pa: s[0],
            temperature_k: s[1],
        };
        self.valve = valve;
        self.time_s = s[Self::STATE_LEN - 1];
        true
    }
    fn check_invariants(&self, x_m: f64, stroke_m: f64) -> Result<(), String> {
        gas_invariant(
            ("p", "T"),
            self.gas.pressure_pa,
            self.gas.temperature_k,
            self.chamber.supply.supply_pressure_pa,
        )?;
        if !self.admits_stroke(x_m, stroke_m) {
            return Err(format!(
                "muscle length {:.6} m outside (0, {:.6}] m (the braid's fibres straight)",
                self.contracted_length_m() + x_m,
                self.chamber.muscle.braid.fibre_length_m()
            ));
        }
        Ok(())
    }
}
