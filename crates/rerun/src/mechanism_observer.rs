//! Rerun recording of a scene with several actuators (docs/multibody.md): every link's collision shapes
//! with their poses over time, each actuator's signals under its own name
//! (`signals/<group>/<actuator>/<name>`, e.g. `signals/force/left/f_e`), the scene's events at their time
//! and why a run ended early, one recording per run. It is a `Sink` of the one loop, as every viewer is.

use std::time::{Duration, Instant};

use pneuflex_control::Signal;
use pneuflex_scene::Plant;
use pneuflex_scene::mechanism::MechanismScene;

use crate::error::RerunError;
use crate::layout::{Eye, Layout};
use crate::paths;
use crate::recorder::{EventLevel, LinkShape, RecorderOptions, RunRecorder};
use crate::scene_observer::{role_colour, sink_for_run};
use crate::sink::Sink;

/// Records each run of a mechanism scene as it goes.
pub struct MechanismRecorder {
    sink: Sink,
    scene_name: String,
    n_runs: usize,
    /// The scene's events as sentences, by time.
    events: Vec<(f64, String)>,
    current: Option<Current>,
    error: Option<RerunError>,
    cost: Duration,
}

/// The run being recorded.
struct Current {
    rec: RunRecorder,
    /// Entity path of each drawn shape, in the plant's `visuals` order.
    entities: Vec<String>,
    /// The next of the scene's events to log.
    next_event: usize,
    /// The last row's time, s (where a run cut short says why).
    last_t: f64,
    /// Entity path of each column after `t`, and the factor to its display unit (m to mm, Pa to kPa:
    /// the units the layout's titles name, [`crate::units`]).
    paths: Vec<(String, f64)>,
}

impl MechanismRecorder {
    /// A recorder for `scene` sending to `sink`; a save path whose folder does not exist is refused here.
    pub fn new(sink: Sink, scene: &MechanismScene) -> Result<Self, RerunError> {
        if let Sink::Save(_) = &sink {
            let first = scene.runs.first().map_or("run", |r| r.name.as_str());
            if let Sink::Save(p) = sink_for_run(&sink, first, scene.runs.len()) {
                crate::sink::check_save_path(&p)?;
            }
        }
        let mut events: Vec<(f64, String)> = scene
            .events
            .iter()
            .map(|e| {
                let (what, name) = match (&e.contact, &e.spring) {
                    (Some(c), _) => ("contact", c.as_str()),
                    (None, Some(s)) => ("spring", s.as_str()),
                    (None, None) => ("contact", ""),
                };
                let damping = e
                    .damping_n_s_per_m
                    .map(|c| format!(", damping {c} N s/m"))
                    .unwrap_or_default();
                (
                    e.t_s,
                    format!(
                        "{what} '{name}' stiffens to {} N/m{damping}",
                        e.stiffness_n_per_m
                    ),
                )
            })
            .collect();
        events.sort_by(|a, b| a.0.total_cmp(&b.0));
        Ok(Self {
            sink,
            scene_name: scene.name.clone(),
            n_runs: scene.runs.len(),
            events,
            current: None,
            error: None,
            cost: Duration::ZERO,
        })
    }

    /// Time spent logging.
    pub fn cost(&self) -> Duration {
        self.cost
    }

    /// The first logging error, if any.
    pub fn finish(mut self) -> Result<(), RerunError> {
        if let Some(c) = self.current.take() {
            c.rec.finish()?;
        }
        self.error.map_or(Ok(()), Err)
    }

    /// A run's recording: its links, and a series per column after `t` (`left.f_e` under
    /// `signals/force/left/f_e`).
    fn open(
        &mut self,
        run: &str,
        plant: &dyn Plant,
        columns: &[Signal],
    ) -> Result<Current, RerunError> {
        let signals = columns.get(1..).unwrap_or_default();
        let names: Vec<String> = signals.iter().map(|c| c.name.replace('.', "/")).collect();
        let layout = Layout::for_signals(
            signals
                .iter()
                .zip(&names)
                .map(|(c, n)| (n.as_str(), c.unit, c.group)),
        );
        let visuals = plant.visuals();
        let mut layout = layout;
        layout.eye = framing_eye(plant, &visuals);
        let options = RecorderOptions {
            layout,
            ..RecorderOptions::default()
        };
        let sink = sink_for_run(&self.sink, run, self.n_runs);
        let mut rec = RunRecorder::with_options(
            "pneuflex",
            &format!("{}/{run}", self.scene_name),
            &sink,
            options,
        )?;
        let mut entities = Vec::with_capacity(visuals.len());
        for v in &visuals {
            let entity = paths::link(&v.name);
            rec.log_link_shape(&LinkShape {
                entity: entity.clone(),
                shape: v.shape.clone(),
                colour: role_colour(v.role),
            })?;
            entities.push(entity);
        }
        let paths = signals
            .iter()
            .zip(&names)
            .map(|(c, n)| {
                (
                    format!("signals/{}/{n}", c.group),
                    crate::units::display_unit(c.unit).scale,
                )
            })
            .collect();
        Ok(Current {
            rec,
            entities,
            next_event: 0,
            last_t: 0.0,
            paths,
        })
    }

    fn log(&mut self, plant: &dyn Plant, row: &[f64]) -> Result<(), RerunError> {
        let Some(c) = self.current.as_mut() else {
            return Ok(());
        };
        let t = row[0];
        c.last_t = t;
        // The events due by this tick, as the loop applied them (half a tick of rounding).
        while let Some((t_e, text)) = self.events.get(c.next_event)
            && *t_e <= t + 1e-9
        {
            c.rec.log_event(*t_e, EventLevel::Info, text)?;
            c.next_event += 1;
        }
        let mut failed = None;
        plant.visual_poses(&mut |i, p| {
            if failed.is_none()
                && let Err(e) =
                    c.rec
                        .set_link_pose(t, &c.entities[i], p.translation_m, p.rotation_xyzw)
            {
                failed = Some(e);
            }
        });
        if let Some(e) = failed {
            return Err(e);
        }
        for ((path, scale), v) in c.paths.iter().zip(&row[1..]) {
            c.rec.log_scalars(t, &[(path.as_str(), v * scale)])?;
        }
        Ok(())
    }

    fn keep(&mut self, r: Result<(), RerunError>) {
        if let (Err(e), None) = (r, &self.error) {
            self.error = Some(e);
        }
    }
}

/// The radius of a sphere about a shape's origin that holds it, m.
fn bounding_radius(shape: &pneuflex_scene::plants::VisualShape) -> f64 {
    use pneuflex_scene::plants::VisualShape;
    let norm = |v: [f64; 3]| (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
    match shape {
        VisualShape::Box { half_extents_m } => norm(*half_extents_m),
        VisualShape::Cylinder {
            radius_m,
            half_length_m,
        } => radius_m.hypot(*half_length_m),
        VisualShape::Sphere { radius_m } => *radius_m,
        VisualShape::Mesh { vertices_m, .. } => {
            vertices_m.iter().map(|v| norm(*v)).fold(0.0, f64::max)
        }
    }
}

/// A camera that frames the whole mechanism at t = 0: it looks at the middle of the box that holds every
/// drawn shape, from the front (−y), a little to the side and above, far enough that the box's diagonal
/// fills about half the view. None for a plant that draws nothing.
fn framing_eye(plant: &dyn Plant, visuals: &[pneuflex_scene::Visual]) -> Option<Eye> {
    let (mut lo, mut hi) = ([f64::INFINITY; 3], [f64::NEG_INFINITY; 3]);
    plant.visual_poses(&mut |i, p| {
        let r = visuals.get(i).map_or(0.0, |v| bounding_radius(&v.shape));
        for k in 0..3 {
            lo[k] = lo[k].min(p.translation_m[k] - r);
            hi[k] = hi[k].max(p.translation_m[k] + r);
        }
    });
    if !lo.iter().chain(&hi).all(|v| v.is_finite()) {
        return None;
    }
    let look_at_m: [f64; 3] = std::array::from_fn(|k| 0.5 * (lo[k] + hi[k]));
    let diagonal = (0..3).map(|k| (hi[k] - lo[k]).powi(2)).sum::<f64>().sqrt();
    // From the front-right and above: a unit direction (0.35, −0.85, 0.4) at 1.6 diagonals.
    let dir = [0.35, -0.85, 0.4];
    let n: f64 = dir[0] * dir[0] + dir[1] * dir[1] + dir[2] * dir[2];
    let d = 1.6 * diagonal.max(1e-3) / n.sqrt();
    Some(Eye {
        position_m: std::array::from_fn(|k| look_at_m[k] + d * dir[k]),
        look_at_m,
    })
}

impl<'p> pneuflex_control::Sink<dyn Plant + 'p> for MechanismRecorder {
    fn begin(&mut self, run: &str, columns: &[Signal], plant: &(dyn Plant + 'p)) {
        let start = Instant::now();
        if let Some(c) = self.current.take() {
            let r = c.rec.finish();
            self.keep(r);
        }
        match self.open(run, plant, columns) {
            Ok(c) => self.current = Some(c),
            Err(e) => self.keep(Err(e)),
        }
        self.cost += start.elapsed();
    }

    fn row(&mut self, values: &[f64], plant: &(dyn Plant + 'p)) {
        if self.error.is_some() {
            return;
        }
        let start = Instant::now();
        let r = self.log(plant, values);
        self.keep(r);
        self.cost += start.elapsed();
    }

    fn end(&mut self, why: Option<&str>) {
        if let Some(mut c) = self.current.take() {
            if let Some(why) = why {
                let r = c.rec.log_event(c.last_t, EventLevel::Error, why);
                self.keep(r);
            }
            let r = c.rec.finish();
            self.keep(r);
        }
    }
}
