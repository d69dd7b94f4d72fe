//! A mechanism scene as a plant of the one loop: the general engine with every actuator's drive, each
//! actuator's sensors and command, its contact and spring events, its invariants and its drawing, behind
//! the [`Plant`] trait that the simulation host drives for every scene kind.

use pneuflex_control::{Sensors, Signal, Telemetry, ValveCommand};
use pneuflex_multibody::ActuatorFamily;
use pneuflex_multibody::ContactParams;

use super::build::{Built, build};
use super::schema::MechanismScene;
use crate::error::SceneError;
use crate::plants::{EventSpec, Plant, PlantError, Visual, VisualPose};

/// Each actuator's own recorded signals beyond the loop's, after its name and a dot (`left.x_dot`).
const ACTUATOR_SIGNALS: [Signal; 2] = [
    Signal::new(
        "x_dot",
        "m/s",
        "velocity",
        "actuator velocity (stroke rate or joint rate)",
    ),
    Signal::new(
        "force",
        "N",
        "cylinder",
        "force of the actuator on the mechanism along its line, + pushing the anchors apart (a muscle's is -tension)",
    ),
];

/// Whether a family's sensors are the control loop's own `p_a`, `p_b` columns (a cylinder's chambers).
fn loop_pressures(drive: &dyn ActuatorFamily) -> bool {
    drive.sensors() == pneuflex_multibody::actuator::CHAMBER_PRESSURES
}

/// A family's sensors the plant records beside the loop's columns: none for a cylinder (the loop's
/// `p_a`, `p_b` carry them), any other family's own (a muscle's `p_muscle`).
fn family_signals(drive: &dyn ActuatorFamily) -> Vec<Signal> {
    if loop_pressures(drive) {
        return Vec::new();
    }
    drive
        .sensors()
        .iter()
        .map(|s| Signal::new(s.name, s.unit, "pressure", s.description))
        .collect()
}

/// The mechanism of a scene with several actuators, as the loop drives it.
pub struct MechanismPlant {
    scene: MechanismScene,
    built: Built,
    names: Vec<String>,
    signals: &'static [Signal],
    physics_steps_per_tick: u32,
    /// An end stop passed during the last tick's physics steps, reported by the next invariant check.
    overrun: Option<String>,
}

impl MechanismPlant {
    /// The scene's mechanism at its initial state (errors name the scene key that causes them).
    pub fn new(scene: &MechanismScene) -> Result<Self, SceneError> {
        let built = build(scene)?;
        let names: Vec<String> = scene.actuators.iter().map(|a| a.name.clone()).collect();
        let mut signals: Vec<Signal> = Vec::new();
        for (a, drive) in names.iter().zip(&built.drives) {
            let own = family_signals(drive.as_ref());
            signals.extend(ACTUATOR_SIGNALS.iter().chain(&own).map(|s| Signal {
                name: crate::run::interned(format!("{a}.{}", s.name)),
                ..*s
            }));
        }
        Ok(Self {
            scene: scene.clone(),
            built,
            signals: crate::run::interned_signals(signals),
            names,
            physics_steps_per_tick: scene.physics_steps_per_tick,
            overrun: None,
        })
    }

    /// The engine, for a viewer or a test.
    pub fn mechanism(&self) -> &pneuflex_multibody::Mechanism {
        &self.built.mechanism
    }

    /// Actuator `i`'s supply pressure, Pa absolute (`None`: a family without one).
    pub fn supply_pa(&self, i: usize) -> Option<f64> {
        self.built.drives[i].supply_pa()
    }

    /// Sets actuator `i`'s supply pressure, Pa absolute (an emulated board's supply lost, or dumped to vent
    /// the actuator); `false` for a family without one.
    pub fn set_supply_pa(&mut self, i: usize, p: f64) -> bool {
        self.built.drives[i].set_supply_pa(p)
    }

    /// Each actuator's setpoint schedule (force pieces and x_d), in scene order.
    pub fn schedules(&self) -> &[pneuflex_control::SetpointSchedule] {
        &self.built.schedules
    }

    /// The contact or spring an event names (a name is one or the other: [`build`] refuses a name that
    /// is both), and its parameters now.
    fn event_target(&self, name: &str) -> Option<(bool, usize, ContactParams)> {
        let m = &self.built.mechanism;
        if let Ok(i) = m.contact_index(name) {
            return Some((true, i, m.contact_params(i)));
        }
        m.spring_index(name)
            .ok()
            .map(|i| (false, i, m.spring_params(i)))
    }
}

impl Plant for MechanismPlant {
    fn sense(&self) -> Sensors {
        self.sense_actuator(0)
    }

    fn actuate(&mut self, command: ValveCommand, telemetry: &Telemetry) {
        self.actuate_actuator(0, command, telemetry);
    }

    fn actuator_names(&self) -> &[String] {
        &self.names
    }

    fn sense_actuator(&self, i: usize) -> Sensors {
        let b = &self.built;
        let (x, x_dot) = match &b.positions[i] {
            Some(joint) => b.mechanism.joint_position(joint).expect("checked at build"),
            None => {
                let s = b.mechanism.actuator_state(i);
                (s.x_m, s.x_dot_m_s)
            }
        };
        let drive = &b.drives[i];
        // A family whose sensors are a cylinder's two chambers fills the loop's p_a, p_b; any other's
        // sensors are the plant's own columns (`record`), and the loop's stay empty.
        let (p_a, p_b) = if loop_pressures(drive.as_ref()) {
            let mut p = [0.0; 2];
            drive.read_sensors(&mut p);
            (p[0], p[1])
        } else {
            (f64::NAN, f64::NAN)
        };
        let load_cell = b.mechanism.actuator_force(i);
        // A muscle reports its contraction L0 - L (stroke - x) and its tension: a larger command, a
        // larger sensed position and force, as for a cylinder.
        let (x, x_dot, load_cell) = match (&b.positions[i], drive.pulls()) {
            (None, true) => (b.mechanism.actuator_stroke(i) - x, -x_dot, -load_cell),
            (_, true) => (x, x_dot, -load_cell),
            (_, false) => (x, x_dot, load_cell),
        };
        Sensors {
            t: b.mechanism.time(),
            x,
            x_dot,
            f_e: match b.sensors[i] {
                Some(ci) => b.mechanism.contact(ci).force_n,
                None => load_cell,
            },
            p_a,
            p_b,
        }
    }

    fn actuate_actuator(&mut self, i: usize, command: ValveCommand, _telemetry: &Telemetry) {
        self.built.drives[i].set_command(command.u);
    }

    fn advance(&mut self, _dt: f64) {
        // The drives step in place: no allocation in the loop.
        for _ in 0..self.physics_steps_per_tick {
            self.built.mechanism.step(&mut self.built.drives);
            if self.overrun.is_none()
                && let Err(why) = self.built.mechanism.check_families(&self.built.drives)
            {
                self.overrun = Some(why);
            }
        }
    }

    fn apply(&mut self, event: &EventSpec) -> Result<(), PlantError> {
        let EventSpec::Stiffness {
            stiffness_n_per_m,
            material: Some(name),
            damping_n_s_per_m,
            ..
        } = event
        else {
            return Err(PlantError::unsupported(format!(
                "a mechanism's events change a contact's or a spring's stiffness; `{}` is not one",
                event.kind()
            )));
        };
        let (contact, i, old) = self
            .event_target(name)
            .ok_or_else(|| PlantError::from(format!("no contact or spring named '{name}'")))?;
        let params = ContactParams {
            stiffness_n_per_m: *stiffness_n_per_m,
            damping_n_s_per_m: damping_n_s_per_m.unwrap_or(old.damping_n_s_per_m),
        };
        let m = &mut self.built.mechanism;
        if contact {
            m.set_contact(i, params)
        } else {
            m.set_spring(i, params)
        }
        .map_err(|e| PlantError::from(e.to_string()))
    }

    fn reset(&mut self) {
        // The engine has no reset: build it again from the scene (built once already, so it builds).
        if let Ok(b) = build(&self.scene) {
            self.built = b;
        }
        self.overrun = None;
    }

    /// Every actuator's chambers within (0, 2 × supply], temperatures positive, its piston within its
    /// stroke — the one-actuator plants' invariants, per actuator and named — and no end stop passed.
    fn check_invariants(&self) -> Result<(), PlantError> {
        if let Some(why) = &self.overrun {
            return Err(PlantError::invariant(why.clone()));
        }
        let b = &self.built;
        for (i, name) in self.names.iter().enumerate() {
            let stroke = b.mechanism.actuator_stroke(i);
            let x = b.mechanism.actuator_state(i).x_m;
            b.drives[i]
                .check_invariants(x, stroke)
                .map_err(|v| PlantError::invariant(format!("{name}: {v}")))?;
        }
        Ok(())
    }

    fn signals(&self) -> &'static [Signal] {
        self.signals
    }

    fn record(&self, out: &mut [f64]) {
        let mut at = 0;
        for (i, drive) in self.built.drives.iter().enumerate() {
            out[at] = self.sense_actuator(i).x_dot;
            out[at + 1] = self.built.mechanism.actuator_force(i);
            at += ACTUATOR_SIGNALS.len();
            if !loop_pressures(drive.as_ref()) {
                let n = drive.sensors().len();
                drive.read_sensors(&mut out[at..at + n]);
                at += n;
            }
        }
    }

    fn visuals(&self) -> Vec<Visual> {
        super::draw::visuals(&self.built.mechanism)
    }

    fn visual_poses(&self, pose: &mut dyn FnMut(usize, VisualPose)) {
        super::draw::visual_poses(&self.built.mechanism, pose)
    }
}

/// The scene's events as the one loop applies them: each a stiffness change of the contact or spring it
/// names ([`MechanismPlant::apply`]).
pub fn loop_events(scene: &MechanismScene) -> Vec<EventSpec> {
    scene
        .events
        .iter()
        .map(|e| EventSpec::Stiffness {
            t_s: e.t_s,
            stiffness_n_per_m: e.stiffness_n_per_m,
            material: e.contact.clone().or_else(|| e.spring.clone()),
            damping_n_s_per_m: e.damping_n_s_per_m,
        })
        .collect()
}
