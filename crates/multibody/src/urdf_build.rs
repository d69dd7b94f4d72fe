//! URDF -> rapier3d-f64 builder.
//!
//! `rapier3d-urdf` only exists for f32 Rapier, so this module maps a `urdf_rs::Robot` onto an f64
//! `PhysicsWorld` itself:
//! - links become rigid bodies; a link hanging on a `fixed` joint is merged into its parent's body (a fixed
//!   joint would only cost solver work), so base + platform + cylinder are one fixed body;
//! - the root link is a fixed body; links named as kinematic become position-driven kinematic bodies
//!   (their URDF joint only declares the degrees of freedom the scene drives);
//! - `<collision>` box / cylinder / sphere / capsule become colliders, and a mesh (STL or OBJ) its convex
//!   hull ([`crate::mesh`]);
//! - `<inertial>` become the bodies' mass properties (colliders carry no density);
//! - prismatic / revolute / continuous / planar / spherical joints become Rapier impulse joints with the
//!   URDF limits; `<dynamics damping>` becomes a force-based velocity motor (a true viscous damper).
//!
//! Impulse joints, not multibody joints: the environment faces hang on a kinematic carriage that moves
//! during the wood-to-iron swap, and impulse joints take a moving kinematic parent like any other body;
//! with f64, warm-started joints and 4+ iterations the off-axis joint residual is far below the 1 %
//! force budget (see the tests), and contacts stay on Rapier's fast rigid-contact path.

use std::collections::HashMap;
use std::path::{Path, PathBuf};

use rapier3d_f64::parry::mass_properties::MassProperties;
use rapier3d_f64::prelude::*;

use crate::error::MultibodyError;

/// A collision shape of a link, in the link frame, for visualisation.
#[derive(Debug, Clone, PartialEq)]
pub enum LinkShape {
    /// A box with full edge lengths, m.
    Box {
        /// Edge lengths along the shape's x, y, z, m.
        size_m: [f64; 3],
    },
    /// A cylinder along the shape's z axis (URDF convention).
    Cylinder {
        /// Radius, m.
        radius_m: f64,
        /// Full length, m.
        length_m: f64,
    },
    /// A sphere.
    Sphere {
        /// Radius, m.
        radius_m: f64,
    },
    /// A capsule along the shape's z axis (URDF convention).
    Capsule {
        /// Radius, m.
        radius_m: f64,
        /// Length of the cylindrical part, m.
        length_m: f64,
    },
    /// The convex hull of a mesh file (scaled), which is what collides.
    ConvexHull(crate::mesh::ConvexHull),
}

/// One collision element of a link: where it sits in the link frame and what it is.
#[derive(Debug, Clone, PartialEq)]
pub struct LinkGeometry {
    /// Pose of the shape in the link frame.
    pub origin: Pose,
    /// The primitive.
    pub shape: LinkShape,
}

/// A URDF link as built: the body that carries it and its geometry.
#[derive(Debug, Clone)]
pub struct LinkInfo {
    /// URDF link name.
    pub name: String,
    /// The rigid body carrying this link (shared by links merged over fixed joints).
    pub body: RigidBodyHandle,
    /// Pose of the link frame in the body frame.
    pub body_from_link: Pose,
    /// Collision geometry in the link frame.
    pub geometry: Vec<LinkGeometry>,
    /// The Rapier colliders made from `geometry`, in the same order.
    pub colliders: Vec<ColliderHandle>,
    /// Total mass of the carrying body (all links merged into it), kg.
    pub body_mass_kg: f64,
    /// The link's `<visual>` meshes (pose in the link frame, triangles), drawn by viewers beside the
    /// collision shapes; primitive visuals repeat the collisions and are not kept.
    pub visual_meshes: Vec<(Pose, crate::mesh::TriangleMesh)>,
}

/// A link as viewers draw it: its name, its pose now, its collision shapes and its visual meshes.
#[derive(Debug, Clone, Copy)]
pub struct LinkView<'a> {
    /// URDF link name.
    pub name: &'a str,
    /// Pose of the link frame now.
    pub pose: Pose,
    /// Collision shapes in the link frame.
    pub collisions: &'a [LinkGeometry],
    /// Visual meshes in the link frame.
    pub visual_meshes: &'a [(Pose, crate::mesh::TriangleMesh)],
}

/// A URDF joint as built.
#[derive(Debug, Clone)]
pub struct JointInfo {
    /// URDF joint name.
    pub name: String,
    /// URDF joint type.
    pub kind: urdf_rs::JointType,
    /// Index of the parent link in [`BuiltRig::links`].
    pub parent: usize,
    /// Index of the child link in [`BuiltRig::links`].
    pub child: usize,
    /// The Rapier joint, if one was made (none for fixed, floating and kinematically driven joints).
    pub handle: Option<ImpulseJointHandle>,
    /// Joint frame in the parent link frame (URDF `<origin>`).
    pub origin: Pose,
    /// Unit joint axis in the joint frame (URDF `<axis>`, normalised).
    pub axis: Vector,
    /// `[lower, upper]` limits when finite, m or rad.
    pub limits: Option<[f64; 2]>,
    /// URDF `<dynamics damping>`, N s/m or N m s/rad.
    pub damping: f64,
}

/// The result of building a URDF into a Rapier world.
pub struct BuiltRig {
    /// The Rapier world with all bodies, colliders and joints.
    pub world: PhysicsWorld,
    /// Links in URDF order.
    pub links: Vec<LinkInfo>,
    /// Joints in URDF order.
    pub joints: Vec<JointInfo>,
    /// The URDF file the rig came from.
    pub file: PathBuf,
}

impl BuiltRig {
    /// Index of the link named `name`, or a `MissingLink` error naming `field`.
    pub fn link_index(&self, name: &str, field: &'static str) -> Result<usize, MultibodyError> {
        self.links
            .iter()
            .position(|l| l.name == name)
            .ok_or_else(|| MultibodyError::MissingLink {
                file: self.file.clone(),
                field,
                link: name.to_owned(),
            })
    }

    /// Index of the joint named `name`, or a `MissingJoint` error naming `field`.
    pub fn joint_index(&self, name: &str, field: &'static str) -> Result<usize, MultibodyError> {
        self.joints
            .iter()
            .position(|j| j.name == name)
            .ok_or_else(|| MultibodyError::MissingJoint {
                file: self.file.clone(),
                field,
                joint: name.to_owned(),
            })
    }

    /// Every link as viewers draw it, in URDF order.
    pub fn link_views(&self) -> impl Iterator<Item = LinkView<'_>> + '_ {
        self.links.iter().enumerate().map(|(i, l)| LinkView {
            name: l.name.as_str(),
            pose: self.link_pose(i),
            collisions: l.geometry.as_slice(),
            visual_meshes: l.visual_meshes.as_slice(),
        })
    }

    /// World pose of a link frame now.
    pub fn link_pose(&self, link: usize) -> Pose {
        let l = &self.links[link];
        *self.world.bodies[l.body].position() * l.body_from_link
    }
}

/// What the builder needs besides the URDF.
#[derive(Debug, Clone, Default)]
pub struct BuildOptions<'a> {
    /// Links driven kinematically by position (their joint is not simulated).
    pub kinematic_links: &'a [&'a str],
    /// Coulomb friction coefficient of every collider, -.
    pub friction: f64,
}

/// URDF `rpy` (fixed-axis roll, pitch, yaw) + `xyz` to a pose.
pub fn urdf_pose(p: &urdf_rs::Pose) -> Pose {
    let [r, pch, y] = p.rpy.0;
    let rot = Rotation::from_rotation_z(y)
        * Rotation::from_rotation_y(pch)
        * Rotation::from_rotation_x(r);
    Pose::from_parts(Vector::from_array(p.xyz.0), rot)
}

/// Read a URDF file with `urdf-rs`: a regular file within `InputKind::Urdf`'s size limit, pre-scanned
/// for nesting depth and malformed numbers (errors with line and element, see [`crate::urdf_scan`]).
pub fn read_urdf(path: &Path) -> Result<urdf_rs::Robot, MultibodyError> {
    let text = pneuflex_files::read_text(path, pneuflex_files::InputKind::Urdf)?;
    crate::urdf_scan::scan(path, &text)?;
    urdf_rs::read_from_string(&text).map_err(|e| MultibodyError::Parse {
        file: path.to_path_buf(),
        reason: e.to_string(),
    })
}

/// Principal moments of a symmetric 3x3 tensor, descending (closed form, Smith 1961).
fn principal_moments(i: &urdf_rs::Inertia) -> [f64; 3] {
    let off = i.ixy * i.ixy + i.ixz * i.ixz + i.iyz * i.iyz;
    let mut e = if off == 0.0 {
        [i.ixx, i.iyy, i.izz]
    } else {
        let q = (i.ixx + i.iyy + i.izz) / 3.0;
        let (a, b, c) = (i.ixx - q, i.iyy - q, i.izz - q);
        let p = ((a * a + b * b + c * c + 2.0 * off) / 6.0).sqrt();
        // det((A - qI) / p) / 2, clamped against rounding.
        let det = a * (b * c - i.iyz * i.iyz) - i.ixy * (i.ixy * c - i.iyz * i.ixz)
            + i.ixz * (i.ixy * i.iyz - b * i.ixz);
        let r = (det / (2.0 * p * p * p)).clamp(-1.0, 1.0);
        let phi = r.acos() / 3.0;
        let e1 = q + 2.0 * p * phi.cos();
        let e3 = q + 2.0 * p * (phi + 2.0 * core::f64::consts::PI / 3.0).cos();
        [e1, 3.0 * q - e1 - e3, e3]
    };
    e.sort_by(|x, y| y.total_cmp(x));
    e
}

/// Relative slack of the triangle-inequality check: URDF files round moments to 3-4 digits, and thin
/// plates sit on the boundary (the shipped carriage plate exceeds it by 0.09 % from rounding).
const TRIANGLE_SLACK: f64 = 1e-2;

fn inertial_check(
    file: &Path,
    link: &urdf_rs::Link,
) -> Result<Option<MassProperties>, MultibodyError> {
    let bad = |reason: String| MultibodyError::BadInertial {
        file: file.to_path_buf(),
        link: link.name.clone(),
        reason,
    };
    let m = link.inertial.mass.value;
    let i = &link.inertial.inertia;
    let vals = [m, i.ixx, i.ixy, i.ixz, i.iyy, i.iyz, i.izz];
    if vals.iter().any(|v| !v.is_finite()) {
        return Err(bad("mass and inertia must be finite numbers".into()));
    }
    if m < 0.0 {
        return Err(bad(format!("mass must be > 0 kg, got {m}")));
    }
    if m == 0.0 {
        // A massless link (no <inertial>): allowed for fixed/kinematic bodies, checked per body.
        return Ok(None);
    }
    // Sylvester's criterion on the symmetric inertia tensor.
    let d1 = i.ixx;
    let d2 = i.ixx * i.iyy - i.ixy * i.ixy;
    let d3 = i.ixx * (i.iyy * i.izz - i.iyz * i.iyz) - i.ixy * (i.ixy * i.izz - i.iyz * i.ixz)
        + i.ixz * (i.ixy * i.iyz - i.iyy * i.ixz);
    if !(d1 > 0.0 && d2 > 0.0 && d3 > 0.0) {
        return Err(bad(format!(
            "inertia tensor must be positive definite (ixx={}, ixy={}, ixz={}, iyy={}, iyz={}, izz={})",
            i.ixx, i.ixy, i.ixz, i.iyy, i.iyz, i.izz
        )));
    }
    // Each principal moment is an integral of r^2 over two axes: no rigid body has one larger than the
    // sum of the other two.
    let [e1, e2, e3] = principal_moments(i);
    if e1 > (e2 + e3) * (1.0 + TRIANGLE_SLACK) {
        return Err(bad(format!(
            "principal moments of inertia {e1:e}, {e2:e}, {e3:e} kg m^2 break the triangle inequality \
             ({e1:e} > {e2:e} + {e3:e}): no rigid body has them (ixx={}, ixy={}, ixz={}, iyy={}, iyz={}, izz={})",
            i.ixx, i.ixy, i.ixz, i.iyy, i.iyz, i.izz
        )));
    }
    let tensor = Matrix::from_cols(
        Vector::new(i.ixx, i.ixy, i.ixz),
        Vector::new(i.ixy, i.iyy, i.iyz),
        Vector::new(i.ixz, i.iyz, i.izz),
    );
    let frame = urdf_pose(&link.inertial.origin);
    Ok(Some(
        MassProperties::with_inertia_matrix(Vector::ZERO, m, tensor).transform_by(&frame),
    ))
}

fn geometry_of(file: &Path, link: &urdf_rs::Link) -> Result<Vec<LinkGeometry>, MultibodyError> {
    let bad = |reason: String| MultibodyError::BadGeometry {
        file: file.to_path_buf(),
        link: link.name.clone(),
        reason,
    };
    let pos = |v: f64, what: &str| -> Result<f64, MultibodyError> {
        if v.is_finite() && v > 0.0 {
            Ok(v)
        } else {
            Err(bad(format!("{what} must be a finite size > 0 m, got {v}")))
        }
    };
    let mut out = Vec::with_capacity(link.collision.len());
    for c in &link.collision {
        let shape = match &c.geometry {
            urdf_rs::Geometry::Box { size } => LinkShape::Box {
                size_m: [
                    pos(size.0[0], "box size x")?,
                    pos(size.0[1], "box size y")?,
                    pos(size.0[2], "box size z")?,
                ],
            },
            urdf_rs::Geometry::Cylinder { radius, length } => LinkShape::Cylinder {
                radius_m: pos(*radius, "cylinder radius")?,
                length_m: pos(*length, "cylinder length")?,
            },
            urdf_rs::Geometry::Sphere { radius } => LinkShape::Sphere {
                radius_m: pos(*radius, "sphere radius")?,
            },
            urdf_rs::Geometry::Capsule { radius, length } => LinkShape::Capsule {
                radius_m: pos(*radius, "capsule radius")?,
                length_m: pos(*length, "capsule length")?,
            },
            urdf_rs::Geometry::Mesh { filename, scale } => {
                let scale = scale.map_or([1.0; 3], |s| s.0);
                if !scale.iter().all(|s| s.is_finite() && *s > 0.0) {
                    return Err(bad(format!(
                        "mesh '{filename}': scale {scale:?} must be three finite factors > 0"
                    )));
                }
                let path = crate::mesh::resolve(file, filename).map_err(&bad)?;
                let points = crate::mesh::read_vertices(&path, scale)
                    .map_err(|e| bad(format!("mesh '{filename}': {e}")))?;
                let hull = crate::mesh::convex_hull(&points)
                    .map_err(|e| bad(format!("mesh '{filename}' ({}): {e}", path.display())))?;
                LinkShape::ConvexHull(hull)
            }
        };
        out.push(LinkGeometry {
            origin: urdf_pose(&c.origin),
            shape,
        });
    }
    Ok(out)
}

/// The `<visual>` meshes of a link, read and scaled (a mesh that cannot be read is an error naming the
/// link, as a collision mesh's is: a viewer that silently drew nothing would hide the mistake).
fn visual_meshes_of(
    file: &Path,
    link: &urdf_rs::Link,
) -> Result<Vec<(Pose, crate::mesh::TriangleMesh)>, MultibodyError> {
    let bad = |reason: String| MultibodyError::BadVisual {
        file: file.to_path_buf(),
        link: link.name.clone(),
        reason,
    };
    let mut out = Vec::new();
    for v in &link.visual {
        let urdf_rs::Geometry::Mesh { filename, scale } = &v.geometry else {
            continue;
        };
        let scale = scale.map_or([1.0; 3], |s| s.0);
        if !scale.iter().all(|s| s.is_finite() && *s > 0.0) {
            return Err(bad(format!(
                "mesh '{filename}': scale {scale:?} must be three finite factors > 0"
            )));
        }
        let path = crate::mesh::resolve(file, filename).map_err(&bad)?;
        let mesh = crate::mesh::read_mesh(&path, scale)
            .map_err(|e| bad(format!("mesh '{filename}': {e}")))?;
        out.push((urdf_pose(&v.origin), mesh));
    }
    Ok(out)
}

/// The collider for one geometry element, positioned in the body frame.
fn collider_for(g: &LinkGeometry, body_from_link: &Pose, friction: f64) -> Collider {
    // parry's cylinder and capsule run along y, URDF's along z: turn y onto z.
    let y_to_z = Pose::from_rotation(Rotation::from_rotation_x(core::f64::consts::FRAC_PI_2));
    let (builder, local) = match &g.shape {
        LinkShape::Box { size_m } => (
            ColliderBuilder::cuboid(size_m[0] / 2.0, size_m[1] / 2.0, size_m[2] / 2.0),
            g.origin,
        ),
        LinkShape::Cylinder { radius_m, length_m } => (
            ColliderBuilder::cylinder(length_m / 2.0, *radius_m),
            g.origin * y_to_z,
        ),
        LinkShape::Sphere { radius_m } => (ColliderBuilder::ball(*radius_m), g.origin),
        LinkShape::Capsule { radius_m, length_m } => (
            ColliderBuilder::capsule_y(length_m / 2.0, *radius_m),
            g.origin * y_to_z,
        ),
        // The hull's own vertices and faces: checked convex and solid when the mesh was read.
        LinkShape::ConvexHull(hull) => (hull.collider(), g.origin),
    };
    builder
        .position(*body_from_link * local)
        .density(0.0)
        .friction(friction)
        .restitution(0.0)
        .build()
}

/// A joint's axis, origin, limits and damping, checked.
fn joint_info(
    file: &Path,
    j: &urdf_rs::Joint,
    parent: usize,
    child: usize,
) -> Result<JointInfo, MultibodyError> {
    let needs_axis = !matches!(
        j.joint_type,
        urdf_rs::JointType::Fixed | urdf_rs::JointType::Floating | urdf_rs::JointType::Spherical
    );
    let a = Vector::from_array(j.axis.xyz.0);
    let axis = if needs_axis {
        let n = a.length();
        if !n.is_finite() || n < 1e-12 {
            return Err(MultibodyError::BadJoint {
                file: file.to_path_buf(),
                joint: j.name.clone(),
                reason: format!(
                    "<axis xyz> must be a non-zero finite vector, got [{}, {}, {}]",
                    a.x, a.y, a.z
                ),
            });
        }
        a / n
    } else {
        Vector::X
    };
    let origin = urdf_pose(&j.origin);
    if !origin.is_finite() {
        return Err(MultibodyError::BadJoint {
            file: file.to_path_buf(),
            joint: j.name.clone(),
            reason: "<origin> must be finite".into(),
        });
    }
    let limits = match j.joint_type {
        urdf_rs::JointType::Prismatic | urdf_rs::JointType::Revolute => {
            let (lo, hi) = (j.limit.lower, j.limit.upper);
            if lo.is_nan() || hi.is_nan() || lo > hi {
                return Err(MultibodyError::BadJoint {
                    file: file.to_path_buf(),
                    joint: j.name.clone(),
                    reason: format!("<limit> needs lower <= upper, got [{lo}, {hi}]"),
                });
            }
            (lo.is_finite() && hi.is_finite()).then_some([lo, hi])
        }
        _ => None,
    };
    let damping = j.dynamics.as_ref().map_or(0.0, |d| d.damping);
    if !(damping.is_finite() && damping >= 0.0) {
        return Err(MultibodyError::BadJoint {
            file: file.to_path_buf(),
            joint: j.name.clone(),
            reason: format!("<dynamics damping> must be >= 0, got {damping}"),
        });
    }
    Ok(JointInfo {
        name: j.name.clone(),
        kind: j.joint_type.clone(),
        parent,
        child,
        handle: None,
        origin,
        axis,
        limits,
        damping,
    })
}

/// A link's body: the index of its [`Slot`] and the body's pose of the link (body_from_link).
type LinkBody = (usize, Pose);

/// A rigid body: the links merged over fixed joints into it, their mass, its pose at the zero configuration.
struct Slot {
    kind: RigidBodyType,
    pose: Pose,
    mass: MassProperties,
    has_mass: bool,
    first_link: usize,
}

/// Assigns each link a body (a fixed joint merges the child into its parent's, a kinematic link gets its
/// own) by a depth-first walk from the root, which finds unreached links (a cycle); sums each body's
/// mass. Returns the bodies and each link's (body, body_from_link).
fn assign_bodies(
    file: &Path,
    robot: &urdf_rs::Robot,
    opts: &BuildOptions<'_>,
    joints: &[JointInfo],
    root: usize,
    mass_props: &[Option<MassProperties>],
) -> Result<(Vec<Slot>, Vec<LinkBody>), MultibodyError> {
    let tree_err = |reason: String| MultibodyError::BadTree {
        file: file.to_path_buf(),
        reason,
    };
    let mut children: Vec<Vec<usize>> = vec![Vec::new(); robot.links.len()];
    for (ji, j) in joints.iter().enumerate() {
        children[j.parent].push(ji);
    }
    let mut slots: Vec<Slot> = Vec::new();
    let mut link_slot: Vec<Option<(usize, Pose)>> = vec![None; robot.links.len()];
    let mut stack = vec![root];
    slots.push(Slot {
        kind: RigidBodyType::Fixed,
        pose: Pose::IDENTITY,
        mass: MassProperties::default(),
        has_mass: false,
        first_link: root,
    });
    link_slot[root] = Some((0, Pose::IDENTITY));
    while let Some(li) = stack.pop() {
        let (ps, body_from_parent) = link_slot[li].expect("assigned before push");
        let parent_world = slots[ps].pose * body_from_parent;
        for &ji in &children[li] {
            let j = &joints[ji];
            let child = j.child;
            let kinematic = opts
                .kinematic_links
                .contains(&robot.links[child].name.as_str());
            let assigned = if j.kind == urdf_rs::JointType::Fixed && !kinematic {
                (ps, body_from_parent * j.origin)
            } else {
                slots.push(Slot {
                    kind: if kinematic {
                        RigidBodyType::KinematicPositionBased
                    } else {
                        RigidBodyType::Dynamic
                    },
                    pose: parent_world * j.origin,
                    mass: MassProperties::default(),
                    has_mass: false,
                    first_link: child,
                });
                (slots.len() - 1, Pose::IDENTITY)
            };
            link_slot[child] = Some(assigned);
            stack.push(child);
        }
    }
    if let Some(i) = link_slot.iter().position(Option::is_none) {
        return Err(tree_err(format!(
            "link '{}' is not reachable from the root '{}' (cycle?)",
            robot.links[i].name, robot.links[root].name
        )));
    }
    for (li, mp) in mass_props.iter().enumerate() {
        if let Some(mp) = mp {
            let (s, bfl) = link_slot[li].expect("checked");
            slots[s].mass += mp.transform_by(&bfl);
            slots[s].has_mass = true;
        }
    }
    for s in &slots {
        if s.kind == RigidBodyType::Dynamic && !(s.has_mass && s.mass.mass() > 0.0) {
            return Err(MultibodyError::BadInertial {
                file: file.to_path_buf(),
                link: robot.links[s.first_link].name.clone(),
                reason: "a moving link needs mass > 0 kg (and a positive definite inertia)".into(),
            });
        }
    }

    let link_slot = link_slot.into_iter().map(|s| s.expect("checked")).collect();
    Ok((slots, link_slot))
}

/// The Rapier joint of a URDF joint between two bodies, with its frames, limits and damping; None for a
/// floating or fixed joint (no constraint to add). `pbfl`: the parent body's pose of the parent link.
fn impulse_joint(j: &JointInfo, pbfl: Pose) -> Option<GenericJoint> {
    // Joint frames whose x axis is the URDF axis, identical in world at the zero configuration.
    let r_axis = Pose::from_rotation(Rotation::from_rotation_arc(Vector::X, j.axis));
    let frame1 = pbfl * j.origin * r_axis;
    let frame2 = r_axis;
    let (locked, free_axis) = match j.kind {
        urdf_rs::JointType::Prismatic => {
            (JointAxesMask::LOCKED_PRISMATIC_AXES, Some(JointAxis::LinX))
        }
        urdf_rs::JointType::Revolute | urdf_rs::JointType::Continuous => {
            (JointAxesMask::LOCKED_REVOLUTE_AXES, Some(JointAxis::AngX))
        }
        urdf_rs::JointType::Planar => (
            JointAxesMask::LIN_X
                | JointAxesMask::ANG_X
                | JointAxesMask::ANG_Y
                | JointAxesMask::ANG_Z,
            None,
        ),
        urdf_rs::JointType::Spherical => (JointAxesMask::LOCKED_SPHERICAL_AXES, None),
        urdf_rs::JointType::Floating | urdf_rs::JointType::Fixed => return None,
    };
    let mut gj = GenericJointBuilder::new(locked)
        .local_frame1(frame1)
        .local_frame2(frame2)
        .contacts_enabled(false)
        .build();
    if let Some(ax) = free_axis {
        if let (Some(l), true) = (j.limits, j.kind != urdf_rs::JointType::Continuous) {
            gj.set_limits(ax, l);
        }
        if j.damping > 0.0 {
            // Viscous joint damping: a force-based velocity motor towards 0 is exactly -c * v.
            gj.set_motor_model(ax, MotorModel::ForceBased);
            gj.set_motor(ax, 0.0, 0.0, 0.0, j.damping);
        }
    }
    Some(gj)
}

/// Build the Rapier world from a parsed URDF.
pub fn build(
    file: &Path,
    robot: &urdf_rs::Robot,
    opts: &BuildOptions<'_>,
) -> Result<BuiltRig, MultibodyError> {
    let tree_err = |reason: String| MultibodyError::BadTree {
        file: file.to_path_buf(),
        reason,
    };
    // Names -> indices, rejecting duplicates.
    let mut link_idx: HashMap<&str, usize> = HashMap::new();
    for (i, l) in robot.links.iter().enumerate() {
        if link_idx.insert(l.name.as_str(), i).is_some() {
            return Err(tree_err(format!("link '{}' is defined twice", l.name)));
        }
    }
    for k in opts.kinematic_links {
        if !link_idx.contains_key(k) {
            return Err(MultibodyError::MissingLink {
                file: file.to_path_buf(),
                field: "kinematic link",
                link: (*k).to_owned(),
            });
        }
    }
    let mut joints = Vec::with_capacity(robot.joints.len());
    let mut parent_joint: Vec<Option<usize>> = vec![None; robot.links.len()];
    for (ji, j) in robot.joints.iter().enumerate() {
        let find = |name: &str, role: &str| {
            link_idx
                .get(name)
                .copied()
                .ok_or_else(|| MultibodyError::BadJoint {
                    file: file.to_path_buf(),
                    joint: j.name.clone(),
                    reason: format!("{role} link '{name}' is not defined"),
                })
        };
        let parent = find(&j.parent.link, "parent")?;
        let child = find(&j.child.link, "child")?;
        if parent_joint[child].replace(ji).is_some() {
            return Err(tree_err(format!(
                "link '{}' has two parent joints",
                j.child.link
            )));
        }
        joints.push(joint_info(file, j, parent, child)?);
    }
    let roots: Vec<usize> = (0..robot.links.len())
        .filter(|&i| parent_joint[i].is_none())
        .collect();
    if roots.len() != 1 {
        let names: Vec<&str> = roots
            .iter()
            .map(|&i| robot.links[i].name.as_str())
            .collect();
        return Err(tree_err(format!(
            "expected exactly one root link, found {} ({})",
            roots.len(),
            names.join(", ")
        )));
    }
    let root = roots[0];

    // Per-link checks before anything is built.
    let mut mass_props = Vec::with_capacity(robot.links.len());
    let mut geometry = Vec::with_capacity(robot.links.len());
    let mut visual_meshes = Vec::with_capacity(robot.links.len());
    for l in &robot.links {
        mass_props.push(inertial_check(file, l)?);
        geometry.push(geometry_of(file, l)?);
        visual_meshes.push(visual_meshes_of(file, l)?);
    }
    let (slots, link_slot) = assign_bodies(file, robot, opts, &joints, root, &mass_props)?;

    let mut world = PhysicsWorld::new();
    let mut handles = Vec::with_capacity(slots.len());
    for s in &slots {
        let mut b = RigidBodyBuilder::new(s.kind).pose(s.pose).can_sleep(false);
        if s.kind == RigidBodyType::Dynamic {
            b = b.additional_mass_properties(s.mass);
        }
        handles.push(world.insert_body(b));
    }
    let mut links = Vec::with_capacity(robot.links.len());
    for (li, l) in robot.links.iter().enumerate() {
        let (s, bfl) = link_slot[li];
        let mut colliders = Vec::with_capacity(geometry[li].len());
        for g in &geometry[li] {
            let c = collider_for(g, &bfl, opts.friction);
            colliders.push(world.insert_collider(c, Some(handles[s])));
        }
        links.push(LinkInfo {
            name: l.name.clone(),
            body: handles[s],
            body_from_link: bfl,
            geometry: std::mem::take(&mut geometry[li]),
            colliders,
            body_mass_kg: if slots[s].has_mass {
                slots[s].mass.mass()
            } else {
                0.0
            },
            visual_meshes: std::mem::take(&mut visual_meshes[li]),
        });
    }
    for j in &mut joints {
        let (ps, pbfl) = link_slot[j.parent];
        let (cs, _) = link_slot[j.child];
        if ps == cs || slots[cs].kind != RigidBodyType::Dynamic {
            continue; // merged over a fixed joint, or driven kinematically
        }
        if let Some(gj) = impulse_joint(j, pbfl) {
            j.handle = Some(world.insert_impulse_joint(handles[ps], handles[cs], gj));
        }
    }
    Ok(BuiltRig {
        world,
        links,
        joints,
        file: file.to_path_buf(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// diag(d) turned by `a` about z, as a URDF inertia.
    fn turned(d: [f64; 3], a: f64) -> urdf_rs::Inertia {
        let (s, c) = a.sin_cos();
        urdf_rs::Inertia {
            ixx: c * c * d[0] + s * s * d[1],
            ixy: c * s * (d[0] - d[1]),
            ixz: 0.0,
            iyy: s * s * d[0] + c * c * d[1],
            iyz: 0.0,
            izz: d[2],
        }
    }

    #[test]
    fn principal_moments_of_a_full_tensor() {
        let e = principal_moments(&turned([1.0, 2.0, 2.9], 0.5));
        for (got, want) in e.iter().zip([2.9, 2.0, 1.0]) {
            assert!((got - want).abs() < 1e-12, "{e:?}");
        }
    }

    #[test]
    fn a_turned_tensor_breaking_the_triangle_inequality_is_refused() {
        // Positive definite on the diagonal and by Sylvester, but 5 > 1 + 3 after turning.
        let link = urdf_rs::Link {
            name: "l".into(),
            inertial: urdf_rs::Inertial {
                origin: Default::default(),
                mass: urdf_rs::Mass { value: 1.0 },
                inertia: turned([5.0, 1.0, 3.0], 0.7),
            },
            visual: vec![],
            collision: vec![],
        };
        let e = inertial_check(Path::new("t.urdf"), &link).unwrap_err();
        assert!(e.to_string().contains("triangle inequality"), "{e}");
        let mut ok = link.clone();
        ok.inertial.inertia = turned([4.0, 1.0, 3.0], 0.7);
        assert!(inertial_check(Path::new("t.urdf"), &ok).unwrap().is_some());
    }
}
