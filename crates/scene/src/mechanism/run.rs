//! Runs a mechanism scene: per run, one controller per actuator closes its loop on its own contact force
//! and stroke, every tick `sense → update → set valve → physics_steps_per_tick physics steps` (zero-order
//! hold), events on their tick.

use pneuflex_control::{Controller, Sensors, SetpointSchedule};
use pneuflex_multibody::{
    ActuatorConfig, ContactConfig, ContactParams, Mechanism, MechanismConfig, Mount,
};
use pneuflex_pneumatics::{ActuatorSheet, ChamberState};

use super::schema::MechanismScene;
use crate::error::SceneError;
use crate::plants::FlangeDrive;

/// The loop's columns of each actuator, after its name and a dot (`left.f_e`): name, SI unit, plot group.
pub const ACTUATOR_COLUMNS: [(&str, &str, &str); 8] = [
    ("f_r", "N", "force"),
    ("f_e", "N", "force"),
    ("x", "m", "position"),
    ("x_dot", "m/s", "velocity"),
    ("u", "1", "valve"),
    ("p_a", "Pa", "pressure"),
    ("p_b", "Pa", "pressure"),
    ("force", "N", "cylinder"),
];

impl MechanismScene {
    /// Every inner step of a run: per physics step, the solver's iterations and each actuator's chamber
    /// substeps, all physics steps of every tick.
    pub fn inner_steps_per_run(&self) -> u64 {
        let ticks = self.n_steps() as u64 + 1;
        let per_physics_step = (self.solver_iterations as u64).saturating_add(
            u64::from(self.chamber_substeps).saturating_mul(self.actuators.len() as u64),
        );
        ticks
            .saturating_mul(u64::from(self.physics_steps_per_tick))
            .saturating_mul(per_physics_step)
    }

    /// Refuses a scene whose runs would take more physics steps or trace memory than `limits` allow (the
    /// same limits as a one-actuator scene's, `--max-steps` and `--max-trace-mb`), before anything runs.
    pub fn check_budget(&self, limits: &crate::Limits) -> Result<(), SceneError> {
        let ticks = self.n_steps() as u64 + 1;
        let steps = self.inner_steps_per_run();
        if steps > limits.max_steps_per_run {
            // Blame the key that multiplies the cost most (a tick's share of each inner loop).
            let n = self.actuators.len() as u64;
            let key = [
                (
                    "physics_steps_per_tick",
                    u64::from(self.physics_steps_per_tick),
                ),
                ("solver_iterations", self.solver_iterations as u64),
                ("chamber_substeps", u64::from(self.chamber_substeps) * n),
            ]
            .into_iter()
            .max_by_key(|&(_, f)| f)
            .map_or("physics_steps_per_tick", |(k, _)| k);
            return Err(self.invalid(
                key,
                format!(
                    "the scene needs {steps:.3e} inner steps per run ({ticks} ticks x physics_steps_per_tick = {} x \
                     (solver_iterations = {} + chamber_substeps = {} x {n} actuator(s))), more than the limit of \
                     {:.3e}; use fewer, a shorter run, or raise the limit with `--max-steps {steps}`",
                    self.physics_steps_per_tick,
                    self.solver_iterations,
                    self.chamber_substeps,
                    limits.max_steps_per_run as f64
                ),
            ));
        }
        // A row: t, then per actuator the loop's columns and at most 8 of the controller's own, 8 bytes each.
        let columns = 1 + self.actuators.len() as u64 * (ACTUATOR_COLUMNS.len() as u64 + 8);
        let bytes = ticks
            .saturating_mul(columns * 8)
            .saturating_mul(self.runs.len() as u64);
        if bytes > limits.max_trace_bytes {
            let mib = bytes as f64 / f64::from(1u32 << 20);
            return Err(self.invalid(
                "duration_s",
                format!(
                    "the traces of {} run(s) of {ticks} ticks need up to {mib:.0} MiB, more than the limit of {:.0} \
                     MiB; shorten the run or raise the limit with `--max-trace-mb {}`",
                    self.runs.len(),
                    limits.max_trace_bytes as f64 / f64::from(1u32 << 20),
                    mib.ceil()
                ),
            ));
        }
        Ok(())
    }
}

/// One column of a run's trace after `t`: its actuator, its name there, SI unit and plot group.
#[derive(Clone, Debug, PartialEq)]
pub struct ColumnSignal {
    /// The actuator it belongs to.
    pub actuator: String,
    /// Its name within the actuator (`f_e`, or a controller's own `g`).
    pub name: &'static str,
    /// SI unit.
    pub unit: &'static str,
    /// Plot group (`force`, `position`, `adaptive`, ...).
    pub group: &'static str,
}

/// What watches a run as it goes (a viewer): the mechanism before the first tick, every row, the end.
pub trait MechanismObserver {
    /// A run starts: its name, the mechanism at t = 0, and the columns after `t`.
    fn begin(&mut self, _run: &str, _mechanism: &Mechanism, _columns: &[ColumnSignal]) {}
    /// A tick's row (`t` first, then the columns given to `begin`), with the mechanism at that time.
    fn tick(&mut self, _mechanism: &Mechanism, _row: &[f64]) {}
    /// The run ended.
    fn end(&mut self) {}
}

impl MechanismObserver for () {}

/// One run's trace: `t`, then each actuator's [`ACTUATOR_COLUMNS`] and its controller's own signals.
#[derive(Clone, Debug)]
pub struct MechanismRun {
    /// Run name.
    pub name: String,
    /// Column names.
    pub columns: Vec<String>,
    /// Rows, one per tick from t = 0 to the duration, each `columns.len()` values.
    pub rows: Vec<Vec<f64>>,
    /// Why the run stopped early (a NaN, a cylinder pulled past its end stop), if it did.
    pub diverged: Option<String>,
    /// Whether it reached the scene's duration (false: diverged, or stopped by a signal).
    pub complete: bool,
}

impl MechanismRun {
    /// Its trace file's name, as every scene kind names it: `trace.csv` for a complete run,
    /// `trace.diverged.csv` or `trace.interrupted.csv` for one cut short (never mistaken for a whole run).
    pub fn trace_file(&self) -> &'static str {
        match (&self.diverged, self.complete) {
            (Some(_), _) => "trace.diverged.csv",
            (None, false) => "trace.interrupted.csv",
            (None, true) => "trace.csv",
        }
    }
}

impl MechanismRun {
    /// The column named `name`, or None.
    pub fn column(&self, name: &str) -> Option<Vec<f64>> {
        let i = self.columns.iter().position(|c| c == name)?;
        Some(self.rows.iter().map(|r| r[i]).collect())
    }
}

/// The mechanism, its actuators' drives and schedules, built from the scene: what every run starts from.
pub struct Built {
    mechanism: Mechanism,
    drives: Vec<FlangeDrive>,
    schedules: Vec<SetpointSchedule>,
    /// Each actuator's force sensor: a contact's index, or None for the rod's load cell.
    sensors: Vec<Option<usize>>,
    /// Each actuator's position sensor: a joint, or None for the cylinder's stroke.
    positions: Vec<Option<String>>,
    /// Each event: its tick, what it changes, the new values.
    events: Vec<(usize, EventTarget, ContactParams)>,
}

/// What an event changes.
#[derive(Clone, Copy, Debug)]
enum EventTarget {
    Contact(usize),
    Spring(usize),
}

/// Builds the mechanism a scene describes (errors name the key that causes them).
pub fn build(scene: &MechanismScene) -> Result<Built, SceneError> {
    let urdf = scene.resolve(&scene.urdf);
    let robot = pneuflex_multibody::urdf_build::read_urdf(&urdf)
        .map_err(|e| scene.invalid("urdf", e.to_string()))?;
    let sheets = actuator_sheets(scene)?;
    let config = mechanism_config(scene, &sheets);
    let mechanism = Mechanism::from_robot(&urdf, &robot, &config)
        .map_err(|e| scene.invalid(&mechanism_key(scene, &e), e.to_string()))?;
    let mut drives = Vec::with_capacity(sheets.len());
    let mut schedules = Vec::with_capacity(sheets.len());
    let mut sensors = Vec::with_capacity(sheets.len());
    for (i, sheet) in sheets.iter().enumerate() {
        let (drive, schedule, sensor) = actuator_drive(scene, &mechanism, i, sheet)?;
        drives.push(drive);
        schedules.push(schedule);
        sensors.push(sensor);
    }
    let mut positions = Vec::with_capacity(scene.actuators.len());
    for (i, a) in scene.actuators.iter().enumerate() {
        if let Some(j) = &a.position_sensor {
            mechanism.joint_position(j).map_err(|e| {
                scene.invalid(&format!("actuators[{i}].position_sensor"), e.to_string())
            })?;
        }
        positions.push(a.position_sensor.clone());
    }
    let events = scheduled_events(scene, &mechanism)?;
    Ok(Built {
        mechanism,
        drives,
        schedules,
        sensors,
        positions,
        events,
    })
}

/// Each actuator's sheet, refused when it models more than a mechanism's cylinders do.
fn actuator_sheets(scene: &MechanismScene) -> Result<Vec<ActuatorSheet>, SceneError> {
    let mut sheets = Vec::with_capacity(scene.actuators.len());
    for (i, a) in scene.actuators.iter().enumerate() {
        let path = scene.resolve(&a.sheet);
        let key = format!("actuators[{i}].sheet");
        let sheet = pneuflex_pneumatics::ActuatorSheet::load_overlaid(&path, &Default::default())
            .map_err(|e| scene.invalid(&key, e.to_string()))?;
        let beyond = sheet.effects_beyond_paper();
        if !beyond.is_empty() {
            return Err(scene.invalid(
                &key,
                format!(
                    "{} gives {}: a mechanism's cylinders model the paper's chambers, valve and friction only",
                    path.display(),
                    beyond.join(", ")
                ),
            ));
        }
        sheets.push(sheet);
    }
    Ok(sheets)
}

/// The multibody crate's description of the scene's mechanism.
fn mechanism_config(scene: &MechanismScene, sheets: &[ActuatorSheet]) -> MechanismConfig {
    let actuators = scene
        .actuators
        .iter()
        .zip(sheets)
        .map(|(a, sheet)| ActuatorConfig {
            name: a.name.clone(),
            mount: match (&a.joint, &a.anchors) {
                (Some(j), _) => Mount::Joint { joint: j.clone() },
                (None, Some(an)) => Mount::Anchors {
                    link_a: an.link_a.clone(),
                    point_a_m: an.point_a_m,
                    link_b: an.link_b.clone(),
                    point_b_m: an.point_b_m,
                    retracted_length_m: an.retracted_length_m,
                    stroke_m: sheet.actuator().cylinder.stroke_m,
                },
                (None, None) => unreachable!("checked at load: one mount per actuator"),
            },
        })
        .collect();
    let contacts = scene
        .contacts
        .iter()
        .map(|c| ContactConfig {
            name: c.name.clone(),
            link_a: c.link_a.clone(),
            link_b: c.link_b.clone(),
            stiffness_n_per_m: c.stiffness_n_per_m,
            damping_n_s_per_m: c.damping_n_s_per_m,
        })
        .collect();
    MechanismConfig {
        actuators,
        contacts,
        gravity_m_s2: scene.gravity_m_s2,
        dt_s: scene.dt_s / f64::from(scene.physics_steps_per_tick),
        solver_iterations: scene.solver_iterations,
        initial_positions: scene
            .actuators
            .iter()
            .filter_map(|a| Some((a.joint.clone()?, a.initial_position_m?)))
            .collect(),
        springs: scene
            .springs
            .iter()
            .map(|s| pneuflex_multibody::SpringConfig {
                name: s.name.clone(),
                joint: s.joint.clone(),
                stiffness: s.stiffness_n_per_m,
                damping: s.damping_n_s_per_m,
            })
            .collect(),
        held_links: scene.held_links.clone(),
    }
}

/// Actuator `i`'s force element at rest, its setpoints and the contact its force sensor reads (None: the
/// rod's load cell).
fn actuator_drive(
    scene: &MechanismScene,
    mechanism: &Mechanism,
    i: usize,
    sheet: &ActuatorSheet,
) -> Result<(FlangeDrive, SetpointSchedule, Option<usize>), SceneError> {
    let a = &scene.actuators[i];
    let actuator = sheet.actuator();
    let stroke = mechanism.actuator_stroke(i);
    if (stroke - actuator.cylinder.stroke_m).abs() > 1e-9 {
        return Err(scene.invalid(
            &format!("actuators[{i}].sheet"),
            format!(
                "the cylinder's stroke is {} m, the joint '{}' allows {stroke} m: they must agree",
                actuator.cylinder.stroke_m,
                a.joint.as_deref().unwrap_or("")
            ),
        ));
    }
    // At rest with no net force: B halfway between supply and atmosphere, A balancing it (eq. (1)).
    let (s, c) = (&actuator.supply, &actuator.cylinder);
    let p_b = 0.5 * (s.supply_pressure_pa + s.atmosphere_pressure_pa);
    let p_a = (p_b * c.area_b() + s.atmosphere_pressure_pa * c.area_rod()) / c.area_a();
    let element = pneuflex_multibody::PneumaticForceElement::new(
        actuator,
        ChamberState::new(p_a, p_b),
        scene.chamber_substeps,
    );
    let drive = FlangeDrive {
        element,
        friction: sheet.mechanics.friction,
        // Gravity is Rapier's; along an anchored cylinder it has no one value to drive stick-slip.
        gravity_force_n: 0.0,
    };
    let mut sp = SetpointSchedule::default();
    for (j, piece) in a.force.iter().enumerate() {
        sp.force_n
            .push(piece.start_s(), piece.reference())
            .map_err(|e| scene.invalid(&format!("actuators[{i}].force[{j}]"), e.to_string()))?;
    }
    sp.position_m
        .push(
            0.0,
            pneuflex_control::Reference::Constant { value: a.x_d_m },
        )
        .map_err(|e| scene.invalid(&format!("actuators[{i}].x_d_m"), e.to_string()))?;
    let sensor =
        if a.force_sensor == super::schema::LOAD_CELL {
            None
        } else {
            Some(mechanism.contact_index(&a.force_sensor).map_err(|e| {
                scene.invalid(&format!("actuators[{i}].force_sensor"), e.to_string())
            })?)
        };
    Ok((drive, sp, sensor))
}

/// Each event's tick, what it changes and the values it sets.
fn scheduled_events(
    scene: &MechanismScene,
    mechanism: &Mechanism,
) -> Result<Vec<(usize, EventTarget, ContactParams)>, SceneError> {
    let mut events = Vec::with_capacity(scene.events.len());
    for (i, e) in scene.events.iter().enumerate() {
        let at = |k: &str| format!("events[{i}].{k}");
        let (target, old) = match (&e.contact, &e.spring) {
            (Some(c), _) => {
                let ci = mechanism
                    .contact_index(c)
                    .map_err(|err| scene.invalid(&at("contact"), err.to_string()))?;
                (EventTarget::Contact(ci), mechanism.contact_params(ci))
            }
            (None, Some(sp)) => {
                let si = mechanism
                    .spring_index(sp)
                    .map_err(|err| scene.invalid(&at("spring"), err.to_string()))?;
                (EventTarget::Spring(si), mechanism.spring_params(si))
            }
            (None, None) => unreachable!("checked at load: one target per event"),
        };
        let tick = (e.t_s / scene.dt_s).round() as usize;
        events.push((
            tick,
            target,
            ContactParams {
                stiffness_n_per_m: e.stiffness_n_per_m,
                damping_n_s_per_m: e.damping_n_s_per_m.unwrap_or(old.damping_n_s_per_m),
            },
        ));
    }
    Ok(events)
}

/// The scene key a mechanism error is about: the actuator or contact key it names, or the URDF.
fn mechanism_key(scene: &MechanismScene, e: &pneuflex_multibody::MultibodyError) -> String {
    let pneuflex_multibody::MultibodyError::BadMechanism { item, key, .. } = e else {
        return "urdf".into();
    };
    if let Some(i) = scene.actuators.iter().position(|a| {
        a.joint
            .as_ref()
            .is_some_and(|j| *item == format!("initial position of joint '{j}'"))
    }) {
        return format!("actuators[{i}].initial_position_m");
    }
    if let Some(i) = scene
        .actuators
        .iter()
        .position(|a| *item == format!("actuator '{}'", a.name))
    {
        let k = match *key {
            "initial_x_m" => "initial_position_m".into(),
            "link_a" | "link_b" => format!("anchors.{key}"),
            "point_a" | "point_b" | "retracted_length" => format!("anchors.{key}_m"),
            "stroke" => "sheet".into(),
            other => other.into(),
        };
        return format!("actuators[{i}].{k}");
    }
    if let Some(i) = scene
        .springs
        .iter()
        .position(|s| *item == format!("spring '{}'", s.name))
    {
        let k = match *key {
            "stiffness" => "stiffness_n_per_m",
            "damping" => "damping_n_s_per_m",
            other => other,
        };
        return format!("springs[{i}].{k}");
    }
    if *key == "held_links" {
        return "held_links".into();
    }
    if let Some(i) = scene
        .contacts
        .iter()
        .position(|c| *item == format!("contact '{}'", c.name))
    {
        let k = match *key {
            "stiffness" => "stiffness_n_per_m",
            "damping" => "damping_n_s_per_m",
            other => other,
        };
        return format!("contacts[{i}].{k}");
    }
    "urdf".into()
}

/// Runs every run of the scene; `progress` gets the fraction done, `stop` is polled every tick (a signal).
pub fn run_all(
    scene: &MechanismScene,
    progress: &mut dyn FnMut(f64),
    stop: &dyn Fn() -> bool,
    observer: &mut dyn MechanismObserver,
) -> Result<Vec<MechanismRun>, SceneError> {
    let mut out = Vec::with_capacity(scene.runs.len());
    for (r, spec) in scene.runs.iter().enumerate() {
        let built = build(scene)?;
        let controllers = (0..scene.actuators.len())
            .map(|a| scene.actuator_run(r, a).build())
            .collect::<Result<Vec<_>, _>>()
            .map_err(|e| scene.invalid(&format!("runs[{r}].{}", e.key), e.message))?;
        let n = scene.runs.len() as f64;
        let run = run_one(
            scene,
            &spec.name,
            built,
            controllers,
            &mut |f| progress((r as f64 + f) / n),
            stop,
            observer,
        );
        let stopped = !run.complete && run.diverged.is_none();
        out.push(run);
        if stopped {
            break;
        }
    }
    Ok(out)
}

/// Why actuator states at time `t` are a divergence (the first actuator that breaks an invariant, named),
/// through the checks every scene kind's loop makes: [`crate::schema::DivergenceSpec::exceeded`] and
/// [`crate::plants::chamber_invariants`]. `row` is the tick's trace row, `sensed` each actuator's columns
/// of f_e and x in it, `x_r` each controller's reference position.
fn actuator_invariants(
    scene: &MechanismScene,
    b: &Built,
    sensed: &[(usize, usize)],
    x_r: &[f64],
    row: &[f64],
    t: f64,
) -> Option<String> {
    for (i, (a, &(f_e, x))) in scene.actuators.iter().zip(sensed).enumerate() {
        if let Some(why) = scene.divergence.exceeded(t, row[x], row[f_e], x_r[i]) {
            return Some(format!("{}: {why}", a.name));
        }
        let el = &b.drives[i].element;
        let stroke = b.mechanism.actuator_stroke(i);
        let piston = b.mechanism.actuator_state(i).x_m;
        if let Err(v) =
            crate::plants::chamber_invariants(&el.chambers, &el.actuator.supply, piston, stroke)
        {
            return Some(format!("{}: {v} at t = {t:.4} s", a.name));
        }
    }
    None
}

fn run_one(
    scene: &MechanismScene,
    name: &str,
    mut b: Built,
    mut controllers: Vec<Box<dyn Controller + Send + Sync>>,
    progress: &mut dyn FnMut(f64),
    stop: &dyn Fn() -> bool,
    observer: &mut dyn MechanismObserver,
) -> MechanismRun {
    let mut signals = Vec::new();
    for (a, c) in scene.actuators.iter().zip(&controllers) {
        let own = c.signals().iter().map(|s| (s.name, s.unit, s.group));
        for (name, unit, group) in ACTUATOR_COLUMNS.iter().copied().chain(own) {
            signals.push(ColumnSignal {
                actuator: a.name.clone(),
                name,
                unit,
                group,
            });
        }
    }
    let columns: Vec<String> = std::iter::once("t".to_string())
        .chain(signals.iter().map(|s| format!("{}.{}", s.actuator, s.name)))
        .collect();
    let column = |a: &str, s: &str| {
        columns
            .iter()
            .position(|c| *c == format!("{a}.{s}"))
            .expect("every actuator has the loop's columns")
    };
    let sensed: Vec<(usize, usize)> = scene
        .actuators
        .iter()
        .map(|a| (column(&a.name, "f_e"), column(&a.name, "x")))
        .collect();
    observer.begin(name, &b.mechanism, &signals);
    let n = scene.n_steps();
    let dt = scene.dt_s;
    let mut rows = Vec::with_capacity(n + 1);
    let mut diverged = None;
    let mut own = Vec::new();
    let mut x_r = vec![0.0; scene.actuators.len()];
    for k in 0..=n {
        let t = k as f64 * dt;
        for &(tick, target, params) in &b.events {
            if tick == k {
                match target {
                    EventTarget::Contact(i) => b.mechanism.set_contact(i, params),
                    EventTarget::Spring(i) => b.mechanism.set_spring(i, params),
                }
                .expect("checked at load");
            }
        }
        let mut row = Vec::with_capacity(columns.len());
        row.push(t);
        for (i, c) in controllers.iter_mut().enumerate() {
            let (x, x_dot) = match &b.positions[i] {
                Some(joint) => b.mechanism.joint_position(joint).expect("checked at build"),
                None => {
                    let s = b.mechanism.actuator_state(i);
                    (s.x_m, s.x_dot_m_s)
                }
            };
            let (p_a, p_b) = b.drives[i].element.pressures();
            let sensors = Sensors {
                t,
                x,
                x_dot,
                f_e: match b.sensors[i] {
                    Some(ci) => b.mechanism.contact(ci).force_n,
                    None => b.mechanism.actuator_force(i),
                },
                p_a,
                p_b,
            };
            let setpoint = b.schedules[i].at(t);
            let cmd = c.update(&sensors, &setpoint, dt);
            x_r[i] = c.telemetry().x_r;
            b.drives[i].element.set_command(cmd.u);
            row.extend([
                setpoint.f_ref,
                sensors.f_e,
                sensors.x,
                sensors.x_dot,
                cmd.u,
                p_a,
                p_b,
                b.mechanism.actuator_force(i),
            ]);
            own.resize(c.signals().len(), 0.0);
            c.record(&mut own);
            row.extend_from_slice(&own);
        }
        let bad = row.iter().position(|v| !v.is_finite());
        observer.tick(&b.mechanism, &row);
        rows.push(row);
        if let Some(j) = bad {
            diverged = Some(format!("{} is not finite at t = {t} s", columns[j]));
            break;
        }
        if let Err(why) = b.mechanism.check_strokes() {
            diverged = Some(format!("{why} at t = {t} s"));
            break;
        }
        // The same invariants as a one-actuator scene's, per actuator: position and force within the
        // scene's `[divergence]`, chambers within (0, 2 x supply], the piston within its stroke.
        if let Some(why) =
            actuator_invariants(scene, &b, &sensed, &x_r, rows.last().expect("pushed"), t)
        {
            diverged = Some(why);
            break;
        }
        if k == n || stop() {
            break;
        }
        // The drives step in place: no allocation in the loop.
        for _ in 0..scene.physics_steps_per_tick {
            b.mechanism.step(&mut b.drives);
            if let Err(why) = b.mechanism.check_strokes() {
                diverged = Some(format!("{why} at t = {t} s"));
                break;
            }
        }
        if diverged.is_some() {
            break;
        }
        if k % 1000 == 0 {
            progress(k as f64 / n as f64);
        }
    }
    progress(1.0);
    observer.end();
    MechanismRun {
        name: name.to_string(),
        complete: diverged.is_none() && rows.len() == n + 1,
        columns,
        rows,
        diverged,
    }
}
