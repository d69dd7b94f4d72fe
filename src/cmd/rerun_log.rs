//! `pneuflex run --rerun save FILE | spawn | connect URL`: each run of a scene as a Rerun recording.
//!
//! A [`StepObserver`] logs every control tick while the scene runs; it only reads the plant, so the results
//! are those of a run without logging. Plants with geometry (the multibody rig) are drawn link by link at
//! their simulated poses; the 1-DOF and ideal plants as a schematic of the actuator along its inclined axis.
//! Either way the contact point carries a force arrow and the chambers are coloured by pressure.

use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use anyhow::{Context, bail};
use pneuflex_rerun::{
    ChamberSample, Contact, EventLevel, LinkShape, RunRecorder, Shape, Sink, paths,
};
use pneuflex_scene::schema::RunSpec;
use pneuflex_scene::trace::Row;
use pneuflex_scene::{Plant, RunResult, Scene, StepObserver, VisualPose, VisualShape};

/// Parses the words after `--rerun`: `save FILE`, `spawn` or `connect URL`.
pub fn parse_sink(words: &[String]) -> anyhow::Result<Sink> {
    match words {
        [mode, file] if mode == "save" => Ok(Sink::Save(PathBuf::from(file))),
        [mode] if mode == "spawn" => Ok(Sink::Spawn),
        [mode, url] if mode == "connect" => Ok(Sink::Connect(url.clone())),
        _ => bail!(
            "--rerun takes `save <file.rrd>`, `spawn` or `connect <url>`, got `{}`",
            words.join(" ")
        ),
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

/// Actuator geometry from the scene's actuator sheet (SI), for the schematic and the chambers.
struct Schematic {
    stroke_m: f64,
    bore_m: f64,
    alpha_rad: f64,
    x_e_m: f64,
}

impl Schematic {
    fn of(scene: &Scene, scene_path: &Path) -> anyhow::Result<Self> {
        let sheet_path = pneuflex_pneumatics::find_actuator_sheet(scene_path)?;
        let model = pneuflex_pneumatics::ActuatorSheet::load(&sheet_path)?.model();
        Ok(Self {
            stroke_m: model.actuator.cylinder.stroke_m,
            bore_m: model.actuator.cylinder.bore_m,
            alpha_rad: model.mechanics.alpha_rad,
            x_e_m: scene.environment.x_e_m,
        })
    }

    /// Rotation taking x onto the actuator axis, tilted down by alpha about y (z up).
    fn along_axis(&self) -> [f64; 4] {
        let h = 0.5 * self.alpha_rad;
        [0.0, h.sin(), 0.0, h.cos()]
    }

    /// Point at distance `s` along the axis from the rod end of the cylinder.
    fn at(&self, s: f64) -> [f64; 3] {
        let n = rotate(self.along_axis(), [1.0, 0.0, 0.0]);
        n.map(|c| c * s)
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

/// The run being recorded.
struct Recording {
    rec: RunRecorder,
    /// Entity paths of the plant's visuals (empty: the schematic is drawn).
    links: Vec<String>,
    /// Index of the flange among the visuals, and its half thickness along its x.
    flange: Option<(usize, f64)>,
    /// Index of the cylinder body among the visuals.
    cylinder: Option<usize>,
    poses: Vec<VisualPose>,
    /// Entity path of each recorded column, from its declaration (filled at the first tick).
    signal_paths: Vec<String>,
}

/// Logs every run of a scene to Rerun; the first error stops logging and is returned by [`finish`].
pub struct RerunObserver {
    sink: Sink,
    n_runs: usize,
    scene_name: String,
    events: Vec<(f64, String)>,
    geo: Schematic,
    current: Option<Recording>,
    error: Option<anyhow::Error>,
    /// Time spent logging, and ticks logged.
    pub cost: Duration,
    /// Ticks logged over all runs.
    pub steps: usize,
}

impl RerunObserver {
    /// An observer for `scene` sending to `sink`; fails when the scene's actuator sheet cannot be read.
    pub fn new(sink: Sink, scene: &Scene, scene_path: &Path) -> anyhow::Result<Self> {
        let geo = Schematic::of(scene, scene_path)
            .with_context(|| format!("{}: geometry for the Rerun view", scene_path.display()))?;
        Ok(Self {
            sink,
            n_runs: scene.runs.len(),
            scene_name: scene.name.clone(),
            events: scene
                .events
                .iter()
                .map(|ev| (ev.t_s(), format!("{}: {ev:?}", ev.kind())))
                .collect(),
            geo,
            current: None,
            error: None,
            cost: Duration::ZERO,
            steps: 0,
        })
    }

    /// Returns the first logging error, if any (recordings of finished runs are complete).
    pub fn finish(self) -> anyhow::Result<()> {
        self.error.map_or(Ok(()), Err)
    }

    fn begin(&mut self, run: &RunSpec, plant: &dyn Plant) -> anyhow::Result<Recording> {
        let sink = sink_for_run(&self.sink, &run.name, self.n_runs);
        let mut rec = RunRecorder::new(
            "pneuflex",
            &format!("{}/{}", self.scene_name, run.name),
            &sink,
        )
        .with_context(|| format!("Rerun recording of run `{}`", run.name))?;
        let visuals = plant.visuals();
        let mut links = Vec::with_capacity(visuals.len());
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
            let colour = match v.name.as_str() {
                "flange" => [90, 90, 100, 255],
                n if n.starts_with("wood") => [170, 120, 60, 255],
                n if n.starts_with("iron") => [120, 130, 140, 255],
                _ => [170, 170, 180, 110],
            };
            rec.log_link_shape(&LinkShape {
                entity: entity.clone(),
                shape,
                colour,
            })?;
            if v.name == "flange" {
                let half = match v.shape {
                    VisualShape::Box { half_extents_m } => half_extents_m[0],
                    _ => 0.0,
                };
                flange = Some((i, half));
            }
            if v.name == "cylinder" {
                cylinder = Some(i);
            }
            links.push(entity);
        }
        let geo = &self.geo;
        if links.is_empty() {
            // Schematic: the cylinder body spans s in [-stroke, 0]; the flange sits at s = x.
            let r = 0.5 * geo.bore_m + 0.004;
            for (name, half_extents_m, colour) in [
                ("cylinder", [0.5 * geo.stroke_m, r, r], [150, 150, 160, 120]),
                (
                    "flange",
                    [FLANGE_HALF_THICKNESS_M, 0.02, 0.02],
                    [90, 90, 100, 255],
                ),
                (
                    "environment",
                    [FACE_HALF_THICKNESS_M, 0.03, 0.03],
                    [160, 110, 60, 255],
                ),
            ] {
                rec.log_link_shape(&LinkShape {
                    entity: paths::link(name),
                    shape: Shape::Box { half_extents_m },
                    colour,
                })?;
            }
            rec.set_link_pose(
                0.0,
                &paths::link("cylinder"),
                geo.at(-0.5 * geo.stroke_m),
                geo.along_axis(),
            )?;
            rec.set_link_pose(
                0.0,
                paths::CHAMBERS,
                geo.at(-geo.stroke_m),
                qmul(geo.along_axis(), Z_TO_X),
            )?;
        }
        rec.set_chamber_bore(geo.bore_m)?;
        for (t, text) in &self.events {
            rec.log_event(*t, EventLevel::Info, text)?;
        }
        Ok(Recording {
            rec,
            poses: vec![
                VisualPose {
                    translation_m: [0.0; 3],
                    rotation_xyzw: [0.0, 0.0, 0.0, 1.0]
                };
                links.len()
            ],
            links,
            flange,
            cylinder,
            signal_paths: Vec::new(),
        })
    }

    fn step(
        geo: &Schematic,
        r: &mut Recording,
        row: &Row,
        plant: &dyn Plant,
    ) -> anyhow::Result<()> {
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
            if i != pneuflex_control::signal::index::T && v.is_finite() {
                r.rec.log_scalars(t, &[(path.as_str(), v)])?;
            }
        }

        // Where the flange's front face is and which way the axis points.
        let (front, axis) = if r.links.is_empty() {
            let q = geo.along_axis();
            r.rec.set_link_pose(
                t,
                &paths::link("flange"),
                geo.at(row.x() + FLANGE_HALF_THICKNESS_M),
                q,
            )?;
            let front_s = row.x() + 2.0 * FLANGE_HALF_THICKNESS_M;
            let face_s = front_s.max(geo.x_e_m + 2.0 * FLANGE_HALF_THICKNESS_M);
            r.rec.set_link_pose(
                t,
                &paths::link("environment"),
                geo.at(face_s + FACE_HALF_THICKNESS_M),
                q,
            )?;
            (geo.at(front_s), rotate(q, [1.0, 0.0, 0.0]))
        } else {
            let poses = &mut r.poses;
            plant.visual_poses(&mut |i, p| {
                if let Some(slot) = poses.get_mut(i) {
                    *slot = p;
                }
            });
            for (entity, p) in r.links.iter().zip(r.poses.iter()) {
                r.rec
                    .set_link_pose(t, entity, p.translation_m, p.rotation_xyzw)?;
            }
            if let Some(c) = r.cylinder {
                let p = r.poses[c];
                let axis = rotate(p.rotation_xyzw, [1.0, 0.0, 0.0]);
                let base = std::array::from_fn(|k| p.translation_m[k] - axis[k] * geo.stroke_m);
                r.rec
                    .set_link_pose(t, paths::CHAMBERS, base, qmul(p.rotation_xyzw, Z_TO_X))?;
            }
            match r.flange {
                Some((i, half)) => {
                    let p = r.poses[i];
                    let axis = rotate(p.rotation_xyzw, [1.0, 0.0, 0.0]);
                    (
                        std::array::from_fn(|k| p.translation_m[k] + axis[k] * half),
                        axis,
                    )
                }
                None => (geo.at(row.x()), rotate(geo.along_axis(), [1.0, 0.0, 0.0])),
            }
        };
        let contact = (row.f_e() > 0.0).then(|| Contact {
            point_m: front,
            force_n: axis.map(|c| c * row.f_e()),
        });
        r.rec.log_contact(t, contact.as_ref())?;
        if row.p_a().is_finite() {
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

impl StepObserver for RerunObserver {
    fn begin_run(&mut self, run: &RunSpec, plant: &dyn Plant) {
        if self.error.is_some() {
            return;
        }
        let t0 = Instant::now();
        match self.begin(run, plant) {
            Ok(r) => self.current = Some(r),
            Err(e) => self.error = Some(e),
        }
        self.cost += t0.elapsed();
    }

    fn on_step(&mut self, row: &Row, plant: &dyn Plant) {
        let Some(r) = self.current.as_mut() else {
            return;
        };
        let t0 = Instant::now();
        if let Err(e) = Self::step(&self.geo, r, row, plant) {
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
        let done = (|| -> anyhow::Result<()> {
            if let Some(why) = &result.diverged {
                let t_end = result.trace.t().last().copied().unwrap_or(0.0);
                r.rec
                    .log_event(t_end, EventLevel::Error, &format!("diverged: {why}"))?;
            }
            r.rec.finish()?;
            Ok(())
        })();
        if let Err(e) = done {
            self.error = Some(e.context(format!("Rerun recording of run `{}`", result.name)));
        }
        self.cost += t0.elapsed();
    }
}
