//! The force-control task of `pneuflex.envs` (Gymnasium), stepped in Rust: a batch of episodes of a
//! 1-DOF pneumatic or multibody scene, each its own plant (the scene crate's plant, the one
//! `pneuflex.run` simulates), spring environment, events and domain-randomised parameters.
//!
//! One `step` advances every episode by one action (a valve command for a tick, or a retune of the
//! impedance controller and its ticks), in parallel over the machine's cores with the GIL released. `ForceControl` is a batch of one, `ForceControlVector` the
//! `gymnasium.vector.VectorEnv` over a batch of many: one implementation of the task for both.

use std::path::{Path, PathBuf};

use numpy::{IntoPyArray, PyArray1, PyArray2, PyArrayMethods, PyReadonlyArray1};
use pneuflex_control::{
    Controller, ImpedanceController, ImpedanceParams, Sensors, SetpointSchedule, Telemetry,
    ValveCommand,
};
use pneuflex_pneumatics::ValveKind;
use pneuflex_scene::plants::{LinearSpring, MultibodyPlant, OneDofPneumatic, Plant};
use pneuflex_scene::schema::{ControllerKind, EventSpec, PlantSpec};
use pneuflex_scene::{Scene, SceneError};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::PyDict;
use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};
use rayon::prelude::*;

use crate::errors;

/// Observation scales: f_e and f_ref in 10 N, x - x_e in 10 mm, velocity in 0.1 m/s, pressures in bar.
pub const SCALES: [f64; OBS] = [10.0, 10.0, 0.01, 0.1, 1e5, 1e5];
/// Length of an observation: f_e, f_ref, x - x_e, x_dot, p_a, p_b.
const OBS: usize = 6;

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
}

const RANGES: Ranges = Ranges {
    stiffness_n_per_m: (350.0, 2800.0),
    t_change_s: (4.0, 8.0),
    mass_scale: (0.5, 2.0),
    friction_scale: (0.5, 2.0),
    delay_scale: (0.5, 2.0),
};

fn log_uniform(rng: &mut StdRng, (lo, hi): (f64, f64)) -> f64 {
    (lo.ln() + rng.random::<f64>() * (hi.ln() - lo.ln())).exp()
}

/// One episode's physical parameters.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Draw {
    k_before: f64,
    k_after: f64,
    t_change_s: f64,
    mass_scale: f64,
    friction_scale: f64,
    delay_scale: f64,
}

/// What an action is.
#[derive(Clone, Debug)]
enum Action {
    /// The valve command u in [-1, 1], held over one control tick.
    Valve,
    /// Adjustments (a_m, a_b) in [-1, 1]^2 of the scene's impedance controller, which then runs each
    /// tick: m_d = m_d0 4^a_m, b_d = b_d0 4^a_b (k_d kept), held over `ticks` control ticks.
    Impedance {
        /// The scene's impedance run's controller, its m_d0, b_d0, k_d0.
        controller: Box<ImpedanceController>,
        ticks: u32,
    },
}

impl Action {
    /// Values in one action.
    fn width(&self) -> usize {
        match self {
            Action::Valve => 1,
            Action::Impedance { .. } => 2,
        }
    }
}

/// The scene's values: what every episode starts from.
struct Task {
    action: Action,
    scene: Scene,
    /// A 1-DOF pneumatic scene's plant at its initial state: each episode is built from its model with the
    /// draw's mass and friction. None for a multibody scene, whose episodes reset their own plant.
    one_dof: Option<OneDofPneumatic>,
    setpoints: SetpointSchedule,
    /// The scene's events in time order.
    events: Vec<EventSpec>,
    /// The scene's own parameters (no randomisation).
    own: Draw,
    dt: f64,
    duration: f64,
    x_e: f64,
    stroke: f64,
    /// Gymnasium's `max_episode_steps`: an episode is truncated at that many steps (None: the scene's
    /// duration only).
    max_steps: Option<u64>,
}

impl Task {
    fn load(path: &Path, action: &str, decision_ticks: u32) -> Result<Self, SceneError> {
        let scene = Scene::load(path)?;
        let action = match action {
            "valve" => Action::Valve,
            "impedance" => {
                let run = scene
                    .runs
                    .iter()
                    .find(|r| r.controller == ControllerKind::Impedance && r.frozen.is_none())
                    .ok_or_else(|| {
                        scene.invalid(
                            "runs",
                            "no impedance run: the impedance action retunes the scene's impedance controller".into(),
                        )
                    })?;
                let controller = ImpedanceController::new(run.impedance, run.inner)
                    .map_err(|e| scene.invalid("runs", e.to_string()))?;
                Action::Impedance {
                    controller: Box::new(controller),
                    ticks: decision_ticks,
                }
            }
            other => {
                return Err(SceneError::Plant {
                    file: scene.source.clone(),
                    message: format!("action = {other:?}: expected \"valve\" or \"impedance\""),
                });
            }
        };
        let env = LinearSpring {
            stiffness_n_per_m: scene.environment.stiffness_n_per_m,
            x_e_m: scene.environment.x_e_m,
        };
        let one_dof = match scene.plant {
            PlantSpec::Pneumatic { .. } => Some(OneDofPneumatic::from_scene(&scene, env)?),
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
            one_dof,
            setpoints: scene.setpoints()?,
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
            x_e: env.x_e_m,
            stroke: f64::INFINITY,
            max_steps: None,
            scene,
        };
        let plant = task.build()?;
        task.stroke = plant
            .actuator_geometry()
            .map_or(f64::INFINITY, |g| g.stroke_m);
        // Every event must be one this plant takes (validation says so too; here it is the environment's).
        for (i, ev) in task.scene.events.iter().enumerate() {
            task.build()?
                .apply(ev)
                .map_err(|e| task.scene.invalid(&format!("events[{i}]"), e.to_string()))?;
        }
        Ok(task)
    }

    /// A new plant of the scene at its initial state.
    fn build(&self) -> Result<Box<dyn Plant + Send + Sync>, SceneError> {
        Ok(match &self.one_dof {
            Some(p) => Box::new(p.clone()),
            None => Box::new(MultibodyPlant::from_scene(&self.scene)?),
        })
    }

    /// The draw of a new episode (the scene's own values without randomisation; the multibody plant's
    /// mass and friction are its URDF's and its sheet's, not drawn).
    fn draw(&self, rng: &mut StdRng, randomize: bool) -> Draw {
        if !randomize {
            return self.own;
        }
        let r = RANGES;
        let one_dof = self.one_dof.is_some();
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

    /// The scene's events, with its first stiffness change (or one added) at the draw's time and value.
    fn events(&self, draw: &Draw) -> Vec<EventSpec> {
        let mut events = self.events.clone();
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

/// One running episode.
struct Episode {
    plant: Box<dyn Plant + Send + Sync>,
    /// The impedance action's controller, at the scene's parameters at each restart.
    controller: Option<ImpedanceController>,
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
}

impl Episode {
    fn new(task: &Task, stream: u64) -> Result<Self, SceneError> {
        let mut e = Self {
            plant: task.build()?,
            controller: None,
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
        };
        e.restart(task, false);
        Ok(e)
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
        match &task.one_dof {
            Some(p) => {
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
                    x_e_m: task.x_e,
                };
                // The chambers start at the static balance of this episode's mass (OneDofPneumatic::new).
                self.plant = Box::new(OneDofPneumatic::new(model, p.state().x, env, p.substeps()));
            }
            None => {
                self.plant.reset();
                // The material facing the flange at the draw's stiffness (checked at load: it takes it).
                let _ = self.plant.apply(&EventSpec::Stiffness {
                    t_s: 0.0,
                    stiffness_n_per_m: draw.k_before,
                    material: None,
                    damping_n_s_per_m: None,
                });
            }
        }
        self.controller = match task.action {
            Action::Impedance { ref controller, .. } => Some(**controller),
            Action::Valve => None,
        };
        self.events = task.events(&draw);
        self.draw = draw;
        self.next = 0;
        self.t = 0.0;
        self.ended = false;
        self.apply_due();
    }

    /// Applies the events due at the current time, as the scene loop does before it senses.
    fn apply_due(&mut self) {
        while let Some(ev) = self.events.get(self.next) {
            if ev.t_s() > self.t + 1e-9 {
                break;
            }
            // Checked when the task was loaded: the plant takes each of the scene's events.
            let _ = self.plant.apply(ev);
            self.next += 1;
        }
    }

    fn observe(&self, task: &Task, out: &mut [f32]) {
        let s = self.plant.sense();
        let f_ref = task.setpoints.at(self.t).f_ref;
        let raw = [s.f_e, f_ref, s.x - task.x_e, s.x_dot, s.p_a, s.p_b];
        for ((o, r), k) in out.iter_mut().zip(raw).zip(SCALES) {
            *o = (r / k) as f32;
        }
    }

    /// One action: a control tick under a valve command, or a retune of the impedance controller and
    /// its ticks; the rewards summed over the ticks.
    fn step(&mut self, task: &Task, action: &[f64]) -> Outcome {
        self.actions.extend_from_slice(action);
        self.steps += 1;
        let out = self.act(task, action);
        // Gymnasium's max_episode_steps: truncated at that many steps (unless the episode ended anyway).
        match task.max_steps {
            Some(m) if self.steps >= m && !out.terminated => Outcome {
                truncated: true,
                ..out
            },
            _ => out,
        }
    }

    fn act(&mut self, task: &Task, action: &[f64]) -> Outcome {
        let clamp = |a: f64| {
            if a.is_finite() {
                a.clamp(-1.0, 1.0)
            } else {
                0.0
            }
        };
        let Some(c) = self.controller.as_mut() else {
            let (reward, terminated, truncated) = self.tick(task, action[0]);
            return Outcome {
                reward,
                terminated,
                truncated,
            };
        };
        let Action::Impedance { controller, ticks } = &task.action else {
            unreachable!("an episode has a controller only under the impedance action")
        };
        let p0 = controller.filter().params();
        let retuned = ImpedanceParams {
            m_d_kg: p0.m_d_kg * 4f64.powf(clamp(action[0])),
            b_d_ns_per_m: p0.b_d_ns_per_m * 4f64.powf(clamp(action[1])),
            k_d_n_per_m: p0.k_d_n_per_m,
        };
        // Positive and finite by construction: the scene's parameters were validated.
        let _ = c.set_impedance(retuned);
        let mut out = Outcome::default();
        for _ in 0..*ticks {
            let mut s: Sensors = self.plant.sense();
            s.t = self.t;
            let sp = task.setpoints.at(self.t);
            let u = self
                .controller
                .as_mut()
                .map_or(0.0, |c| c.update(&s, &sp, task.dt).u);
            let (reward, terminated, truncated) = self.tick(task, u);
            out.reward += reward;
            (out.terminated, out.truncated) = (terminated, truncated);
            if terminated || truncated {
                break;
            }
        }
        out
    }

    /// One control tick under valve command `u`: (reward, terminated, truncated).
    fn tick(&mut self, task: &Task, u: f64) -> (f64, bool, bool) {
        let u = if u.is_finite() {
            u.clamp(-1.0, 1.0)
        } else {
            0.0
        };
        self.plant
            .actuate(ValveCommand { u }, &Telemetry::default());
        self.plant.advance(task.dt);
        self.t += task.dt;
        self.apply_due();
        let s = self.plant.sense();
        let f_ref = task.setpoints.at(self.t).f_ref;
        let reward = tick_reward(f_ref, s.f_e);
        let terminated = s.x <= 0.0 || s.x >= task.stroke || !s.x.is_finite();
        let truncated = self.t >= task.duration - 0.5 * task.dt;
        (reward, terminated, truncated && !terminated)
    }
}

/// What one step of the batch returns for one episode.
#[derive(Clone, Copy, Default)]
struct Outcome {
    reward: f64,
    terminated: bool,
    truncated: bool,
}

/// A batch of force-control episodes on a 1-DOF pneumatic scene (the Rust side of `pneuflex.envs`).
#[pyclass(name = "ForceControlBatch", module = "pneuflex")]
pub struct PyForceControlBatch {
    /// The constructor's arguments (a pickle rebuilds the batch from them, then replays its state).
    args: Args,
    task: Task,
    episodes: Vec<Episode>,
    randomize: bool,
    /// Whether an ended episode is reset by the next step (a vector environment) or stays ended.
    autoreset: bool,
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
}

/// The batch's thread pool, one per process: a pool made before a `fork` has no threads in the child (a
/// parallel step there would wait for them forever), so a process whose id is not the pool's makes its own.
mod pool {
    use std::sync::{Arc, Mutex};

    static POOL: Mutex<Option<(u32, Arc<rayon::ThreadPool>)>> = Mutex::new(None);

    /// This process's pool (made on first use; `RAYON_NUM_THREADS` or one thread per core).
    pub fn this_process() -> Arc<rayon::ThreadPool> {
        let pid = std::process::id();
        let mut held = POOL.lock().unwrap_or_else(|e| e.into_inner());
        if let Some((owner, pool)) = held.as_ref()
            && *owner == pid
        {
            return pool.clone();
        }
        // The parent's pool: its threads are not in this process, and dropping it would signal them.
        if let Some(old) = held.take() {
            std::mem::forget(old);
        }
        let pool = Arc::new(
            rayon::ThreadPoolBuilder::new()
                .thread_name(|i| format!("pneuflex-gym-{i}"))
                .build()
                .expect("a thread pool for the batch"),
        );
        *held = Some((pid, pool.clone()));
        pool
    }
}

/// One episode's state in a pickle: (stream, k, randomized, the actions since its start as float64 bytes).
type EpisodeState = (u64, u64, bool, Vec<u8>);

/// The actions of a step: a 1-D float64 numpy array (contiguous or not); anything else is a TypeError
/// saying what is expected.
fn flat_actions(actions: &Bound<'_, PyAny>) -> PyResult<Vec<f64>> {
    match actions.extract::<PyReadonlyArray1<'_, f64>>() {
        Ok(a) => Ok(a.as_array().to_vec()),
        Err(_) => Err(pyo3::exceptions::PyTypeError::new_err(format!(
            "actions must be a 1-D float64 numpy array (num_envs x action_width values), got {}",
            describe(actions)
        ))),
    }
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
    /// `num_envs` episodes of the scene at `scene_path` (a pneumatic 1-DOF or a multibody scene), at the
    /// scene's values until reset. `randomize`: draw each episode's stiffness before and after the change
    /// (log-uniform 350-2800 N/m), the change's time (uniform 4-8 s) and, on the 1-DOF plant, the moving
    /// mass, the seal friction and an on/off valve's switching delay (each log-uniform 0.5-2x the sheet's)
    /// at every reset; otherwise the scene's own values. `autoreset`: a step resets an episode that ended at the step before
    /// (Gymnasium's next-step autoreset), returning its first observation. `action`: "valve" (u, one tick
    /// per step) or "impedance" (a_m, a_b retune the scene's impedance run: m_d = m_d0 4^a_m,
    /// b_d = b_d0 4^a_b, then `decision_ticks` ticks of that controller per step, the rewards summed).
    #[new]
    #[pyo3(signature = (scene_path, num_envs = 1, randomize = true, autoreset = false, action = "valve", decision_ticks = 10, max_episode_steps = None))]
    fn new(
        scene_path: crate::shipped::ScenePath,
        num_envs: usize,
        randomize: bool,
        autoreset: bool,
        action: &str,
        decision_ticks: u32,
        max_episode_steps: Option<u64>,
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
        let mut task = Task::load(&scene_path, action, decision_ticks).map_err(|e| {
            // A scene with [[actuators]] reads as an unknown key of a one-plant scene: say what it is.
            let text = std::fs::read_to_string(&scene_path).unwrap_or_default();
            if pneuflex_scene::mechanism::MechanismScene::is_mechanism(&text) {
                errors::other(format!(
                    "{}: a scene with [[actuators]] (several cylinders): the force-control environments \
                     take a scene with one [plant], pneumatic or multibody",
                    scene_path.display()
                ))
            } else {
                errors::scene(e)
            }
        })?;
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
            },
            task,
            episodes,
            randomize,
            autoreset,
        })
    }

    /// The constructor's arguments, for pickle (with `__getstate__`, what rebuilds this batch).
    #[allow(clippy::type_complexity)]
    fn __getnewargs__(&self) -> (PathBuf, usize, bool, bool, String, u32, Option<u64>) {
        let a = &self.args;
        (
            a.scene_path.clone(),
            a.num_envs,
            a.randomize,
            self.autoreset,
            a.action.clone(),
            a.decision_ticks,
            a.max_episode_steps,
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
        let width = self.task.action.width();
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
        let episodes = &mut self.episodes;
        let pool = pool::this_process();
        py.detach(|| {
            pool.install(|| {
                episodes.par_iter_mut().zip(saved.par_iter()).for_each(
                    |(e, (stream, k, randomized, bytes))| {
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
                    },
                );
            })
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

    /// One step of every episode under `actions`, `action_width` values per episode, flat (a valve command,
    /// or the impedance adjustments a_m, a_b): finite values, clipped to [-1, 1]; a NaN or an infinity is
    /// refused, naming the episode and the value. Returns (observations (num_envs, 6) float32, rewards,
    /// terminated, truncated).
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
        let width = self.task.action.width();
        let u = flat_actions(actions)?;
        if u.len() != n * width {
            return Err(PyValueError::new_err(format!(
                "actions: {} values for {n} environments of {width} each",
                u.len()
            )));
        }
        // A NaN would be read as some command (the valve closed, the scene's gains): refused instead.
        if let Some(k) = u.iter().position(|v| !v.is_finite()) {
            return Err(PyValueError::new_err(format!(
                "actions[{k}] (environment {}, value {}) is {}: an action must be finite (values outside \
                 [-1, 1] are clipped)",
                k / width,
                k % width,
                u[k]
            )));
        }
        let mut obs = vec![0f32; n * OBS];
        let mut out = vec![Outcome::default(); n];
        let (task, randomize, autoreset) = (&self.task, self.randomize, self.autoreset);
        let episodes = &mut self.episodes;
        let pool = pool::this_process();
        py.detach(|| {
            pool.install(|| {
                // Chunks of episodes to the cores: an episode's tick is about a microsecond.
                let chunk = n.div_ceil(4 * rayon::current_num_threads()).max(16);
                episodes
                    .par_chunks_mut(chunk)
                    .zip(obs.par_chunks_mut(chunk * OBS))
                    .zip(out.par_chunks_mut(chunk))
                    .zip(u.par_chunks(chunk * width))
                    .for_each(|(((eps, obs), out), u)| {
                        for (((e, o), r), u) in eps
                            .iter_mut()
                            .zip(obs.chunks_mut(OBS))
                            .zip(out.iter_mut())
                            .zip(u.chunks(width))
                        {
                            if e.ended && autoreset {
                                e.next_episode(task, randomize);
                            } else {
                                *r = e.step(task, u);
                                e.ended = r.terminated || r.truncated;
                            }
                            e.observe(task, o);
                        }
                    });
            });
        });
        let obs = obs.into_pyarray(py).reshape([n, OBS])?;
        let rewards = out.iter().map(|o| o.reward).collect::<Vec<_>>();
        let term = out.iter().map(|o| o.terminated).collect::<Vec<_>>();
        let trunc = out.iter().map(|o| o.truncated).collect::<Vec<_>>();
        Ok((
            obs,
            rewards.into_pyarray(py),
            term.into_pyarray(py),
            trunc.into_pyarray(py),
        ))
    }

    /// Each episode's parameters as arrays: stiffness_n_per_m (before the change),
    /// stiffness_after_n_per_m, t_change_s, mass_scale, friction_scale, switching_delay_scale.
    fn params<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let d = PyDict::new(py);
        let col = |f: fn(&Draw) -> f64| {
            self.episodes
                .iter()
                .map(|e| f(&e.draw))
                .collect::<Vec<_>>()
                .into_pyarray(py)
        };
        d.set_item("stiffness_n_per_m", col(|d| d.k_before))?;
        d.set_item("stiffness_after_n_per_m", col(|d| d.k_after))?;
        d.set_item("t_change_s", col(|d| d.t_change_s))?;
        d.set_item("mass_scale", col(|d| d.mass_scale))?;
        d.set_item("friction_scale", col(|d| d.friction_scale))?;
        d.set_item("switching_delay_scale", col(|d| d.delay_scale))?;
        Ok(d)
    }

    /// Episode `i`'s time and sensors in SI (pressures absolute): (t, x, x_dot, f_e, p_a, p_b); a
    /// controller reads them as a policy.
    fn sensors(&self, i: usize) -> PyResult<(f64, f64, f64, f64, f64, f64)> {
        let e = self.episodes.get(i).ok_or_else(|| {
            PyValueError::new_err(format!(
                "environment {i} out of range: the batch has {}",
                self.episodes.len()
            ))
        })?;
        let s = e.plant.sense();
        Ok((e.t, s.x, s.x_dot, s.f_e, s.p_a, s.p_b))
    }

    /// The scene's (f_ref N, x_d m) at time `t` s.
    fn setpoint(&self, t: f64) -> (f64, f64) {
        let s = self.task.setpoints.at(t);
        (s.f_ref, s.x_d)
    }

    /// Number of episodes.
    #[getter]
    fn num_envs(&self) -> usize {
        self.episodes.len()
    }

    /// Values per action: 1 (the valve command) or 2 (the impedance adjustments a_m, a_b).
    #[getter]
    fn action_width(&self) -> usize {
        self.task.action.width()
    }

    /// Control ticks per step: 1 under the valve action, `decision_ticks` under the impedance action.
    #[getter]
    fn ticks_per_step(&self) -> u32 {
        match self.task.action {
            Action::Valve => 1,
            Action::Impedance { ticks, .. } => ticks,
        }
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
    fn observations<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray2<f32>> {
        let n = self.episodes.len();
        let mut obs = vec![0f32; n * OBS];
        for (e, o) in self.episodes.iter().zip(obs.chunks_mut(OBS)) {
            e.observe(&self.task, o);
        }
        obs.into_pyarray(py)
            .reshape([n, OBS])
            .expect("n * 6 values reshape to (n, 6)")
    }
}
