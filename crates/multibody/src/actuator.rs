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
    /// Sets the pressure behind the valve's supply port, Pa absolute (an emulated board's supply lost, or dumped
    /// to atmosphere to vent the actuator); `false` for a family without one (nothing changed).
    fn set_supply_pa(&mut self, _p: f64) -> bool {
        false
    }
    /// The pressure behind the valve's supply port, Pa absolute (`None` for a family without one).
    fn supply_pa(&self) -> Option<f64> {
        None
    }
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
    fn set_supply_pa(&mut self, p: f64) -> bool {
        (**self).set_supply_pa(p)
    }
    fn supply_pa(&self) -> Option<f64> {
        (**self).supply_pa()
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
    fn set_supply_pa(&mut self, p: f64) -> bool {
        self.actuator.supply.supply_pressure_pa = p;
        true
    }
    fn supply_pa(&self) -> Option<f64> {
        Some(self.actuator.supply.supply_pressure_pa)
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
/// It lives in `pneuflex-muscle` (re-exported here) so that the MuJoCo plugin `pneuflex.muscle` runs it
/// without Rapier, as the cylinder's `PneumaticForceElement` lives in `pneuflex-pneumatics`.
pub use pneuflex_muscle::MuscleForceElement;

impl AxialActuator for MuscleForceElement {
    fn force(&mut self, x: f64, x_dot: f64, dt: f64) -> f64 {
        -self.step_length(self.contracted_length_m() + x, x_dot, dt)
    }
}

impl ActuatorFamily for MuscleForceElement {
    fn family(&self) -> &'static str {
        "muscle"
    }
    fn set_supply_pa(&mut self, p: f64) -> bool {
        self.chamber.supply.supply_pressure_pa = p;
        true
    }
    fn supply_pa(&self) -> Option<f64> {
        Some(self.chamber.supply.supply_pressure_pa)
    }
    fn set_command(&mut self, u: f64) {
        MuscleForceElement::set_command(self, u)
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
        MuscleForceElement::state(self).to_vec()
    }
    fn set_state(&mut self, s: &[f64]) -> bool {
        <&[f64; Self::STATE_LEN]>::try_from(s).is_ok_and(|s| MuscleForceElement::set_state(self, s))
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
