"""MJCF generation: the MuJoCo model of a pneuflex scene, derived from a URDF in one way (`urdf_to_mjcf`).

The derivation: links become bodies (a fixed joint is a jointless child body, welded), prismatic joints
slides, revolute and continuous joints hinges, planar joints two slides in the plane; the URDF's inertials,
collision geometry (box, sphere, cylinder; an STL or OBJ mesh, which MuJoCo collides as its convex hull, as
Rapier does), limits and joint damping carry over. What a scene adds to the URDF is given in `Options`:
gravity, step and integrator, per-joint overrides (a compliant mount's stiffness and spring reference), which
links' geoms touch and how (contype/conaffinity, solref/solimp), links held kinematically (mocap bodies),
sites, spatial tendons and motors. Every caller goes through it: the scenes
with [[actuators]] (crossval/mechanism.py) and the paper's rig (`build_mjcf`), whether its rig comes from a
URDF (`multibody` scenes: urdf/rig.urdf itself) or from a 1-DOF scene's numbers (`rig_urdf` writes that rig
as a URDF first).

The paper's rig. Rig frame (as urdf/rig.urdf and crates/multibody): x = actuator axis (flange extension,
towards the environment), z = platform normal. The incline alpha (actuator axis below the horizontal,
gravity aids extension by m g sin(alpha)) is applied by turning gravity in the rig frame, exactly as
CarriageRig does: g_rig = g (sin(alpha) x - cos(alpha) z).
- the cylinder is fixed (welded to the platform), so the actuator force acts on the flange's slide dof;
- the flange slides along x (range = stroke, damping = K_v of eq. (1)); its collision box's front face
  is `flange_front_m` ahead of its joint origin;
- each environment material is a thin face body on a slide joint along x (the compliant mount): joint
  stiffness k_e, damping c_e, spring reference chosen so that the face's own weight along the axis is
  absorbed (the unloaded face rests at q = 0 at every incline, so f_e = k_e (x - x_e), eq. (21));
- only flange-face contacts exist (contype/conaffinity), frictionless normal contacts (condim 1), made
  near-rigid with solref/solimp so that the compliance lives in the mount, as in the Rapier world;
- the carriage carrying the faces (urdf/rig.urdf's planar joint) is a mocap body: it is moved, not pushed.
"""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from dataclasses import dataclass, field
from pathlib import Path

# Near-rigid contact: measured here (issue 6) to give a steady f_e = k_e x within 0.05 N at dt = 1 ms,
# where MuJoCo's default (solref 0.02 1) sinks 2 mm at 14 N (a ~7e3 N/m series spring).
CONTACT_SOLREF = "0.002 1"
CONTACT_SOLIMP = "0.99 0.999 0.0001 0.5 2"


# ---------------------------------------------------------------- the one derivation: URDF -> MJCF


@dataclass
class Options:
    """What a scene adds to its URDF's tree. Attribute values are MJCF text."""

    name: str
    timestep_s: float
    gravity: tuple[float, float, float] = (0.0, 0.0, -9.80665)
    integrator: str = "implicitfast"
    # Attributes every geom starts from (`<default><geom .../>`); a geom touches nothing unless its link is
    # in `contacts`.
    geom_defaults: dict[str, str] = field(default_factory=lambda: {"contype": "0", "conaffinity": "0"})
    # Link name -> attributes of its collision geoms (contype, conaffinity, solref, solimp, rgba).
    contacts: dict[str, dict[str, str]] = field(default_factory=dict)
    # Joint name -> attributes set on (or over) the derived joint: stiffness, springref, damping, range, ...
    joints: dict[str, dict[str, str]] = field(default_factory=dict)
    # Links held kinematically -> offset of the mocap body from the link's URDF pose (world frame), m. Their
    # own joint is dropped; the body sits under <worldbody> at its URDF pose plus the offset.
    mocap: dict[str, tuple[float, float, float]] = field(default_factory=dict)
    # Link name -> sites on it: (site name, position in the link frame).
    sites: dict[str, list[tuple[str, list[float]]]] = field(default_factory=dict)
    # Spatial tendons: (name, site a, site b).
    tendons: list[tuple[str, str, str]] = field(default_factory=list)
    # Motors: (name, target attribute, e.g. 'joint="j"' or 'tendon="t"').
    motors: list[tuple[str, str]] = field(default_factory=list)
    # Plugin instances in <extension>: (plugin, instance name, {config key: value}).
    plugins: list[tuple[str, str, dict[str, str]]] = field(default_factory=list)
    # Plugin actuators after the motors: (name, target attribute, plugin, instance), gear 1, ctrl in [-1, 1].
    plugin_actuators: list[tuple[str, str, str, str]] = field(default_factory=list)


def _floats(text: str | None, n: int = 3, default: float = 0.0) -> list[float]:
    if text is None:
        return [default] * n
    v = [float(x) for x in text.split()]
    if len(v) != n or not all(math.isfinite(a) for a in v):
        raise ValueError(f"expected {n} finite numbers, got {text!r}")
    return v


def _rpy_quat(rpy: list[float]) -> list[float]:
    """URDF fixed-axis roll, pitch, yaw as a MuJoCo quaternion (w, x, y, z): R = Rz(y) Ry(p) Rx(r)."""
    r, p, y = (0.5 * a for a in rpy)
    cr, sr, cp, sp, cy, sy = math.cos(r), math.sin(r), math.cos(p), math.sin(p), math.cos(y), math.sin(y)
    return [
        cr * cp * cy + sr * sp * sy,
        sr * cp * cy - cr * sp * sy,
        cr * sp * cy + sr * cp * sy,
        cr * cp * sy - sr * sp * cy,
    ]


def _quat_mul(a: list[float], b: list[float]) -> list[float]:
    aw, ax, ay, az = a
    bw, bx, by, bz = b
    return [
        aw * bw - ax * bx - ay * by - az * bz,
        aw * bx + ax * bw + ay * bz - az * by,
        aw * by - ax * bz + ay * bw + az * bx,
        aw * bz + ax * by - ay * bx + az * bw,
    ]


def _rotate(q: list[float], v: list[float]) -> list[float]:
    """v turned by the unit quaternion q: q (0, v) q*."""
    return _quat_mul(_quat_mul(q, [0.0, *v]), [q[0], -q[1], -q[2], -q[3]])[1:]


def _origin(el) -> tuple[list[float], list[float]]:
    o = el.find("origin") if el is not None else None
    if o is None:
        return [0.0] * 3, [1.0, 0.0, 0.0, 0.0]
    return _floats(o.get("xyz")), _rpy_quat(_floats(o.get("rpy")))


def _fmt(v) -> str:
    return " ".join(repr(float(x)) for x in v)


def _attrs(a: dict[str, str]) -> str:
    return "".join(f' {k}="{v}"' for k, v in a.items())


def urdf_to_mjcf(urdf: str | Path, opt: Options) -> str:
    """The MJCF of a URDF (a path, or the URDF's text when it starts with '<') with what `opt` adds.
    Collision geoms keep their link's name (`<link>/<i>`)."""
    text = str(urdf)
    where = "URDF" if text.lstrip().startswith("<") else text
    try:
        robot = ET.fromstring(text) if where == "URDF" else ET.parse(text).getroot()
    except (OSError, ET.ParseError) as e:
        raise ValueError(f"{where}: cannot read URDF: {e}") from e
    links = {l.get("name"): l for l in robot.findall("link")}
    children: dict[str, list] = {}
    has_parent = set()
    for j in robot.findall("joint"):
        children.setdefault(j.find("parent").get("link"), []).append(j)
        has_parent.add(j.find("child").get("link"))
    roots = [n for n in links if n not in has_parent]
    if len(roots) != 1:
        raise ValueError(f"{where}: expected one root link, found {roots}")
    world_level: list[list[str]] = []
    meshes: list[str] = []

    def mesh_asset(g) -> str:
        """A <mesh> asset for a URDF mesh: its file relative to the URDF's folder (or absolute), its scale."""
        filename = g.get("filename", "")
        if filename.startswith("package://"):
            raise NotImplementedError(f"{where}: mesh {filename!r}: package:// paths need a ROS package index")
        path = Path(filename.removeprefix("file://"))
        if not path.is_absolute():
            if where == "URDF":
                raise ValueError(f"mesh {filename!r}: a relative path needs the URDF's file")
            path = Path(where).parent / path
        name = f"mesh{len(meshes)}"
        scale = f' scale="{_fmt(_floats(g.get("scale"), default=1.0))}"'
        meshes.append(f'    <mesh name="{name}" file="{path.resolve()}"{scale}/>')
        return name

    def link_xml(name: str, depth: int, moving: bool) -> list[str]:
        pad = "  " * depth
        l = links[name]
        out = []
        inertial = l.find("inertial")
        # A link no joint moves (welded to the world or to a mocap body) carries no dynamics: its inertial is
        # left out (MuJoCo would still check it; urdf/rig.urdf's carriage misses A + B >= C by 2e-6).
        if moving and inertial is not None and float(inertial.find("mass").get("value")) > 0.0:
            xyz, quat = _origin(inertial)
            if quat != [1.0, 0.0, 0.0, 0.0]:
                raise NotImplementedError(f"{where}: link {name!r}: a rotated <inertial> frame")
            i = inertial.find("inertia")
            full = [float(i.get(k)) for k in ("ixx", "iyy", "izz", "ixy", "ixz", "iyz")]
            out.append(f'{pad}<inertial pos="{_fmt(xyz)}" mass="{float(inertial.find("mass").get("value"))!r}" fullinertia="{_fmt(full)}"/>')
        for k, c in enumerate(l.findall("collision")):
            xyz, quat = _origin(c)
            g = c.find("geometry")[0]
            if g.tag == "box":
                shape = f'type="box" size="{_fmt([0.5 * s for s in _floats(g.get("size"))])}"'
            elif g.tag == "sphere":
                shape = f'type="sphere" size="{float(g.get("radius"))!r}"'
            elif g.tag == "cylinder":
                shape = f'type="cylinder" size="{float(g.get("radius"))!r} {0.5 * float(g.get("length"))!r}"'
            elif g.tag == "mesh":
                # MuJoCo collides a mesh as its convex hull, as the Rapier builder does (crates/multibody mesh.rs).
                shape = f'type="mesh" mesh="{mesh_asset(g)}"'
            else:
                raise NotImplementedError(f"{where}: link {name!r}: <{g.tag}> collisions have no MuJoCo equivalent here")
            out.append(f'{pad}<geom name="{name}/{k}" {shape} pos="{_fmt(xyz)}" quat="{_fmt(quat)}" mass="0"{_attrs(opt.contacts.get(name, {}))}/>')
        for sname, p in opt.sites.get(name, []):
            out.append(f'{pad}<site name="{sname}" pos="{_fmt(p)}" size="0.005"/>')
        return out

    def subtree(name: str, depth: int, pose: tuple[list[float], list[float]], moving: bool) -> list[str]:
        pad = "  " * depth
        out = link_xml(name, depth, moving)
        for j in children.get(name, []):
            child = j.find("child").get("link")
            xyz, quat = _origin(j)
            jn, kind = j.get("name"), j.get("type")
            # The child's pose in the world: the parent's composed with the joint origin.
            world = ([a + b for a, b in zip(pose[0], _rotate(pose[1], xyz))], _quat_mul(pose[1], quat))
            if child in opt.mocap:
                off = opt.mocap[child]
                body = [f'    <body name="{child}" mocap="true" pos="{_fmt([a + b for a, b in zip(world[0], off)])}" quat="{_fmt(world[1])}">']
                world_level.append(body + subtree(child, 3, world, False) + ["    </body>"])
                continue
            out.append(f'{pad}<body name="{child}" pos="{_fmt(xyz)}" quat="{_fmt(quat)}">')
            axis = _floats(j.find("axis").get("xyz") if j.find("axis") is not None else "1 0 0")
            dyn = j.find("dynamics")
            damping = float(dyn.get("damping", 0.0)) if dyn is not None else 0.0
            lim = j.find("limit")
            attrs = {"damping": repr(damping)}
            if lim is not None and kind in ("prismatic", "revolute"):
                attrs.update({"range": f"{float(lim.get('lower'))!r} {float(lim.get('upper'))!r}", "limited": "true"})
            attrs.update(opt.joints.get(jn, {}))
            if kind in ("prismatic", "revolute", "continuous"):
                t = "slide" if kind == "prismatic" else "hinge"
                out.append(f'{pad}  <joint name="{jn}" type="{t}" axis="{_fmt(axis)}"{_attrs(attrs)}/>')
            elif kind == "planar":
                norm = math.sqrt(sum(a * a for a in axis))
                n = [a / norm for a in axis]
                e = [1.0, 0.0, 0.0] if abs(n[0]) < 0.9 else [0.0, 1.0, 0.0]
                u = [n[1] * e[2] - n[2] * e[1], n[2] * e[0] - n[0] * e[2], n[0] * e[1] - n[1] * e[0]]
                un = math.sqrt(sum(a * a for a in u))
                u = [a / un for a in u]
                v = [n[1] * u[2] - n[2] * u[1], n[2] * u[0] - n[0] * u[2], n[0] * u[1] - n[1] * u[0]]
                d = {"damping": attrs["damping"]}
                out.append(f'{pad}  <joint name="{jn}_u" type="slide" axis="{_fmt(u)}"{_attrs(d)}/>')
                out.append(f'{pad}  <joint name="{jn}_v" type="slide" axis="{_fmt(v)}"{_attrs(d)}/>')
            elif kind != "fixed":
                raise NotImplementedError(f"{where}: joint {jn!r}: {kind} joints have no MuJoCo equivalent here")
            out += subtree(child, depth + 1, world, moving or kind != "fixed")
            out.append(f"{pad}</body>")
        return out

    body = subtree(roots[0], 2, ([0.0] * 3, [1.0, 0.0, 0.0, 0.0]), False)
    for b in world_level:
        body += b
    lines = [
        f'<mujoco model="{opt.name}">',
        '  <compiler angle="radian" inertiafromgeom="false" autolimits="true"/>',
        f'  <option timestep="{opt.timestep_s!r}" gravity="{_fmt(opt.gravity)}" integrator="{opt.integrator}"/>',
        "  <default>",
        f"    <geom{_attrs(opt.geom_defaults)}/>",
        "  </default>",
    ]
    if meshes:
        lines += ["  <asset>", *meshes, "  </asset>"]
    if opt.plugins:
        from xml.sax.saxutils import quoteattr

        lines.append("  <extension>")
        for plugin, inst, cfg in opt.plugins:
            lines.append(f'    <plugin plugin="{plugin}"><instance name="{inst}">')
            lines += [f"      <config key={quoteattr(k)} value={quoteattr(str(v))}/>" for k, v in cfg.items()]
            lines.append("    </instance></plugin>")
        lines.append("  </extension>")
    lines += ["  <worldbody>", *body, "  </worldbody>"]
    if opt.tendons:
        lines.append("  <tendon>")
        lines += [f'    <spatial name="{n}"><site site="{a}"/><site site="{b}"/></spatial>' for n, a, b in opt.tendons]
        lines.append("  </tendon>")
    if opt.motors or opt.plugin_actuators:
        lines.append("  <actuator>")
        lines += [f'    <motor name="{n}" {target} gear="1"/>' for n, target in opt.motors]
        lines += [
            f'    <plugin name="{n}" {target} plugin="{p}" instance="{i}" gear="1" ctrlrange="-1 1" ctrllimited="true" forcelimited="false"/>'
            for n, target, p, i in opt.plugin_actuators
        ]
        lines.append("  </actuator>")
    lines.append("</mujoco>")
    return "\n".join(lines) + "\n"


# ---------------------------------------------------------------- the paper's rig as one case of it


@dataclass
class Face:
    """One environment material: a compliant face on a slide mount."""

    name: str
    stiffness_n_per_m: float
    damping_n_s_per_m: float
    mass_kg: float
    thickness_m: float
    # Flange extension at first touch with the unloaded face, m.
    x_e_m: float
    # Transverse (y) position of the face on the carriage, m.
    y_m: float = 0.0
    # The mount's joint and the face's link in the URDF (default: `<name>_mount`, `<name>_face`).
    mount_joint: str | None = None
    link: str | None = None

    @property
    def joint(self) -> str:
        return self.mount_joint or f"{self.name}_mount"

    @property
    def body(self) -> str:
        return self.link or f"{self.name}_face"


@dataclass
class RigSpec:
    """Everything the MJCF needs, from the scene (and its URDF when it has one)."""

    name: str
    timestep_s: float
    stroke_m: float
    flange_mass_kg: float
    flange_damping_n_s_per_m: float
    flange_front_m: float
    alpha_rad: float
    gravity_m_s2: float
    x0_m: float
    faces: list[Face] = field(default_factory=list)
    # Axis height above the platform, m (visual only).
    axis_z_m: float = 0.04
    # Faces on a kinematic carriage (mocap body) that can swap them; the first face faces the flange at t = 0.
    carriage: bool = False
    # The rig's URDF (multibody scenes); None: the rig is written from these numbers (`rig_urdf`).
    urdf: str | None = None
    flange_link: str = "flange"
    flange_joint: str = "flange_slide"


def gravity_vector(alpha_rad: float, g: float) -> tuple[float, float, float]:
    """Gravity in the rig frame: m g sin(alpha) along +x aids extension (eq. (1)'s G_alpha)."""
    return (g * math.sin(alpha_rad), 0.0, -g * math.cos(alpha_rad))


def spring_ref(face: Face, alpha_rad: float, g: float) -> float:
    """Spring reference of a face mount that carries the face's weight along the axis: q0 = -m g_x / k."""
    if face.stiffness_n_per_m <= 0.0:
        return 0.0
    return -face.mass_kg * gravity_vector(alpha_rad, g)[0] / face.stiffness_n_per_m


def _box_inertia(m: float, ixx: float, iyy: float) -> str:
    return f'<inertia ixx="{m * ixx!r}" iyy="{m * iyy!r}" izz="{m * iyy!r}" ixy="0" ixz="0" iyz="0"/>'


def rig_urdf(spec: RigSpec) -> str:
    """The rig of a scene without a URDF (a 1-DOF scene) as a URDF: the cylinder fixed to the world, the
    flange (moving mass, K_v, stroke) on a prismatic joint along x, each face on a prismatic mount whose
    flange-side surface is x_e ahead of the flange's front face. The flange's and the faces' inertias are
    plausible boxes (irrelevant on a slide joint)."""
    z, half, fm = spec.axis_z_m, 0.5 * spec.flange_front_m, spec.flange_mass_kg
    lines = [
        f'<robot name="{spec.name}">',
        f'  <link name="base"><collision><origin xyz="-0.045 0 {z!r}" rpy="0 1.5707963267948966 0"/>'
        '<geometry><cylinder radius="0.014" length="0.08"/></geometry></collision></link>',
        f'  <link name="{spec.flange_link}"><inertial><origin xyz="{half!r} 0 0"/><mass value="{fm!r}"/>{_box_inertia(fm, 2.7e-4, 1.4e-4)}</inertial>'
        f'<collision><origin xyz="{half!r} 0 0"/><geometry><box size="{spec.flange_front_m!r} 0.04 0.04"/></geometry></collision></link>',
        f'  <joint name="{spec.flange_joint}" type="prismatic"><parent link="base"/><child link="{spec.flange_link}"/>'
        f'<origin xyz="0 0 {z!r}"/><axis xyz="1 0 0"/><limit lower="0" upper="{spec.stroke_m!r}"/>'
        f'<dynamics damping="{spec.flange_damping_n_s_per_m!r}"/></joint>',
    ]
    parent = "base"
    if spec.carriage:
        lines.append('  <link name="carriage"/>')
        lines.append('  <joint name="carriage_slide" type="planar"><parent link="base"/><child link="carriage"/><axis xyz="0 0 1"/></joint>')
        parent = "carriage"
    for f in spec.faces:
        t, m = f.thickness_m, f.mass_kg
        # Unloaded face: its flange-side surface at x_e + flange_front (flange front face at x + front).
        x_face = f.x_e_m + spec.flange_front_m + 0.5 * t
        lines += [
            f'  <link name="{f.body}"><inertial><mass value="{m!r}"/>{_box_inertia(m, 6e-4, 3e-4)}</inertial>'
            f'<collision><geometry><box size="{t!r} 0.06 0.06"/></geometry></collision></link>',
            f'  <joint name="{f.joint}" type="prismatic"><parent link="{parent}"/><child link="{f.body}"/>'
            f'<origin xyz="{x_face!r} {f.y_m!r} {z!r}"/><axis xyz="1 0 0"/><limit lower="-0.01" upper="0.05"/>'
            f'<dynamics damping="{f.damping_n_s_per_m!r}"/></joint>',
        ]
    lines.append("</robot>")
    return "\n".join(lines) + "\n"


def rig_options(spec: RigSpec) -> Options:
    """What the rig adds to its URDF: the tilted gravity, explicit Euler, near-rigid frictionless contacts
    between the flange and the faces only, each face mount's k_e, c_e and spring reference, the flange's
    stroke ends as stiff as the contacts, and the carriage as a mocap body with the first face in front."""
    flange = {"contype": "1", "conaffinity": "2", "solref": CONTACT_SOLREF, "solimp": CONTACT_SOLIMP, "rgba": "0.8 0.8 0.8 1"}
    face = {"contype": "2", "conaffinity": "1", "solref": CONTACT_SOLREF, "solimp": CONTACT_SOLIMP, "rgba": "0.7 0.5 0.3 1"}
    joints = {spec.flange_joint: {"solreflimit": CONTACT_SOLREF, "solimplimit": CONTACT_SOLIMP}}
    for f in spec.faces:
        ref = spring_ref(f, spec.alpha_rad, spec.gravity_m_s2)
        joints[f.joint] = {"stiffness": repr(f.stiffness_n_per_m), "damping": repr(f.damping_n_s_per_m), "springref": repr(ref)}
    return Options(
        name=spec.name,
        timestep_s=spec.timestep_s,
        gravity=gravity_vector(spec.alpha_rad, spec.gravity_m_s2),
        integrator="Euler",
        geom_defaults={"contype": "0", "conaffinity": "0", "condim": "1"},
        contacts={spec.flange_link: flange, **{f.body: face for f in spec.faces}},
        joints=joints,
        mocap={"carriage": (0.0, -spec.faces[0].y_m if spec.faces else 0.0, 0.0)} if spec.carriage else {},
    )


def build_mjcf(spec: RigSpec) -> str:
    """The MJCF text of the rig: its URDF (or `rig_urdf`'s) through `urdf_to_mjcf` with `rig_options`."""
    return urdf_to_mjcf(spec.urdf if spec.urdf is not None else rig_urdf(spec), rig_options(spec))


# ---------------------------------------------------------------- URDF -> RigSpec (multibody scenes)


def _xyz(el, attr="xyz") -> tuple[float, float, float]:
    x, y, z = _floats(el.get(attr) if el is not None else None)
    return (x, y, z)


def spec_from_urdf(
    urdf_path: str,
    materials: dict[str, tuple[str, float, float]],
    alpha_rad: float,
    timestep_s: float,
    x0_m: float = 0.0,
    gravity_m_s2: float = 9.80665,
    flange_link: str = "flange",
    flange_joint: str = "flange_slide",
) -> RigSpec:
    """The roles of urdf/rig.urdf's links and joints (as crates/multibody's RigConfig::paper_rig), for
    the coupling (couple.Sim) and `build_mjcf`, which derives the MJCF from the URDF itself:
    `materials` maps a material name to (mount joint, k N/m, c N s/m). Flange mass, K_v (joint damping),
    stroke, the flange's front face and every face's mass, thickness, transverse position and x_e come from
    the URDF, the same numbers the Rapier builder reads. Assumes the rig's layout: fixed cylinder, boxes,
    axes along +x, no rotations."""
    try:
        root = ET.parse(urdf_path).getroot()
    except (OSError, ET.ParseError) as e:
        raise ValueError(f"{urdf_path}: cannot read URDF: {e}") from e
    links = {l.get("name"): l for l in root.findall("link")}
    joints = {j.get("name"): j for j in root.findall("joint")}

    def joint(name: str):
        if name not in joints:
            raise ValueError(f"{urdf_path}: joint {name!r} not found")
        return joints[name]

    def link(name: str):
        if name not in links:
            raise ValueError(f"{urdf_path}: link {name!r} not found")
        return links[name]

    def box(l) -> tuple[tuple[float, float, float], tuple[float, float, float]]:
        g = l.find("collision/geometry/box")
        if g is None:
            raise ValueError(f"{urdf_path}: link {l.get('name')!r}: a <collision> box is expected")
        return _xyz(l.find("collision/origin")), _xyz(g, "size")

    def mass(l) -> float:
        m = l.find("inertial/mass")
        v = float(m.get("value")) if m is not None else 0.0
        if not v > 0.0:
            raise ValueError(f"{urdf_path}: link {l.get('name')!r}: mass must be > 0")
        return v

    fj = joint(flange_joint)
    lim = fj.find("limit")
    lower, upper = float(lim.get("lower")), float(lim.get("upper"))
    damping = float(fj.find("dynamics").get("damping", "0")) if fj.find("dynamics") is not None else 0.0
    fl = link(flange_link)
    (ox, _, _), (sx, _, _) = box(fl)
    front = ox + 0.5 * sx  # front face ahead of the flange joint origin
    f_origin = _xyz(fj.find("origin"))
    cyl_origin = _xyz(joints[[n for n, j in joints.items() if j.find("child").get("link") == fj.find("parent").get("link")][0]].find("origin"))
    faces = []
    for name, (mount, k, c) in materials.items():
        mj = joint(mount)
        fo = _xyz(mj.find("origin"))
        face_link = link(mj.find("child").get("link"))
        (fx, _, _), (tx, _, _) = box(face_link)
        face_front = fo[0] + fx - 0.5 * tx  # flange-side surface of the face, carriage frame
        x_e = face_front - (cyl_origin[0] + f_origin[0] + front) - lower
        faces.append(Face(name, k, c, mass(face_link), tx, x_e, y_m=fo[1], mount_joint=mount, link=face_link.get("name")))
    return RigSpec(
        name=root.get("name", "rig"),
        timestep_s=timestep_s,
        stroke_m=upper - lower,
        flange_mass_kg=mass(fl),
        flange_damping_n_s_per_m=damping,
        flange_front_m=front,
        alpha_rad=alpha_rad,
        gravity_m_s2=gravity_m_s2,
        x0_m=x0_m,
        faces=faces,
        axis_z_m=cyl_origin[2],
        carriage=True,
        urdf=urdf_path,
        flange_link=flange_link,
        flange_joint=flange_joint,
    )


# ---------------------------------------------------------------- the native plugin (docs/mujoco-plugin.md)


def with_cylinder_plugin(xml: str, config: dict[str, str], joint: str = "flange_slide", name: str = "cylinder") -> str:
    """The rig's MJCF with the pneumatic cylinder as MuJoCo's own actuator: the `pneuflex.cylinder` plugin
    (crates/mujoco-plugin) on the flange slide (gear 1: length = extension in m, force in N), command in
    ctrl[0] within [-1, 1]. `config` is the plugin's `<config>` (sheet, inline values, initial chambers)."""
    from xml.sax.saxutils import quoteattr

    cfg = "".join(f"\n        <config key={quoteattr(k)} value={quoteattr(str(v))}/>" for k, v in config.items())
    ext = (
        '  <extension>\n    <plugin plugin="pneuflex.cylinder">\n'
        f'      <instance name="{name}">{cfg}\n      </instance>\n    </plugin>\n  </extension>\n'
    )
    act = (
        "  <actuator>\n"
        f'    <plugin name="{name}" joint="{joint}" plugin="pneuflex.cylinder" instance="{name}" gear="1"'
        ' ctrlrange="-1 1" ctrllimited="true" forcelimited="false"/>\n'
        "  </actuator>\n"
    )
    head, sep, rest = xml.partition("\n")
    if not rest.rstrip().endswith("</mujoco>"):
        raise ValueError("not an MJCF ending in </mujoco>")
    body = rest.rstrip()[: -len("</mujoco>")]
    return head + sep + ext + body + act + "</mujoco>\n"
