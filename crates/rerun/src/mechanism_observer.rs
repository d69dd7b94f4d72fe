//! Rerun recording of a scene with several actuators (docs/multibody.md): every link's collision shapes
//! with their poses over time, and each actuator's signals under its own name
//! (`signals/<group>/<actuator>/<name>`, e.g. `signals/force/left/f_e`), one recording per run.

use std::time::{Duration, Instant};

use pneuflex_scene::mechanism::{ColumnSignal, Mechanism, MechanismObserver, MechanismScene, draw};

use crate::error::RerunError;
use crate::layout::Layout;
use crate::paths;
use crate::recorder::{LinkShape, RecorderOptions, RunRecorder};
use crate::scene_observer::{role_colour, sink_for_run};
use crate::sink::Sink;

/// Records each run of a mechanism scene as it goes.
pub struct MechanismRecorder {
    sink: Sink,
    scene_name: String,
    n_runs: usize,
    current: Option<Current>,
    error: Option<RerunError>,
    cost: Duration,
}

/// The run being recorded.
struct Current {
    rec: RunRecorder,
    /// Entity path of each drawn shape, in [`draw::visuals`] order.
    entities: Vec<String>,
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
        Ok(Self {
            sink,
            scene_name: scene.name.clone(),
            n_runs: scene.runs.len(),
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

    fn open(
        &mut self,
        run: &str,
        m: &Mechanism,
        columns: &[ColumnSignal],
    ) -> Result<Current, RerunError> {
        let signal_name = |c: &ColumnSignal| format!("{}/{}", c.actuator, c.name);
        let names: Vec<String> = columns.iter().map(signal_name).collect();
        let layout = Layout::for_signals(
            columns
                .iter()
                .zip(&names)
                .map(|(c, n)| (n.as_str(), c.unit, c.group)),
        );
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
        let visuals = draw::visuals(m);
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
        let paths = columns
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
            paths,
        })
    }

    fn log(&mut self, m: &Mechanism, row: &[f64]) -> Result<(), RerunError> {
        let Some(c) = self.current.as_mut() else {
            return Ok(());
        };
        let t = row[0];
        let mut failed = None;
        draw::visual_poses(m, &mut |i, p| {
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

impl MechanismObserver for MechanismRecorder {
    fn begin(&mut self, run: &str, m: &Mechanism, columns: &[ColumnSignal]) {
        let start = Instant::now();
        if let Some(c) = self.current.take() {
            let r = c.rec.finish();
            self.keep(r);
        }
        match self.open(run, m, columns) {
            Ok(c) => self.current = Some(c),
            Err(e) => self.keep(Err(e)),
        }
        self.cost += start.elapsed();
    }

    fn tick(&mut self, m: &Mechanism, row: &[f64]) {
        if self.error.is_some() {
            return;
        }
        let start = Instant::now();
        let r = self.log(m, row);
        self.keep(r);
        self.cost += start.elapsed();
    }

    fn end(&mut self) {
        if let Some(c) = self.current.take() {
            let r = c.rec.finish();
            self.keep(r);
        }
    }
}
