//! The run recorder: static geometry once, then per-step samples batched into columns.

use std::collections::HashMap;
use std::time::Duration;

use rerun::{
    Arrows3D, Boxes3D, Color, Cylinders3D, Ellipsoids3D, EntityPath, FillMode, LineStrips3D,
    Mesh3D, Points3D, RecordingStream, RecordingStreamBuilder, Scalars, SeriesLines, TextLog,
    TimeCell, TimeColumn, Transform3D, ViewCoordinates,
};

use pneuflex_scene::plants::VisualShape;

use crate::RerunError;
use crate::layout::Layout;
use crate::paths;
pub use crate::paths::Clock;
use crate::sink::{self, CONNECT_PROBE_TIMEOUT, RERUN_VERSION, Sink};

/// Seconds since the Unix epoch now, for [`Clock::Wall`] recordings.
pub fn wall_clock_s() -> f64 {
    std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map(|d| d.as_secs_f64())
        .unwrap_or(0.0)
}

/// Settings of a recorder beyond its sink.
#[derive(Debug, Clone, PartialEq)]
pub struct RecorderOptions {
    /// Timeline of the per-step samples.
    pub clock: Clock,
    /// Samples buffered per entity before they are handed to Rerun as one column chunk.
    /// Larger is cheaper; smaller shows live data sooner (1 = every step immediately).
    pub batch_rows: usize,
    /// Chamber pressure drawn fully blue (absolute, Pa).
    pub pressure_low_pa: f64,
    /// Chamber pressure drawn fully red (absolute, Pa).
    pub pressure_high_pa: f64,
    /// Length of the contact-force arrow per newton (m/N).
    pub force_arrow_m_per_n: f64,
    /// Send the layout (3D view beside force and position plots), active from the start and the default.
    pub send_blueprint: bool,
    /// The plots of the layout.
    pub layout: Layout,
    /// Longest wait for a viewer to take the data in `flush`/`finish` (file sinks always wait).
    pub stream_flush_timeout: Duration,
}

impl Default for RecorderOptions {
    fn default() -> Self {
        Self {
            clock: Clock::Sim,
            batch_rows: 1024,
            pressure_low_pa: 1.0e5,
            pressure_high_pa: 7.0e5,
            force_arrow_m_per_n: 1.0e-3,
            send_blueprint: true,
            layout: Layout::default(),
            stream_flush_timeout: Duration::from_secs(5),
        }
    }
}

impl RecorderOptions {
    fn validate(&self) -> Result<(), RerunError> {
        let bad = |option, reason: String| Err(RerunError::BadOption { option, reason });
        if self.batch_rows == 0 {
            return bad("batch_rows", "must be at least 1".into());
        }
        if !(self.pressure_low_pa.is_finite()
            && self.pressure_high_pa.is_finite()
            && self.pressure_high_pa > self.pressure_low_pa)
        {
            return bad(
                "pressure_low_pa/pressure_high_pa",
                format!(
                    "need finite low < high, got {} .. {}",
                    self.pressure_low_pa, self.pressure_high_pa
                ),
            );
        }
        if !(self.force_arrow_m_per_n.is_finite() && self.force_arrow_m_per_n > 0.0) {
            return bad(
                "force_arrow_m_per_n",
                format!("must be finite and > 0, got {}", self.force_arrow_m_per_n),
            );
        }
        Ok(())
    }
}

/// A link drawn as its collision shape; its pose is set over time with [`RunRecorder::set_link_pose`].
#[derive(Debug, Clone, PartialEq)]
pub struct LinkShape {
    /// Entity path, e.g. `world/links/flange` (see [`paths::link`]).
    pub entity: String,
    /// Geometry in the link frame.
    pub shape: VisualShape,
    /// Colour as RGBA.
    pub colour: [u8; 4],
}

/// A contact between the actuator and the environment at one instant (world frame).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Contact {
    /// Contact point (m), drawn as a point.
    pub point_m: [f64; 3],
    /// The force drawn (N), as an arrow of `force_arrow_m_per_n` per newton labelled with its magnitude.
    pub force_n: [f64; 3],
    /// Where the arrow starts (m): the contact point, or beside it so that the arrow is outside the bodies.
    pub arrow_from_m: [f64; 3],
}

/// Radius of the drawn contact point, m.
const CONTACT_POINT_RADIUS_M: f32 = 0.003;
/// Shaft radius of the contact-force arrow, m.
const FORCE_ARROW_RADIUS_M: f32 = 0.0015;
/// Colour of the contact point and the force arrow: a yellow that stands out against every body.
const CONTACT_COLOUR: [u8; 4] = [255, 210, 0, 255];

/// Both chambers of the cylinder at one instant.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ChamberSample {
    /// Length of chamber A along the cylinder axis (m).
    pub length_a_m: f64,
    /// Absolute pressure in chamber A (Pa).
    pub pressure_a_pa: f64,
    /// Length of chamber B along the cylinder axis (m).
    pub length_b_m: f64,
    /// Absolute pressure in chamber B (Pa).
    pub pressure_b_pa: f64,
}

/// Severity of a scene event.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum EventLevel {
    /// Normal progress (phase change, object arrives).
    Info,
    /// Something the user should look at (saturation, limit reached).
    Warn,
    /// A fault (safety stop).
    Error,
}

/// Per-step time series of one scalar signal.
struct ScalarColumn {
    path: EntityPath,
    times: Vec<i64>,
    values: Vec<f64>,
}

/// Per-step poses of one link.
struct PoseColumn {
    path: EntityPath,
    times: Vec<i64>,
    translations: Vec<[f32; 3]>,
    rotations_xyzw: Vec<[f32; 4]>,
}

/// Per-step contact: zero or one point/arrow per row.
struct ContactColumn {
    times: Vec<i64>,
    counts: Vec<usize>,
    points: Vec<[f32; 3]>,
    origins: Vec<[f32; 3]>,
    arrows: Vec<[f32; 3]>,
    labels: Vec<String>,
}

/// Radius of the leader line from the arrow to the contact point, m.
const LEADER_RADIUS_M: f32 = 0.0005;

/// Per-step chamber cylinders (length, centre and pressure colour per row).
struct ChamberColumn {
    path: EntityPath,
    times: Vec<i64>,
    lengths: Vec<f32>,
    centres: Vec<[f32; 3]>,
    colours: Vec<Color>,
}

/// Records one run (simulation or rig) to Rerun.
///
/// Per-step calls only copy numbers into preallocated column buffers; every `batch_rows` samples
/// an entity's buffer is sent as one column chunk (`send_columns`), so a step costs no Rerun call.
pub struct RunRecorder {
    rec: RecordingStream,
    sink: Sink,
    opts: RecorderOptions,
    scalars: Vec<ScalarColumn>,
    scalar_index: HashMap<String, usize>,
    poses: Vec<PoseColumn>,
    pose_index: HashMap<String, usize>,
    contact: ContactColumn,
    chambers: [ChamberColumn; 2],
}

impl RunRecorder {
    /// Opens a recording with default options (`sim_time`, default layout).
    pub fn new(app_id: &str, recording_name: &str, sink: &Sink) -> Result<Self, RerunError> {
        Self::with_options(app_id, recording_name, sink, RecorderOptions::default())
    }

    /// Opens a recording; checks the sink first so that a bad path or address fails here, fast.
    pub fn with_options(
        app_id: &str,
        recording_name: &str,
        sink: &Sink,
        opts: RecorderOptions,
    ) -> Result<Self, RerunError> {
        opts.validate()?;
        let app = rerun::ApplicationId::try_new(app_id).map_err(|e| RerunError::BadOption {
            option: "app_id",
            reason: format!("`{app_id}`: {e}"),
        })?;
        let mut builder = RecordingStreamBuilder::new(app.clone()).recording_name(recording_name);
        if opts.send_blueprint && opts.layout.eye.is_none() {
            // Active when the recording starts (a viewer's own layout does not win over it) and the
            // default the viewer returns to on "reset".
            builder = builder.with_blueprint(crate::layout::blueprint(opts.clock, &opts.layout));
        }
        let rec = match sink {
            Sink::Save(path) => {
                sink::check_save_path(path)?;
                builder.save(path).map_err(|e| RerunError::SaveCreate {
                    path: path.clone(),
                    reason: e.to_string(),
                })?
            }
            Sink::Connect(addr) => {
                let (url, host_port) = sink::normalise_url(addr)?;
                sink::probe(&url, &host_port, CONNECT_PROBE_TIMEOUT)?;
                builder
                    .connect_grpc_opts(url.clone())
                    .map_err(|e| RerunError::BadUrl {
                        url,
                        reason: e.to_string(),
                    })?
            }
            Sink::Spawn => {
                if sink::find_viewer(std::env::var_os("PATH").as_deref()).is_none() {
                    return Err(RerunError::ViewerNotFound {
                        version: RERUN_VERSION,
                    });
                }
                builder
                    .spawn()
                    .map_err(|e| RerunError::Spawn(e.to_string()))?
            }
        };
        if opts.send_blueprint
            && let Some(eye) = opts.layout.eye
        {
            crate::layout::send_with_eye(&rec, &app, opts.clock, &opts.layout, eye).map_err(
                |reason| RerunError::Log {
                    entity: "blueprint".into(),
                    reason,
                },
            )?;
        }
        let n = opts.batch_rows;
        let chamber = |path: &str| ChamberColumn {
            path: EntityPath::from(path),
            times: Vec::with_capacity(n),
            lengths: Vec::with_capacity(n),
            centres: Vec::with_capacity(n),
            colours: Vec::with_capacity(n),
        };
        let mut me = Self {
            rec,
            sink: sink.clone(),
            scalars: Vec::new(),
            scalar_index: HashMap::new(),
            poses: Vec::new(),
            pose_index: HashMap::new(),
            contact: ContactColumn {
                times: Vec::with_capacity(n),
                counts: Vec::with_capacity(n),
                points: Vec::with_capacity(n),
                origins: Vec::with_capacity(n),
                arrows: Vec::with_capacity(n),
                labels: Vec::with_capacity(n),
            },
            chambers: [chamber(paths::CHAMBER_A), chamber(paths::CHAMBER_B)],
            opts,
        };
        me.log_static_styles()?;
        Ok(me)
    }

    /// What does not change over a run: the 3D view's up direction (z), the contact's colour and sizes.
    fn log_static_styles(&mut self) -> Result<(), RerunError> {
        let [r, g, b, a] = CONTACT_COLOUR;
        let colour = Color::from_unmultiplied_rgba(r, g, b, a);
        let statics: [(&str, &dyn rerun::AsComponents); 4] = [
            (paths::WORLD, &ViewCoordinates::RIGHT_HAND_Z_UP()),
            (
                paths::CONTACT_POINT,
                &Points3D::update_fields()
                    .with_radii([CONTACT_POINT_RADIUS_M])
                    .with_colors([colour]),
            ),
            (
                paths::CONTACT_FORCE,
                &Arrows3D::update_fields()
                    .with_radii([FORCE_ARROW_RADIUS_M])
                    .with_colors([colour])
                    .with_show_labels(true),
            ),
            (
                paths::CONTACT_LEADER,
                &LineStrips3D::update_fields()
                    .with_radii([LEADER_RADIUS_M])
                    .with_colors([colour]),
            ),
        ];
        for (path, arch) in statics {
            let entity = EntityPath::from(path);
            self.rec
                .log_static(entity.clone(), arch)
                .map_err(|e| Self::log_err(&entity, e))?;
        }
        Ok(())
    }

    /// Registers a signal path with its series name, colour (RGBA) and line width (UI points), before
    /// or after its first sample; without it a path is registered on first use named by its last part.
    pub fn register_series(
        &mut self,
        path: &str,
        name: &str,
        colour: [u8; 4],
        width: f32,
    ) -> Result<(), RerunError> {
        self.scalar_slot(path)?;
        let entity = EntityPath::from(path);
        let [r, g, b, a] = colour;
        self.rec
            .log_static(
                entity.clone(),
                &SeriesLines::new()
                    .with_names([name])
                    .with_colors([Color::from_unmultiplied_rgba(r, g, b, a)])
                    .with_widths([width]),
            )
            .map_err(|e| Self::log_err(&entity, e))
    }

    /// The options this recorder runs with.
    pub fn options(&self) -> &RecorderOptions {
        &self.opts
    }

    /// Converts seconds to the integer nanoseconds of the active timeline.
    fn nanos(t_s: f64) -> i64 {
        if t_s.is_finite() {
            // Saturating cast keeps absurd times from wrapping around.
            (t_s * 1e9).round() as i64
        } else {
            0
        }
    }

    fn time_column(&self, times: &[i64]) -> TimeColumn {
        match self.opts.clock {
            Clock::Sim => TimeColumn::new_duration_nanos(paths::SIM_TIME, times.iter().copied()),
            Clock::Wall => {
                TimeColumn::new_timestamp_nanos_since_epoch(paths::WALL_TIME, times.iter().copied())
            }
        }
    }

    fn log_err(entity: &EntityPath, e: impl std::fmt::Display) -> RerunError {
        RerunError::Log {
            entity: entity.to_string(),
            reason: e.to_string(),
        }
    }

    /// Registers a scalar path once (entity path built and a style logged), returns its slot.
    fn scalar_slot(&mut self, path: &str) -> Result<usize, RerunError> {
        if let Some(&i) = self.scalar_index.get(path) {
            return Ok(i);
        }
        let entity = EntityPath::from(path);
        let name = path.rsplit('/').next().unwrap_or(path);
        self.rec
            .log_static(entity.clone(), &SeriesLines::new().with_names([name]))
            .map_err(|e| Self::log_err(&entity, e))?;
        let i = self.scalars.len();
        self.scalars.push(ScalarColumn {
            path: entity,
            times: Vec::with_capacity(self.opts.batch_rows),
            values: Vec::with_capacity(self.opts.batch_rows),
        });
        self.scalar_index.insert(path.to_owned(), i);
        Ok(i)
    }

    /// Logs one sample of each named signal at time `t_s` (paths as in [`paths`]; new paths are
    /// registered on first use). Allocation-free for known paths until a batch is sent.
    pub fn log_scalars(&mut self, t_s: f64, samples: &[(&str, f64)]) -> Result<(), RerunError> {
        let t = Self::nanos(t_s);
        for &(path, value) in samples {
            let i = self.scalar_slot(path)?;
            let col = &mut self.scalars[i];
            col.times.push(t);
            col.values.push(value);
            if col.times.len() >= self.opts.batch_rows {
                self.send_scalars(i)?;
            }
        }
        Ok(())
    }

    fn send_scalars(&mut self, i: usize) -> Result<(), RerunError> {
        let col = &self.scalars[i];
        if col.times.is_empty() {
            return Ok(());
        }
        let time = self.time_column(&col.times);
        let data = Scalars::new(col.values.iter().copied())
            .columns_of_unit_batches()
            .map_err(|e| Self::log_err(&col.path, e))?;
        self.rec
            .send_columns(col.path.clone(), [time], data)
            .map_err(|e| Self::log_err(&col.path, e))?;
        let col = &mut self.scalars[i];
        col.times.clear();
        col.values.clear();
        Ok(())
    }

    /// Logs a link's collision shape once (static, shown on every timeline).
    pub fn log_link_shape(&mut self, link: &LinkShape) -> Result<(), RerunError> {
        let bad = |reason: String| RerunError::BadShape {
            entity: link.entity.clone(),
            reason,
        };
        let positive = |what: &str, v: f64| {
            if v.is_finite() && v > 0.0 {
                Ok(v as f32)
            } else {
                Err(bad(format!("{what} must be finite and > 0, got {v}")))
            }
        };
        if link.entity.trim_matches('/').is_empty() {
            return Err(bad("empty entity path".into()));
        }
        let entity = EntityPath::from(link.entity.as_str());
        let [r, g, b, a] = link.colour;
        let colour = Color::from_unmultiplied_rgba(r, g, b, a);
        let res = match &link.shape {
            VisualShape::Box { half_extents_m: h } => {
                let h = [
                    positive("half_extents_m[0]", h[0])?,
                    positive("half_extents_m[1]", h[1])?,
                    positive("half_extents_m[2]", h[2])?,
                ];
                self.rec.log_static(
                    entity.clone(),
                    &Boxes3D::from_half_sizes([h])
                        .with_colors([colour])
                        .with_fill_mode(FillMode::Solid),
                )
            }
            VisualShape::Cylinder {
                radius_m,
                half_length_m,
            } => {
                let r = positive("radius_m", *radius_m)?;
                let l = 2.0 * positive("half_length_m", *half_length_m)?;
                self.rec.log_static(
                    entity.clone(),
                    &Cylinders3D::from_lengths_and_radii([l], [r])
                        .with_colors([colour])
                        .with_fill_mode(FillMode::Solid),
                )
            }
            VisualShape::Sphere { radius_m } => {
                let r = positive("radius_m", *radius_m)?;
                self.rec.log_static(
                    entity.clone(),
                    &Ellipsoids3D::from_radii([r])
                        .with_colors([colour])
                        .with_fill_mode(FillMode::Solid),
                )
            }
            VisualShape::Mesh {
                vertices_m,
                triangles,
            } => {
                let n = vertices_m.len();
                if let Some(v) = vertices_m.iter().find(|v| v.iter().any(|c| !c.is_finite())) {
                    return Err(bad(format!("a mesh vertex is not finite: {v:?}")));
                }
                if let Some(t) = triangles
                    .iter()
                    .find(|t| t.iter().any(|&i| i as usize >= n))
                {
                    return Err(bad(format!(
                        "a triangle {t:?} indexes past the {n} vertices"
                    )));
                }
                self.rec.log_static(
                    entity.clone(),
                    &Mesh3D::new(vertices_m.iter().map(|v| v.map(|c| c as f32)))
                        .with_triangle_indices(triangles.iter().copied())
                        .with_vertex_colors(std::iter::repeat_n(colour, n)),
                )
            }
        };
        res.map_err(|e| Self::log_err(&entity, e))
    }

    /// Sets a link's pose in its parent frame at `t_s`: translation (m) and unit quaternion `[x, y, z, w]`.
    pub fn set_link_pose(
        &mut self,
        t_s: f64,
        entity: &str,
        translation_m: [f64; 3],
        rotation_xyzw: [f64; 4],
    ) -> Result<(), RerunError> {
        let i = match self.pose_index.get(entity) {
            Some(&i) => i,
            None => {
                let i = self.poses.len();
                self.poses.push(PoseColumn {
                    path: EntityPath::from(entity),
                    times: Vec::with_capacity(self.opts.batch_rows),
                    translations: Vec::with_capacity(self.opts.batch_rows),
                    rotations_xyzw: Vec::with_capacity(self.opts.batch_rows),
                });
                self.pose_index.insert(entity.to_owned(), i);
                i
            }
        };
        let col = &mut self.poses[i];
        col.times.push(Self::nanos(t_s));
        col.translations.push(translation_m.map(|v| v as f32));
        col.rotations_xyzw.push(rotation_xyzw.map(|v| v as f32));
        if col.times.len() >= self.opts.batch_rows {
            self.send_poses(i)?;
        }
        Ok(())
    }

    fn send_poses(&mut self, i: usize) -> Result<(), RerunError> {
        let col = &self.poses[i];
        if col.times.is_empty() {
            return Ok(());
        }
        let time = self.time_column(&col.times);
        let data = Transform3D::update_fields()
            .with_many_translation(col.translations.iter().copied())
            .with_many_quaternion(col.rotations_xyzw.iter().copied())
            .columns_of_unit_batches()
            .map_err(|e| Self::log_err(&col.path, e))?;
        self.rec
            .send_columns(col.path.clone(), [time], data)
            .map_err(|e| Self::log_err(&col.path, e))?;
        let col = &mut self.poses[i];
        col.times.clear();
        col.translations.clear();
        col.rotations_xyzw.clear();
        Ok(())
    }

    /// Logs the contact at `t_s` as a point and a force arrow, or clears both when `None`.
    pub fn log_contact(&mut self, t_s: f64, contact: Option<&Contact>) -> Result<(), RerunError> {
        let c = &mut self.contact;
        c.times.push(Self::nanos(t_s));
        match contact {
            Some(k) => {
                let s = self.opts.force_arrow_m_per_n;
                let magnitude = k.force_n.iter().map(|f| f * f).sum::<f64>().sqrt();
                c.counts.push(1);
                c.points.push(k.point_m.map(|v| v as f32));
                c.origins.push(k.arrow_from_m.map(|v| v as f32));
                c.arrows.push(k.force_n.map(|f| (f * s) as f32));
                c.labels.push(format!("{magnitude:.1} N"));
            }
            None => c.counts.push(0),
        }
        if c.times.len() >= self.opts.batch_rows {
            self.send_contact()?;
        }
        Ok(())
    }

    fn send_contact(&mut self) -> Result<(), RerunError> {
        if self.contact.times.is_empty() {
            return Ok(());
        }
        let point_path = EntityPath::from(paths::CONTACT_POINT);
        let force_path = EntityPath::from(paths::CONTACT_FORCE);
        let c = &self.contact;
        let counts = c.counts.clone();
        let points = Points3D::update_fields()
            .with_positions(c.points.iter().copied())
            .columns(counts.iter().copied())
            .map_err(|e| Self::log_err(&point_path, e))?;
        self.rec
            .send_columns(point_path.clone(), [self.time_column(&c.times)], points)
            .map_err(|e| Self::log_err(&point_path, e))?;
        let arrows = Arrows3D::update_fields()
            .with_origins(c.origins.iter().copied())
            .with_vectors(c.arrows.iter().copied())
            .with_labels(c.labels.iter().map(String::as_str))
            .columns(counts.iter().copied())
            .map_err(|e| Self::log_err(&force_path, e))?;
        self.rec
            .send_columns(force_path.clone(), [self.time_column(&c.times)], arrows)
            .map_err(|e| Self::log_err(&force_path, e))?;
        let leader_path = EntityPath::from(paths::CONTACT_LEADER);
        // A leader line from where the arrow starts to the contact point, when they differ.
        let leaders = LineStrips3D::update_fields()
            .with_strips(c.origins.iter().zip(&c.points).map(|(a, b)| [*a, *b]))
            .columns(counts.iter().copied())
            .map_err(|e| Self::log_err(&leader_path, e))?;
        self.rec
            .send_columns(leader_path.clone(), [self.time_column(&c.times)], leaders)
            .map_err(|e| Self::log_err(&leader_path, e))?;
        let c = &mut self.contact;
        c.times.clear();
        c.counts.clear();
        c.points.clear();
        c.origins.clear();
        c.arrows.clear();
        c.labels.clear();
        Ok(())
    }

    /// Logs the chamber radius once: both chambers are drawn as cylinders along z of
    /// [`paths::CHAMBERS`] (A from z = 0, B after it); place them with `set_link_pose(paths::CHAMBERS, …)`.
    pub fn set_chamber_bore(&mut self, bore_m: f64) -> Result<(), RerunError> {
        if !(bore_m.is_finite() && bore_m > 0.0) {
            return Err(RerunError::BadShape {
                entity: paths::CHAMBERS.into(),
                reason: format!("bore_m must be finite and > 0, got {bore_m}"),
            });
        }
        let r = (0.5 * bore_m) as f32;
        for (ch, label) in self.chambers.iter().zip(["A", "B"]) {
            self.rec
                .log_static(
                    ch.path.clone(),
                    &Cylinders3D::update_fields()
                        .with_radii([r])
                        .with_fill_mode(FillMode::Solid)
                        .with_labels([label]),
                )
                .map_err(|e| Self::log_err(&ch.path, e))?;
        }
        Ok(())
    }

    /// Colour of a chamber: blue at `pressure_low_pa`, red at `pressure_high_pa`, clamped.
    pub fn pressure_colour(&self, pressure_pa: f64) -> [u8; 4] {
        let span = self.opts.pressure_high_pa - self.opts.pressure_low_pa;
        let s = ((pressure_pa - self.opts.pressure_low_pa) / span).clamp(0.0, 1.0);
        let s = if s.is_nan() { 0.0 } else { s };
        let r = (255.0 * s).round() as u8;
        let b = (255.0 * (1.0 - s)).round() as u8;
        [r, 64, b, 200]
    }

    /// Logs both chambers at `t_s`: lengths along the cylinder axis and colour by pressure.
    pub fn log_chambers(&mut self, t_s: f64, s: &ChamberSample) -> Result<(), RerunError> {
        let t = Self::nanos(t_s);
        let la = s.length_a_m.max(0.0);
        let lb = s.length_b_m.max(0.0);
        let rows = [
            (la, 0.5 * la, s.pressure_a_pa),
            (lb, la + 0.5 * lb, s.pressure_b_pa),
        ];
        let colours = [
            self.pressure_colour(rows[0].2),
            self.pressure_colour(rows[1].2),
        ];
        let mut full = false;
        for ((ch, (len, centre, _)), [r, g, b, a]) in
            self.chambers.iter_mut().zip(rows).zip(colours)
        {
            ch.times.push(t);
            ch.lengths.push(len as f32);
            ch.centres.push([0.0, 0.0, centre as f32]);
            ch.colours.push(Color::from_unmultiplied_rgba(r, g, b, a));
            full |= ch.times.len() >= self.opts.batch_rows;
        }
        if full {
            self.send_chambers()?;
        }
        Ok(())
    }

    fn send_chambers(&mut self) -> Result<(), RerunError> {
        for k in 0..2 {
            let ch = &self.chambers[k];
            if ch.times.is_empty() {
                continue;
            }
            let data = Cylinders3D::update_fields()
                .with_lengths(ch.lengths.iter().copied())
                .with_centers(ch.centres.iter().copied())
                .with_colors(ch.colours.iter().copied())
                .columns_of_unit_batches()
                .map_err(|e| Self::log_err(&ch.path, e))?;
            self.rec
                .send_columns(ch.path.clone(), [self.time_column(&ch.times)], data)
                .map_err(|e| Self::log_err(&ch.path, e))?;
            let ch = &mut self.chambers[k];
            ch.times.clear();
            ch.lengths.clear();
            ch.centres.clear();
            ch.colours.clear();
        }
        Ok(())
    }

    /// Logs a scene event (phase change, object arrival, fault) as a text entry at `t_s`.
    pub fn log_event(&mut self, t_s: f64, level: EventLevel, text: &str) -> Result<(), RerunError> {
        let cell = match self.opts.clock {
            Clock::Sim => TimeCell::from_duration_nanos(Self::nanos(t_s)),
            Clock::Wall => TimeCell::from_timestamp_nanos_since_epoch(Self::nanos(t_s)),
        };
        self.rec.set_time(self.opts.clock.timeline(), cell);
        let level = match level {
            EventLevel::Info => rerun::TextLogLevel::INFO,
            EventLevel::Warn => rerun::TextLogLevel::WARN,
            EventLevel::Error => rerun::TextLogLevel::ERROR,
        };
        let entity = EntityPath::from(paths::EVENTS);
        let res = self
            .rec
            .log(entity.clone(), &TextLog::new(text).with_level(level));
        self.rec.reset_time();
        res.map_err(|e| Self::log_err(&entity, e))
    }

    /// Sends every buffered sample to Rerun and waits until the sink has taken it
    /// (for a file: written; for a viewer: at most `stream_flush_timeout`).
    pub fn flush(&mut self) -> Result<(), RerunError> {
        self.send_buffers()?;
        let res = match self.sink {
            Sink::Save(_) => self.rec.flush_blocking(),
            Sink::Spawn | Sink::Connect(_) => {
                self.rec.flush_with_timeout(self.opts.stream_flush_timeout)
            }
        };
        res.map_err(|e| RerunError::Flush(e.to_string()))
    }

    /// Flushes and closes the recording; for [`Sink::Save`] the `.rrd` file is complete
    /// (footer included) when this returns.
    pub fn finish(mut self) -> Result<(), RerunError> {
        let flushed = self.flush();
        // Dropping the only stream handle joins Rerun's batcher and file-writer threads,
        // which writes the file footer.
        drop(self);
        flushed
    }

    /// Hands every partly filled column buffer to Rerun.
    fn send_buffers(&mut self) -> Result<(), RerunError> {
        for i in 0..self.scalars.len() {
            self.send_scalars(i)?;
        }
        for i in 0..self.poses.len() {
            self.send_poses(i)?;
        }
        self.send_contact()?;
        self.send_chambers()
    }
}

impl Drop for RunRecorder {
    /// A recorder dropped without `finish` still hands its buffered samples to Rerun.
    fn drop(&mut self) {
        if let Err(e) = self.send_buffers() {
            eprintln!("warning: {e}");
        }
    }
}
