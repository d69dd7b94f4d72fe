//! What a plant shows a viewer: its drawn shapes, their roles and poses, and the actuator's geometry.

/// What a drawn shape is to the experiment, set by the plant that builds it: viewers colour by it and
/// attach the chambers to the cylinder and the contact force to the flange.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum VisualRole {
    /// The moving flange (piston rod end) that pushes the environment.
    Flange,
    /// The cylinder body, in which the chambers are.
    Cylinder,
    /// The environment the flange pushes (faces and their blocks).
    Environment,
    /// Anything else (platform, carriage, ...).
    #[default]
    Other,
}

/// The actuator's geometry for viewers (SI), at the plant's initial state.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ActuatorGeometry {
    /// Piston stroke, m.
    pub stroke_m: f64,
    /// Cylinder bore, m.
    pub bore_m: f64,
    /// Incline of the actuator axis below the horizontal, rad.
    pub alpha_rad: f64,
    /// Flange extension at which the environment is first touched, m.
    pub x_e_m: f64,
    /// Period of the valve's PWM carrier, s (an on/off valve under PWM); None for a proportional valve.
    pub pwm_period_s: Option<f64>,
}

/// One drawable collision shape of a plant's link.
#[derive(Clone, Debug, PartialEq)]
pub struct Visual {
    /// Link name (with `/<i>` for a link's i-th shape when it has several).
    pub name: String,
    /// The shape, centred on its pose.
    pub shape: VisualShape,
    /// What the shape is to the experiment.
    pub role: VisualRole,
}

/// A shape for viewers (SI).
#[derive(Clone, Debug, PartialEq)]
pub enum VisualShape {
    /// Box with half edge lengths along its x, y, z, m.
    Box {
        /// Half edge lengths, m.
        half_extents_m: [f64; 3],
    },
    /// Cylinder along its z axis, m.
    Cylinder {
        /// Radius, m.
        radius_m: f64,
        /// Half length, m.
        half_length_m: f64,
    },
    /// Sphere, m.
    Sphere {
        /// Radius, m.
        radius_m: f64,
    },
    /// A triangle mesh (a URDF mesh's convex hull): vertices, m, and triangles, indices into them.
    Mesh {
        /// Vertices, m.
        vertices_m: Vec<[f64; 3]>,
        /// Triangles, counter-clockwise seen from outside.
        triangles: Vec<[u32; 3]>,
    },
}

impl VisualShape {
    /// How a URDF collision shape is drawn (the one conversion: every plant and scene with a URDF uses it).
    pub fn of(shape: &pneuflex_multibody::LinkShape) -> Self {
        use pneuflex_multibody::LinkShape;
        match shape.clone() {
            LinkShape::Box { size_m } => VisualShape::Box {
                half_extents_m: size_m.map(|v| 0.5 * v),
            },
            LinkShape::Cylinder { radius_m, length_m } => VisualShape::Cylinder {
                radius_m,
                half_length_m: 0.5 * length_m,
            },
            // Drawn as its cylinder part plus the caps' length.
            LinkShape::Capsule { radius_m, length_m } => VisualShape::Cylinder {
                radius_m,
                half_length_m: 0.5 * length_m + radius_m,
            },
            LinkShape::Sphere { radius_m } => VisualShape::Sphere { radius_m },
            LinkShape::ConvexHull(hull) => VisualShape::Mesh {
                vertices_m: hull.vertices,
                triangles: hull.triangles,
            },
        }
    }
}

/// The drawn shapes of a URDF's links: each collision shape (`<link>`, or `<link>/<i>` for a link's i-th of
/// several), then each visual mesh (`<link>/visual/<i>`); `role` says what a link is to the experiment.
pub fn drawn_links<'a>(
    links: impl Iterator<Item = pneuflex_multibody::LinkView<'a>>,
    role: impl Fn(&str) -> VisualRole,
) -> Vec<Visual> {
    let mut out = Vec::new();
    for l in links {
        for (j, g) in l.collisions.iter().enumerate() {
            out.push(Visual {
                name: if l.collisions.len() == 1 {
                    l.name.to_string()
                } else {
                    format!("{}/{j}", l.name)
                },
                shape: VisualShape::of(&g.shape),
                role: role(l.name),
            });
        }
        for (j, (_, mesh)) in l.visual_meshes.iter().enumerate() {
            out.push(Visual {
                name: format!("{}/visual/{j}", l.name),
                shape: VisualShape::Mesh {
                    vertices_m: mesh.vertices.clone(),
                    triangles: mesh.triangles.clone(),
                },
                role: role(l.name),
            });
        }
    }
    out
}

/// The pose of each of [`drawn_links`]' shapes now, in that order, in the frame `world` takes the URDF's
/// root frame to.
pub fn drawn_poses<'a>(
    links: impl Iterator<Item = pneuflex_multibody::LinkView<'a>>,
    world: pneuflex_multibody::Pose,
    pose: &mut dyn FnMut(usize, VisualPose),
) {
    let mut i = 0;
    for l in links {
        let origins = l.collisions.iter().map(|g| g.origin);
        for origin in origins.chain(l.visual_meshes.iter().map(|(o, _)| *o)) {
            let p = world * l.pose * origin;
            let (t, q) = (p.translation, p.rotation);
            pose(
                i,
                VisualPose {
                    translation_m: [t.x, t.y, t.z],
                    rotation_xyzw: [q.x, q.y, q.z, q.w],
                },
            );
            i += 1;
        }
    }
}

/// Pose of a shape in the world: translation (m) and unit quaternion [x, y, z, w].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct VisualPose {
    /// Translation, m.
    pub translation_m: [f64; 3],
    /// Rotation as a unit quaternion [x, y, z, w].
    pub rotation_xyzw: [f64; 4],
}
