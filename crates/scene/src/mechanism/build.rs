//! A mechanism scene built: its URDF in the general engine with each actuator's drive, setpoints and
//! sensors, and its events resolved (errors name the key that causes them); its step budget.

use pneuflex_control::SetpointSchedule;
use pneuflex_multibody::actuator::MuscleForceElement;
use pneuflex_multibody::actuator::pneuflex_muscle::{self, MuscleSheet};
use pneuflex_multibody::{
    ActuatorConfig, ActuatorFamily, ContactConfig, Mechanism, MechanismConfig, Mount,
};
use pneuflex_pneumatics::{ActuatorSheet, ChamberState};

use super::schema::MechanismScene;
use crate::error::SceneError;
use crate::plants::FlangeDrive;

/// The loop's and the plant's columns of each actuator in a mechanism run's row, after `t`: at most this
/// many per actuator beside its controller's own (the trace budget's count).
const COLUMNS_PER_ACTUATOR: u64 = 9;

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
        let columns = 1 + self.actuators.len() as u64 * (COLUMNS_PER_ACTUATOR + 8);
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

/// The mechanism, its actuators' drives and schedules, built from the scene: what every run starts from.
pub struct Built {
    pub(super) mechanism: Mechanism,
    pub(super) drives: Vec<Drive>,
    pub(super) schedules: Vec<SetpointSchedule>,
    /// Each actuator's force sensor: a contact's index, or None for the rod's load cell.
    pub(super) sensors: Vec<Option<usize>>,
    /// Each actuator's position sensor: a joint, or None for the cylinder's stroke.
    pub(super) positions: Vec<Option<String>>,
}

/// Builds the mechanism a scene describes (errors name the key that causes them).
pub fn build(scene: &MechanismScene) -> Result<Built, SceneError> {
    let urdf = scene.resolve(&scene.urdf);
    let robot = pneuflex_multibody::urdf_build::read_urdf(&urdf)
        .map_err(|e| scene.invalid("urdf", e.to_string()))?;
    let sheets = actuator_sheets(scene)?;
    let config = mechanism_config(scene, &sheets)?;
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
    check_events(scene, &mechanism)?;
    Ok(Built {
        mechanism,
        drives,
        schedules,
        sensors,
        positions,
    })
}

impl MechanismScene {
    /// Reads every actuator's sheet (through the overlay) and refuses one the mechanism cannot model.
    pub fn check_sheets(&self) -> Result<(), SceneError> {
        actuator_sheets(self).map(drop)
    }
}

/// An actuator's force element, of whichever family, as the engine steps it and the plant asks it.
pub type Drive = Box<dyn ActuatorFamily + Send>;

/// An actuator's sheet by family (the families' one seam on the scene's side: a new family is a variant
/// here and its force element in `pneuflex_multibody::actuator`). The sheet says which: a muscle sheet
/// has a `[muscle]` table (docs/muscles.md), any other is a cylinder's actuator sheet.
pub enum FamilySheet {
    /// A cylinder and its valve, supply and friction (docs/components.md).
    Cylinder(Box<ActuatorSheet>),
    /// A McKibben muscle and its 3/2 valve or regulator.
    Muscle(Box<MuscleSheet>),
}

impl FamilySheet {
    /// Reads the sheet at `path` (an edited copy from `overlay` in its place), of the family it gives.
    fn load(
        path: &std::path::Path,
        overlay: &pneuflex_pneumatics::FileOverlay,
    ) -> Result<Self, String> {
        let text = match overlay.get(path) {
            Some(t) => t.clone(),
            None => pneuflex_files::read_text(path, pneuflex_files::InputKind::Sheet)
                .map_err(|e| e.to_string())?,
        };
        if text
            .parse::<toml::Table>()
            .is_ok_and(|t| t.contains_key("muscle"))
        {
            return MuscleSheet::from_str(path, &text)
                .map(|m| Self::Muscle(Box::new(m)))
                .map_err(|e| e.to_string());
        }
        ActuatorSheet::load_overlaid(path, overlay)
            .map(|a| Self::Cylinder(Box::new(a)))
            .map_err(|e| e.to_string())
    }

    /// An anchors mount's (retracted length, stroke), m: a cylinder's retracted length is the scene's
    /// `anchors.retracted_length_m` and its stroke the sheet's; a muscle's span from fully contracted,
    /// L0 (1 - eps_max), to its rest length L0 (M6), both from its sheet.
    fn span(&self, retracted_m: Option<f64>) -> Result<(f64, f64), &'static str> {
        match (self, retracted_m) {
            (Self::Cylinder(s), Some(r)) => Ok((r, s.actuator().cylinder.stroke_m)),
            (Self::Cylinder(_), None) => {
                Err("a cylinder between anchors needs anchors.retracted_length_m")
            }
            (Self::Muscle(m), None) => {
                let b = &m.chamber.muscle.braid;
                let l_min = b.rest_length_m * (1.0 - b.max_contraction());
                Ok((l_min, b.rest_length_m - l_min))
            }
            (Self::Muscle(_), Some(_)) => Err(
                "a muscle's lengths come from its sheet (fully contracted to rest): give no retracted_length_m",
            ),
        }
    }
}

/// Each actuator's sheet, refused when it models more than a mechanism's actuators do.
fn actuator_sheets(scene: &MechanismScene) -> Result<Vec<FamilySheet>, SceneError> {
    let mut sheets = Vec::with_capacity(scene.actuators.len());
    for (i, a) in scene.actuators.iter().enumerate() {
        let path = scene.resolve(&a.sheet);
        let key = format!("actuators[{i}].sheet");
        let sheet = match FamilySheet::load(&path, &scene.overlay)
            .map_err(|e| scene.invalid(&key, e))?
        {
            FamilySheet::Cylinder(s) => s,
            FamilySheet::Muscle(m) => {
                if a.anchors.is_none() {
                    return Err(scene.invalid(
                        &format!("actuators[{i}].joint"),
                        format!(
                            "{} is a muscle: it pulls between two anchor points, give `anchors` (no joint mount)",
                            path.display()
                        ),
                    ));
                }
                sheets.push(FamilySheet::Muscle(m));
                continue;
            }
        };
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
        sheets.push(FamilySheet::Cylinder(sheet));
    }
    Ok(sheets)
}

/// The multibody crate's description of the scene's mechanism.
fn mechanism_config(
    scene: &MechanismScene,
    sheets: &[FamilySheet],
) -> Result<MechanismConfig, SceneError> {
    let mut actuators = Vec::with_capacity(sheets.len());
    for (i, (a, sheet)) in scene.actuators.iter().zip(sheets).enumerate() {
        actuators.push(ActuatorConfig {
            name: a.name.clone(),
            mount: match (&a.joint, &a.anchors) {
                (Some(j), _) => Mount::Joint { joint: j.clone() },
                (None, Some(an)) => {
                    let (retracted_length_m, stroke_m) =
                        sheet.span(an.retracted_length_m).map_err(|m| {
                            scene.invalid(
                                &format!("actuators[{i}].anchors.retracted_length_m"),
                                m.into(),
                            )
                        })?;
                    Mount::Anchors {
                        link_a: an.link_a.clone(),
                        point_a_m: an.point_a_m,
                        link_b: an.link_b.clone(),
                        point_b_m: an.point_b_m,
                        retracted_length_m,
                        stroke_m,
                    }
                }
                (None, None) => unreachable!("checked at load: one mount per actuator"),
            },
        });
    }
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
    Ok(MechanismConfig {
        actuators,
        contacts,
        gravity_m_s2: scene.gravity_m_s2,
        dt_s: scene.dt_s / f64::from(scene.physics_steps_per_tick),
        solver_iterations: scene.solver_iterations,
        pad_integration: match scene.pads {
            super::schema::PadSpec::Explicit => pneuflex_multibody::PadIntegration::Explicit,
            super::schema::PadSpec::Implicit => pneuflex_multibody::PadIntegration::Implicit,
        },
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
    })
}

/// Actuator `i`'s force element at rest, its setpoints and the contact its force sensor reads (None: the
/// rod's load cell).
fn actuator_drive(
    scene: &MechanismScene,
    mechanism: &Mechanism,
    i: usize,
    sheet: &FamilySheet,
) -> Result<(Drive, SetpointSchedule, Option<usize>), SceneError> {
    let a = &scene.actuators[i];
    let drive: Drive = match sheet {
        FamilySheet::Cylinder(sheet) => Box::new(cylinder_drive(scene, mechanism, i, sheet)?),
        // Unpressurised, the gas at the atmosphere's temperature: the muscle pulls nothing until filled.
        FamilySheet::Muscle(m) => {
            let s = &m.chamber.supply;
            Box::new(MuscleForceElement::new(
                m.chamber,
                m.plant_feed(),
                pneuflex_muscle::ChamberState {
                    pressure_pa: s.atmosphere_pressure_pa,
                    temperature_k: s.atmosphere_temperature_k,
                },
                scene.chamber_substeps,
            ))
        }
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

/// A cylinder's drive at rest with no net force.
fn cylinder_drive(
    scene: &MechanismScene,
    mechanism: &Mechanism,
    i: usize,
    sheet: &ActuatorSheet,
) -> Result<FlangeDrive, SceneError> {
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
    Ok(FlangeDrive {
        element,
        friction: sheet.mechanics.friction,
        // Gravity is Rapier's; along an anchored cylinder it has no one value to drive stick-slip.
        gravity_force_n: 0.0,
    })
}

/// Checks that every event names a contact or a spring of the mechanism, and only one of them: the loop
/// applies an event by that name ([`super::plant::MechanismPlant`]).
fn check_events(scene: &MechanismScene, mechanism: &Mechanism) -> Result<(), SceneError> {
    for (i, e) in scene.events.iter().enumerate() {
        let at = |k: &str| format!("events[{i}].{k}");
        match (&e.contact, &e.spring) {
            (Some(c), _) => {
                mechanism
                    .contact_index(c)
                    .map_err(|err| scene.invalid(&at("contact"), err.to_string()))?;
                if mechanism.spring_index(c).is_ok() {
                    return Err(scene.invalid(
                        &at("contact"),
                        format!(
                            "'{c}' names both a contact and a spring: give them different names"
                        ),
                    ));
                }
            }
            (None, Some(sp)) => {
                mechanism
                    .spring_index(sp)
                    .map_err(|err| scene.invalid(&at("spring"), err.to_string()))?;
                if mechanism.contact_index(sp).is_ok() {
                    return Err(scene.invalid(
                        &at("spring"),
                        format!(
                            "'{sp}' names both a contact and a spring: give them different names"
                        ),
                    ));
                }
            }
            (None, None) => unreachable!("checked at load: one target per event"),
        }
    }
    Ok(())
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
