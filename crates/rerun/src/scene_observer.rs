//! A scene's runs as Rerun recordings: [`SceneRecorder`] observes the run loop of `pneuflex-scene`
//! (`pneuflex run --rerun save FILE | spawn | connect URL`).
//!
//! It only reads the plant, so the results are those of a run without logging. Plants with geometry
//! (the multibody rig) are drawn link by link at their simulated poses, coloured by the role the plant
//! gives each shape; the chambers sit in the shape whose role is the cylinder and the contact force
//! starts at the flange. Plants without geometry are drawn as a schematic along the actuator axis from
//! the plant's [`ActuatorGeometry`]; a plant without an actuator (the ideal loop) as the flange and the
//! environment on a horizontal axis, without chambers.

use std::path::PathBuf;
use std::time::{Duration, Instant};

use pneuflex_control::Sink as SinkTrait;
use pneuflex_control::signal::index;
use pneuflex_scene::plants::{ActuatorGeometry, VisualRole};
use pneuflex_scene::run::trace::{Column, Row};
use pneuflex_scene::schema::{EventSpec, ForcePiece};
use pneuflex_scene::{Plant, Scene, VisualPose, VisualShape};

use crate::layout::{Eye, Layout};
use crate::{
    ChamberSample, Contact, EventLevel, LinkShape, RecorderOptions, RerunError, RunRecorder, Sink,
    paths, units,
};

/// Parses the words after `--rerun`: `save FILE`, `spawn` or `connect URL`.
pub fn parse_sink(words: &[String]) -> Result<Sink, RerunError> {
    match words {
        [mode, file] if mode == "save" => Ok(Sink::Save(PathBuf::from(file))),
        [mode] if mode == "spawn" => Ok(Sink::Spawn),
        [mode, url] if mode == "connect" => Ok(Sink::Connect(url.clone())),
        _ => Err(RerunError::BadOption {
            option: "--rerun",
            reason: format!(
                "takes `save <file.rrd>`, `spawn` or `connect <url>`, got `{}`",
                words.join(" ")
            ),
        }),
    }
}

/// The sink of one run: with several runs, `save a.rrd` writes `a-<run>.rrd` per run (one recording each).
pub fn sink_for_run(sink: &Sink, run: &str, n_runs: usize) -> Sink {
    match sink {
        Sink::Save(path) if n_runs > 1 => {
            let stem = path.file_stem().and_then(|s| s.to_str()).unwrap_or("run");
            let ext = path.extension().and_then(|s| s.to_str()).unwrap_or("rrd");
            Sink::Save(path.with_file_name(format!("{stem}-{run}.{ext}")))
        }
        other => other.clone(),
    }
}

/// Hamilton product a ⊗ b of quaternions [x, y, z, w].
fn qmul(a: [f64; 4], b: [f64; 4]) -> [f64; 4] {
    let [ax, ay, az, aw] = a;
    let [bx, by, bz, bw] = b;
    [
        aw * bx + ax * bw + ay * bz - az * by,
        aw * by - ax * bz + ay * bw + az * bx,
        aw * bz + ax * by - ay * bx + az * bw,
        aw * bw - ax * bx - ay * by - az * bz,
    ]
}

/// Rotates v by the unit quaternion q.
fn rotate(q: [f64; 4], v: [f64; 3]) -> [f64; 3] {
    let r = qmul(
        qmul(q, [v[0], v[1], v[2], 0.0]),
        [-q[0], -q[1], -q[2], q[3]],
    );
    [r[0], r[1], r[2]]
}

/// Quarter turn about y: takes z (the chambers' cylinder axis) onto x.
const Z_TO_X: [f64; 4] = [
    0.0,
    std::f64::consts::FRAC_1_SQRT_2,
    0.0,
    std::f64::consts::FRAC_1_SQRT_2,
];
/// Half turn about x: takes z onto -z.
const FLIP_Z: [f64; 4] = [1.0, 0.0, 0.0, 0.0];
const FLANGE_HALF_THICKNESS_M: f64 = 0.005;
const FLANGE_HALF_WIDTH_M: f64 = 0.02;
const FACE_HALF_THICKNESS_M: f64 = 0.0025;
/// Gap between the flange's edge and the force arrow beside it, m.
const ARROW_CLEARANCE_M: f64 = 0.012;
/// Length the largest reference force of a scene is drawn with, before rounding the scale, m.
const ARROW_LENGTH_FOR_MAX_FORCE_M: f64 = 0.06;

/// Colour of a plant's shape by its role: the environment translucent, so that the contact point behind
/// its face shows; the cylinder translucent, so that the chambers inside show.
pub(crate) fn role_colour(role: VisualRole) -> [u8; 4] {
    match role {
        VisualRole::Flange => [90, 90, 100, 255],
        VisualRole::Environment => [170, 120, 60, 140],
        VisualRole::Cylinder | VisualRole::Other => [170, 170, 180, 110],
    }
}
const ROD_COLOUR: [u8; 4] = [200, 200, 210, 255];

/// Dot product.
fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

/// a + s b.
fn add(a: [f64; 3], s: f64, b: [f64; 3]) -> [f64; 3] {
    std::array::from_fn(|k| a[k] + s * b[k])
}

/// Unit vector across `axis`, as close to world up (z) as it can be (world y if the axis is vertical).
fn up_across(axis: [f64; 3]) -> [f64; 3] {
    for guess in [[0.0, 0.0, 1.0], [0.0, 1.0, 0.0]] {
        let v = add(guess, -dot(guess, axis), axis);
        let n = dot(v, v).sqrt();
        if n > 1e-6 {
            return v.map(|c| c / n);
        }
    }
    [0.0, 0.0, 1.0]
}

/// The largest reference force magnitude of a scene over its duration, N (at least 1).
fn force_range_n(scene: &Scene) -> f64 {
    let pieces = &scene.reference.force;
    let mut f_max: f64 = 1.0;
    for (i, piece) in pieces.iter().enumerate() {
        let f = match *piece {
            ForcePiece::Step { value_n, .. } => value_n.abs(),
            ForcePiece::Sine {
                bias_n,
                amplitude_n,
                ..
            } => bias_n.abs() + amplitude_n.abs(),
            ForcePiece::Ramp {
                start_s,
                value0_n,
                slope_n_per_s,
            } => {
                let end = pieces.get(i + 1).map_or(scene.duration_s, |p| p.start_s());
                value0_n
                    .abs()
                    .max((value0_n + slope_n_per_s * (end - start_s).max(0.0)).abs())
            }
        };
        if f.is_finite() {
            f_max = f_max.max(f);
        }
    }
    f_max
}

/// Length of the force arrow per newton for a scene: the largest reference force drawn about
/// [`ARROW_LENGTH_FOR_MAX_FORCE_M`] long, rounded down to 1, 2 or 5 times a power of ten (m/N), so that
/// 10 N in a 10 N scene is 50 mm — the size of the rig.
pub fn force_arrow_scale(scene: &Scene) -> f64 {
    let raw = ARROW_LENGTH_FOR_MAX_FORCE_M / force_range_n(scene);
    let decade = 10f64.powf(raw.log10().floor());
    let mantissa = [5.0, 2.0, 1.0]
        .into_iter()
        .find(|m| m * decade <= raw * (1.0 + 1e-9))
        .unwrap_or(1.0);
    mantissa * decade
}

/// A scene event as a person reads it: `t = 3.00 s: carriage swaps the environment to iron (0.9 s)`,
/// `t = 6.00 s: environment stiffness 700 → 1400 N/m`. `state` follows the stiffnesses and the incline
/// over the events, for the "from" values.
fn describe_event(ev: &EventSpec, state: &mut EventState) -> String {
    let t = ev.t_s();
    let what = match ev {
        EventSpec::Stiffness {
            stiffness_n_per_m,
            material,
            damping_n_s_per_m,
            ..
        } => {
            let (subject, from) = match material {
                Some(m) => (
                    format!("{m} stiffness"),
                    state.materials.get(m.as_str()).copied(),
                ),
                None => ("environment stiffness".to_owned(), state.stiffness_n_per_m),
            };
            let from = from.map_or(String::new(), |k| format!("{} → ", number(k)));
            match material {
                Some(m) => {
                    state.materials.insert(m.clone(), *stiffness_n_per_m);
                }
                None => state.stiffness_n_per_m = Some(*stiffness_n_per_m),
            }
            let damping = damping_n_s_per_m
                .map_or(String::new(), |d| format!(", damping {} N·s/m", number(d)));
            format!(
                "{subject} {from}{} N/m{damping}",
                number(*stiffness_n_per_m)
            )
        }
        EventSpec::SwapEnvironment { to, duration_s, .. } => {
            format!(
                "carriage swaps the environment to {to} ({} s)",
                number(*duration_s)
            )
        }
        EventSpec::Alpha { alpha_deg, .. } => {
            let from = state
                .alpha_deg
                .map_or(String::new(), |a| format!("{} → ", number(a)));
            state.alpha_deg = Some(*alpha_deg);
            format!("platform incline {from}{}°", number(*alpha_deg))
        }
    };
    format!("t = {t:.2} s: {what}")
}

/// A number as a person writes it: no trailing zeros, at most 3 decimals.
fn number(v: f64) -> String {
    let s = format!("{v:.3}");
    let s = s.trim_end_matches('0').trim_end_matches('.');
    if s == "-0" { "0".into() } else { s.into() }
}

/// What the events change, as the event log follows it.
#[derive(Clone, Debug, Default)]
struct EventState {
    stiffness_n_per_m: Option<f64>,
    materials: std::collections::HashMap<String, f64>,
    alpha_deg: Option<f64>,
}

/// The schematic's axis: the actuator axis, tilted down by alpha, with the flange's retracted stop at
/// the origin (s = 0); the flange plate spans s in [x, x + 10 mm].
#[derive(Clone, Copy, Debug)]
struct Axis {
    alpha_rad: f64,
    x_e_m: f64,
}

impl Axis {
    /// Rotation taking x onto the actuator axis, tilted down by alpha about y (z up).
    fn along(&self) -> [f64; 4] {
        let h = 0.5 * self.alpha_rad;
        [0.0, h.sin(), 0.0, h.cos()]
    }

    /// The unit actuator axis.
    fn dir(&self) -> [f64; 3] {
        rotate(self.along(), [1.0, 0.0, 0.0])
    }

    /// Point at distance `s` along the axis from the flange's retracted stop.
    fn at(&self, s: f64) -> [f64; 3] {
        self.dir().map(|c| c * s)
    }
}

/// The schematic cylinder body along the axis, in the proportions of the rig's (urdf/rig.urdf: an 80 mm
/// body for a 50 mm stroke, its front end 5 mm behind the flange's retracted stop): end caps of 0.3
/// stroke each, the front end 0.1 stroke behind s = 0.
#[derive(Clone, Copy, Debug, PartialEq)]
struct SchematicBody {
    /// Back end of the body, s (m).
    back_s: f64,
    /// Front end of the body, s (m).
    front_s: f64,
    /// Outer radius, m.
    radius_m: f64,
}

impl SchematicBody {
    fn of(g: &ActuatorGeometry) -> Self {
        let front_s = -0.1 * g.stroke_m;
        Self {
            back_s: front_s - 1.6 * g.stroke_m,
            front_s,
            radius_m: 0.5 * g.bore_m + 0.004,
        }
    }

    /// Where chamber A starts: the stroke centred in the body.
    fn chamber_base_s(&self, stroke_m: f64) -> f64 {
        0.5 * (self.back_s + self.front_s) - 0.5 * stroke_m
    }
}

/// How the run's plant is drawn.
enum Drawing {
    /// Link by link from the plant's visuals.
    Links {
        /// Entity path of each visual.
        entities: Vec<String>,
        /// Poses of the visuals at the current tick.
        poses: Vec<VisualPose>,
        /// Index of the flange visual, its half thickness along its x and half width across.
        flange: Option<(usize, f64, f64)>,
        /// Index of the cylinder visual and its local axis.
        cylinder: Option<(usize, CylinderAxis)>,
    },
    /// The schematic along the actuator axis.
    Schematic(Axis),
}

/// Which local axis of the cylinder shape is the actuator axis.
#[derive(Clone, Copy, Debug)]
struct CylinderAxis {
    /// Rotation from the shape's frame to a frame whose z is the shape's axis.
    to_z: [f64; 4],
    /// Unit axis in the shape's frame.
    axis: [f64; 3],
}

/// The actuator as drawn at one tick (world frame, m).
#[derive(Clone, Copy, Debug, PartialEq)]
struct RigFrame {
    /// Unit actuator axis, from the cylinder towards the flange.
    axis: [f64; 3],
    /// Rotation taking z onto `axis`: the frame of the chambers and the rod.
    to_axis: [f64; 4],
    /// Start of chamber A (the back end of the stroke inside the body); None without chambers.
    chamber_base: Option<[f64; 3]>,
    /// Centre of the flange's back face, where the rod ends.
    flange_back: [f64; 3],
    /// Centre of the flange's front face, where it touches the environment.
    flange_front: [f64; 3],
    /// Unit vector across the axis, up as far as it can be.
    up: [f64; 3],
    /// Half width of the flange across the axis.
    flange_half_width_m: f64,
}

impl Drawing {
    /// Reads the plant's visuals: entity path, the shape to draw and its colour; finds the flange and
    /// the cylinder among them by their roles.
    fn links(visuals: &[pneuflex_scene::Visual]) -> (Self, Vec<LinkShape>) {
        let mut entities = Vec::with_capacity(visuals.len());
        let mut shapes = Vec::with_capacity(visuals.len());
        let (mut flange, mut cylinder) = (None, None);
        for (i, v) in visuals.iter().enumerate() {
            let entity = paths::link(&v.name);
            let shape = v.shape.clone();
            shapes.push(LinkShape {
                entity: entity.clone(),
                shape,
                colour: role_colour(v.role),
            });
            match v.role {
                VisualRole::Flange if flange.is_none() => {
                    let (half, width) = match &v.shape {
                        VisualShape::Box { half_extents_m } => {
                            (half_extents_m[0], half_extents_m[1].max(half_extents_m[2]))
                        }
                        VisualShape::Cylinder {
                            radius_m,
                            half_length_m,
                        } => (*half_length_m, *radius_m),
                        VisualShape::Sphere { radius_m } => (*radius_m, *radius_m),
                        // Its extent along x and across, from the vertices.
                        VisualShape::Mesh { vertices_m, .. } => {
                            let span = |k: usize| {
                                let (lo, hi) = vertices_m
                                    .iter()
                                    .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), v| {
                                        (lo.min(v[k]), hi.max(v[k]))
                                    });
                                0.5 * (hi - lo)
                            };
                            (span(0), span(1).max(span(2)))
                        }
                    };
                    flange = Some((i, half, width));
                }
                VisualRole::Cylinder if cylinder.is_none() => {
                    // A cylinder shape runs along its z, a box is taken along its x.
                    let axis = match &v.shape {
                        VisualShape::Cylinder { .. } => CylinderAxis {
                            to_z: [0.0, 0.0, 0.0, 1.0],
                            axis: [0.0, 0.0, 1.0],
                        },
                        VisualShape::Box { .. }
                        | VisualShape::Sphere { .. }
                        | VisualShape::Mesh { .. } => CylinderAxis {
                            to_z: Z_TO_X,
                            axis: [1.0, 0.0, 0.0],
                        },
                    };
                    cylinder = Some((i, axis));
                }
                _ => {}
            }
            entities.push(entity);
        }
        let drawing = Drawing::Links {
            poses: vec![
                VisualPose {
                    translation_m: [0.0; 3],
                    rotation_xyzw: [0.0, 0.0, 0.0, 1.0]
                };
                entities.len()
            ],
            entities,
            flange,
            cylinder,
        };
        (drawing, shapes)
    }

    /// Takes the plant's current poses (link drawings only).
    fn update_poses(&mut self, plant: &dyn Plant) {
        if let Drawing::Links { poses, .. } = self {
            plant.visual_poses(&mut |i, p| {
                if let Some(slot) = poses.get_mut(i) {
                    *slot = p;
                }
            });
        }
    }

    /// Where the actuator is at flange position `x` (the link drawing at its current poses).
    fn frame(&self, geometry: Option<&ActuatorGeometry>, x: f64) -> RigFrame {
        match self {
            Drawing::Schematic(ax) => {
                let axis = ax.dir();
                RigFrame {
                    axis,
                    to_axis: qmul(ax.along(), Z_TO_X),
                    chamber_base: geometry
                        .map(|g| ax.at(SchematicBody::of(g).chamber_base_s(g.stroke_m))),
                    flange_back: ax.at(x),
                    flange_front: ax.at(x + 2.0 * FLANGE_HALF_THICKNESS_M),
                    up: up_across(axis),
                    flange_half_width_m: FLANGE_HALF_WIDTH_M,
                }
            }
            Drawing::Links {
                poses,
                flange,
                cylinder,
                ..
            } => {
                let (flange_back, flange_front, flange_axis, width) = match flange {
                    Some((i, half, width)) => {
                        let p = poses[*i];
                        let fx = rotate(p.rotation_xyzw, [1.0, 0.0, 0.0]);
                        (
                            add(p.translation_m, -half, fx),
                            add(p.translation_m, *half, fx),
                            fx,
                            *width,
                        )
                    }
                    None => ([0.0; 3], [0.0; 3], [1.0, 0.0, 0.0], FLANGE_HALF_WIDTH_M),
                };
                let (axis, to_axis, chamber_base) = match (cylinder, geometry) {
                    (Some((c, ca)), Some(g)) => {
                        let p = poses[*c];
                        let mut axis = rotate(p.rotation_xyzw, ca.axis);
                        let mut to_axis = qmul(p.rotation_xyzw, ca.to_z);
                        // The axis points from the body to the flange.
                        let to_flange: [f64; 3] =
                            std::array::from_fn(|k| flange_back[k] - p.translation_m[k]);
                        if flange.is_some() && dot(axis, to_flange) < 0.0 {
                            axis = axis.map(|v| -v);
                            to_axis = qmul(to_axis, FLIP_Z);
                        }
                        // The stroke centred in the body, as in the rig (end caps at both ends).
                        let base = add(p.translation_m, -0.5 * g.stroke_m, axis);
                        (axis, to_axis, Some(base))
                    }
                    _ => (flange_axis, qmul([0.0, 0.0, 0.0, 1.0], Z_TO_X), None),
                };
                RigFrame {
                    axis,
                    to_axis,
                    chamber_base,
                    flange_back,
                    flange_front,
                    up: up_across(axis),
                    flange_half_width_m: width,
                }
            }
        }
    }
}

/// How the signals of a run are logged: each column's path and scale to its display unit, and the
/// PWM-period averages.
pub(crate) struct SignalLog {
    /// Per column (in the row's order): entity path and the factor from SI to the display unit; None for
    /// time and for a signal the plant does not have.
    columns: Vec<Option<(String, f64)>>,
    /// The moving averages over one PWM period, of the columns that chatter.
    averages: Vec<PeriodMean>,
    /// Means ready to log (reused).
    ready: Vec<(f64, f64)>,
}

/// Mean of one column over one PWM period of `n` samples, centred on each sample and with whole windows
/// at both ends: the averaging of the metrics and figures (`pneuflex_scene::analysis::metrics::moving_average`),
/// computed as the samples arrive. A sample's mean is logged once the half period after it is in.
struct PeriodMean {
    column: usize,
    path: String,
    n: usize,
    window: std::collections::VecDeque<f64>,
    sum: f64,
    /// Times of the samples whose mean is not logged yet.
    pending: std::collections::VecDeque<f64>,
}

impl PeriodMean {
    fn new(column: usize, path: String, n: usize) -> Self {
        Self {
            column,
            path,
            n: n.max(1),
            window: std::collections::VecDeque::with_capacity(n.max(1) + 1),
            sum: 0.0,
            pending: std::collections::VecDeque::with_capacity(n.max(1) + 1),
        }
    }

    /// Takes the sample (t, v); returns the (time, mean) pairs now complete.
    fn push(&mut self, t: f64, v: f64, out: &mut Vec<(f64, f64)>) {
        self.window.push_back(v);
        self.sum += v;
        if self.window.len() > self.n {
            let old = self.window.pop_front().unwrap_or(0.0);
            self.sum -= old;
        }
        self.pending.push_back(t);
        if self.window.len() == self.n {
            // The current window is centred on the sample `lag` samples before the newest; that sample
            // and every earlier pending one (the first ones: whole windows at the start) take its mean.
            let lag = self.n - 1 - self.n / 2;
            let mean = self.sum / self.n as f64;
            while self.pending.len() > lag {
                if let Some(t) = self.pending.pop_front() {
                    out.push((t, mean));
                }
            }
        }
    }

    /// The last samples (after the last whole window's centre) take the last window's mean.
    fn flush(&mut self, out: &mut Vec<(f64, f64)>) {
        if self.window.is_empty() {
            return;
        }
        let mean = self.sum / self.window.len() as f64;
        out.extend(self.pending.drain(..).map(|t| (t, mean)));
    }
}

impl SignalLog {
    /// Registers every column of the run (name with its display unit, colour) and the averages.
    pub(crate) fn register(
        rec: &mut RunRecorder,
        columns: &[Column],
        shown: &[bool],
        pwm_period_s: Option<f64>,
        dt_s: f64,
    ) -> Result<Self, RerunError> {
        let mut out = Vec::with_capacity(columns.len());
        let mut averages = Vec::new();
        for (i, c) in columns.iter().enumerate() {
            if i == index::T || !shown[i] {
                out.push(None);
                continue;
            }
            let path = format!("signals/{}/{}", c.group, c.name);
            let unit = units::display_unit(&c.unit);
            let averaged = pwm_period_s.filter(|_| units::is_averaged(&c.name, &c.group));
            let (colour, width) = units::series_style(&c.name, averaged.is_some());
            rec.register_series(&path, &units::series_name(&c.name, &c.unit), colour, width)?;
            if let Some(period_s) = averaged {
                let avg = paths::average(&path);
                let (colour, width) = units::average_style(&c.name);
                rec.register_series(
                    &avg,
                    &format!(
                        "{}, mean over 1 PWM period ({} ms, centred) [{}]",
                        c.name,
                        number(period_s * 1e3),
                        unit.label
                    ),
                    colour,
                    width,
                )?;
                let n = (period_s / dt_s).round().max(1.0) as usize;
                averages.push(PeriodMean::new(i, avg, n));
            }
            out.push(Some((path, unit.scale)));
        }
        Ok(Self {
            columns: out,
            averages,
            ready: Vec::new(),
        })
    }

    fn log(&mut self, rec: &mut RunRecorder, row: &Row) -> Result<(), RerunError> {
        self.log_at(rec, 0.0, row)
    }

    /// [`SignalLog::log`] on a timeline that starts at `t0_s` (the wall clock at a rig run's start).
    pub(crate) fn log_at(
        &mut self,
        rec: &mut RunRecorder,
        t0_s: f64,
        row: &Row,
    ) -> Result<(), RerunError> {
        let t = t0_s + row.t();
        for (col, &v) in self.columns.iter().zip(row.values) {
            if let Some((path, scale)) = col
                && v.is_finite()
            {
                rec.log_scalars(t, &[(path.as_str(), v * scale)])?;
            }
        }
        for m in &mut self.averages {
            let scale = self.columns[m.column].as_ref().map_or(1.0, |c| c.1);
            self.ready.clear();
            m.push(t, row.values[m.column], &mut self.ready);
            for &(t, mean) in &self.ready {
                rec.log_scalars(t, &[(m.path.as_str(), mean * scale)])?;
            }
        }
        Ok(())
    }

    /// Logs the means of the last half period (at the end of a run).
    pub(crate) fn flush(&mut self, rec: &mut RunRecorder) -> Result<(), RerunError> {
        for m in &mut self.averages {
            let scale = self.columns[m.column].as_ref().map_or(1.0, |c| c.1);
            self.ready.clear();
            m.flush(&mut self.ready);
            for &(t, mean) in &self.ready {
                rec.log_scalars(t, &[(m.path.as_str(), mean * scale)])?;
            }
        }
        Ok(())
    }
}

/// The run being recorded.
struct Recording {
    rec: RunRecorder,
    drawing: Drawing,
    signals: SignalLog,
    /// The run's columns, as its producers declared them.
    columns: Vec<Column>,
    /// Time of the last row, s (where a divergence is marked).
    t_last: f64,
    /// The run's name.
    run: String,
    /// Length of the piston rod, from the first tick (None until then, and without chambers).
    rod_length_m: Option<f64>,
}

/// Records every run of a scene to Rerun, one recording per run; the first error stops logging and is
/// returned by [`SceneRecorder::finish`].
pub struct SceneRecorder {
    sink: Sink,
    options: RecorderOptions,
    n_runs: usize,
    scene_name: String,
    events: Vec<EventSpec>,
    /// The scene's environment: surface for plants without an actuator geometry, and the stiffness the
    /// event log starts from.
    x_e_m: f64,
    stiffness_n_per_m: f64,
    /// Control period, s (samples per PWM period for the averages).
    dt_s: f64,
    materials: Vec<(String, f64)>,
    geometry: Option<ActuatorGeometry>,
    current: Option<Recording>,
    error: Option<RerunError>,
    cost: Duration,
    steps: usize,
}

impl SceneRecorder {
    /// A recorder for `scene` sending to `sink` with the default options and the force arrow scaled to
    /// the scene ([`force_arrow_scale`]). A save path whose directory does not exist and a malformed
    /// connect address are refused here, before anything runs.
    pub fn new(sink: Sink, scene: &Scene) -> Result<Self, RerunError> {
        let options = RecorderOptions {
            force_arrow_m_per_n: force_arrow_scale(scene),
            ..RecorderOptions::default()
        };
        Self::with_options(sink, scene, options)
    }

    /// [`SceneRecorder::new`] with recorder options (their layout is replaced per run by the run's).
    pub fn with_options(
        sink: Sink,
        scene: &Scene,
        options: RecorderOptions,
    ) -> Result<Self, RerunError> {
        match &sink {
            Sink::Save(path) => {
                let first = scene.runs.first().map_or("run", |r| r.name.as_str());
                if let Sink::Save(p) = sink_for_run(&sink, first, scene.runs.len()) {
                    crate::sink::check_save_path(&p).map_err(|e| match e {
                        RerunError::SaveDirMissing { dir, .. } => RerunError::SaveDirMissing {
                            path: path.clone(),
                            dir,
                        },
                        e => e,
                    })?;
                }
            }
            Sink::Connect(addr) => {
                crate::sink::normalise_url(addr)?;
            }
            Sink::Spawn => {}
        }
        let materials = scene.plant.multibody().map_or_else(Vec::new, |m| {
            m.materials
                .iter()
                .map(|m| (m.name.clone(), m.stiffness_n_per_m))
                .collect()
        });
        Ok(Self {
            sink,
            options,
            n_runs: scene.runs.len(),
            scene_name: scene.name.clone(),
            events: scene.events.clone(),
            x_e_m: scene.environment.x_e_m,
            stiffness_n_per_m: scene.environment.stiffness_n_per_m,
            dt_s: scene.dt_s,
            materials,
            geometry: None,
            current: None,
            error: None,
            cost: Duration::ZERO,
            steps: 0,
        })
    }

    /// Time spent logging so far.
    pub fn cost(&self) -> Duration {
        self.cost
    }

    /// Ticks logged over all runs.
    pub fn steps(&self) -> usize {
        self.steps
    }

    /// Returns the first logging error, if any (recordings of finished runs are complete).
    pub fn finish(self) -> Result<(), RerunError> {
        self.error.map_or(Ok(()), Err)
    }

    /// The scene's events as the event log writes them, for a plant with `geometry`.
    fn event_texts(&self, geometry: Option<&ActuatorGeometry>) -> Vec<(f64, String)> {
        let mut state = EventState {
            stiffness_n_per_m: Some(self.stiffness_n_per_m),
            materials: self.materials.iter().cloned().collect(),
            alpha_deg: geometry.map(|g| g.alpha_rad.to_degrees()),
        };
        let mut events: Vec<&EventSpec> = self.events.iter().collect();
        events.sort_by(|a, b| a.t_s().total_cmp(&b.t_s()));
        events
            .into_iter()
            .map(|ev| (ev.t_s(), describe_event(ev, &mut state)))
            .collect()
    }

    /// The columns the run records, in order: the loop's, the controller's, the plant's.
    fn begin(
        &mut self,
        run: &str,
        declared: &[pneuflex_control::Signal],
        plant: &dyn Plant,
    ) -> Result<Recording, RerunError> {
        let sink = sink_for_run(&self.sink, run, self.n_runs);
        self.geometry = plant.actuator_geometry();
        let columns: Vec<Column> = declared.iter().map(Column::from).collect();
        // No chambers (the ideal loop): its pressures are not signals it has.
        let has = |c: &Column| self.geometry.is_some() || c.group != "pressure";
        let mut options = self.options.clone();
        let pwm = self.geometry.and_then(|g| g.pwm_period_s);
        options.layout = Layout::for_signals(
            columns
                .iter()
                .filter(|c| has(c))
                .map(|c| (c.name.as_str(), c.unit.as_str(), c.group.as_str())),
        );
        let visuals = plant.visuals();
        options.layout.eye = Some(self.initial_eye(plant, &visuals));
        options.layout.hidden_in_3d = visuals
            .iter()
            .filter(|v| v.role == VisualRole::Other)
            .map(|v| paths::link(&v.name))
            .collect();
        let mut rec = RunRecorder::with_options(
            "pneuflex",
            &format!("{}/{}", self.scene_name, run),
            &sink,
            options,
        )?;
        let shown: Vec<bool> = columns.iter().map(has).collect();
        let signals = SignalLog::register(&mut rec, &columns, &shown, pwm, self.dt_s)?;
        let drawing = if visuals.is_empty() {
            self.begin_schematic(&mut rec)?
        } else {
            let (drawing, shapes) = Drawing::links(&visuals);
            for shape in &shapes {
                rec.log_link_shape(shape)?;
            }
            if let Some(geo) = &self.geometry {
                rec.set_chamber_bore(geo.bore_m)?;
            }
            drawing
        };
        for (t, text) in self.event_texts(self.geometry.as_ref()) {
            rec.log_event(t, EventLevel::Info, &text)?;
        }
        Ok(Recording {
            rec,
            drawing,
            signals,
            columns,
            t_last: 0.0,
            run: run.to_string(),
            rod_length_m: None,
        })
    }

    /// The schematic's axis: the actuator's, or horizontal through the environment surface without one.
    fn schematic_axis(&self) -> Axis {
        match &self.geometry {
            Some(g) => Axis {
                alpha_rad: g.alpha_rad,
                x_e_m: g.x_e_m,
            },
            None => Axis {
                alpha_rad: 0.0,
                x_e_m: self.x_e_m,
            },
        }
    }

    /// The 3D view's camera: beside the actuator (the side from which its axis runs left to right),
    /// a little above and in front, looking at the middle between the cylinder's back end and the
    /// environment, at 4.5 strokes — the rig fills the view.
    fn initial_eye(&self, plant: &dyn Plant, visuals: &[pneuflex_scene::Visual]) -> Eye {
        let drawing = if visuals.is_empty() {
            Drawing::Schematic(self.schematic_axis())
        } else {
            let (mut d, _) = Drawing::links(visuals);
            d.update_poses(plant);
            d
        };
        let f = drawing.frame(self.geometry.as_ref(), plant.sense().x);
        let stroke = self.geometry.map_or(0.05, |g| g.stroke_m);
        let back = match f.chamber_base {
            Some(b) => add(b, -0.3 * stroke, f.axis),
            None => add(f.flange_back, -stroke, f.axis),
        };
        let front = add(f.flange_front, 0.8 * stroke, f.axis);
        let look_at_m: [f64; 3] = std::array::from_fn(|k| 0.5 * (back[k] + front[k]));
        let (u, a) = (f.up, f.axis);
        // up × axis: seen from minus this, the axis points right and up is up.
        let forward = [
            u[1] * a[2] - u[2] * a[1],
            u[2] * a[0] - u[0] * a[2],
            u[0] * a[1] - u[1] * a[0],
        ];
        let d = 4.5 * stroke;
        let position_m = add(add(add(look_at_m, -d, forward), 0.3 * d, u), 0.1 * d, a);
        Eye {
            position_m,
            look_at_m,
        }
    }

    /// The schematic: the cylinder body behind the flange's retracted stop (s = 0), the flange plate at
    /// s = x, the environment face at x_e. Without an actuator: flange and face on a horizontal axis.
    fn begin_schematic(&self, rec: &mut RunRecorder) -> Result<Drawing, RerunError> {
        let axis = self.schematic_axis();
        for (name, half_extents_m, colour) in [
            (
                "flange",
                [
                    FLANGE_HALF_THICKNESS_M,
                    FLANGE_HALF_WIDTH_M,
                    FLANGE_HALF_WIDTH_M,
                ],
                role_colour(VisualRole::Flange),
            ),
            (
                "environment",
                [FACE_HALF_THICKNESS_M, 0.03, 0.03],
                role_colour(VisualRole::Environment),
            ),
        ] {
            rec.log_link_shape(&LinkShape {
                entity: paths::link(name),
                shape: VisualShape::Box { half_extents_m },
                colour,
            })?;
        }
        if let Some(g) = &self.geometry {
            let body = SchematicBody::of(g);
            rec.log_link_shape(&LinkShape {
                entity: paths::link("cylinder"),
                shape: VisualShape::Cylinder {
                    radius_m: body.radius_m,
                    half_length_m: 0.5 * (body.front_s - body.back_s),
                },
                colour: role_colour(VisualRole::Cylinder),
            })?;
            rec.set_link_pose(
                0.0,
                &paths::link("cylinder"),
                axis.at(0.5 * (body.back_s + body.front_s)),
                qmul(axis.along(), Z_TO_X),
            )?;
            rec.set_chamber_bore(g.bore_m)?;
        }
        Ok(Drawing::Schematic(axis))
    }

    fn step(
        geometry: Option<&ActuatorGeometry>,
        r: &mut Recording,
        row: &Row,
        plant: &dyn Plant,
    ) -> Result<(), RerunError> {
        let t = row.t();
        r.signals.log(&mut r.rec, row)?;

        r.drawing.update_poses(plant);
        match &r.drawing {
            Drawing::Schematic(ax) => {
                let q = ax.along();
                r.rec.set_link_pose(
                    t,
                    &paths::link("flange"),
                    ax.at(row.x() + FLANGE_HALF_THICKNESS_M),
                    q,
                )?;
                let front_s = row.x() + 2.0 * FLANGE_HALF_THICKNESS_M;
                let face_s = front_s.max(ax.x_e_m + 2.0 * FLANGE_HALF_THICKNESS_M);
                r.rec.set_link_pose(
                    t,
                    &paths::link("environment"),
                    ax.at(face_s + FACE_HALF_THICKNESS_M),
                    q,
                )?;
            }
            Drawing::Links {
                entities, poses, ..
            } => {
                for (entity, p) in entities.iter().zip(poses.iter()) {
                    r.rec
                        .set_link_pose(t, entity, p.translation_m, p.rotation_xyzw)?;
                }
            }
        }
        let frame = r.drawing.frame(geometry, row.x());

        if let (Some(g), Some(base)) = (geometry, frame.chamber_base) {
            r.rec
                .set_link_pose(t, paths::CHAMBERS, base, frame.to_axis)?;
            let x = row.x().clamp(0.0, g.stroke_m);
            if row.p_a().is_finite() {
                r.rec.log_chambers(
                    t,
                    &ChamberSample {
                        length_a_m: x,
                        pressure_a_pa: row.p_a(),
                        length_b_m: g.stroke_m - x,
                        pressure_b_pa: row.p_b(),
                    },
                )?;
            }
            // The piston rod: from the piston (the end of chamber A) to the flange's back face. Its
            // length is that of the first tick; it is placed to end at the flange.
            let rod = match r.rod_length_m {
                Some(l) => l,
                None => {
                    let piston = add(base, x, frame.axis);
                    let d: [f64; 3] = std::array::from_fn(|k| frame.flange_back[k] - piston[k]);
                    let l = dot(d, frame.axis).max(1e-3);
                    r.rec.log_link_shape(&LinkShape {
                        entity: paths::ROD.into(),
                        shape: VisualShape::Cylinder {
                            radius_m: rod_radius_m(g),
                            half_length_m: 0.5 * l,
                        },
                        colour: ROD_COLOUR,
                    })?;
                    r.rod_length_m = Some(l);
                    l
                }
            };
            r.rec.set_link_pose(
                t,
                paths::ROD,
                add(frame.flange_back, -0.5 * rod, frame.axis),
                frame.to_axis,
            )?;
        }

        // The contact force as the load cell reads it: the force the environment pushes back with,
        // drawn beside the flange (outside the bodies) from the contact plane, pointing away from the
        // block; the contact point on the flange's front face.
        let contact = (row.f_e() > 0.0).then(|| Contact {
            point_m: frame.flange_front,
            force_n: frame.axis.map(|c| -c * row.f_e()),
            arrow_from_m: add(
                frame.flange_front,
                frame.flange_half_width_m + ARROW_CLEARANCE_M,
                frame.up,
            ),
        });
        r.rec.log_contact(t, contact.as_ref())
    }
}

/// Radius of the drawn piston rod: 0.3 of the bore in diameter (the rig's 16 mm bore has a 5 mm rod).
fn rod_radius_m(g: &ActuatorGeometry) -> f64 {
    0.15 * g.bore_m
}

impl<'p> SinkTrait<dyn Plant + 'p> for SceneRecorder {
    fn begin(&mut self, run: &str, columns: &[pneuflex_control::Signal], plant: &(dyn Plant + 'p)) {
        if self.error.is_some() {
            return;
        }
        let t0 = Instant::now();
        match SceneRecorder::begin(self, run, columns, plant) {
            Ok(r) => self.current = Some(r),
            Err(e) => {
                self.error = Some(RerunError::Run {
                    run: run.to_string(),
                    source: Box::new(e),
                })
            }
        }
        self.cost += t0.elapsed();
    }

    fn row(&mut self, values: &[f64], plant: &(dyn Plant + 'p)) {
        let Some(r) = self.current.as_mut() else {
            return;
        };
        let t0 = Instant::now();
        let columns = std::mem::take(&mut r.columns);
        let row = Row {
            columns: &columns,
            values,
        };
        r.t_last = row.t();
        let stepped = Self::step(self.geometry.as_ref(), r, &row, plant);
        r.columns = columns;
        if let Err(e) = stepped {
            self.error = Some(e);
            self.current = None;
        }
        self.steps += 1;
        self.cost += t0.elapsed();
    }

    fn end(&mut self, why: Option<&str>) {
        let Some(mut r) = self.current.take() else {
            return;
        };
        let t0 = Instant::now();
        let name = r.run.clone();
        let done = (|| -> Result<(), RerunError> {
            if let Some(why) = why {
                let t_end = r.t_last;
                r.rec.log_event(
                    t_end,
                    EventLevel::Error,
                    &format!("t = {t_end:.2} s: the run diverged: {why}"),
                )?;
            }
            r.signals.flush(&mut r.rec)?;
            r.rec.finish()
        })();
        if let Err(e) = done {
            self.error = Some(RerunError::Run {
                run: name,
                source: Box::new(e),
            });
        }
        self.cost += t0.elapsed();
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sinks_parse_and_split_per_run() {
        let w = |s: &str| s.split(' ').map(String::from).collect::<Vec<_>>();
        assert_eq!(
            parse_sink(&w("save a/b.rrd")).unwrap(),
            Sink::Save("a/b.rrd".into())
        );
        assert_eq!(parse_sink(&w("spawn")).unwrap(), Sink::Spawn);
        assert_eq!(
            parse_sink(&w("connect 127.0.0.1:9876")).unwrap(),
            Sink::Connect("127.0.0.1:9876".into())
        );
        assert!(parse_sink(&w("save")).is_err());
        let s = Sink::Save("d/x.rrd".into());
        assert_eq!(
            sink_for_run(&s, "adaptive", 2),
            Sink::Save("d/x-adaptive.rrd".into())
        );
        assert_eq!(sink_for_run(&s, "adaptive", 1), s);
    }

    #[test]
    fn the_period_mean_is_the_metrics_moving_average() {
        let y: Vec<f64> = (0..103)
            .map(|k| (k as f64 * 0.7).sin() * 3.0 + k as f64 * 0.01)
            .collect();
        for n in [1, 2, 5, 25, 200] {
            let mut m = PeriodMean::new(0, String::new(), n);
            let mut out = Vec::new();
            for (k, &v) in y.iter().enumerate() {
                m.push(k as f64, v, &mut out);
            }
            m.flush(&mut out);
            let expected = pneuflex_scene::analysis::metrics::moving_average(&y, n);
            assert_eq!(out.len(), y.len(), "n = {n}");
            for (k, ((t, got), want)) in out.iter().zip(&expected).enumerate() {
                assert_eq!(*t, k as f64, "n = {n}");
                assert!(
                    (got - want).abs() < 1e-9,
                    "n = {n}, k = {k}: {got} vs {want}"
                );
            }
        }
    }

    #[test]
    fn events_read_as_sentences() {
        let mut state = EventState {
            stiffness_n_per_m: Some(700.0),
            ..EventState::default()
        };
        let swap = EventSpec::SwapEnvironment {
            t_s: 3.0,
            to: "iron".into(),
            duration_s: 0.9,
        };
        assert_eq!(
            describe_event(&swap, &mut state),
            "t = 3.00 s: carriage swaps the environment to iron (0.9 s)"
        );
        let k = EventSpec::Stiffness {
            t_s: 6.0,
            stiffness_n_per_m: 1400.0,
            material: None,
            damping_n_s_per_m: None,
        };
        assert_eq!(
            describe_event(&k, &mut state),
            "t = 6.00 s: environment stiffness 700 → 1400 N/m"
        );
        state.alpha_deg = Some(0.0);
        let a = EventSpec::Alpha {
            t_s: 1.5,
            alpha_deg: 30.0,
        };
        assert_eq!(
            describe_event(&a, &mut state),
            "t = 1.50 s: platform incline 0 → 30°"
        );
    }

    #[test]
    fn ten_newtons_read_clearly_in_every_shipped_scene() {
        for path in shipped_scenes() {
            let scene = Scene::load(&path).unwrap();
            let s = force_arrow_scale(&scene);
            let ten_n = 10.0 * s;
            assert!(
                (0.02..=0.12).contains(&ten_n),
                "{}: 10 N drawn {ten_n} m long",
                path.display()
            );
            assert!(force_range_n(&scene) * s <= ARROW_LENGTH_FOR_MAX_FORCE_M + 1e-12);
        }
    }

    /// The shipped one-actuator scenes (those with `[[actuators]]` have their own recorder).
    fn shipped_scenes() -> Vec<std::path::PathBuf> {
        let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scenes");
        let mut v: Vec<_> = std::fs::read_dir(&dir)
            .unwrap()
            .map(|e| e.unwrap().path())
            .filter(|p| p.extension().is_some_and(|e| e == "toml"))
            .filter(|p| {
                !pneuflex_scene::mechanism::MechanismScene::is_mechanism(
                    &std::fs::read_to_string(p).unwrap(),
                )
            })
            .collect();
        v.sort();
        v
    }

    /// `<tag attr="...">` of the collision of `link` in a URDF: the attribute's numbers.
    fn urdf_numbers(urdf: &str, link: &str, tag: &str, attr: &str) -> Vec<f64> {
        let start = urdf
            .find(&format!("<link name=\"{link}\">"))
            .unwrap_or_else(|| panic!("no link {link}"));
        let body = &urdf[start..];
        let body = &body[..body.find("</link>").unwrap()];
        let col = &body[body.find("<collision>").unwrap()..];
        let at = col
            .find(&format!("<{tag} "))
            .unwrap_or_else(|| panic!("{link}: no <{tag}>"));
        let el = &col[at..];
        let el = &el[..el.find('>').unwrap()];
        let Some(a) = el.find(&format!("{attr}=\"")) else {
            return Vec::new();
        };
        let v = &el[a + attr.len() + 2..];
        v[..v.find('"').unwrap()]
            .split_whitespace()
            .map(|x| x.parse().unwrap())
            .collect()
    }

    /// Quaternion [x, y, z, w] of URDF roll, pitch, yaw (R = Rz(yaw) Ry(pitch) Rx(roll)).
    fn rpy_quat(rpy: &[f64]) -> [f64; 4] {
        let (r, p, y) = (rpy[0], rpy[1], rpy[2]);
        let qx = [(0.5 * r).sin(), 0.0, 0.0, (0.5 * r).cos()];
        let qy = [0.0, (0.5 * p).sin(), 0.0, (0.5 * p).cos()];
        let qz = [0.0, 0.0, (0.5 * y).sin(), (0.5 * y).cos()];
        qmul(qmul(qz, qy), qx)
    }

    fn conj(q: [f64; 4]) -> [f64; 4] {
        [-q[0], -q[1], -q[2], q[3]]
    }

    fn close(a: [f64; 3], b: [f64; 3], tol: f64) -> bool {
        (0..3).all(|k| (a[k] - b[k]).abs() < tol)
    }

    /// For every shipped scene (every plant kind): the chambers drawn along the cylinder's axis, inside its
    /// body, no wider than it; the rod from the piston to the flange's back face. For the multibody rig the
    /// cylinder is the URDF's (its collision cylinder's origin, rpy, length and radius, read from the file
    /// here); for the 1-DOF plant the schematic body drawn from the actuator sheet; the ideal loop has no
    /// chambers.
    #[test]
    fn the_drawn_chambers_and_rod_match_the_cylinder_for_every_plant_kind() {
        let mut kinds = std::collections::HashSet::new();
        for path in shipped_scenes() {
            let scene = Scene::load(&path).unwrap();
            let what = path.display().to_string();
            let plant = pneuflex_scene::build_plant(&scene).unwrap();
            let geometry = plant.actuator_geometry();
            let visuals = plant.visuals();
            let x0 = plant.sense().x;
            let multibody = scene.plant.multibody();
            match (&geometry, multibody) {
                (None, _) => {
                    kinds.insert("no actuator (ideal loop)");
                    let frame = Drawing::Schematic(Axis {
                        alpha_rad: 0.0,
                        x_e_m: scene.environment.x_e_m,
                    })
                    .frame(None, x0);
                    assert!(frame.chamber_base.is_none(), "{what}: no chambers");
                }
                (Some(g), None) => {
                    kinds.insert("1-DOF schematic");
                    let g = *g;
                    assert!(visuals.is_empty(), "{what}: drawn as the schematic");
                    let ax = Axis {
                        alpha_rad: g.alpha_rad,
                        x_e_m: g.x_e_m,
                    };
                    let body = SchematicBody::of(&g);
                    for x in [0.0, 0.5 * g.stroke_m, g.stroke_m] {
                        let f = Drawing::Schematic(ax).frame(Some(&g), x);
                        // Along the inclined axis, down by alpha, z of the chamber frame on it.
                        let n = [g.alpha_rad.cos(), 0.0, -g.alpha_rad.sin()];
                        assert!(close(f.axis, n, 1e-12), "{what}: axis {:?}", f.axis);
                        assert!(
                            close(rotate(f.to_axis, [0.0, 0.0, 1.0]), n, 1e-12),
                            "{what}"
                        );
                        let base = f.chamber_base.unwrap();
                        let s0 = dot(base, n);
                        assert!(close(base, ax.at(s0), 1e-12), "{what}: base off the axis");
                        assert!(s0 >= body.back_s - 1e-12, "{what}");
                        assert!(s0 + g.stroke_m <= body.front_s + 1e-12, "{what}");
                        assert!(0.5 * g.bore_m < body.radius_m, "{what}");
                        // The rod from the piston (end of chamber A) to the flange's back face at s = x.
                        assert!(close(f.flange_back, ax.at(x), 1e-12), "{what}");
                        assert!(dot(f.flange_back, n) > s0 + x, "{what}: rod length");
                    }
                }
                (Some(g), Some(mb)) => {
                    kinds.insert("multibody");
                    let g = *g;
                    let urdf = std::fs::read_to_string(scene.resolve(&mb.urdf)).unwrap();
                    let (mut drawing, _) = Drawing::links(&visuals);
                    drawing.update_poses(plant.as_ref());
                    let Drawing::Links {
                        poses,
                        cylinder: Some((ci, _)),
                        flange: Some((fi, ..)),
                        ..
                    } = &drawing
                    else {
                        panic!("{what}: no cylinder or flange visual")
                    };
                    let cyl_link = visuals[*ci].name.clone();
                    let fl_link = visuals[*fi].name.clone();
                    // The URDF's cylinder: collision origin and rpy in the link frame, length, radius.
                    let xyz = urdf_numbers(&urdf, &cyl_link, "origin", "xyz");
                    let rpy = urdf_numbers(&urdf, &cyl_link, "origin", "rpy");
                    let length = urdf_numbers(&urdf, &cyl_link, "cylinder", "length")[0];
                    let radius = urdf_numbers(&urdf, &cyl_link, "cylinder", "radius")[0];
                    let q_geom = if rpy.is_empty() {
                        [0.0, 0.0, 0.0, 1.0]
                    } else {
                        rpy_quat(&rpy)
                    };
                    // The link's world pose from the drawn shape's: world_from_shape = link * origin.
                    let p = poses[*ci];
                    let q_link = qmul(p.rotation_xyzw, conj(q_geom));
                    let t_link = add(
                        p.translation_m,
                        -1.0,
                        rotate(q_link, [xyz[0], xyz[1], xyz[2]]),
                    );
                    let to_link = |w: [f64; 3]| {
                        rotate(conj(q_link), std::array::from_fn(|k| w[k] - t_link[k]))
                    };
                    // The URDF cylinder's axis in its link frame, and its centre.
                    let urdf_axis = rotate(q_geom, [0.0, 0.0, 1.0]);
                    let centre = [xyz[0], xyz[1], xyz[2]];
                    let f = drawing.frame(Some(&g), x0);
                    let axis_link = rotate(conj(q_link), f.axis);
                    assert!(
                        (dot(axis_link, urdf_axis).abs() - 1.0).abs() < 1e-9,
                        "{what}: chamber axis {axis_link:?} (link frame) against the URDF cylinder's {urdf_axis:?}"
                    );
                    assert!(
                        close(rotate(f.to_axis, [0.0, 0.0, 1.0]), f.axis, 1e-9),
                        "{what}: the chamber frame's z is the axis"
                    );
                    // Both ends of the chambers on the URDF cylinder's axis, inside its length.
                    let base = to_link(f.chamber_base.unwrap());
                    let end = add(base, g.stroke_m, axis_link);
                    for (name, pt) in [("chamber A start", base), ("chamber B end", end)] {
                        let d: [f64; 3] = std::array::from_fn(|k| pt[k] - centre[k]);
                        let along = dot(d, urdf_axis);
                        let across = add(d, -along, urdf_axis);
                        assert!(
                            along.abs() <= 0.5 * length + 1e-9,
                            "{what}: {name} {along} m from the body centre, half length {}",
                            0.5 * length
                        );
                        assert!(
                            dot(across, across).sqrt() < 1e-9,
                            "{what}: {name} off the axis"
                        );
                    }
                    assert!(0.5 * g.bore_m <= radius, "{what}: bore wider than the body");
                    // The rod ends at the flange link's origin (its back face: the URDF box from x = 0).
                    let fx = urdf_numbers(&urdf, &fl_link, "origin", "xyz");
                    let size = urdf_numbers(&urdf, &fl_link, "box", "size");
                    assert!(
                        (fx[0] - 0.5 * size[0]).abs() < 1e-12,
                        "{what}: the flange plate starts at its link origin"
                    );
                    let pf = poses[*fi];
                    let flange_origin = add(
                        pf.translation_m,
                        -1.0,
                        rotate(pf.rotation_xyzw, [fx[0], fx[1], fx[2]]),
                    );
                    assert!(
                        close(f.flange_back, flange_origin, 1e-9),
                        "{what}: rod end {:?} vs flange origin {flange_origin:?}",
                        f.flange_back
                    );
                    // The piston inside the body; the rod leaves through the body's front end.
                    let piston = add(base, x0.clamp(0.0, g.stroke_m), axis_link);
                    let rod_end = to_link(f.flange_back);
                    assert!(
                        dot(add(rod_end, -1.0, piston), axis_link) > 0.0,
                        "{what}: rod runs forward"
                    );
                    let front = dot(centre, axis_link) + 0.5 * length;
                    assert!(
                        dot(rod_end, axis_link) >= front - 1e-9,
                        "{what}: the flange outside the body"
                    );
                }
            }
        }
        assert_eq!(kinds.len(), 3, "every plant kind: {kinds:?}");
    }

    #[test]
    fn rotations_take_x_along_the_incline() {
        let ax = Axis {
            alpha_rad: 30f64.to_radians(),
            x_e_m: 0.0,
        };
        let p = ax.at(1.0);
        assert!((p[0] - 30f64.to_radians().cos()).abs() < 1e-12);
        assert!((p[2] + 30f64.to_radians().sin()).abs() < 1e-12);
        let z = rotate(Z_TO_X, [0.0, 0.0, 1.0]);
        assert!((z[0] - 1.0).abs() < 1e-12 && z[1].abs() < 1e-12 && z[2].abs() < 1e-12);
    }
}
