"""MJCF generation: the MuJoCo model equivalent to a pneuflex scene.

Rig frame (as urdf/rig.urdf and crates/multibody): x = actuator axis (flange extension, towards the
environment), z = platform normal. The incline alpha (actuator axis below the horizontal, gravity aids
extension by m g sin(alpha)) is applied by turning gravity in the rig frame, exactly as RigWorld does:
g_rig = g (sin(alpha) x - cos(alpha) z).

Bodies:
- the cylinder is fixed (welded to the platform), so the actuator force acts on the flange's slide dof;
- the flange slides along x (range = stroke, damping = K_v of eq. (1)); its collision box's front face
  is `flange_front_m` ahead of its joint origin;
- each environment material is a thin face body on a slide joint along x (the compliant mount): joint
  stiffness k_e, damping c_e, spring reference chosen so that the face's own weight along the axis is
  absorbed (the unloaded face rests at q = 0 at every incline, so f_e = k_e (x - x_e), eq. (21));
- only flange-face contacts exist (contype/conaffinity), frictionless normal contacts (condim 1), made
  near-rigid with solref/solimp so that the compliance lives in the mount, as in the Rapier world.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

# Near-rigid contact: measured here (issue 6) to give a steady f_e = k_e x within 0.05 N at dt = 1 ms,
# where MuJoCo's default (solref 0.02 1) sinks 2 mm at 14 N (a ~7e3 N/m series spring).
CONTACT_SOLREF = "0.002 1"
CONTACT_SOLIMP = "0.99 0.999 0.0001 0.5 2"


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


def gravity_vector(alpha_rad: float, g: float) -> tuple[float, float, float]:
    """Gravity in the rig frame: m g sin(alpha) along +x aids extension (eq. (1)'s G_alpha)."""
    return (g * math.sin(alpha_rad), 0.0, -g * math.cos(alpha_rad))


def spring_ref(face: Face, alpha_rad: float, g: float) -> float:
    """Spring reference of a face mount that carries the face's weight along the axis: q0 = -m g_x / k."""
    if face.stiffness_n_per_m <= 0.0:
        return 0.0
    return -face.mass_kg * gravity_vector(alpha_rad, g)[0] / face.stiffness_n_per_m


def build_mjcf(spec: RigSpec) -> str:
    """The MJCF text of the rig."""
    gx, gy, gz = gravity_vector(spec.alpha_rad, spec.gravity_m_s2)
    z = spec.axis_z_m
    half = 0.5 * spec.flange_front_m
    # The flange's inertia is irrelevant on a slide joint; give a plausible box inertia.
    fm = spec.flange_mass_kg
    lines = [
        f'<mujoco model="{spec.name}">',
        '  <compiler angle="radian" autolimits="true"/>',
        f'  <option timestep="{spec.timestep_s!r}" gravity="{gx!r} {gy!r} {gz!r}" integrator="Euler"/>',
        "  <default>",
        '    <geom contype="0" conaffinity="0" condim="1"/>',
        "  </default>",
        "  <worldbody>",
        # Cylinder body: welded to the platform (part of the world), visual only.
        f'    <geom name="cylinder" type="cylinder" size="0.014 0.04" pos="-0.045 0 {z}" zaxis="1 0 0" rgba="0.6 0.6 0.7 1"/>',
        f'    <body name="flange" pos="0 0 {z}">',
        f'      <joint name="flange_slide" type="slide" axis="1 0 0" range="0 {spec.stroke_m!r}" damping="{spec.flange_damping_n_s_per_m!r}"'
        f' solreflimit="{CONTACT_SOLREF}" solimplimit="{CONTACT_SOLIMP}"/>',
        f'      <inertial pos="{half!r} 0 0" mass="{fm!r}" diaginertia="{fm * 2.7e-4!r} {fm * 1.4e-4!r} {fm * 1.4e-4!r}"/>',
        f'      <geom name="flange_box" type="box" size="{half!r} 0.02 0.02" pos="{half!r} 0 0" contype="1" conaffinity="2"'
        f' solref="{CONTACT_SOLREF}" solimp="{CONTACT_SOLIMP}" rgba="0.8 0.8 0.8 1"/>',
        "    </body>",
    ]
    indent = "    "
    if spec.carriage:
        # The carriage is driven kinematically (a mocap body, as Rapier's kinematic body): its pose is set
        # every step; the faces ride on it on their compliant mounts. Initially the first face is aligned.
        y0 = -spec.faces[0].y_m if spec.faces else 0.0
        lines.append(f'{indent}<body name="carriage" mocap="true" pos="0 {y0!r} 0">')
        indent += "  "
    for f in spec.faces:
        t = f.thickness_m
        # Unloaded face: its flange-side surface at x_e + flange_front (flange front face at x + front).
        x_face = f.x_e_m + spec.flange_front_m + 0.5 * t
        m = f.mass_kg
        ref = spring_ref(f, spec.alpha_rad, spec.gravity_m_s2)
        lines += [
            f'{indent}<body name="{f.name}_face" pos="{x_face!r} {f.y_m!r} {z}">',
            f'{indent}  <joint name="{f.name}_mount" type="slide" axis="1 0 0" range="-0.01 0.05"'
            f' stiffness="{f.stiffness_n_per_m!r}" damping="{f.damping_n_s_per_m!r}" springref="{ref!r}"/>',
            f'{indent}  <inertial pos="0 0 0" mass="{m!r}" diaginertia="{m * 6e-4!r} {m * 3e-4!r} {m * 3e-4!r}"/>',
            f'{indent}  <geom name="{f.name}_box" type="box" size="{0.5 * t!r} 0.03 0.03" contype="2" conaffinity="1"'
            f' solref="{CONTACT_SOLREF}" solimp="{CONTACT_SOLIMP}" rgba="0.7 0.5 0.3 1"/>',
            f"{indent}</body>",
        ]
    if spec.carriage:
        lines.append("    </body>")
    lines += ["  </worldbody>", "</mujoco>"]
    return "\n".join(lines) + "\n"


# ---------------------------------------------------------------- URDF -> RigSpec (multibody scenes)


def _xyz(el, attr="xyz") -> tuple[float, float, float]:
    if el is None or el.get(attr) is None:
        return (0.0, 0.0, 0.0)
    v = [float(s) for s in el.get(attr).split()]
    if len(v) != 3 or not all(math.isfinite(a) for a in v):
        raise ValueError(f"bad {attr}={el.get(attr)!r}")
    return (v[0], v[1], v[2])


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
    """The MuJoCo rig of urdf/rig.urdf (the roles of crates/multibody's MultibodyConfig::paper_rig):
    `materials` maps a material name to (mount joint, k N/m, c N s/m). Flange mass, K_v (joint damping),
    stroke, the flange's front face and every face's mass, thickness, transverse position and x_e come from
    the URDF, the same numbers the Rapier builder reads. Assumes the rig's layout: fixed cylinder, boxes,
    axes along +x, no rotations."""
    import xml.etree.ElementTree as ET

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
        faces.append(Face(name, k, c, mass(face_link), tx, x_e, y_m=fo[1]))
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
