//! `pneuflex run --rerun save FILE | spawn | connect URL`: each run of a scene as a Rerun recording.
//!
//! Logging reads the finished run's in-memory trace (one sample per control tick), so it cannot change the
//! simulation's results. The 3D view is the actuator schematic along its inclined axis: cylinder body, flange,
//! the environment face, the contact point with a force arrow, and both chambers coloured by pressure.

use std::path::{Path, PathBuf};

use anyhow::{Context, bail};
use pneuflex_rerun::{
    ChamberSample, Contact, EventLevel, LinkShape, RunRecorder, Shape, Sink, paths,
};
use pneuflex_scene::{RunResult, Scene};

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

/// Geometry of the schematic, from the scene's actuator sheet (SI).
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

    /// Unit vector of the actuator axis: +x tilted down by alpha (z up).
    fn axis(&self) -> [f64; 3] {
        [self.alpha_rad.cos(), 0.0, -self.alpha_rad.sin()]
    }

    /// Point at distance `s` along the axis from the rod end of the cylinder.
    fn at(&self, s: f64) -> [f64; 3] {
        let n = self.axis();
        [n[0] * s, n[1] * s, n[2] * s]
    }

    /// Rotation taking the link x axis onto the actuator axis (about y by alpha).
    fn along_axis(&self) -> [f64; 4] {
        let h = 0.5 * self.alpha_rad;
        [0.0, h.sin(), 0.0, h.cos()]
    }

    /// Rotation taking z (the chambers' cylinder axis) onto the actuator axis (about y by 90 deg + alpha).
    fn z_along_axis(&self) -> [f64; 4] {
        let h = 0.5 * (std::f64::consts::FRAC_PI_2 + self.alpha_rad);
        [0.0, h.sin(), 0.0, h.cos()]
    }
}

const FLANGE_HALF_THICKNESS_M: f64 = 0.005;
const FACE_HALF_THICKNESS_M: f64 = 0.0025;

/// Records one finished run to `sink`; returns when the recording is complete (file written or stream flushed).
pub fn log_run(
    sink: &Sink,
    scene: &Scene,
    scene_path: &Path,
    result: &RunResult,
) -> anyhow::Result<()> {
    let geo = Schematic::of(scene, scene_path)
        .with_context(|| format!("{}: geometry for the Rerun view", scene_path.display()))?;
    let mut rec = RunRecorder::new("pneuflex", &format!("{}/{}", scene.name, result.name), sink)?;
    let body = paths::link("cylinder");
    let flange = paths::link("flange");
    let face = paths::link("environment");
    let r = 0.5 * geo.bore_m + 0.004;
    for (entity, shape, colour) in [
        (
            &body,
            Shape::Box {
                half_extents_m: [0.5 * geo.stroke_m, r, r],
            },
            [150, 150, 160, 120],
        ),
        (
            &flange,
            Shape::Box {
                half_extents_m: [FLANGE_HALF_THICKNESS_M, 0.02, 0.02],
            },
            [90, 90, 100, 255],
        ),
        (
            &face,
            Shape::Box {
                half_extents_m: [FACE_HALF_THICKNESS_M, 0.03, 0.03],
            },
            [160, 110, 60, 255],
        ),
    ] {
        rec.log_link_shape(&LinkShape {
            entity: entity.clone(),
            shape,
            colour,
        })?;
    }
    rec.set_chamber_bore(geo.bore_m)?;
    let q = geo.along_axis();
    // The cylinder body spans s in [-stroke, 0]; the piston sits at s = x - stroke, the flange at s = x.
    rec.set_link_pose(0.0, &body, geo.at(-0.5 * geo.stroke_m), q)?;
    rec.set_link_pose(
        0.0,
        paths::CHAMBERS,
        geo.at(-geo.stroke_m),
        geo.z_along_axis(),
    )?;
    for ev in &scene.events {
        rec.log_event(
            ev.t_s(),
            EventLevel::Info,
            &format!("{}: {ev:?}", ev.kind()),
        )?;
    }
    if let Some(why) = &result.diverged {
        let t_end = result.trace.t.last().copied().unwrap_or(0.0);
        rec.log_event(t_end, EventLevel::Error, &format!("diverged: {why}"))?;
    }

    let tr = &result.trace;
    let adaptive = !tr.g.is_empty();
    let n = geo.axis();
    let mut signals: Vec<(&str, f64)> = Vec::with_capacity(paths::SIGNALS.len());
    for k in 0..tr.len() {
        let t = tr.t[k];
        let x = tr.x[k];
        signals.clear();
        signals.extend([
            (paths::F_REF, tr.f_ref[k]),
            (paths::F_E, tr.f_e[k]),
            (paths::X, x),
            (paths::X_R, tr.x_r[k]),
            (paths::VALVE_U, tr.u[k]),
        ]);
        if tr.p_a[k].is_finite() {
            signals.extend([(paths::P_A, tr.p_a[k]), (paths::P_B, tr.p_b[k])]);
        }
        if adaptive {
            signals.extend([
                (paths::ADAPTIVE_G, tr.g[k]),
                (paths::ADAPTIVE_P, tr.p[k]),
                (paths::ADAPTIVE_D, tr.d[k]),
            ]);
        }
        rec.log_scalars(t, &signals)?;

        let flange_front = x + 2.0 * FLANGE_HALF_THICKNESS_M;
        rec.set_link_pose(t, &flange, geo.at(x + FLANGE_HALF_THICKNESS_M), q)?;
        // The face rests at x_e until the flange pushes it.
        let face_s = flange_front.max(geo.x_e_m + 2.0 * FLANGE_HALF_THICKNESS_M);
        rec.set_link_pose(t, &face, geo.at(face_s + FACE_HALF_THICKNESS_M), q)?;
        let contact = (tr.f_e[k] > 0.0).then(|| Contact {
            point_m: geo.at(flange_front),
            force_n: [n[0] * tr.f_e[k], n[1] * tr.f_e[k], n[2] * tr.f_e[k]],
        });
        rec.log_contact(t, contact.as_ref())?;
        if tr.p_a[k].is_finite() {
            rec.log_chambers(
                t,
                &ChamberSample {
                    length_a_m: x.max(0.0),
                    pressure_a_pa: tr.p_a[k],
                    length_b_m: (geo.stroke_m - x).max(0.0),
                    pressure_b_pa: tr.p_b[k],
                },
            )?;
        }
    }
    rec.finish()?;
    Ok(())
}
