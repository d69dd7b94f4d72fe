"""Tests of the native MuJoCo plugin `pneuflex.muscle` (crates/mujoco-plugin src/muscle.rs, docs/mujoco-plugin.md
"pneuflex.muscle"): the McKibben muscle of crates/muscle on a spatial tendon. It registers beside
`pneuflex.cylinder` from the same library; a muscle held at a length and filled from the supply pulls the
closed-form force (M5) of its sheet; it pulls along its tendon (the antagonist elbow turns towards the filled
muscle); a bad configuration is MuJoCo's error naming the key. Its step equals the engine's muscle element bit
for bit (the Rust test `muscle::tests::a_step_is_the_engines_muscle_element_step`); the closed loop against
the engine is scripts/crossval on scenes/antagonist.toml (crossval/mechanism.py). Plain asserts; non-zero exit
on failure. Run: scripts/test_python.sh."""

from __future__ import annotations

import math
import sys
import tomllib
from pathlib import Path

import mujoco
import numpy as np

import pneuflex
from plain_tests import main, test

ROOT = Path(__file__).resolve().parents[3]
SHEET = ROOT / "pneumatics" / "festo-dmsp-10-muscle.toml"
H = 1e-4


def load_plugin() -> None:
    mujoco.mj_loadPluginLibrary(pneuflex.mujoco_plugin_path())


def held(length_m: float, config: dict | None = None, integrator: str = "implicitfast") -> str:
    """A muscle on a tendon between two world sites `length_m` apart: its length is held, its rate 0."""
    cfg = {"sheet": str(SHEET), "chamber_substeps": "2"}
    cfg.update(config or {})
    conf = "".join(f'<config key="{k}" value="{v}"/>' for k, v in cfg.items() if v is not None)
    return (
        f'<mujoco><option timestep="{H!r}" integrator="{integrator}"/>'
        f'<extension><plugin plugin="pneuflex.muscle"><instance name="m">{conf}</instance></plugin></extension>'
        f'<worldbody><site name="a" pos="0 0 0"/><site name="b" pos="{length_m!r} 0 0"/>'
        '<body name="dummy"><joint type="slide" axis="0 0 1"/><geom type="sphere" size="0.01" mass="0.1"/></body>'
        "</worldbody>"
        '<tendon><spatial name="t"><site site="a"/><site site="b"/></spatial></tendon>'
        '<actuator><plugin name="muscle" tendon="t" plugin="pneuflex.muscle" instance="m" ctrlrange="-1 1"/></actuator>'
        "</mujoco>"
    )


def closed_form_tension(p_gauge: float, length_m: float) -> float:
    """(M5)/(M6) from the sheet's catalogue numbers, written out here: r0 = D/2, a = 3/tan^2 a0,
    b = 1/sin^2 a0, k from the largest contraction eps_max = (1 - 1/(sqrt 3 cos a0)) / k."""
    s = tomllib.loads(SHEET.read_text())["muscle"]
    a0 = math.radians(s["braid_angle_deg"])
    k = (1 - 1 / (math.sqrt(3) * math.cos(a0))) / s["max_contraction"]
    r0 = s["nominal_diameter_m"] / 2
    eps = 1 - length_m / s["rest_length_m"]
    return math.pi * r0**2 * p_gauge * (3 / math.tan(a0) ** 2 * (1 - k * eps) ** 2 - 1 / math.sin(a0) ** 2)


@test
def it_registers_beside_the_cylinder_with_its_state():
    load_plugin()
    m = mujoco.MjModel.from_xml_string(held(0.18))
    d = mujoco.MjData(m)
    # p, T, the valve's 6 numbers, the clock; unpressurised at the sheet's atmosphere at reset.
    assert m.plugin_statenum[0] == 9, m.plugin_statenum
    assert d.plugin_state[0] == 101325.0 and d.plugin_state[1] == 293.15, d.plugin_state[:2]
    mujoco.mj_step(m, d)
    # At u = 0 the proportional valve's underlap leaks both ways: a first step pulls next to nothing.
    assert abs(d.actuator_force[0]) < 0.1, d.actuator_force
    # The same library registered the cylinder.
    cyl = (
        '<mujoco><extension><plugin plugin="pneuflex.cylinder"><instance name="c">'
        f'<config key="sheet" value="{ROOT / "pneumatics" / "paper-actuator.toml"}"/></instance></plugin></extension>'
        '<worldbody><body><joint name="s" type="slide" range="0 0.05"/><geom type="box" size="0.01 0.01 0.01" mass="0.6"/></body></worldbody>'
        '<actuator><plugin joint="s" plugin="pneuflex.cylinder" instance="c" ctrlrange="-1 1"/></actuator></mujoco>'
    )
    assert mujoco.MjModel.from_xml_string(cyl).plugin_statenum[0] == 11


@test
def a_held_muscle_filled_from_the_supply_pulls_the_closed_form_force():
    """Held at 10 % and 20 % contraction, u = +1 for 1.5 s: the pressure reaches the supply's and the force is
    -(M5) at the supply's gauge pressure (no friction at rest, no stretch below L0), to 1e-9 relative."""
    load_plugin()
    for length in (0.18, 0.16):
        m = mujoco.MjModel.from_xml_string(held(length))
        d = mujoco.MjData(m)
        d.ctrl[0] = 1.0
        mujoco.mj_step(m, d, nstep=15000)
        p = float(d.plugin_state[0])
        assert abs(p - 601325.0) < 1.0, p
        mujoco.mj_step(m, d)
        want = closed_form_tension(float(d.plugin_state[0]) - 101325.0, length)
        got = -float(d.actuator_force[0])
        assert abs(got - want) < 1e-9 * want, (length, got, want)
        # Vented again (u = -1): back to the atmosphere, no force.
        d.ctrl[0] = -1.0
        mujoco.mj_step(m, d, nstep=15000)
        assert abs(float(d.plugin_state[0]) - 101325.0) < 1.0 and abs(d.actuator_force[0]) < 1e-3, (d.plugin_state[0], d.actuator_force)


@test
def it_pulls_along_its_tendon_the_antagonist_elbow_turns_towards_the_filled_muscle():
    """The antagonist scene's MJCF (crossval/mechanism.py): the flexor filled alone turns the arm towards
    +angle (its tendon shortens), the extensor alone towards -angle."""
    load_plugin()
    sys.path.insert(0, str(ROOT))
    from crossval import mechanism

    scene = ROOT / "scenes" / "antagonist.toml"
    doc = tomllib.loads(scene.read_text())
    for filled, sign in ((0, 1.0), (1, -1.0)):
        mm = mechanism.MujocoMechanism(scene, doc, 10)
        mm.d.ctrl[mm.act_ids[filled]] = 1.0
        mm.d.ctrl[mm.act_ids[1 - filled]] = -1.0
        l0 = float(mm.d.ten_length[mm.acts[filled][1]])
        mujoco.mj_step(mm.m, mm.d, nstep=3000)
        q = float(mm.d.qpos[0])
        assert sign * q > 0.05, (filled, q)
        assert float(mm.d.ten_length[mm.acts[filled][1]]) < l0
        assert mm.d.actuator_force[mm.act_ids[filled]] < -10.0


@test
def bad_configuration_is_a_mujoco_error_naming_the_key():
    load_plugin()
    cases = [
        ({"sheet": None}, "config key 'sheet': required"),
        ({"sheet": str(ROOT / "pneumatics" / "paper-actuator.toml")}, "config key 'sheet': "),
        ({"sheet": "no/such-muscle.toml"}, "(a relative sheet is read from the working directory"),
        ({"chamber_substeps": "0"}, "config key 'chamber_substeps'"),
        ({"initial_pressure_pa": "1e300"}, "config key 'initial_pressure_pa': expected an absolute pressure"),
        ({"initial_temperature_k": "1000"}, "config key 'initial_temperature_k'"),
        ({"muscle.rest_length_m": "0.3"}, "unrecognized attribute 'plugin:muscle.rest_length_m'"),
    ]
    for cfg, says in cases:
        try:
            mujoco.MjModel.from_xml_string(held(0.18, cfg))
        except ValueError as e:
            text = str(e)
        else:
            raise AssertionError(f"{cfg}: loaded")
        assert says in text, (cfg, text)
        if "config key" in says:
            assert "pneuflex.muscle: instance 'm'" in text and "init failed" not in text, text
    try:
        mujoco.MjModel.from_xml_string(held(0.18, integrator="RK4"))
    except ValueError as e:
        assert 'integrator="RK4" is not supported' in str(e), e
    else:
        raise AssertionError("RK4 loaded")
    # A good model still loads and steps after the errors.
    m = mujoco.MjModel.from_xml_string(held(0.18))
    mujoco.mj_step(m, mujoco.MjData(m))


if __name__ == "__main__":
    sys.exit(main())
