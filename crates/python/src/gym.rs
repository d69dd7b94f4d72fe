//! The force-control task of `pneuflex.envs` (Gymnasium), stepped in Rust: a batch of episodes of a
//! scene — a 1-DOF pneumatic or multibody plant, or a mechanism of several actuators — each its own plant
//! (the scene crate's plant, the one `pneuflex.run` simulates), environment, events and domain-randomised
//! parameters.
//!
//! One `step` advances every episode by one action (a valve command per actuator for a tick, the chambers'
//! pressure set-points behind pressure regulators for a tick, or a retune of each actuator's impedance
//! controller and its ticks), in parallel over the machine's cores with the GIL released (a batch of one
//! never leaves the calling thread).
//! `ForceControl` is a batch of one (`step_single`), `ForceControlVector` the `gymnasium.vector.VectorEnv`
//! over a batch of many: one implementation of the task for both.

use std::path::{Path, PathBuf};
use std::sync::Mutex;

use numpy::{IntoPyArray, PyArray1, PyArray2, PyArrayDyn, PyArrayMethods, PyReadonlyArrayDyn};
use pneuflex_control::{
    Controller, ImpedanceController, ImpedanceParams, Sensors, SetpointSchedule, Telemetry,
    ValveCommand,
};
use pneuflex_pneumatics::{PressureRegulator, ValveKind};
use pneuflex_scene::mechanism::plant::loop_events;
use pneuflex_scene::mechanism::{MechanismPlant, MechanismScene};
use pneuflex_scene::plants::{LinearSpring, MultibodyPlant, OneDofPneumatic, Plant};
use pneuflex_scene::schema::{ControllerKind, DivergenceSpec, EventSpec, PlantSpec};
use pneuflex_scene::{Scene, SceneError};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::PyDict;
use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};

use crate::errors;

/// Observation scales: f_e and f_ref in 10 N, x - x_e in 10 mm, velocity in 0.1 m/s, pressures in bar.
pub const SCALES: [f64; OBS] = [10.0, 10.0, 0.01, 0.1, 1e5, 1e5];
/// Length of an actuator's observation block: f_e, f_ref, x - x_e, x_dot, p_a, p_b.
const OBS: usize = 6;
/// The pressure regulators' time constant unless given, s: a fast proportional pressure regulator.
pub const DEFAULT_REGULATOR_TIME_CONSTANT_S: f64 = 0.01;

/// What domain randomisation draws from at each reset: every range is log-uniform but the switch time's.
#[derive(Clone, Copy, Debug)]
struct Ranges {
    /// The stiffness before and after the change, each log-uniform, N/m (the paper's 350-2800 N/m).
    stiffness_n_per_m: (f64, f64),
    /// The time of the stiffness change, uniform, s.
    t_change_s: (f64, f64),
    /// The moving mass as a multiple of the sheet's, log-uniform.
    mass_scale: (f64, f64),
    /// The seal friction's Coulomb and break-away forces as a multiple of the sheet's, log-uniform.
    friction_scale: (f64, f64),
    /// An on/off valve's switching delay as a multiple of the sheet's, log-uniform (kept below 0.9 of the
    /// PWM period).
    delay_scale: (f64, f64),
    /// A mechanism's contacts and springs: every stiffness before its events, and every event's, as a
    /// multiple of the scene's, log-uniform (a softer or stiffer object than the scene's).
    compliance_scale: (f64, f64),
}

const RANGES: Ranges = Ranges {
    stiffness_n_per_m: (350.0, 2800.0),
    t_change_s: (4.0, 8.0),
    mass_scale: (0.5, 2.0),
    friction_scale: (0.5, 2.0),
    delay_scale: (0.5, 2.0),
    compliance_scale: (0.5, 2.0),
};

fn log_uniform(rng: &mut StdRng, (lo, hi): (f64, f64)) -> f64 {
    (lo.ln() + rng.random::<f64>() * (hi.ln() - lo.ln())).exp()
}

/// One episode's physical parameters. On a mechanism `k_before` and `k_after` are the scales of its
/// contacts' and springs' stiffness before and after their events (1: the scene's).
#[derive(Clone, Copy, Debug, PartialEq)]
struct Draw {
    k_before: f64,
    k_after: f64,
    t_change_s: f64,
    mass_scale: f64,
    friction_scale: f64,
    delay_scale: f64,
}

/// What an action is, per actuator.
#[derive(Clone, Debug)]
enum Action {
    /// The valve command u in [-1, 1], held over one control tick.
    Valve,
    /// The set-points (p_a, p_b) of a pressure regulator in front of each chamber (in place of the valve),
    /// Pa absolute in [atmosphere, supply], held over one control tick.
    Pressure { regulator: PressureRegulator },
    /// Adjustments (a_m, a_b) in [-1, 1]^2 of the scene's impedance controller, which then runs each
    /// tick: m_d = m_d0 4^a_m, b_d = b_d0 4^a_b (k_d kept), held over `ticks` control ticks.
    Impedance {
        /// The scene's impedance run's controller of each actuator, its m_d0, b_d0, k_d0.
        controllers: Vec<ImpedanceController>,
        ticks: u32,
    },
}

impl Action {
    /// Values in one actuator's action.
    fn width(&self) -> usize {
        match self {
            Action::Valve => 1,
            Action::Impedance { .. } | Action::Pressure { .. } => 2,
        }
    }

    /// Control ticks one step takes.
    fn ticks(&self) -> u32 {
        match self {
            Action::Impedance { ticks, .. } => *ticks,
            Action::Valve | Action::Pressure { .. } => 1,
        }
    }
}

/// The scene an environment runs.
enum Rig {
    /// A scene of one `[plant]`, with its 1-DOF pneumatic plant at its initial state (each episode is
    /// built from its model with the draw's mass and friction), or None for a multibody plant, whose
    /// episodes reset their own.
    Single {
        scene: Box<Scene>,
        one_dof: Option<Box<OneDofPneumatic>>,
    },
    /// A scene of several actuators (`[[actuators]]`).
    Mechanism {
        scene: Box<MechanismScene>,
        /// Every contact's and spring's name and stiffness: what a draw scales from the start.
        compliances: Vec<(String, f64)>,
    },
}

/// The scene's values: what every episode starts from.
struct Task {
    action: Action,
    rig: Rig,
    /// Each actuator's reference.
    setpoints: Vec<SetpointSchedule>,
    /// The scene's events in time order.
    events: Vec<EventSpec>,
    /// The scene's own parameters (no randomisation).
    own: Draw,
    dt: f64,
    duration: f64,
    /// Each actuator's x_e, where its observation's position is measured from: the environment's surface
    /// (one plant), or its `x_d_m` (a mechanism: where the scene's impedance law rests, the gripper's pad
    /// touching the object).
    x_e: Vec<f64>,
    /// The 1-DOF plant's stroke: an episode ends at either end (a multibody rig's end stops hold the
    /// flange, as in the scene's runs: its episode ends where a run diverges).
    stroke: f64,
    /// Each actuator's position and force limits (the scene's `[divergence]`): past them, or past a
    /// plant's invariant, a multibody or mechanism episode ends, as a run stops.
    divergence: DivergenceSpec,
    /// Gymnasium's `max_episode_steps`: an episode is truncated at that many steps (None: the scene's
    /// duration only).
    max_steps: Option<u64>,
    /// Each action value's range, in the action's order: [-1, 1] for the valve and the impedance actions
    /// (finite values beyond are clipped), [atmosphere, supply] Pa for the pressure set-points (refused
    /// beyond).
    bounds: Vec<(f64, f64)>,
}

/// The impedance run a `"impedance"` action retunes: the scene's first impedance run, not frozen.
fn impedance_run(runs: &[pneuflex_scene::schema::RunSpec]) -> Option<usize> {
    runs.iter()
        .position(|r| r.controller == ControllerKind::Impedance && r.frozen.is_none())
}

const NO_IMPEDANCE_RUN: &str =
    "no impedance run: the impedance action retunes the scene's impedance controller";

fn unknown_action(file: &Path, other: &str) -> SceneError {
    SceneError::Plant {
        file: file.to_path_buf(),
        message: format!("action = {other:?}: expected \"valve\", \"pressure\" or \"impedance\""),
    }
}

impl Task {
    /// The task of the scene at `path`, one `[plant]` or `[[actuators]]`.
    fn load(
        path: &Path,
        action: &str,
        decision_ticks: u32,
        regulator: PressureRegulator,
    ) -> Result<Self, SceneError> {
        // An unreadable file is the loader's to report, with its own message.
        let text = std::fs::read_to_string(path).unwrap_or_default();
        let mut task = if MechanismScene::is_mechanism(&text) {
            Self::load_mechanism(path, action, decision_ticks)?
        } else {
            Self::load_single(path, action, decision_ticks, regulator)?
        };
        task.bounds = task.action_bounds()?;
        Ok(task)
    }

    /// Each action value's range ([`Task::bounds`]); under the pressure action the regulators are fitted to
    /// a plant of the scene, which says the range (or refuses them).
    fn action_bounds(&self) -> Result<Vec<(f64, f64)>, SceneError> {
        let Action::Pressure { regulator } = self.action else {
            return Ok(vec![(-1.0, 1.0); self.width()]);
        };
        let mut plant = self.build()?;
        let mut bounds = Vec::with_capacity(self.width());
        for i in 0..self.actuators() {
            let range = plant.set_regulators(i, Some(regulator)).map_err(|e| {
                self.invalid(
                    "plant.actuator",
                    format!("action = \"pressure\": {}", e.message),
                )
            })?;
            bounds.extend([range, range]);
        }
        Ok(bounds)
    }

    fn load_single(
        path: &Path,
        action: &str,
        decision_ticks: u32,
        regulator: PressureRegulator,
    ) -> Result<Self, SceneError> {
        let scene = Scene::load(path)?;
        let action = match action {
            "valve" => Action::Valve,
            "pressure" => Action::Pressure { regulator },
            "impedance" => {
                let run = impedance_run(&scene.runs)
                    .map(|r| &scene.runs[r])
                    .ok_or_else(|| scene.invalid("runs", NO_IMPEDANCE_RUN.into()))?;
                let controller = ImpedanceController::new(run.impedance, run.inner)
                    .map_err(|e| scene.invalid("runs", e.to_string()))?;
                Action::Impedance {
                    controllers: vec![controller],
                    ticks: decision_ticks,
                }
            }
            other => return Err(unknown_action(&scene.source, other)),
        };
        let env = LinearSpring {
            stiffness_n_per_m: scene.environment.stiffness_n_per_m,
            x_e_m: scene.environment.x_e_m,
        };
        let one_dof = match scene.plant {
            PlantSpec::Pneumatic { .. } => {
                Some(Box::new(OneDofPneumatic::from_scene(&scene, env)?))
            }
            PlantSpec::Multibody(_) => None,
            _ => {
                return Err(scene.invalid(
                    "plant.kind",
                    format!(
                        "is {:?}; the force-control environment needs a pneumatic or multibody plant (a valve to command)",
                        scene.plant.kind()
                    ),
                ));
            }
        };
        let mut events = scene.events.clone();
        events.sort_by(|a, b| a.t_s().total_cmp(&b.t_s()));
        let change = events.iter().find_map(|e| match *e {
            EventSpec::Stiffness {
                t_s,
                stiffness_n_per_m,
                ..
            } => Some((t_s, stiffness_n_per_m)),
            _ => None,
        });
        let k0 = env.stiffness_n_per_m;
        let (t_change_s, k_after) = change.unwrap_or((f64::INFINITY, k0));
        let mut task = Self {
            action,
            setpoints: vec![scene.setpoints()?],
            events,
            own: Draw {
                k_before: k0,
                k_after,
                t_change_s,
                mass_scale: 1.0,
                friction_scale: 1.0,
                delay_scale: 1.0,
            },
            dt: scene.dt_s,
            duration: scene.duration_s,
            x_e: vec![env.x_e_m],
            stroke: f64::INFINITY,
            divergence: scene.divergence,
            max_steps: None,
            bounds: Vec::new(),
            rig: Rig::Single {
                scene: Box::new(scene),
                one_dof,
            },
        };
        let plant = task.build()?;
        task.stroke = plant
            .actuator_geometry()
            .map_or(f64::INFINITY, |g| g.stroke_m);
        task.check_events()?;
        Ok(task)
    }

    fn load_mechanism(path: &Path, action: &str, decision_ticks: u32) -> Result<Self, SceneError> {
        let scene = MechanismScene::load(path)?;
        let action = match action {
            "valve" => Action::Valve,
            "pressure" => {
                return Err(scene.invalid(
                    "actuators",
                    "action = \"pressure\" (pressure regulators in front of the chambers) runs on a scene of \
                     one [plant], pneumatic or multibody; a scene of several actuators takes \"valve\" or \
                     \"impedance\" (not yet the pressure action)"
                        .into(),
                ));
            }
            "impedance" => {
                let r = impedance_run(&scene.runs)
                    .ok_or_else(|| scene.invalid("runs", NO_IMPEDANCE_RUN.into()))?;
                // Each actuator's own gains where it gives them, as the scene's run drives it.
                let controllers = (0..scene.actuators.len())
                    .map(|a| {
                        let spec = scene.actuator_run(r, a);
                        ImpedanceController::new(spec.impedance, spec.inner).map_err(|e| {
                            scene.invalid(&format!("actuators[{a}].gains"), e.to_string())
                        })
                    })
                    .collect::<Result<_, _>>()?;
                Action::Impedance {
                    controllers,
                    ticks: decision_ticks,
                }
            }
            other => return Err(unknown_action(&scene.source, other)),
        };
        let plant = MechanismPlant::new(&scene)?;
        // The observation is each actuator's two chambers: a family without them (a muscle) is refused
        // here rather than observed as NaN.
        for (i, a) in scene.actuators.iter().enumerate() {
            let s = plant.sense_actuator(i);
            if !(s.p_a.is_finite() && s.p_b.is_finite()) {
                return Err(scene.invalid(
                    &format!("actuators[{i}].sheet"),
                    format!(
                        "actuator '{}' has no chamber pressures p_a, p_b (a muscle?): the force-control \
                         environment observes each actuator's two chambers",
                        a.name
                    ),
                ));
            }
        }
        let mut events = loop_events(&scene);
        events.sort_by(|a, b| a.t_s().total_cmp(&b.t_s()));
        let compliances = scene
            .contacts
            .iter()
            .map(|c| (c.name.clone(), c.stiffness_n_per_m))
            .chain(
                scene
                    .springs
                    .iter()
                    .map(|s| (s.name.clone(), s.stiffness_n_per_m)),
            )
            .collect();
        let task = Self {
            action,
            setpoints: plant.schedules().to_vec(),
            events,
            own: Draw {
                k_before: 1.0,
                k_after: 1.0,
                t_change_s: f64::NAN,
                mass_scale: 1.0,
                friction_scale: 1.0,
                delay_scale: 1.0,
            },
            dt: scene.dt_s,
            duration: scene.duration_s,
            x_e: scene.actuators.iter().map(|a| a.x_d_m).collect(),
            stroke: f64::INFINITY,
            divergence: scene.divergence,
            max_steps: None,
            bounds: Vec::new(),
            rig: Rig::Mechanism {
                scene: Box::new(scene),
                compliances,
            },
        };
        task.check_events()?;
        Ok(task)
    }

    /// Every event must be one this plant takes (validation says so too; here it is the environment's).
    fn check_events(&self) -> Result<(), SceneError> {
        for (i, ev) in self.events.iter().enumerate() {
            self.build()?
                .apply(ev)
                .map_err(|e| self.invalid(&format!("events[{i}]"), e.to_string()))?;
        }
        Ok(())
    }

    fn invalid(&self, key: &str, message: String) -> SceneError {
        match &self.rig {
            Rig::Single { scene, .. } => scene.invalid(key, message),
            Rig::Mechanism { scene, .. } => scene.invalid(key, message),
        }
    }

    /// Actuators each episode drives.
    fn actuators(&self) -> usize {
        self.setpoints.len()
    }

    /// Values in one episode's action: the actuator's action for each actuator, actuator by actuator.
    fn width(&self) -> usize {
        self.action.width() * self.actuators()
    }

    /// Values in one episode's observation: each actuator's block, actuator by actuator.
    fn obs_len(&self) -> usize {
        OBS * self.actuators()
    }

    /// A new plant of the scene at its initial state.
    fn build(&self) -> Result<Box<dyn Plant + Send>, SceneError> {
        Ok(match &self.rig {
            Rig::Single {
                one_dof: Some(p), ..
            } => Box::new((**p).clone()),
            Rig::Single {
                scene,
                one_dof: None,
            } => Box::new(MultibodyPlant::from_scene(scene)?),
            Rig::Mechanism { scene, .. } => Box::new(MechanismPlant::new(scene)?),
        })
    }

    /// The draw of a new episode (the scene's own values without randomisation; the multibody plant's
    /// mass and friction are its URDF's and its sheet's, not drawn).
    fn draw(&self, rng: &mut StdRng, randomize: bool) -> Draw {
        if !randomize {
            return self.own;
        }
        let r = RANGES;
        let one_dof = match &self.rig {
            Rig::Single { one_dof, .. } => one_dof.is_some(),
            Rig::Mechanism { .. } => {
                return Draw {
                    k_before: log_uniform(rng, r.compliance_scale),
                    k_after: log_uniform(rng, r.compliance_scale),
                    ..self.own
                };
            }
        };
        Draw {
            k_before: log_uniform(rng, r.stiffness_n_per_m),
            k_after: log_uniform(rng, r.stiffness_n_per_m),
            t_change_s: r.t_change_s.0 + rng.random::<f64>() * (r.t_change_s.1 - r.t_change_s.0),
            mass_scale: if one_dof {
                log_uniform(rng, r.mass_scale)
            } else {
                1.0
            },
            friction_scale: if one_dof {
                log_uniform(rng, r.friction_scale)
            } else {
                1.0
            },
            delay_scale: if one_dof {
                log_uniform(rng, r.delay_scale)
            } else {
                1.0
            },
        }
    }

    /// The scene's events for the draw: one plant's first stiffness change (or one added) at the draw's
    /// time and value; a mechanism's every stiffness scaled by the draw's `k_after`.
    fn events(&self, draw: &Draw) -> Vec<EventSpec> {
        let mut events = self.events.clone();
        if let Rig::Mechanism { .. } = self.rig {
            for e in &mut events {
                if let EventSpec::Stiffness {
                    stiffness_n_per_m, ..
                } = e
                {
                    *stiffness_n_per_m *= draw.k_after;
                }
            }
            return events;
        }
        let first = events
            .iter()
            .position(|e| matches!(e, EventSpec::Stiffness { .. }));
        match first {
            Some(i) => {
                if let EventSpec::Stiffness {
                    t_s,
                    stiffness_n_per_m,
                    ..
                } = &mut events[i]
                {
                    (*t_s, *stiffness_n_per_m) = (draw.t_change_s, draw.k_after);
                }
            }
            None if draw.t_change_s.is_finite() => events.push(EventSpec::Stiffness {
                t_s: draw.t_change_s,
                stiffness_n_per_m: draw.k_after,
                material: None,
                damping_n_s_per_m: None,
            }),
            None => {}
        }
        events.sort_by(|a, b| a.t_s().total_cmp(&b.t_s()));
        events
    }
}

/// An episode's plant: the 1-DOF pneumatic plant as itself (a batch advances several of them together,
/// [`OneDofPneumatic::advance_together`]), any other behind the plant trait.
enum EpisodePlant {
    OneDof(Box<OneDofPneumatic>),
    Other(Box<dyn Plant + Send>),
}

impl EpisodePlant {
    fn get(&self) -> &dyn Plant {
        match self {
            Self::OneDof(p) => &**p,
            Self::Other(p) => &**p,
        }
    }

    fn get_mut(&mut self) -> &mut dyn Plant {
        match self {
            Self::OneDof(p) => &mut **p,
            Self::Other(p) => &mut **p,
        }
    }
}

/// One running episode.
struct Episode {
    /// Behind a lock only to be shared with Python (a mechanism's drives are `Send`, not `Sync`); the
    /// batch reaches it through `&mut`, which takes no lock.
    plant: Mutex<EpisodePlant>,
    /// The impedance action's controller of each actuator, at the scene's parameters at each restart
    /// (empty under the valve action).
    controllers: Vec<ImpedanceController>,
    /// Each actuator's valve command of the tick (scratch).
    commands: Vec<f64>,
    events: Vec<EventSpec>,
    /// The first event not yet applied.
    next: usize,
    t: f64,
    draw: Draw,
    /// The episode's stream: its k-th episode since the last reset draws from `restart_rng(stream, k)`.
    stream: u64,
    /// Episodes started on this stream since the last reset (the first is 0).
    k: u64,
    /// Whether this episode's draw was randomised.
    randomized: bool,
    /// The actions taken since this episode started, flat: with (stream, k, randomized) they are its whole
    /// state (a pickled batch replays them; the plant is deterministic).
    actions: Vec<f64>,
    /// Steps taken since this episode started.
    steps: u64,
    /// Terminated or truncated at the last step: the next step resets it (Gymnasium's next-step autoreset).
    ended: bool,
    /// Why a multibody or mechanism episode terminated (an actuator's limit, an invariant), for the message.
    why: Option<String>,
    /// Each actuator's sensors and f_ref as the last tick read them for its reward, which the observation
    /// after it reuses (`seen_fresh`: nothing moved since).
    seen: Vec<(Sensors, f64)>,
    seen_fresh: bool,
}

impl Episode {
    fn new(task: &Task, stream: u64) -> Result<Self, SceneError> {
        let mut e = Self {
            plant: Mutex::new(EpisodePlant::Other(task.build()?)),
            controllers: Vec::new(),
            commands: vec![0.0; task.actuators()],
            events: Vec::new(),
            next: 0,
            t: 0.0,
            draw: task.own,
            stream,
            k: 0,
            randomized: false,
            actions: Vec::new(),
            steps: 0,
            ended: false,
            why: None,
            seen: Vec::with_capacity(task.actuators()),
            seen_fresh: false,
        };
        e.restart(task, false);
        Ok(e)
    }

    /// The plant, through `&mut` (no lock taken).
    fn plant(&mut self) -> &mut dyn Plant {
        self.held_plant().get_mut()
    }

    fn held_plant(&mut self) -> &mut EpisodePlant {
        self.plant.get_mut().unwrap_or_else(|e| e.into_inner())
    }

    /// Starts the next episode of the stream (an autoreset) with a new draw.
    fn next_episode(&mut self, task: &Task, randomize: bool) {
        self.k += 1;
        self.restart(task, randomize);
    }

    /// Starts episode `k` of the stream afresh with its draw (the scene's own values unless `randomize`).
    fn restart(&mut self, task: &Task, randomize: bool) {
        let draw = task.draw(&mut restart_rng(self.stream, self.k), randomize);
        self.randomized = randomize;
        self.actions.clear();
        self.steps = 0;
        match &task.rig {
            Rig::Single {
                one_dof: Some(p), ..
            } => {
                let mut model = *p.model();
                model.mechanics.moving_mass_kg *= draw.mass_scale;
                model.mechanics.friction = model.mechanics.friction.scaled(draw.friction_scale);
                if let ValveKind::OnOffPwm {
                    pwm_frequency_hz,
                    switching_delay_s,
                } = &mut model.actuator.valve.kind
                {
                    *switching_delay_s =
                        (*switching_delay_s * draw.delay_scale).min(0.9 / *pwm_frequency_hz);
                }
                let env = LinearSpring {
                    stiffness_n_per_m: draw.k_before,
                    x_e_m: task.x_e[0],
                };
                // The chambers start at the static balance of this episode's mass (OneDofPneumatic::new).
                *self.held_plant() = EpisodePlant::OneDof(Box::new(OneDofPneumatic::new(
                    model,
                    p.state().x,
                    env,
                    p.substeps(),
                )));
            }
            Rig::Single { one_dof: None, .. } => {
                let plant = self.plant();
                plant.reset();
                // The material facing the flange at the draw's stiffness (checked at load: it takes it).
                let _ = plant.apply(&EventSpec::Stiffness {
                    t_s: 0.0,
                    stiffness_n_per_m: draw.k_before,
                    material: None,
                    damping_n_s_per_m: None,
                });
            }
            Rig::Mechanism { compliances, .. } => {
                let plant = self.plant();
                plant.reset();
                // Every contact and spring at the draw's multiple of its stiffness (the scene's when 1:
                // then left as built). Their names are the scene's, so the plant takes them.
                if draw.k_before != 1.0 {
                    for (name, k) in compliances {
                        let _ = plant.apply(&EventSpec::Stiffness {
                            t_s: 0.0,
                            stiffness_n_per_m: k * draw.k_before,
                            material: Some(name.clone()),
                            damping_n_s_per_m: None,
                        });
                    }
                }
            }
        }
        match &task.action {
            Action::Impedance { controllers, .. } => self.controllers.clone_from(controllers),
            Action::Valve => self.controllers.clear(),
            Action::Pressure { regulator } => {
                self.controllers.clear();
                // Fitted when the task was loaded: every plant of the scene takes them.
                let _ = self.plant().set_regulators(0, Some(*regulator));
            }
        }
        self.events = task.events(&draw);
        self.draw = draw;
        self.next = 0;
        self.t = 0.0;
        self.ended = false;
        self.why = None;
        self.seen_fresh = false;
        self.apply_due();
    }

    /// Applies the events due at the current time, as the scene loop does before it senses.
    fn apply_due(&mut self) {
        let plant = self
            .plant
            .get_mut()
            .unwrap_or_else(|e| e.into_inner())
            .get_mut();
        while let Some(ev) = self.events.get(self.next) {
            if ev.t_s() > self.t + 1e-9 {
                break;
            }
            // Checked when the task was loaded: the plant takes each of the scene's events.
            let _ = plant.apply(ev);
            self.next += 1;
        }
    }

    /// The observation: each actuator's block (f_e, f_ref, x - x_e, x_dot, p_a, p_b, scaled).
    fn observe(&mut self, task: &Task, out: &mut [f32]) {
        let t = self.t;
        let fresh = self.seen_fresh && self.seen.len() == task.actuators();
        let plant = self
            .plant
            .get_mut()
            .unwrap_or_else(|e| e.into_inner())
            .get();
        for (i, block) in out.chunks_mut(OBS).enumerate() {
            // What the tick's reward read (the same plant state and time), else read now.
            let (s, f_ref) = if fresh {
                self.seen[i]
            } else {
                (plant.sense_actuator(i), task.setpoints[i].at(t).f_ref)
            };
            let raw = [s.f_e, f_ref, s.x - task.x_e[i], s.x_dot, s.p_a, s.p_b];
            for ((o, r), k) in block.iter_mut().zip(raw).zip(SCALES) {
                *o = (r / k) as f32;
            }
        }
    }

    /// One action: a control tick under a valve command per actuator, or a retune of each actuator's
    /// impedance controller and its ticks; the rewards summed over the ticks.
    fn step(&mut self, task: &Task, action: &[f64]) -> Outcome {
        self.begin_step(action);
        let out = self.act(task, action);
        self.end_step(task, out)
    }

    /// The step's action kept (the episode's replayable state) and counted.
    fn begin_step(&mut self, action: &[f64]) {
        self.actions.extend_from_slice(action);
        self.steps += 1;
    }

    /// The step's outcome, truncated at Gymnasium's max_episode_steps.
    fn end_step(&self, task: &Task, out: Outcome) -> Outcome {
        // Truncated at that many steps (unless the episode ended anyway).
        match task.max_steps {
            Some(m) if self.steps >= m && !out.terminated => Outcome {
                truncated: true,
                ..out
            },
            _ => out,
        }
    }

    fn act(&mut self, task: &Task, action: &[f64]) -> Outcome {
        let (scene_controllers, ticks) = match &task.action {
            Action::Impedance { controllers, ticks } => (controllers, ticks),
            Action::Valve => {
                self.actuate_valves(action);
                return self.tick(task);
            }
            Action::Pressure { .. } => {
                // The set-points (p_a, p_b) per actuator, within [atmosphere, supply] (checked by the step).
                let plant = self.plant();
                for (i, p) in action.chunks_exact(2).enumerate() {
                    plant.actuate_pressures(i, p[0], p[1]);
                }
                return self.tick(task);
            }
        };
        let mut commands = std::mem::take(&mut self.commands);
        for ((c, c0), a) in self
            .controllers
            .iter_mut()
            .zip(scene_controllers)
            .zip(action.chunks_exact(2))
        {
            let p0 = c0.filter().params();
            let retuned = ImpedanceParams {
                m_d_kg: p0.m_d_kg * 4f64.powf(clamp(a[0])),
                b_d_ns_per_m: p0.b_d_ns_per_m * 4f64.powf(clamp(a[1])),
                k_d_n_per_m: p0.k_d_n_per_m,
            };
            // Positive and finite by construction: the scene's parameters were validated.
            let _ = c.set_impedance(retuned);
        }
        let mut out = Outcome::default();
        for _ in 0..*ticks {
            let t = self.t;
            let plant = self
                .plant
                .get_mut()
                .unwrap_or_else(|e| e.into_inner())
                .get();
            for (i, (c, u)) in self.controllers.iter_mut().zip(&mut commands).enumerate() {
                let s = Sensors {
                    t,
                    ..plant.sense_actuator(i)
                };
                *u = c.update(&s, &task.setpoints[i].at(t), task.dt).u;
            }
            let plant = self.plant();
            for (i, &u) in commands.iter().enumerate() {
                plant.actuate_actuator(i, ValveCommand { u: clamp(u) }, &Telemetry::default());
            }
            let tick = self.tick(task);
            out.reward += tick.reward;
            (out.terminated, out.truncated) = (tick.terminated, tick.truncated);
            if tick.terminated || tick.truncated {
                break;
            }
        }
        self.commands = commands;
        out
    }

    /// A valve command per actuator (finite, clipped to [-1, 1]).
    fn actuate_valves(&mut self, action: &[f64]) {
        let plant = self.plant();
        for (i, &u) in action.iter().enumerate() {
            plant.actuate_actuator(i, ValveCommand { u: clamp(u) }, &Telemetry::default());
        }
    }

    /// One control tick under the commands the plant was given. The reward is the mean of the actuators'
    /// [`tick_reward`]s (one actuator: its own).
    fn tick(&mut self, task: &Task) -> Outcome {
        self.plant().advance(task.dt);
        self.ticked(task)
    }

    /// The tick after the plant advanced: the clock, the events due, the reward and the ends.
    fn ticked(&mut self, task: &Task) -> Outcome {
        self.t += task.dt;
        self.apply_due();
        let t = self.t;
        let plant = self
            .plant
            .get_mut()
            .unwrap_or_else(|e| e.into_inner())
            .get();
        let mut reward = 0.0;
        let mut terminated = false;
        let one_dof = matches!(
            task.rig,
            Rig::Single {
                one_dof: Some(_),
                ..
            }
        );
        self.seen.clear();
        for i in 0..task.actuators() {
            let s = plant.sense_actuator(i);
            let f_ref = task.setpoints[i].at(t).f_ref;
            self.seen.push((s, f_ref));
            reward += tick_reward(f_ref, s.f_e);
            if one_dof {
                terminated |= s.x <= 0.0 || s.x >= task.stroke || !s.x.is_finite();
            } else if self.why.is_none()
                && let Some(why) = task.divergence.exceeded(t, s.x, s.f_e, 0.0)
            {
                // The scene's limits on each actuator's x and f_e, as a run's (no reference position
                // here: x_r is given as 0).
                self.why = Some(match plant.actuator_names().get(i) {
                    Some(name) => format!("{name}: {why}"),
                    None => why,
                });
            }
        }
        if !one_dof
            && self.why.is_none()
            && let Err(v) = plant.check_invariants()
        {
            self.why = Some(format!("{v} at t = {t:.4} s"));
        }
        terminated |= self.why.is_some();
        self.seen_fresh = true;
        let reward = reward / task.actuators() as f64;
        let truncated = self.t >= task.duration - 0.5 * task.dt;
        Outcome {
            reward,
            terminated,
            truncated: truncated && !terminated,
        }
    }
}

/// A finite command clipped to [-1, 1]; anything else 0 (the step refuses it first).
fn clamp(a: f64) -> f64 {
    if a.is_finite() {
        a.clamp(-1.0, 1.0)
    } else {
        0.0
    }
}

/// What one step of the batch returns for one episode.
#[derive(Clone, Copy, Default)]
struct Outcome {
    reward: f64,
    terminated: bool,
    truncated: bool,
}

/// A batch of force-control episodes of a scene (the Rust side of `pneuflex.envs`).
#[pyclass(name = "ForceControlBatch", module = "pneuflex")]
pub struct PyForceControlBatch {
    /// The constructor's arguments (a pickle rebuilds the batch from them, then replays its state).
    args: Args,
    task: Task,
    episodes: Vec<Episode>,
    randomize: bool,
    /// Whether an ended episode is reset by the next step (a vector environment) or stays ended.
    autoreset: bool,
    /// A step's buffers, kept from step to step (a step allocates only the arrays it returns).
    scratch: Scratch,
}

/// The buffers of a step: the actions read, and what each episode's step writes.
#[derive(Default)]
struct Scratch {
    u: Vec<f64>,
    obs: Vec<f32>,
    reward: Vec<f64>,
    terminated: Vec<bool>,
    truncated: Vec<bool>,
}

/// What `ForceControlBatch(...)` was given.
#[derive(Clone, Debug)]
struct Args {
    scene_path: PathBuf,
    num_envs: usize,
    randomize: bool,
    action: String,
    decision_ticks: u32,
    max_episode_steps: Option<u64>,
    regulator_time_constant_s: f64,
}

/// The batch's helper threads, one set per process: helpers made before a `fork` are not in the child (a
/// parallel step there would wait for them forever), so a process whose id is not the helpers' makes its
/// own. The calling thread works beside them ([`for_each_chunk`]), so there is one helper fewer than the
/// threads a step uses.
mod pool {
    use std::sync::{Arc, Mutex};

    use pneuflex_threads::Helpers;

    static POOL: Mutex<Option<(u32, Option<Arc<Helpers>>)>> = Mutex::new(None);

    /// The threads a step uses, the caller's included: `RAYON_NUM_THREADS` (the name the bindings read
    /// when their pool was rayon's), else one per core (read once: the core count comes from the cgroup's
    /// files).
    pub fn threads() -> usize {
        static THREADS: std::sync::OnceLock<usize> = std::sync::OnceLock::new();
        *THREADS.get_or_init(|| {
            std::env::var("RAYON_NUM_THREADS")
                .ok()
                .and_then(|v| v.parse::<usize>().ok())
                .filter(|&n| n > 0)
                .unwrap_or_else(|| std::thread::available_parallelism().map_or(1, |n| n.get()))
        })
    }

    /// This process's helpers (made on first use), or None when the step runs on the caller alone.
    pub fn this_process() -> Option<Arc<Helpers>> {
        let pid = std::process::id();
        let mut held = POOL.lock().unwrap_or_else(|e| e.into_inner());
        if let Some((owner, pool)) = held.as_ref()
            && *owner == pid
        {
            return pool.clone();
        }
        // The parent's helpers: their threads are not in this process, and dropping them would signal them.
        if let Some(old) = held.take() {
            std::mem::forget(old);
        }
        let helpers = threads() - 1;
        let pool = (helpers > 0).then(|| {
            Arc::new(Helpers::new(helpers, "pneuflex-gym").expect("the batch's helper threads"))
        });
        *held = Some((pid, pool.clone()));
        pool
    }
}

/// Runs `work(0..chunks)`, each index once, taken in turn by the calling thread and the helpers (one
/// fewer than the threads a step uses, so each has its core; a batch of one never leaves the caller).
fn for_each_chunk(chunks: usize, work: &(dyn Fn(usize) + Sync)) {
    // One chunk never leaves the caller (nor asks for the helpers: a getpid and a lock).
    match (chunks > 1).then(pool::this_process).flatten() {
        Some(pool) => pool.for_each(chunks, work),
        None => (0..chunks).for_each(work),
    }
}

/// One chunk of a step: its episodes, their actions and what they write.
struct Chunk<'a> {
    episodes: &'a mut [Episode],
    u: &'a [f64],
    obs: &'a mut [f32],
    reward: &'a mut [f64],
    terminated: &'a mut [bool],
    truncated: &'a mut [bool],
}

/// One episode's step into its observation: an episode that ended is started again (autoreset) or else
/// stepped under `action`, then observed.
fn step_episode(
    e: &mut Episode,
    task: &Task,
    action: &[f64],
    obs: &mut [f32],
    randomize: bool,
    autoreset: bool,
) -> Outcome {
    let r = if e.ended && autoreset {
        e.next_episode(task, randomize);
        Outcome::default()
    } else {
        let r = e.step(task, action);
        e.ended = r.terminated || r.truncated;
        r
    };
    e.observe(task, obs);
    r
}

/// Episodes whose plants [`step_together`] advances together, each RK4 stage for all of them at once.
const LANES: usize = pneuflex_pneumatics::PACK;

/// A chunk's step under valve commands on 1-DOF plants: what [`Episode::step`] does for each episode, with
/// the plants of each LANES episodes that step advanced together ([`OneDofPneumatic::advance_together`],
/// bit for bit their own `advance`). Measured in `scripts/bench.py --gym-only` (docs/gymnasium.md).
fn step_together(c: Chunk<'_>, task: &Task, randomize: bool, autoreset: bool) {
    let (width, obs_len) = (task.width(), task.obs_len());
    for (g, group) in c.episodes.chunks_mut(LANES).enumerate() {
        let first = g * LANES;
        if group.len() < LANES {
            // Fewer than a pack: each episode as the plain loop steps it.
            for (j, e) in group.iter_mut().enumerate() {
                let k = first + j;
                let action = &c.u[k * width..(k + 1) * width];
                let obs = &mut c.obs[k * obs_len..(k + 1) * obs_len];
                let r = step_episode(e, task, action, obs, randomize, autoreset);
                (c.reward[k], c.terminated[k], c.truncated[k]) =
                    (r.reward, r.terminated, r.truncated);
            }
            continue;
        }
        let mut outcome = [Outcome::default(); LANES];
        let mut stepping = [false; LANES];
        for (j, e) in group.iter_mut().enumerate() {
            if e.ended && autoreset {
                e.next_episode(task, randomize);
            } else {
                let action = &c.u[(first + j) * width..(first + j + 1) * width];
                e.begin_step(action);
                e.actuate_valves(action);
                stepping[j] = true;
            }
        }
        let mut plants: [Option<&mut OneDofPneumatic>; LANES] = Default::default();
        for ((e, p), &on) in group.iter_mut().zip(&mut plants).zip(&stepping) {
            if let (true, EpisodePlant::OneDof(one)) = (on, e.held_plant()) {
                *p = Some(&mut **one);
            }
        }
        if plants.iter().all(Option::is_some) {
            OneDofPneumatic::advance_together(plants.map(|p| p.expect("all some")), task.dt);
        } else {
            for (e, &on) in group.iter_mut().zip(&stepping) {
                if on {
                    e.plant().advance(task.dt);
                }
            }
        }
        for (j, e) in group.iter_mut().enumerate() {
            if stepping[j] {
                let r = e.ticked(task);
                outcome[j] = e.end_step(task, r);
                e.ended = outcome[j].terminated || outcome[j].truncated;
            }
            let k = first + j;
            e.observe(task, &mut c.obs[k * obs_len..(k + 1) * obs_len]);
            let r = outcome[j];
            (c.reward[k], c.terminated[k], c.truncated[k]) = (r.reward, r.terminated, r.truncated);
        }
    }
}

/// One episode's state in a pickle: (stream, k, randomized, the actions since its start as float64 bytes).
type EpisodeState = (u64, u64, bool, Vec<u8>);

/// The actions of a step into `out`: a float64 or float32 numpy array (contiguous or not), read in C order;
/// anything else is a TypeError saying what is expected.
fn read_actions(actions: &Bound<'_, PyAny>, out: &mut Vec<f64>) -> PyResult<()> {
    out.clear();
    if let Ok(a) = actions.cast::<PyArrayDyn<f64>>() {
        // A contiguous array is copied straight (the single environment's every step): under the GIL,
        // with no Rust borrow of a caller's array anywhere, so numpy's borrow bookkeeping (a lock and a
        // hash map per call, 4 % of that step) is skipped.
        // SAFETY: the GIL is held, and nothing here holds a mutable borrow of `a` while we copy it.
        if let Ok(v) = unsafe { a.as_slice() } {
            out.extend_from_slice(v);
            return Ok(());
        }
        let a: PyReadonlyArrayDyn<'_, f64> = a.try_readonly()?;
        out.extend(a.as_array().iter().copied());
        return Ok(());
    }
    if let Ok(a) = actions.cast::<PyArrayDyn<f32>>() {
        let a: PyReadonlyArrayDyn<'_, f32> = a.try_readonly()?;
        out.extend(a.as_array().iter().map(|&v| f64::from(v)));
        return Ok(());
    }
    Err(pyo3::exceptions::PyTypeError::new_err(format!(
        "actions must be a float64 or float32 numpy array (num_envs x action_width values), got {}",
        describe(actions)
    )))
}

/// A Python value's type, with a numpy array's dtype and shape.
fn describe(v: &Bound<'_, PyAny>) -> String {
    let ty = v
        .get_type()
        .name()
        .map_or_else(|_| "?".into(), |n| n.to_string());
    match (v.getattr("dtype"), v.getattr("shape")) {
        (Ok(d), Ok(s)) => format!("{ty} of dtype {d} and shape {s}"),
        _ => ty,
    }
}

/// A reset's seed: one for the batch, or one per episode.
enum Seeds {
    One(u64),
    Each(Vec<u64>),
}

impl Seeds {
    /// An int in [0, 2^64) or a list of them; anything else says what a seed must be.
    fn extract(seed: &Bound<'_, PyAny>) -> PyResult<Self> {
        let one = |v: &Bound<'_, PyAny>, what: &str| -> PyResult<u64> {
            if v.is_instance_of::<pyo3::types::PyBool>() {
                return Err(pyo3::exceptions::PyTypeError::new_err(format!(
                    "{what} must be an int, got a bool"
                )));
            }
            v.extract::<u64>().map_err(|e| {
                if e.is_instance_of::<pyo3::exceptions::PyOverflowError>(v.py()) {
                    PyValueError::new_err(format!("{what} must be in [0, 2^64), got {v}"))
                } else {
                    pyo3::exceptions::PyTypeError::new_err(format!(
                        "{what} must be an int, got {}",
                        describe(v)
                    ))
                }
            })
        };
        // An int, or a numpy integer (an index that is not a sequence).
        let sequence = seed.hasattr("__len__")?;
        if seed.is_instance_of::<pyo3::types::PyInt>() || (seed.hasattr("__index__")? && !sequence)
        {
            return one(seed, "seed").map(Seeds::One);
        }
        if !sequence
            || seed.is_instance_of::<pyo3::types::PyString>()
            || seed.is_instance_of::<pyo3::types::PyBytes>()
            || seed.is_instance_of::<pyo3::types::PyDict>()
        {
            return Err(pyo3::exceptions::PyTypeError::new_err(format!(
                "seed must be an int or a list of ints (one per environment), got {}",
                describe(seed)
            )));
        }
        let mut each = Vec::new();
        for (i, v) in seed.try_iter()?.enumerate() {
            each.push(one(&v?, &format!("seed[{i}]"))?);
        }
        Ok(Seeds::Each(each))
    }
}

/// Episode `i`'s stream of a batch reset with `seed`: the seed and the index mixed (SplitMix64's increment).
fn stream(seed: u64, i: usize) -> u64 {
    seed ^ (i as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15)
}

/// The generator of the `k`-th episode of a stream (0: the one a reset starts; k > 0: the autoresets after
/// it), so that an episode's draw follows from (stream, k) alone.
fn restart_rng(stream: u64, k: u64) -> StdRng {
    StdRng::seed_from_u64(stream.wrapping_add(k.wrapping_mul(0xD1B5_4A32_D192_ED03)))
}

/// The reward of one control tick: 1 - min(((f_ref - f_e) / 10 N)^2, 1), in [0, 1]. The squared force error
/// the paper's RMS metric sums, in (10 N)^2, subtracted from 1 and clipped at an error of 10 N (the size of the
/// paper's reference: pressing nothing). Never negative, so an episode that ends at an end stop earns nothing
/// for the ticks it no longer lives: ending early never pays, without a terminal penalty.
fn tick_reward(f_ref: f64, f_e: f64) -> f64 {
    1.0 - ((f_ref - f_e) / SCALES[0]).powi(2).min(1.0)
}

#[pymethods]
impl PyForceControlBatch {
    /// `num_envs` episodes of the scene at `scene_path` (a pneumatic 1-DOF or a multibody scene, or a scene
    /// of several actuators: each step then takes every actuator's action and observes every actuator's
    /// block, actuator by actuator), at the scene's values until reset. `randomize`: draw each episode's stiffness before and after the change
    /// (log-uniform 350-2800 N/m), the change's time (uniform 4-8 s) and, on the 1-DOF plant, the moving
    /// mass, the seal friction and an on/off valve's switching delay (each log-uniform 0.5-2x the sheet's)
    /// at every reset (on a mechanism: every contact's and spring's stiffness before its events, and every
    /// event's, each set scaled log-uniform 0.5-2x); otherwise the scene's own values. `autoreset`: a step resets an episode that ended at the step before
    /// (Gymnasium's next-step autoreset), returning its first observation. `action`: "valve" (u, one tick
    /// per step), "pressure" (the set-points p_a, p_b in Pa absolute of a pressure regulator in front of each
    /// chamber, time constant `regulator_time_constant_s`, its flow limited by the valve's paths fully open;
    /// one tick per step; a scene of one `[plant]`) or "impedance" (a_m, a_b retune the scene's impedance
    /// run: m_d = m_d0 4^a_m, b_d = b_d0 4^a_b, then `decision_ticks` ticks of that controller per step, the
    /// rewards summed).
    #[new]
    #[pyo3(signature = (scene_path, num_envs = 1, randomize = true, autoreset = false, action = "valve", decision_ticks = 10, max_episode_steps = None, regulator_time_constant_s = DEFAULT_REGULATOR_TIME_CONSTANT_S))]
    #[allow(clippy::too_many_arguments)]
    fn new(
        scene_path: crate::shipped::ScenePath,
        num_envs: usize,
        randomize: bool,
        autoreset: bool,
        action: &str,
        decision_ticks: u32,
        max_episode_steps: Option<u64>,
        regulator_time_constant_s: f64,
    ) -> PyResult<Self> {
        if max_episode_steps == Some(0) {
            return Err(PyValueError::new_err(
                "max_episode_steps must be at least 1 (or None: the scene's duration)",
            ));
        }
        if num_envs == 0 {
            return Err(PyValueError::new_err("num_envs must be at least 1"));
        }
        // A step of zero ticks would stand still: refused rather than read as 1.
        if decision_ticks == 0 {
            return Err(PyValueError::new_err(
                "decision_ticks must be at least 1 (control ticks per impedance action)",
            ));
        }
        let regulator = PressureRegulator::new(regulator_time_constant_s)
            .map_err(|e| PyValueError::new_err(format!("regulator_time_constant_s: {e}")))?;
        let mut task =
            Task::load(&scene_path, action, decision_ticks, regulator).map_err(errors::scene)?;
        task.max_steps = max_episode_steps;
        let episodes = (0..num_envs)
            .map(|i| Episode::new(&task, stream(0, i)))
            .collect::<Result<_, _>>()
            .map_err(errors::scene)?;
        Ok(Self {
            args: Args {
                scene_path: scene_path.to_path_buf(),
                num_envs,
                randomize,
                action: action.to_string(),
                decision_ticks,
                max_episode_steps,
                regulator_time_constant_s,
            },
            task,
            episodes,
            randomize,
            autoreset,
            scratch: Scratch::default(),
        })
    }

    /// The constructor's arguments, for pickle (with `__getstate__`, what rebuilds this batch).
    #[allow(clippy::type_complexity)]
    fn __getnewargs__(&self) -> (PathBuf, usize, bool, bool, String, u32, Option<u64>, f64) {
        let a = &self.args;
        (
            a.scene_path.clone(),
            a.num_envs,
            a.randomize,
            self.autoreset,
            a.action.clone(),
            a.decision_ticks,
            a.max_episode_steps,
            a.regulator_time_constant_s,
        )
    }

    /// The batch's state: (randomize, [(stream, k, randomized, actions since the episode's start)]). The
    /// plants are deterministic, so an episode is its draw's seed and its actions: `__setstate__` replays
    /// them (a pickle's size grows with the steps since each episode's start, 8 bytes per action value).
    fn __getstate__(&self) -> (bool, Vec<EpisodeState>) {
        let episodes = self
            .episodes
            .iter()
            .map(|e| {
                let bytes = e.actions.iter().flat_map(|v| v.to_le_bytes()).collect();
                (e.stream, e.k, e.randomized, bytes)
            })
            .collect();
        (self.randomize, episodes)
    }

    /// Restores `__getstate__`'s state: each episode restarted from its draw and its actions replayed.
    fn __setstate__(&mut self, py: Python<'_>, state: (bool, Vec<EpisodeState>)) -> PyResult<()> {
        let (randomize, saved) = state;
        let width = self.task.width();
        if saved.len() != self.episodes.len() {
            return Err(PyValueError::new_err(format!(
                "state: {} episodes for a batch of {}",
                saved.len(),
                self.episodes.len()
            )));
        }
        if let Some((i, _)) = saved
            .iter()
            .enumerate()
            .find(|(_, s)| s.3.len() % (8 * width) != 0)
        {
            return Err(PyValueError::new_err(format!(
                "state: episode {i}'s actions are not whole actions of {width} float64 values"
            )));
        }
        self.randomize = randomize;
        let task = &self.task;
        let episodes: Vec<Mutex<&mut Episode>> = self.episodes.iter_mut().map(Mutex::new).collect();
        py.detach(|| {
            for_each_chunk(episodes.len(), &|i| {
                let mut e = episodes[i].lock().unwrap_or_else(|e| e.into_inner());
                let (stream, k, randomized, bytes) = &saved[i];
                (e.stream, e.k) = (*stream, *k);
                e.restart(task, *randomized);
                let actions: Vec<f64> = bytes
                    .chunks_exact(8)
                    .map(|b| f64::from_le_bytes(b.try_into().expect("8 bytes")))
                    .collect();
                for a in actions.chunks(width) {
                    let out = e.step(task, a);
                    e.ended = out.terminated || out.truncated;
                }
            });
        });
        Ok(())
    }

    /// Starts every episode afresh: episode i's generator from (`seed`, i), or from (`seed[i]`, 0) when
    /// `seed` is a list of one seed per episode (episode i then draws what a batch of one reset with
    /// `seed[i]` draws); `randomize` overrides the batch's setting for these episodes (and their
    /// autoresets). Returns the observations (num_envs, 6).
    #[pyo3(signature = (seed, randomize = None))]
    fn reset<'py>(
        &mut self,
        py: Python<'py>,
        seed: &Bound<'py, PyAny>,
        randomize: Option<bool>,
    ) -> PyResult<Bound<'py, PyArray2<f32>>> {
        let seed = Seeds::extract(seed)?;
        let n = self.episodes.len();
        if let Seeds::Each(s) = &seed
            && s.len() != n
        {
            return Err(PyValueError::new_err(format!(
                "seed: {} seeds for {n} environments",
                s.len()
            )));
        }
        if let Some(r) = randomize {
            self.randomize = r;
        }
        let task = &self.task;
        let randomize = self.randomize;
        for (i, e) in self.episodes.iter_mut().enumerate() {
            e.stream = match &seed {
                Seeds::One(s) => stream(*s, i),
                Seeds::Each(s) => stream(s[i], 0),
            };
            e.k = 0;
            e.restart(task, randomize);
        }
        Ok(self.observations(py))
    }

    /// One step of every episode under `actions`, `action_width` values per episode, flat (a float64 or
    /// float32 array, read in C order: a valve command, the pressure set-points p_a, p_b, or the impedance
    /// adjustments a_m, a_b): finite values; the valve and impedance actions clipped to [-1, 1], a pressure
    /// set-point outside [atmosphere, supply] refused; a refusal names the episode and the value, and no
    /// episode moves. Returns (observations (num_envs, 6 per actuator) float32, rewards, terminated,
    /// truncated).
    #[allow(clippy::type_complexity)]
    fn step<'py>(
        &mut self,
        py: Python<'py>,
        actions: &Bound<'py, PyAny>,
    ) -> PyResult<(
        Bound<'py, PyArray2<f32>>,
        Bound<'py, PyArray1<f64>>,
        Bound<'py, PyArray1<bool>>,
        Bound<'py, PyArray1<bool>>,
    )> {
        let n = self.episodes.len();
        let obs_len = self.task.obs_len();
        self.run_step(py, actions)?;
        let sc = &self.scratch;
        // SAFETY: a new C-contiguous array of n x obs_len values, written whole before Python sees it.
        let obs = unsafe { PyArray2::<f32>::new(py, [n, obs_len], false) };
        unsafe { obs.as_slice_mut() }
            .expect("a new array is contiguous")
            .copy_from_slice(&sc.obs);
        Ok((
            obs,
            PyArray1::from_slice(py, &sc.reward),
            PyArray1::from_slice(py, &sc.terminated),
            PyArray1::from_slice(py, &sc.truncated),
        ))
    }

    /// One step of a batch of one (the single environment's step): `actions` as `step` takes them; returns
    /// (observation (6 per actuator,) float32, reward, terminated, truncated, t s, f_e N of actuator 0).
    #[allow(clippy::type_complexity)]
    fn step_single<'py>(
        &mut self,
        py: Python<'py>,
        actions: &Bound<'py, PyAny>,
    ) -> PyResult<(Bound<'py, PyArray1<f32>>, f64, bool, bool, f64, f64)> {
        if self.episodes.len() != 1 {
            return Err(PyValueError::new_err(format!(
                "step_single steps a batch of one; this batch has {} (step)",
                self.episodes.len()
            )));
        }
        self.run_step(py, actions)?;
        let sc = &self.scratch;
        let e = &mut self.episodes[0];
        let f_e = e.plant().sense_actuator(0).f_e;
        Ok((
            PyArray1::from_slice(py, &sc.obs),
            sc.reward[0],
            sc.terminated[0],
            sc.truncated[0],
            e.t,
            f_e,
        ))
    }

    /// Each episode's parameters as arrays: stiffness_n_per_m (before the change),
    /// stiffness_after_n_per_m, t_change_s, mass_scale, friction_scale, switching_delay_scale; on a
    /// mechanism stiffness_scale and stiffness_after_scale (its contacts' and springs' stiffness before
    /// and after their events, as multiples of the scene's).
    fn params<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let d = PyDict::new(py);
        let col = |f: fn(&Draw) -> f64| {
            self.episodes
                .iter()
                .map(|e| f(&e.draw))
                .collect::<Vec<_>>()
                .into_pyarray(py)
        };
        if let Rig::Mechanism { .. } = self.task.rig {
            d.set_item("stiffness_scale", col(|d| d.k_before))?;
            d.set_item("stiffness_after_scale", col(|d| d.k_after))?;
            return Ok(d);
        }
        d.set_item("stiffness_n_per_m", col(|d| d.k_before))?;
        d.set_item("stiffness_after_n_per_m", col(|d| d.k_after))?;
        d.set_item("t_change_s", col(|d| d.t_change_s))?;
        d.set_item("mass_scale", col(|d| d.mass_scale))?;
        d.set_item("friction_scale", col(|d| d.friction_scale))?;
        d.set_item("switching_delay_scale", col(|d| d.delay_scale))?;
        Ok(d)
    }

    /// Episode `i`'s time and actuator `actuator`'s sensors in SI (pressures absolute):
    /// (t, x, x_dot, f_e, p_a, p_b); a controller reads them as a policy.
    #[pyo3(signature = (i, actuator = 0))]
    fn sensors(&self, i: usize, actuator: usize) -> PyResult<(f64, f64, f64, f64, f64, f64)> {
        let e = self.episodes.get(i).ok_or_else(|| {
            PyValueError::new_err(format!(
                "environment {i} out of range: the batch has {}",
                self.episodes.len()
            ))
        })?;
        self.check_actuator(actuator)?;
        let s = e
            .plant
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .get()
            .sense_actuator(actuator);
        Ok((e.t, s.x, s.x_dot, s.f_e, s.p_a, s.p_b))
    }

    /// Why episode `i` terminated, when an actuator of a multibody or mechanism scene passed the scene's
    /// limits or its plant an invariant (None otherwise: a 1-DOF episode ends at an end of the stroke).
    fn why(&self, i: usize) -> Option<String> {
        self.episodes.get(i).and_then(|e| e.why.clone())
    }

    /// The scene's (f_ref N, x_d m) of actuator `actuator` at time `t` s.
    #[pyo3(signature = (t, actuator = 0))]
    fn setpoint(&self, t: f64, actuator: usize) -> PyResult<(f64, f64)> {
        self.check_actuator(actuator)?;
        let s = self.task.setpoints[actuator].at(t);
        Ok((s.f_ref, s.x_d))
    }

    /// Number of episodes.
    #[getter]
    fn num_envs(&self) -> usize {
        self.episodes.len()
    }

    /// The actuators' names, in the order of the action's and the observation's blocks (a mechanism's
    /// `[[actuators]]`; empty for a scene of one `[plant]`).
    #[getter]
    fn actuator_names(&self) -> Vec<String> {
        match &self.task.rig {
            Rig::Mechanism { scene, .. } => {
                scene.actuators.iter().map(|a| a.name.clone()).collect()
            }
            Rig::Single { .. } => Vec::new(),
        }
    }

    /// Actuators each episode drives (1 for a scene of one `[plant]`).
    #[getter]
    fn num_actuators(&self) -> usize {
        self.task.actuators()
    }

    /// Values per episode's action: per actuator 1 (the valve command) or 2 (the impedance adjustments
    /// a_m, a_b), times the actuators.
    #[getter]
    fn action_width(&self) -> usize {
        self.task.width()
    }

    /// Values per episode's observation: 6 per actuator.
    #[getter]
    fn observation_width(&self) -> usize {
        self.task.obs_len()
    }

    /// Control ticks per step: 1 under the valve action, `decision_ticks` under the impedance action.
    #[getter]
    fn ticks_per_step(&self) -> u32 {
        self.task.action.ticks()
    }

    /// The lowest value of each action value (the action space's `low`): -1 for the valve and the impedance
    /// actions, the atmosphere's pressure (Pa absolute) for a pressure set-point.
    #[getter]
    fn action_low(&self) -> Vec<f64> {
        self.task.bounds.iter().map(|b| b.0).collect()
    }

    /// The highest value of each action value (the space's `high`): 1, or the supply's pressure (Pa
    /// absolute) for a pressure set-point.
    #[getter]
    fn action_high(&self) -> Vec<f64> {
        self.task.bounds.iter().map(|b| b.1).collect()
    }

    /// The action: "valve", "pressure" or "impedance".
    #[getter]
    fn action(&self) -> String {
        self.args.action.clone()
    }

    /// The pressure regulators' time constant, s (used by the pressure action).
    #[getter]
    fn regulator_time_constant_s(&self) -> f64 {
        self.args.regulator_time_constant_s
    }

    /// The control tick, s.
    #[getter]
    fn dt(&self) -> f64 {
        self.task.dt
    }

    /// The episode's length, s (the scene's duration).
    #[getter]
    fn duration(&self) -> f64 {
        self.task.duration
    }

    /// The observation scales (f_e, f_ref, x - x_e, x_dot, p_a, p_b in SI divided by these).
    #[getter]
    fn scales(&self) -> [f64; OBS] {
        SCALES
    }
}

impl PyForceControlBatch {
    /// Reads and checks `actions`, then steps every episode into the scratch buffers (GIL released, the
    /// episodes in chunks over the caller and the pool).
    fn run_step(&mut self, py: Python<'_>, actions: &Bound<'_, PyAny>) -> PyResult<()> {
        let n = self.episodes.len();
        let width = self.task.width();
        let obs_len = self.task.obs_len();
        let sc = &mut self.scratch;
        read_actions(actions, &mut sc.u)?;
        let u = &sc.u;
        if u.len() != n * width {
            return Err(PyValueError::new_err(format!(
                "actions: {} values for {n} environments of {width} each",
                u.len()
            )));
        }
        let pressure = matches!(self.task.action, Action::Pressure { .. });
        // A NaN would be read as some command (the valve closed, the scene's gains): refused instead.
        if let Some(k) = u.iter().position(|v| !v.is_finite()) {
            let what = if pressure {
                "a pressure set-point must be finite"
            } else {
                "an action must be finite (values outside [-1, 1] are clipped)"
            };
            return Err(PyValueError::new_err(format!(
                "actions[{k}] (environment {}, value {}) is {}: {what}",
                k / width,
                k % width,
                u[k]
            )));
        }
        if pressure {
            // The space's bounds are float32: a value at a bound rounded to float32 is inside.
            let inside = |v: f64, (lo, hi): (f64, f64)| {
                v >= lo.min(f64::from(lo as f32)) && v <= hi.max(f64::from(hi as f32))
            };
            let bounds = &self.task.bounds;
            if let Some(k) = (0..u.len()).find(|&k| !inside(u[k], bounds[k % width])) {
                let (lo, hi) = bounds[k % width];
                let chamber = if k % 2 == 0 { "p_a" } else { "p_b" };
                return Err(PyValueError::new_err(format!(
                    "actions[{k}] (environment {}, value {}: actuator {}'s {chamber} set-point) is {} Pa: a \
                     set-point must be within [{lo}, {hi}] Pa absolute (the atmosphere and the supply)",
                    k / width,
                    k % width,
                    (k % width) / 2,
                    u[k]
                )));
            }
        }
        sc.obs.resize(n * obs_len, 0.0);
        sc.reward.resize(n, 0.0);
        sc.terminated.resize(n, false);
        sc.truncated.resize(n, false);
        let (task, randomize, autoreset) = (&self.task, self.randomize, self.autoreset);
        // Four chunks per thread, and on the 1-DOF plant at least 16 control ticks each (a tick is about a
        // microsecond); a multibody or mechanism episode's tick is tens of microseconds.
        let one_dof = matches!(
            task.rig,
            Rig::Single {
                one_dof: Some(_),
                ..
            }
        );
        // Valve commands to 1-DOF plants: their ticks are advanced LANES at a time (`step_together`).
        let together = one_dof && matches!(task.action, Action::Valve);
        let least = if one_dof {
            (16 / task.action.ticks()).max(1) as usize
        } else {
            1
        };
        let size = if n <= least {
            n
        } else {
            (n / (4 * pool::threads())).max(least)
        };
        let run = |c: Chunk<'_>| {
            if together {
                step_together(c, task, randomize, autoreset);
                return;
            }
            for (j, e) in c.episodes.iter_mut().enumerate() {
                let action = &c.u[j * width..(j + 1) * width];
                let obs = &mut c.obs[j * obs_len..(j + 1) * obs_len];
                let r = step_episode(e, task, action, obs, randomize, autoreset);
                (c.reward[j], c.terminated[j], c.truncated[j]) =
                    (r.reward, r.terminated, r.truncated);
            }
        };
        if one_dof && size == n {
            // A few 1-DOF ticks (the single environment's step: about a microsecond) on this thread,
            // without releasing the GIL or sharing the work out: either would cost more than the tick.
            run(Chunk {
                episodes: &mut self.episodes,
                u: &sc.u,
                obs: &mut sc.obs,
                reward: &mut sc.reward,
                terminated: &mut sc.terminated,
                truncated: &mut sc.truncated,
            });
            return Ok(());
        }
        let chunks: Vec<Mutex<Option<Chunk<'_>>>> = self
            .episodes
            .chunks_mut(size)
            .zip(sc.u.chunks(size * width))
            .zip(sc.obs.chunks_mut(size * obs_len))
            .zip(sc.reward.chunks_mut(size))
            .zip(sc.terminated.chunks_mut(size))
            .zip(sc.truncated.chunks_mut(size))
            .map(
                |(((((episodes, u), obs), reward), terminated), truncated)| {
                    Mutex::new(Some(Chunk {
                        episodes,
                        u,
                        obs,
                        reward,
                        terminated,
                        truncated,
                    }))
                },
            )
            .collect();
        py.detach(|| {
            for_each_chunk(chunks.len(), &|i| {
                if let Some(c) = chunks[i].lock().unwrap_or_else(|e| e.into_inner()).take() {
                    run(c);
                }
            });
        });
        Ok(())
    }

    fn check_actuator(&self, actuator: usize) -> PyResult<()> {
        let n = self.task.actuators();
        if actuator >= n {
            return Err(PyValueError::new_err(format!(
                "actuator {actuator} out of range: the scene has {n}"
            )));
        }
        Ok(())
    }

    fn observations<'py>(&mut self, py: Python<'py>) -> Bound<'py, PyArray2<f32>> {
        let n = self.episodes.len();
        let len = self.task.obs_len();
        let mut obs = vec![0f32; n * len];
        for (e, o) in self.episodes.iter_mut().zip(obs.chunks_mut(len)) {
            e.observe(&self.task, o);
        }
        obs.into_pyarray(py)
            .reshape([n, len])
            .expect("n * len values reshape to (n, len)")
    }
}
