"""Run a pneuflex scene in MuJoCo with the Rust pneumatic force element and controller (via the bindings).

The loop is the scene runner's own (crates/scene/src/runner.rs, called through `pneuflex.run_plant`): at each
control tick t_k = k dt the events due are applied, the plant is sensed, the controller updates, the row is
recorded, the divergence checks run, and the plant is advanced by dt with the valve command held. The plant
is `MujocoPlant`, written here; "advanced" means `substeps` MuJoCo steps of dt/substeps, each one preceded
by a force-element step over the same interval along the flange motion MuJoCo reports:

    F = ForceElement.step(x, x_dot, u, h)            # chambers + valve over [t, t+h], mean force
    qfrc_applied[flange] = F - friction(x_dot)       # eq. (1)'s F_1 and f; K_v is the joint damping
    mj_step                                          # gravity m g sin(alpha) comes from the tilted g

The cylinder body is welded to the platform, so the force acts on the flange slide dof and its reaction
goes to the world. f_e is what a load cell between flange and face reads: the sum of the normal contact
forces between the two geoms from mj_contactForce, projected on the actuator axis.
"""

from __future__ import annotations

import dataclasses
import math
import time
from dataclasses import dataclass
from pathlib import Path

import mujoco
import numpy as np

import pneuflex

from . import mjcf


class DivergedError(RuntimeError):
    """MuJoCo reported a numerical problem (it resets the state silently) or the run left its limits."""


@dataclass
class Coupled:
    """A scene's MuJoCo model, ready to run any of the scene's controllers."""

    scene_path: str
    scene: dict
    spec: mjcf.RigSpec
    xml: str
    # MuJoCo steps per control tick.
    substeps: int
    # Chamber (force element) substeps per MuJoCo step.
    chamber_substeps: int = 1
    # "pneumatic" (1-DOF equivalent) or "multibody" (the URDF rig).
    plant_kind: str = "pneumatic"

    @property
    def dt_s(self) -> float:
        return float(self.scene["dt_s"])


def spec_from_scene(scene_path: str, substeps: int, face_mass_kg: float, face_damping: float) -> mjcf.RigSpec:
    """The MuJoCo rig equivalent to a scene's plant.

    A `pneumatic` (1-DOF) scene has no URDF: its equivalent is the flange (the actuator sheet's moving mass,
    K_v, stroke) on a slide joint pushing one compliant face whose mount stiffness is the scene's k_e and
    whose surface is at the scene's x_e. The 1-DOF plant's environment is massless and undamped; the face
    here carries `face_mass_kg` (default: the URDF's 9 g wood veneer) and `face_damping`.
    """
    scene = pneuflex.load_scene(scene_path)
    plant = scene["plant"]
    if plant["kind"] == "multibody":
        return spec_from_multibody(scene_path, scene)
    if plant["kind"] != "pneumatic":
        raise NotImplementedError(
            f"{scene_path}: plant.kind = {plant['kind']!r}: only the 'pneumatic' and 'multibody' plants have a MuJoCo equivalent"
        )
    act = pneuflex.Actuator.from_scene(scene_path)
    p = act.params()
    env = scene["environment"]
    k = float(env["stiffness_n_per_m"])
    stiffnesses = [k] + [ev["stiffness_n_per_m"] for ev in scene.get("events", []) if ev["kind"] == "stiffness"]
    if min(stiffnesses) <= 0.0:
        raise NotImplementedError(f"{scene_path}: a zero environment stiffness has no face mount equivalent")
    x0 = pneuflex.initial_state(scene_path)["x"]
    return mjcf.RigSpec(
        name=scene["name"],
        timestep_s=float(scene["dt_s"]) / substeps,
        stroke_m=p["stroke_m"],
        flange_mass_kg=p["moving_mass_kg"],
        flange_damping_n_s_per_m=p["viscous_n_s_per_m"],
        flange_front_m=0.01,
        alpha_rad=p["alpha_rad"],
        gravity_m_s2=p["gravity_m_per_s2"],
        x0_m=x0,
        faces=[
            mjcf.Face(
                name="env",
                stiffness_n_per_m=k,
                damping_n_s_per_m=face_damping,
                mass_kg=face_mass_kg,
                thickness_m=0.005,
                x_e_m=float(env["x_e_m"]),
            )
        ],
    )


def spec_from_multibody(scene_path: str, scene: dict) -> mjcf.RigSpec:
    """The MuJoCo rig of a `multibody` scene: the scene's URDF read by mjcf.spec_from_urdf with the scene's
    materials (initial material first: the carriage starts aligned with it), the physics step
    `physics_dt_s`, the incline and the initial extension of the Rapier plant (crates/scene/src/multibody.rs)."""
    plant = scene["plant"]
    base = Path(scene["base_dir"])
    act = pneuflex.Actuator.from_scene(scene_path)
    p = act.params()
    mats = {m["name"]: (m["mount_joint"], float(m["stiffness_n_per_m"]), float(m["damping_n_s_per_m"])) for m in plant["materials"]}
    first = plant.get("initial_material") or plant["materials"][0]["name"]
    ordered = {first: mats[first], **{k: v for k, v in mats.items() if k != first}}
    x0 = pneuflex.initial_state(scene_path)["x"]
    spec = mjcf.spec_from_urdf(
        str(base / plant["urdf"]), ordered, p["alpha_rad"], float(plant["physics_dt_s"]), x0_m=x0, gravity_m_s2=p["gravity_m_per_s2"]
    )
    spec.name = scene["name"]
    return spec


def prepare(
    scene_path: str, substeps: int = 10, face_mass_kg: float = 0.009, face_damping: float = 0.0, mb_refine: int = 1
) -> Coupled:
    """Load the scene and generate its MJCF. For a 1-DOF scene, `substeps` MuJoCo steps per control tick
    (one force-element substep each); for a multibody scene the scene's own physics step and chamber substeps."""
    scene = pneuflex.load_scene(scene_path)
    spec = spec_from_scene(scene_path, substeps, face_mass_kg, face_damping)
    if scene["plant"]["kind"] == "multibody":
        # `mb_refine` MuJoCo steps per Rapier physics step or per control tick, whichever is shorter (a
        # physics step may span several ticks: MuJoCo's step does not follow it); the chamber substep
        # (min(physics_dt, dt) / chamber_substeps, as in crates/scene) stays the scene's, so the valve and
        # chambers are integrated with the same step on both sides.
        chamber = int(scene["plant"]["chamber_substeps"])
        if mb_refine < 1 or chamber % mb_refine != 0:
            raise ValueError(f"mb_refine = {mb_refine} must divide plant.chamber_substeps = {chamber}")
        dt = float(scene["dt_s"])
        spec.timestep_s = min(float(scene["plant"]["physics_dt_s"]), dt) / mb_refine
        steps = round(dt / spec.timestep_s)
        return Coupled(scene_path, scene, spec, mjcf.build_mjcf(spec), steps, chamber // mb_refine, "multibody")
    return Coupled(scene_path, scene, spec, mjcf.build_mjcf(spec), substeps)


class Sim:
    """One MuJoCo model + data of a coupled scene, with helpers to sense and apply events."""

    def __init__(self, c: Coupled, xml: str | None = None):
        self.c = c
        self.model = mujoco.MjModel.from_xml_string(xml if xml is not None else c.xml)
        self.data = mujoco.MjData(self.model)
        m = self.model
        self.flange_jnt = m.joint(c.spec.flange_joint).id
        self.flange_qpos = int(m.jnt_qposadr[self.flange_jnt])
        self.flange_dof = int(m.jnt_dofadr[self.flange_jnt])
        self.flange_geoms = self._geoms(self.flange_jnt)
        self.faces = {}
        for f in c.spec.faces:
            # A copy: events change a face's stiffness here, not in the coupled scene's spec (a reset model
            # starts from the spec's).
            f = dataclasses.replace(f)
            j = m.joint(f.joint).id
            self.faces[f.name] = (f, j, int(m.jnt_qposadr[j]), self._geoms(j))
        self.face_geoms = set().union(*(v[3] for v in self.faces.values()))
        self.alpha = c.spec.alpha_rad
        self.time = 0.0
        # Kinematic carriage (multibody rig): transverse offset and retreat along the axis, m.
        self.mocap = int(m.body("carriage").mocapid[0]) if c.spec.carriage else None
        self.active = c.spec.faces[0].name if c.spec.faces else None
        self.offset = -c.spec.faces[0].y_m if c.spec.carriage else 0.0
        self.retreat = 0.0
        self.motion = None
        min_xe = min((f.x_e_m for f in c.spec.faces), default=0.0)
        self.swap_retreat_m = max(c.spec.stroke_m - min_xe, 0.0) + 0.01
        self.data.qpos[self.flange_qpos] = c.spec.x0_m
        mujoco.mj_forward(self.model, self.data)
        self._cf = np.zeros(6)

    def _geoms(self, joint: int) -> set[int]:
        """The geoms of the body a joint moves (the link's colliders, `<link>/<i>`)."""
        body = self.model.jnt_bodyid[joint]
        return {g for g in range(self.model.ngeom) if self.model.geom_bodyid[g] == body}

    def x(self) -> tuple[float, float]:
        return float(self.data.qpos[self.flange_qpos]), float(self.data.qvel[self.flange_dof])

    def contact_force(self) -> float:
        """Normal force the flange exerts on the environment faces along +x, N (a load cell)."""
        d = self.data
        total = 0.0
        for i in range(d.ncon):
            con = d.contact[i]
            g1, g2 = con.geom1, con.geom2
            if not ({g1, g2} & self.flange_geoms) or not ({g1, g2} & self.face_geoms):
                continue
            mujoco.mj_contactForce(self.model, d, i, self._cf)
            # The contact frame's first axis is the normal; force[0] >= 0 is the normal force on geom2.
            total += self._cf[0] * abs(con.frame[0])
        return total

    def set_stiffness(self, name: str, k: float) -> None:
        f, j, qadr, _ = self.faces[name]
        f.stiffness_n_per_m = k
        self.model.jnt_stiffness[j] = k
        self.model.qpos_spring[qadr] = mjcf.spring_ref(f, self.alpha, self.c.spec.gravity_m_s2)

    def set_alpha(self, alpha_rad: float) -> None:
        self.alpha = alpha_rad
        self.model.opt.gravity[:] = mjcf.gravity_vector(alpha_rad, self.c.spec.gravity_m_s2)
        for name in self.faces:
            self.set_stiffness(name, self.faces[name][0].stiffness_n_per_m)

    def swap(self, to: str, duration_s: float) -> None:
        """Event: move the carriage so that face `to` faces the flange over `duration_s` from now (retreat
        beyond the flange's reach, slide across, come back: CarriageRig::swap_environment)."""
        if self.mocap is None:
            raise NotImplementedError("this model has no carriage to swap the environment with")
        if to not in self.faces:
            raise ValueError(f"unknown material {to!r}, expected one of {sorted(self.faces)}")
        if not (math.isfinite(duration_s) and duration_s > 0.0):
            raise ValueError(f"swap duration_s must be finite and > 0, got {duration_s}")
        target = -self.faces[to][0].y_m
        self.motion = (self.time, duration_s, self.offset, target, self.swap_retreat_m, to)
        self.active = None

    def step(self, h: float) -> None:
        """One mj_step of h seconds, with the carriage at its pose for the end of the step."""
        t1 = self.time + h
        if self.motion is not None:
            t0, dur, a, b, r, to = self.motion
            self.offset, self.retreat = carriage_offset(t1, t0, dur, a, b, r)
            self.data.mocap_pos[self.mocap] = (self.retreat, self.offset, 0.0)
            if t1 >= t0 + dur:
                self.motion, self.active = None, to
        mujoco.mj_step(self.model, self.data)
        self.time = t1

    def apply(self, ev: dict) -> None:
        """A scene event: stiffness (of `material`, default the face in front), alpha, swap."""
        kind = ev["kind"]
        if kind == "stiffness" and self.c.plant_kind == "multibody":
            name = ev.get("material") or self.active
            if name is None:
                raise ValueError("no material faces the flange (the carriage is moving): name one with `material`")
            self.set_stiffness(name, float(ev["stiffness_n_per_m"]))
            if ev.get("damping_n_s_per_m") is not None:
                self.model.dof_damping[self.model.jnt_dofadr[self.faces[name][1]]] = float(ev["damping_n_s_per_m"])
        elif kind == "stiffness":
            name = ev.get("material", self.active or next(iter(self.faces)))
            self.set_stiffness(name, float(ev["stiffness_n_per_m"]))
            if ev.get("damping_n_s_per_m") is not None:
                self.model.dof_damping[self.model.jnt_dofadr[self.faces[name][1]]] = float(ev["damping_n_s_per_m"])
        elif kind == "alpha":
            self.set_alpha(math.radians(float(ev["alpha_deg"])))
        elif kind in ("swap", "swap_environment"):
            self.swap(ev["to"], float(ev["duration_s"]))
        else:
            raise NotImplementedError(f"event kind {kind!r} has no MuJoCo equivalent yet")

    def check(self, t: float) -> None:
        """Raise if MuJoCo warned (it then resets the state and the run would be meaningless)."""
        for i in range(int(mujoco.mjtWarning.mjNWARNING)):
            n = self.data.warning[i].number
            if n > 0:
                name = mujoco.mjtWarning(i).name
                raise DivergedError(f"MuJoCo warning {name} ({n}x) by t = {t:.4f} s: MuJoCo reset the run")


class MujocoPlant:
    """A coupled scene's MuJoCo model as a plant of the scene crate's loop (`pneuflex.run_plant`): the Rust
    loop applies the events, senses, updates the controller, records the row, checks divergence, then
    calls `actuate` and `advance`. Advancing by dt is `substeps` MuJoCo steps of h = dt / substeps, each
    preceded by a force-element step over the same interval along the flange motion MuJoCo reports."""

    def __init__(self, c: Coupled):
        self.c = c
        self.act = pneuflex.Actuator.from_scene(c.scene_path)
        self.init = pneuflex.initial_state(c.scene_path)
        self.reset()

    def reset(self) -> None:
        """A fresh MuJoCo model and data (events change the model) and force element at the initial state."""
        c = self.c
        self.sim = Sim(c)
        self.fe = pneuflex.ForceElement(self.act, p_a=self.init["p_a"], p_b=self.init["p_b"], substeps=c.chamber_substeps)
        self._gravity_drive()
        self.u = 0.0
        self.ticks = 0
        self.f_e = self.sim.contact_force()

    def _gravity_drive(self) -> None:
        # Gravity along the axis on the flange: the drive seen by a stick-slip friction law (as FlangeDrive).
        s = self.c.spec
        self.g_flange = s.flange_mass_kg * s.gravity_m_s2 * math.sin(self.sim.alpha)

    def sense(self) -> tuple[float, float, float, float, float]:
        x, xd = self.sim.x()
        return x, xd, self.f_e, self.fe.p_a, self.fe.p_b

    def actuate(self, u: float, x_r: float) -> None:
        self.u = u

    def apply(self, ev: dict) -> None:
        self.sim.apply(ev)
        if self.c.plant_kind != "multibody":
            # The 1-DOF plant's load cell reads the new environment at once (f_e = k_e (x - x_e)): recompute
            # the contact forces at the current state. (The Rapier plant reads the last step's impulses.)
            mujoco.mj_forward(self.sim.model, self.sim.data)
            self.f_e = self.sim.contact_force()
        self._gravity_drive()

    def advance(self, dt: float) -> None:
        sim, fe, u, g = self.sim, self.fe, self.u, self.g_flange
        qpos, qvel, qfrc = sim.data.qpos, sim.data.qvel, sim.data.qfrc_applied
        iq, dof = sim.flange_qpos, sim.flange_dof
        friction, step = fe.friction_force, fe.step
        h = dt / self.c.substeps
        for _ in range(self.c.substeps):
            xs, vs = qpos[iq], qvel[dof]
            f = step(xs, vs, u, h)
            qfrc[dof] = f - friction(vs, f + g)
            sim.step(h)
        self.ticks += 1
        sim.check(self.ticks * dt)
        self.f_e = sim.contact_force()


def plugin_config(c: Coupled) -> dict[str, str]:
    """The `pneuflex.cylinder` configuration equal to the force element MujocoPlant couples: the scene's
    actuator sheet, the same initial chambers (exact, repr) and chamber substeps per MuJoCo step."""
    act = pneuflex.Actuator.from_scene(c.scene_path)
    init = pneuflex.initial_state(c.scene_path)
    return {
        "sheet": str(Path(act.path).resolve()),
        "initial_p_a_pa": repr(float(init["p_a"])),
        "initial_p_b_pa": repr(float(init["p_b"])),
        "chamber_substeps": str(c.chamber_substeps),
    }


class PluginPlant(MujocoPlant):
    """The same rig with the cylinder as MuJoCo's native actuator, the `pneuflex.cylinder` plugin
    (docs/mujoco-plugin.md): the chambers live in MuJoCo's plugin_state and MuJoCo steps them itself;
    Python only sets ctrl and steps (one `mj_step(nstep=...)` call per tick when no carriage moves).
    Same loop, sensing and events as MujocoPlant, so the two runs differ only in who couples the element."""

    def __init__(self, c: Coupled, library: str | None = None):
        mujoco.mj_loadPluginLibrary(library or pneuflex.mujoco_plugin_path())
        self.xml = mjcf.with_cylinder_plugin(c.xml, plugin_config(c))
        super().__init__(c)

    def reset(self) -> None:
        c = self.c
        self.sim = Sim(c, self.xml)
        self._state = int(self.sim.model.plugin_stateadr[0])
        self._gravity_drive()
        self.u = 0.0
        self.ticks = 0
        self.f_e = self.sim.contact_force()

    def pressures(self) -> tuple[float, float]:
        s = self.sim.data.plugin_state
        return float(s[self._state]), float(s[self._state + 1])

    def sense(self) -> tuple[float, float, float, float, float]:
        x, xd = self.sim.x()
        return (x, xd, self.f_e, *self.pressures())

    def advance(self, dt: float) -> None:
        sim = self.sim
        sim.data.ctrl[0] = self.u
        n = self.c.substeps
        h = dt / n
        if sim.mocap is None:
            mujoco.mj_step(sim.model, sim.data, nstep=n)
            for _ in range(n):
                sim.time += h  # as Sim.step sums it
        else:
            for _ in range(n):
                sim.step(h)
        self.ticks += 1
        sim.check(self.ticks * dt)
        self.f_e = sim.contact_force()


def simulate_plugin(c: Coupled, run, library: str | None = None) -> dict:
    """As `simulate`, with PluginPlant: the cylinder stepped by MuJoCo through the native plugin."""
    trace, status, wall = pneuflex.run_plant(c.scene_path, run, PluginPlant(c, library))
    if isinstance(status, str):
        raise DivergedError(status)
    rows = len(trace["t"])
    return {"trace": trace, "summary": status, "wall_s": wall, "ticks": rows, "physics_steps": (rows - 1) * c.substeps}


def simulate(c: Coupled, run) -> dict:
    """Runs one of the scene's controllers (name or index) on the MuJoCo plant in the scene crate's loop
    (`pneuflex.run_plant`); returns the trace (the runner's columns), the run's summary.json content and
    `wall_s` (wall time of the loop). Raises DivergedError with the loop's reason when the run diverged
    (a MuJoCo warning raised in `advance` is one)."""
    trace, status, wall = pneuflex.run_plant(c.scene_path, run, MujocoPlant(c))
    if isinstance(status, str):
        raise DivergedError(status)
    rows = len(trace["t"])
    return {"trace": trace, "summary": status, "wall_s": wall, "ticks": rows, "physics_steps": (rows - 1) * c.substeps}


def bench_mujoco(c: Coupled, n_steps: int = 20000, force_n: float = 10.0) -> dict:
    """mj_step rate (steps/s) of the scene's model with a constant push on the flange: looped in C
    (`mj_step(nstep=...)`, MuJoCo alone) and from a Python loop (what the coupling pays per step)."""
    return bench_model(mujoco.MjModel.from_xml_string(c.xml), c.spec.x0_m, n_steps, force_n)


def bench_model(model, x0_m: float, n_steps: int, force_n: float) -> dict:
    """Steps per second of a model whose first dof is the flange, pushed with `force_n`."""
    data = mujoco.MjData(model)
    data.qpos[0] = x0_m
    data.qfrc_applied[0] = force_n
    t0 = time.perf_counter()
    mujoco.mj_step(model, data, nstep=n_steps)
    c_rate = n_steps / (time.perf_counter() - t0)
    step = mujoco.mj_step
    t0 = time.perf_counter()
    for _ in range(n_steps):
        step(model, data)
    py_rate = n_steps / (time.perf_counter() - t0)
    if any(data.warning[i].number for i in range(int(mujoco.mjtWarning.mjNWARNING))):
        raise DivergedError("MuJoCo warned during the step-rate probe")
    return {"c_loop": c_rate, "python_loop": py_rate}


def carriage_offset(t_s: float, t0_s: float, duration_s: float, from_m: float, to_m: float, retreat_m: float) -> tuple[float, float]:
    """(transverse offset, retreat along the axis) of the carriage during an environment swap, m: the same
    three legs as CarriageRig::swap_environment (retreat, slide across, come back; each a third of the duration
    with a smoothstep profile)."""
    s = min(max((t_s - t0_s) / duration_s, 0.0), 1.0)

    def smooth(u: float) -> float:
        u = min(max(u, 0.0), 1.0)
        return u * u * (3.0 - 2.0 * u)

    third = 1.0 / 3.0
    if s < third:
        return from_m, retreat_m * smooth(s / third)
    if s < 2.0 * third:
        return from_m + (to_m - from_m) * smooth((s - third) / third), retreat_m
    return to_m, retreat_m * (1.0 - smooth((s - 2.0 * third) / third))
