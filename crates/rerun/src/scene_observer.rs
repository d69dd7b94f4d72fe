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

use pneuflex_control::signal::index;
use pneuflex_scene::plant::{ActuatorGeometry, VisualRole};
use pneuflex_scene::schema::RunSpec;
use pneuflex_scene::trace::Row;
use pneuflex_scene::{Plant, RunResult, Scene, StepObserver, VisualPose, VisualShape};

use crate::{
    ChamberSample, Contact, EventLevel, LinkShape, RecorderOptions, RerunError, RunRecorder, Shape,
    Sink, paths,
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
const FLANGE_HALF_THICKNESS_M: f64 = 0.005;
const FACE_HALF_THICKNESS_M: f64 = 0.0025;

/// Colour of a plant's shape by its role.
fn role_colour(role: VisualRole) -> [u8; 4] {
    match role {
        VisualRole::Flange => [90, 90, 100, 255],
        VisualRole::Environment => [170, 120, 60, 255],
        VisualRole::Cylinder | VisualRole::Other => [170, 170, 180, 110],
    }
}

/// The schematic's axis: the actuator axis, tilted down by alpha, with the rod end of the cylinder at the
/// origin.
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

    /// Point at distance `s` along the axis from the rod end of the cylinder.
    fn at(&self, s: f64) -> [f64; 3] {
        let n = rotate(self.along(), [1.0, 0.0, 0.0]);
        n.map(|c| c * s)
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
        /// Index of the flange visual and its half thickness along its x.
        flange: Option<(usize, f64)>,
        /// Index of the cylinder visual, its local axis and the half length of the body along it.
        cylinder: Option<(usize, CylinderAxis)>,
    },
    /// The schematic along the actuator axis.
    Schematic(Axis),
}

/// Which local axis of the cylinder shape is the actuator axis.
#[derive(Clone, Copy, Debug)]
struct CylinderAxis {
    /// Rotation from the shape's frame to a frame whose z is the actuator axis.
    to_z: [f64; 4],
    /// Unit actuator axis in the shape's frame.
    axis: [f64; 3],
    /// Half length of the body along that axis, m.
    half_length_m: f64,
}

/// The run being recorded.
struct Recording {
    rec: RunRecorder,
    drawing: Drawing,
    /// Entity path of each recorded column, from its declaration (filled at the first tick).
    signal_paths: Vec<String>,
}

/// Records every run of a scene to Rerun, one recording per run; the first error stops logging and is
/// returned by [`SceneRecorder::finish`].
pub struct SceneRecorder {
    sink: Sink,
    options: RecorderOptions,
    n_runs: usize,
    scene_name: String,
    events: Vec<(f64, String)>,
    /// The scene's environment surface, for plants without an actuator geometry.
    x_e_m: f64,
    geometry: Option<ActuatorGeometry>,
    current: Option<Recording>,
    error: Option<RerunError>,
    cost: Duration,
    steps: usize,
}

impl SceneRecorder {
    /// A recorder for `scene` sending to `sink` with the default options. A save path whose directory does
    /// not exist and a malformed connect address are refused here, before anything runs.
    pub fn new(sink: Sink, scene: &Scene) -> Result<Self, RerunError> {
        Self::with_options(sink, scene, RecorderOptions::default())
    }

    /// [`SceneRecorder::new`] with recorder options.
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
        Ok(Self {
            sink,
            options,
            n_runs: scene.runs.len(),
            scene_name: scene.name.clone(),
            events: scene
                .events
                .iter()
                .map(|ev| (ev.t_s(), format!("{}: {ev:?}", ev.kind())))
                .collect(),
            x_e_m: scene.environment.x_e_m,
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

    fn begin(&mut self, run: &RunSpec, plant: &dyn Plant) -> Result<Recording, RerunError> {
        let sink = sink_for_run(&self.sink, &run.name, self.n_runs);
        let mut rec = RunRecorder::with_options(
            "pneuflex",
            &format!("{}/{}", self.scene_name, run.name),
            &sink,
            self.options.clone(),
        )?;
        self.geometry = plant.actuator_geometry();
        let visuals = plant.visuals();
        let drawing = if visuals.is_empty() {
            self.begin_schematic(&mut rec)?
        } else {
            let mut entities = Vec::with_capacity(visuals.len());
            let (mut flange, mut cylinder) = (None, None);
            for (i, v) in visuals.iter().enumerate() {
                let entity = paths::link(&v.name);
                let shape = match v.shape {
                    VisualShape::Box { half_extents_m } => Shape::Box { half_extents_m },
                    VisualShape::Cylinder {
                        radius_m,
                        half_length_m,
                    } => Shape::Cylinder {
                        radius_m,
                        half_length_m,
                    },
                    VisualShape::Sphere { radius_m } => Shape::Sphere { radius_m },
                };
                rec.log_link_shape(&LinkShape {
                    entity: entity.clone(),
                    shape,
                    colour: role_colour(v.role),
                })?;
                match v.role {
                    VisualRole::Flange if flange.is_none() => {
                        let half = match v.shape {
                            VisualShape::Box { half_extents_m } => half_extents_m[0],
                            _ => 0.0,
                        };
                        flange = Some((i, half));
                    }
                    VisualRole::Cylinder if cylinder.is_none() => {
                        // A cylinder shape runs along its z, a box is taken along its x.
                        let axis = match v.shape {
                            VisualShape::Cylinder { half_length_m, .. } => CylinderAxis {
                                to_z: [0.0, 0.0, 0.0, 1.0],
                                axis: [0.0, 0.0, 1.0],
                                half_length_m,
                            },
                            VisualShape::Box { half_extents_m } => CylinderAxis {
                                to_z: Z_TO_X,
                                axis: [1.0, 0.0, 0.0],
                                half_length_m: half_extents_m[0],
                            },
                            VisualShape::Sphere { radius_m } => CylinderAxis {
                                to_z: Z_TO_X,
                                axis: [1.0, 0.0, 0.0],
                                half_length_m: radius_m,
                            },
                        };
                        cylinder = Some((i, axis));
                    }
                    _ => {}
                }
                entities.push(entity);
            }
            if let Some(geo) = &self.geometry {
                rec.set_chamber_bore(geo.bore_m)?;
            }
            Drawing::Links {
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
            }
        };
        for (t, text) in &self.events {
            rec.log_event(*t, EventLevel::Info, text)?;
        }
        Ok(Recording {
            rec,
            drawing,
            signal_paths: Vec::new(),
        })
    }

    /// The schematic: the cylinder body spans s in [-stroke, 0] along the axis, the flange sits at s = x,
    /// the environment face at x_e. Without an actuator: flange and face on a horizontal axis.
    fn begin_schematic(&self, rec: &mut RunRecorder) -> Result<Drawing, RerunError> {
        let axis = match &self.geometry {
            Some(g) => Axis {
                alpha_rad: g.alpha_rad,
                x_e_m: g.x_e_m,
            },
            None => Axis {
                alpha_rad: 0.0,
                x_e_m: self.x_e_m,
            },
        };
        let mut parts = vec![
            (
                "flange",
                [FLANGE_HALF_THICKNESS_M, 0.02, 0.02],
                role_colour(VisualRole::Flange),
            ),
            (
                "environment",
                [FACE_HALF_THICKNESS_M, 0.03, 0.03],
                [160, 110, 60, 255],
            ),
        ];
        if let Some(g) = &self.geometry {
            let r = 0.5 * g.bore_m + 0.004;
            parts.insert(
                0,
                ("cylinder", [0.5 * g.stroke_m, r, r], [150, 150, 160, 120]),
            );
        }
        for (name, half_extents_m, colour) in parts {
            rec.log_link_shape(&LinkShape {
                entity: paths::link(name),
                shape: Shape::Box { half_extents_m },
                colour,
            })?;
        }
        if let Some(g) = &self.geometry {
            rec.set_link_pose(
                0.0,
                &paths::link("cylinder"),
                axis.at(-0.5 * g.stroke_m),
                axis.along(),
            )?;
            rec.set_link_pose(
                0.0,
                paths::CHAMBERS,
                axis.at(-g.stroke_m),
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
        // Every recorded signal but time, at `signals/<group>/<name>` as its producer declared it; a
        // signal the plant does not have (NaN) is not logged.
        if r.signal_paths.is_empty() {
            r.signal_paths = row
                .columns
                .iter()
                .map(|c| format!("signals/{}/{}", c.group, c.name))
                .collect();
        }
        for (i, (path, &v)) in r.signal_paths.iter().zip(row.values).enumerate() {
            if i != index::T && v.is_finite() {
                r.rec.log_scalars(t, &[(path.as_str(), v)])?;
            }
        }

        // Where the flange's front face is and which way the axis points.
        let (front, axis) = match &mut r.drawing {
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
                (ax.at(front_s), rotate(q, [1.0, 0.0, 0.0]))
            }
            Drawing::Links {
                entities,
                poses,
                flange,
                cylinder,
            } => {
                plant.visual_poses(&mut |i, p| {
                    if let Some(slot) = poses.get_mut(i) {
                        *slot = p;
                    }
                });
                for (entity, p) in entities.iter().zip(poses.iter()) {
                    r.rec
                        .set_link_pose(t, entity, p.translation_m, p.rotation_xyzw)?;
                }
                if let Some((c, ca)) = cylinder {
                    // The chambers start at the back end of the body and run along its axis.
                    let p = poses[*c];
                    let axis = rotate(p.rotation_xyzw, ca.axis);
                    let base =
                        std::array::from_fn(|k| p.translation_m[k] - axis[k] * ca.half_length_m);
                    r.rec.set_link_pose(
                        t,
                        paths::CHAMBERS,
                        base,
                        qmul(p.rotation_xyzw, ca.to_z),
                    )?;
                }
                match flange {
                    Some((i, half)) => {
                        let p = poses[*i];
                        let axis = rotate(p.rotation_xyzw, [1.0, 0.0, 0.0]);
                        (
                            std::array::from_fn(|k| p.translation_m[k] + axis[k] * *half),
                            axis,
                        )
                    }
                    None => ([0.0; 3], [1.0, 0.0, 0.0]),
                }
            }
        };
        let contact = (row.f_e() > 0.0).then(|| Contact {
            point_m: front,
            force_n: axis.map(|c| c * row.f_e()),
        });
        r.rec.log_contact(t, contact.as_ref())?;
        if let Some(geo) = geometry
            && row.p_a().is_finite()
        {
            r.rec.log_chambers(
                t,
                &ChamberSample {
                    length_a_m: row.x().max(0.0),
                    pressure_a_pa: row.p_a(),
                    length_b_m: (geo.stroke_m - row.x()).max(0.0),
                    pressure_b_pa: row.p_b(),
                },
            )?;
        }
        Ok(())
    }
}

impl StepObserver for SceneRecorder {
    fn begin_run(&mut self, run: &RunSpec, plant: &dyn Plant) {
        if self.error.is_some() {
            return;
        }
        let t0 = Instant::now();
        match self.begin(run, plant) {
            Ok(r) => self.current = Some(r),
            Err(e) => {
                self.error = Some(RerunError::Run {
                    run: run.name.clone(),
                    source: Box::new(e),
                })
            }
        }
        self.cost += t0.elapsed();
    }

    fn on_step(&mut self, row: &Row, plant: &dyn Plant) {
        let Some(r) = self.current.as_mut() else {
            return;
        };
        let t0 = Instant::now();
        if let Err(e) = Self::step(self.geometry.as_ref(), r, row, plant) {
            self.error = Some(e);
            self.current = None;
        }
        self.steps += 1;
        self.cost += t0.elapsed();
    }

    fn end_run(&mut self, result: &RunResult) {
        let Some(mut r) = self.current.take() else {
            return;
        };
        let t0 = Instant::now();
        let done = (|| -> Result<(), RerunError> {
            if let Some(why) = &result.diverged {
                let t_end = result.trace.t().last().copied().unwrap_or(0.0);
                r.rec
                    .log_event(t_end, EventLevel::Error, &format!("diverged: {why}"))?;
            }
            r.rec.finish()
        })();
        if let Err(e) = done {
            self.error = Some(RerunError::Run {
                run: result.name.clone(),
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
