"""Tests of the native MuJoCo plugin `pneuflex.cylinder` (crates/mujoco-plugin, docs/mujoco-plugin.md): it loads
from the path the package gives, equals the Python coupling of the same force element bit for bit, names the key
of any bad configuration in MuJoCo's error, clamps ctrl, keeps its state in plugin_state, and loads from C.
Plain asserts; non-zero exit on failure. Run: scripts/test_python.sh (builds the bindings and the plugin first).
The closed-loop comparison on the shipped scenes is in scripts/crossval (crossval/__main__.py)."""

from __future__ import annotations

import copy
import os
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

import mujoco
import numpy as np

import pneuflex
from plain_tests import main, test

ROOT = Path(__file__).resolve().parents[3]
SHEET = str(ROOT / "pneumatics" / "paper-actuator.toml")
SHEET_PROPORTIONAL = str(ROOT / "pneumatics" / "paper-actuator-proportional.toml")
H = 1e-4  # MuJoCo step, s
SUBSTEPS = 4  # chamber substeps per step


def load_plugin() -> str:
    path = pneuflex.mujoco_plugin_path()
    mujoco.mj_loadPluginLibrary(path)
    return path


def rig(config: dict | None = None, integrator: str = "Euler", ctrlrange: str = "-1 1", plugin: bool = True,
        actuator_extra: str = "", flanges: int = 1) -> str:
    """A flange (0.6 kg, K_v 20 N s/m as joint damping) on a slide joint along x, gravity along the axis, a
    spring towards 25 mm so the flange keeps moving; with the cylinder as the plugin or (plugin=False) bare."""
    cfg = {"sheet": SHEET, "chamber_substeps": str(SUBSTEPS), "initial_p_a_pa": "300000", "initial_p_b_pa": "350000"}
    cfg.update(config or {})
    conf = "".join(f'<config key="{k}" value="{v}"/>' for k, v in cfg.items() if v is not None)
    bodies = "".join(
        f'<body name="flange{i}" pos="0 {0.1 * i} 0"><joint name="slide{i}" type="slide" axis="1 0 0" range="0 0.05"'
        f' damping="20" stiffness="300" springref="0.025"/><geom type="box" size="0.01 0.01 0.01" mass="0.6"/></body>'
        for i in range(flanges)
    )
    acts = "".join(
        f'<plugin name="cyl{i}" joint="slide{i}" plugin="pneuflex.cylinder" instance="cyl" ctrlrange="{ctrlrange}"'
        f' {actuator_extra}/>'
        for i in range(flanges)
    )
    ext = f'<extension><plugin plugin="pneuflex.cylinder"><instance name="cyl">{conf}</instance></plugin></extension>'
    return (
        f'<mujoco><option timestep="{H!r}" integrator="{integrator}" gravity="4.9 0 -8.5"/>'
        + (ext if plugin else "")
        + f"<worldbody>{bodies}</worldbody>"
        + (f"<actuator>{acts}</actuator>" if plugin else "")
        + "</mujoco>"
    )


def command(k: int) -> float:
    """A valve command that moves every 7 ms, both ways, beyond the range now and then (clamped)."""
    return 1.3 * np.sin(0.7 * (k // 70))


def plugin_run(xml: str, n: int, ctrl=command, x0: float | None = 0.02):
    m = mujoco.MjModel.from_xml_string(xml)
    d = mujoco.MjData(m)
    if x0 is not None:
        d.qpos[0] = x0
    adr = int(m.plugin_stateadr[0])
    out = np.zeros((n, 4))
    for k in range(n):
        d.ctrl[0] = ctrl(k)
        mujoco.mj_step(m, d)
        out[k] = d.qpos[0], d.actuator_force[0], d.plugin_state[adr], d.plugin_state[adr + 1]
    return out


@test
def the_package_gives_the_path_and_loading_twice_is_harmless():
    path = load_plugin()
    assert Path(path).is_file() and path.endswith("libpneuflex_mujoco.so"), path
    mujoco.mj_loadPluginLibrary(path)  # the same library again: dlopen does not register it twice
    m = mujoco.MjModel.from_xml_string(rig())
    assert m.nplugin == 1 and m.npluginstate == 11, (m.nplugin, m.npluginstate)
    # $PNEUFLEX_MUJOCO_PLUGIN naming a folder or nothing: said so, not "no such file" for a folder.
    saved = os.environ.get("PNEUFLEX_MUJOCO_PLUGIN")
    try:
        for value, error, says in ((str(Path(path).parent), IsADirectoryError, "not a file"),
                                   (path + ".gone", FileNotFoundError, "no such file")):
            os.environ["PNEUFLEX_MUJOCO_PLUGIN"] = value
            try:
                pneuflex.mujoco_plugin_path()
                raise AssertionError(f"PNEUFLEX_MUJOCO_PLUGIN={value} accepted")
            except error as e:
                assert f"PNEUFLEX_MUJOCO_PLUGIN={value}: {says}" in str(e), e
    finally:
        if saved is None:
            os.environ.pop("PNEUFLEX_MUJOCO_PLUGIN", None)
        else:
            os.environ["PNEUFLEX_MUJOCO_PLUGIN"] = saved


@test
def the_plugin_equals_the_python_coupling_bit_for_bit():
    """The same model stepped with the force element coupled from Python (crossval/couple.py's way:
    F = ForceElement.step(x, x_dot, u, h), qfrc_applied = F - friction(x_dot, F), mj_step) and with the plugin:
    every position, force and pressure equal, under each integrator the plugin accepts."""
    load_plugin()
    n = 5000
    act = pneuflex.Actuator(SHEET)
    for integrator in ("Euler", "implicit", "implicitfast", "discrete"):
        m = mujoco.MjModel.from_xml_string(rig(integrator=integrator, plugin=False))
        d = mujoco.MjData(m)
        d.qpos[0] = 0.02
        fe = pneuflex.ForceElement(act, p_a=3e5, p_b=3.5e5, substeps=SUBSTEPS)
        ref = np.zeros((n, 4))
        for k in range(n):
            x, v = d.qpos[0], d.qvel[0]
            f = fe.step(x, v, float(np.clip(command(k), -1, 1)), H)
            d.qfrc_applied[0] = f - fe.friction_force(v, f)
            mujoco.mj_step(m, d)
            ref[k] = d.qpos[0], d.qfrc_applied[0], fe.p_a, fe.p_b
        got = plugin_run(rig(integrator=integrator), n)
        assert np.array_equal(got, ref), (integrator, np.max(np.abs(got - ref), axis=0))
        # Not a trivial run: the flange travelled and both chambers swung by > 50 kPa.
        assert np.ptp(got[:, 0]) > 5e-3 and np.ptp(got[:, 2]) > 5e4 and np.ptp(got[:, 3]) > 5e4, np.ptp(got, axis=0)


def load_error(xml: str) -> str:
    try:
        mujoco.MjModel.from_xml_string(xml)
    except ValueError as e:
        return str(e)
    raise AssertionError("the model loaded")


@test
def bad_configuration_is_a_mujoco_error_naming_the_key():
    """Each bad value is the ValueError of MjModel.from_xml_string, whose text names the instance, the key and
    what is wrong (init's mju_error: not MuJoCo's bare "plugin->init failed for plugin id 0")."""
    load_plugin()
    cases = [
        ({"cylinder.bore_m": "-3"}, "config key 'cylinder.bore_m': must be"),
        ({"cylinder.bore_m": "16 mm"}, "config key 'cylinder.bore_m': expected a number"),
        ({"valve.kind": "magic"}, "config key 'valve.kind'"),
        ({"supply.pressure_abs_pa": "1e12"}, "config key 'supply.pressure_abs_pa'"),
        ({"chamber_substeps": "0"}, "config key 'chamber_substeps'"),
        ({"initial_p_a_pa": "-1"}, "config key 'initial_p_a_pa'"),
        # Beyond any chamber or gas: an infinite force on the first step, or a meaningless one.
        ({"initial_p_b_pa": "1e300"}, "config key 'initial_p_b_pa': expected an absolute pressure in [1e3, 1e7] Pa"),
        ({"initial_p_a_pa": "1e-300"}, "config key 'initial_p_a_pa': expected an absolute pressure"),
        ({"initial_temperature_k": "1000"}, "config key 'initial_temperature_k': expected a temperature in [200, 400] K"),
        ({"cylinder.bore_m": "nan"}, "config key 'cylinder.bore_m': must be a finite number, got NaN"),
        ({"mechanics.friction": "stick_slip"}, "config key 'mechanics.friction'"),
        ({"sheet": None}, "config key 'sheet': required"),
        ({"sheet": "/no/such/sheet.toml"}, "config key 'sheet': /no/such/sheet.toml"),
        # MuJoCo gives a plugin no model folder: a relative sheet says where it was looked for.
        ({"sheet": "no/such/sheet.toml"}, f"(a relative sheet is read from the working directory, {os.getcwd()},"),
        # A key the plugin does not declare: MuJoCo's compiler names it.
        ({"cylinder.bore": "0.016"}, "unrecognized attribute 'plugin:cylinder.bore'"),
        ({"mechanics.moving_mass_kg": "1"}, "unrecognized attribute 'plugin:mechanics.moving_mass_kg'"),
    ]
    for cfg, says in cases:
        e = load_error(rig(cfg))
        assert says in e, (cfg, e)
        if "config key" in says:
            assert "pneuflex.cylinder: instance 'cyl'" in e and "init failed" not in e, e
    # A configured instance no actuator names (a forgotten instance= on the actuator) was a silent no-op.
    spare = f'<instance name="spare"><config key="sheet" value="{SHEET}"/></instance></plugin>'
    e = load_error(rig().replace("</instance></plugin>", "</instance>" + spare))
    assert "pneuflex.cylinder: instance 'spare': drives no actuator" in e, e
    e = load_error(rig(integrator="RK4"))
    assert "integrator=\"RK4\" is not supported" in e and "init failed" not in e, e
    # Each case left MuJoCo working: a good model still loads and steps.
    assert plugin_run(rig(), 10).shape == (10, 4)


# A bad model loaded in a fresh process (its own working directory): what it prints and what it leaves there.
LOAD_IN_A_CHILD = """
import sys
import mujoco
mujoco.mj_loadPluginLibrary(sys.argv[1])
try:
    mujoco.MjModel.from_xml_string(sys.stdin.read())
except ValueError as e:
    print("refused:", str(e).replace(chr(10), " | "))
"""


@test
def a_load_error_prints_nothing_and_leaves_no_log_file():
    """The reason is in the exception only: nothing on stdout or stderr (a warning would print there), and no
    MUJOCO_LOG.TXT in the working directory (MuJoCo's default warning handler appends to one)."""
    path = load_plugin()
    with tempfile.TemporaryDirectory() as tmp:
        r = subprocess.run([sys.executable, "-c", LOAD_IN_A_CHILD, path], input=rig({"cylinder.bore_m": "-3"}),
                           capture_output=True, text=True, cwd=tmp, timeout=120)
        assert r.returncode == 0, (r.returncode, r.stdout, r.stderr)
        assert r.stdout == ("refused: Error: engine error: pneuflex.cylinder: instance 'cyl': config key "
                            "'cylinder.bore_m': must be > 0, got -3\n"), r.stdout
        assert r.stderr == "", r.stderr
        assert os.listdir(tmp) == [], os.listdir(tmp)


@test
def an_mjdata_whose_sheet_is_gone_is_an_error_naming_the_key():
    """init runs again for every MjData: a sheet deleted after the model loaded makes MjData(model) raise
    mujoco.FatalError naming the key and the file (it was "plugin->init failed for plugin id 0", the reason on
    stdout); MuJoCo goes on working afterwards."""
    load_plugin()
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp) / "pneumatics"
        shutil.copytree(Path(SHEET).parent, folder)
        sheet = folder / Path(SHEET).name
        m = mujoco.MjModel.from_xml_string(rig({"sheet": str(sheet)}))
        sheet.unlink()
        try:
            mujoco.MjData(m)
            raise AssertionError("an MjData was made without its sheet")
        except mujoco.FatalError as e:
            text = str(e)
        assert text.startswith(f"pneuflex.cylinder: instance 'cyl': config key 'sheet': {sheet}: cannot read"), text
    assert plugin_run(rig(), 10).shape == (10, 4)


@test
def ctrl_is_clamped_to_ctrlrange():
    load_plugin()
    n = 600
    wide = plugin_run(rig(), n, ctrl=lambda k: 5.0)
    one = plugin_run(rig(), n, ctrl=lambda k: 1.0)
    assert np.array_equal(wide, one), "ctrl beyond ctrlrange must act as its end"
    half = plugin_run(rig(ctrlrange="-0.5 0.5"), n, ctrl=lambda k: 1.0)
    half_ref = plugin_run(rig(ctrlrange="-1 1"), n, ctrl=lambda k: 0.5)
    assert np.array_equal(half, half_ref) and not np.array_equal(half, one)


@test
def the_state_lives_in_plugin_state():
    """Reset restores the configured chambers, a copied MjData continues identically, two MjData are
    independent, a disabled actuator group gives no force, and impossible numbers written into plugin_state
    give a zero force and no crash."""
    load_plugin()
    m = mujoco.MjModel.from_xml_string(rig({"initial_temperature_k": "300"}))
    d = mujoco.MjData(m)
    s0 = d.plugin_state.copy()
    assert s0[0] == 3e5 and s0[1] == 3.5e5 and s0[2] == 300.0 and s0[3] == 300.0, s0
    d.ctrl[0] = 0.7
    mujoco.mj_step(m, d, nstep=300)
    assert not np.array_equal(d.plugin_state, s0)
    d2 = copy.copy(d)
    other = mujoco.MjData(m)
    mujoco.mj_step(m, d, nstep=200)
    mujoco.mj_step(m, d2, nstep=200)
    assert np.array_equal(d.plugin_state, d2.plugin_state) and d.qpos[0] == d2.qpos[0]
    assert np.array_equal(other.plugin_state, s0), "another MjData's state moved"
    mujoco.mj_resetData(m, d)
    assert np.array_equal(d.plugin_state, s0)
    d.ctrl[0] = 1.0
    mujoco.mj_step(m, d, nstep=50)
    assert d.actuator_force[0] != 0.0
    m.opt.disableactuator = 1 << int(m.actuator_group[0])
    mujoco.mj_step(m, d)
    assert d.actuator_force[0] == 0.0
    m.opt.disableactuator = 0
    d.plugin_state[0] = -1.0  # a negative pressure: refused, force 0, state held
    held = d.plugin_state.copy()
    mujoco.mj_step(m, d, nstep=5)
    assert d.actuator_force[0] == 0.0 and np.array_equal(d.plugin_state, held)
    mujoco.mj_resetData(m, d)
    mujoco.mj_step(m, d)
    assert d.actuator_force[0] != 0.0 and np.isfinite(d.plugin_state).all()


@test
def several_actuators_share_an_instance_each_with_its_state():
    """Two flanges on one instance: 22 numbers of plugin_state, each cylinder as it runs alone. An implicit
    instance (config on the actuator) and inline values work as well."""
    load_plugin()
    m = mujoco.MjModel.from_xml_string(rig(flanges=2))
    assert m.npluginstate == 22
    d = mujoco.MjData(m)
    d.qpos[:] = 0.02
    alone = plugin_run(rig(), 400, ctrl=lambda k: 0.6)
    for _ in range(400):
        d.ctrl[:] = 0.6, -0.4
        mujoco.mj_step(m, d)
    assert d.plugin_state[0] == alone[-1, 2] and d.plugin_state[1] == alone[-1, 3] and d.qpos[0] == alone[-1, 0]
    assert d.plugin_state[11] != d.plugin_state[0]
    xml = (
        f'<mujoco><option timestep="{H!r}"/><extension><plugin plugin="pneuflex.cylinder"/></extension><worldbody>'
        '<body><joint name="s" type="slide" axis="1 0 0" range="0 0.05"/><geom type="box" size=".01 .01 .01" mass=".6"/>'
        '</body></worldbody><actuator><plugin name="c" joint="s" plugin="pneuflex.cylinder" ctrlrange="-1 1">'
        f'<config key="sheet" value="{SHEET_PROPORTIONAL}"/><config key="valve.response_time_s" value="0.002"/>'
        "</plugin></actuator></mujoco>"
    )
    m = mujoco.MjModel.from_xml_string(xml)
    d = mujoco.MjData(m)
    d.ctrl[0] = 1.0
    mujoco.mj_step(m, d, nstep=200)
    assert d.plugin_state[4] > 0.99, d.plugin_state[:5]  # the spool followed u = 1 with its 2 ms lag
    e = load_error(xml.replace('value="0.002"', 'value="-1"'))
    assert "pneuflex.cylinder: actuator 'c': config key 'valve.response_time_s'" in e, e


def pressure_rig(config: dict | None = None, ctrlrange: str = "101325 601325", second: bool = True) -> str:
    """rig() under command="pressure": the flange's cylinder takes two actuators, chamber A's set-point (named
    cyl0, carrying the force) and chamber B's (named b)."""
    cfg = {"command": "pressure", "regulator.time_constant_s": "0.02"}
    cfg.update(config or {})
    xml = rig(cfg, ctrlrange=ctrlrange)
    if second:
        xml = xml.replace("</actuator>", f'<plugin name="b" joint="slide0" plugin="pneuflex.cylinder" instance="cyl" '
                                         f'ctrlrange="{ctrlrange}"/></actuator>')
    return xml


@test
def the_pressure_command_follows_its_set_points():
    """command="pressure": each cylinder takes two actuators, chamber A's set-point then chamber B's (Pa absolute),
    and keeps 11 numbers of plugin_state. With the flange moving, each chamber follows the regulator's first-order
    law, p_set + (p0 - p_set) e^(-t/tau) (tau = regulator.time_constant_s, the flow within the valve's limit), to
    1e-3 Pa, then holds its set-point (to 1 Pa: MuJoCo's flange does not move exactly as the element's step assumes
    between steps); the first actuator's force is then p_a A_a - p_b A_b - p_atm A_rod minus the
    sheet's friction 0.6 tanh(v / 2 mm/s) at the step's velocity (bore, rod, friction from the sheets, to 1e-6 N),
    the second's 0; the valve's spool stays at rest. A set-point beyond ctrlrange is clamped to it (MuJoCo itself
    zeroes every ctrl when one is NaN, its BADCTRL warning: the set-points then fall to ctrlrange's low end)."""
    import math
    import tomllib

    load_plugin()
    d0 = ROOT / "pneumatics"
    act = tomllib.loads((d0 / "paper-actuator.toml").read_text())
    cyl = tomllib.loads((d0 / act["components"]["cylinder"]).read_text())["cylinder"]
    a_a, a_rod = math.pi / 4 * cyl["bore_m"] ** 2, math.pi / 4 * cyl["rod_m"] ** 2
    a_b, p_atm = a_a - a_rod, 101325.0
    coulomb, v_s = act["mechanics"]["coulomb_n"], act["mechanics"]["smooth_velocity_m_per_s"]
    m = mujoco.MjModel.from_xml_string(pressure_rig())
    assert m.nu == 2 and int(m.plugin_statenum[0]) == 11, (m.nu, m.plugin_statenum)
    d = mujoco.MjData(m)
    d.qpos[0] = 0.02
    p0, ps, tau = np.array([3.0e5, 3.5e5]), np.array([2.5e5, 4.0e5]), 0.02
    d.ctrl[:] = ps
    worst = 0.0
    for k in range(1, 3001):  # 0.3 s = 15 tau
        mujoco.mj_step(m, d)
        want = ps + (p0 - ps) * math.exp(-k * H / tau)
        worst = max(worst, float(np.max(np.abs(d.plugin_state[:2] - want))))
    assert worst < 1e-3, worst
    assert abs(d.qpos[0] - 0.02) > 1e-3, d.qpos[0]  # the flange moved meanwhile
    for _ in range(200):
        v = d.qvel[0]
        mujoco.mj_step(m, d)
        p_a, p_b = d.plugin_state[:2]
        hand = p_a * a_a - p_b * a_b - p_atm * a_rod - coulomb * math.tanh(v / v_s)
        assert abs(d.actuator_force[0] - hand) < 1e-6 and d.actuator_force[1] == 0.0, (d.actuator_force, hand)
    assert np.allclose(d.plugin_state[:2], ps, rtol=0, atol=1.0) and d.plugin_state[4] == 0.0, d.plugin_state[:5]
    # Beyond ctrlrange: clamped to it, bit for bit the run at the bound.
    runs = []
    for ctrl in ([9e5, 5e4], [601325.0, 101325.0]):
        d = mujoco.MjData(m)
        d.ctrl[:] = ctrl
        mujoco.mj_step(m, d, nstep=300)
        runs.append(d.plugin_state[:4].copy())
    assert np.array_equal(*runs), runs


@test
def the_shipped_pressure_mjcf_and_its_errors():
    """pneuflex.mjcf("cylinder-pressure") loads from any directory and holds its set-points (1 s); a pressure
    instance with one actuator, an unknown command, a regulator time constant with the valve command or out of
    range are load errors naming the key."""
    load_plugin()
    m = mujoco.MjModel.from_xml_string(pneuflex.mjcf("cylinder-pressure"))
    d = mujoco.MjData(m)
    d.ctrl[:] = [2.6e5, 2.4e5]
    mujoco.mj_step(m, d, nstep=10000)
    assert np.allclose(d.plugin_state[:2], [2.6e5, 2.4e5], rtol=0, atol=1e-3), d.plugin_state[:2]
    assert d.sensor("cylinder_force").data[0] > 6.0 and d.actuator_force[1] == 0.0
    cases = [
        (pressure_rig(second=False), "command=\"pressure\" takes two actuators per cylinder"),
        (pressure_rig({"command": "torque"}), "config key 'command': expected \"valve\""),
        (rig({"regulator.time_constant_s": "0.01"}), "config key 'regulator.time_constant_s': the regulators replace"),
        (pressure_rig({"regulator.time_constant_s": "0"}), "config key 'regulator.time_constant_s': the regulator's "
                                                          "time constant must be in [1e-5, 10] s, got 0"),
    ]
    for xml, says in cases:
        e = load_error(xml)
        assert says in e and "pneuflex.cylinder: instance 'cyl'" in e, (says, e)


@test
def the_documented_mjcf_loads_and_pushes():
    """docs/mujoco-plugin.md's complete MJCF, as written (its relative sheet from the repository root), is the
    package's pneuflex/mjcf/cylinder.xml: it loads, starts from its inline chamber B pressure, and under u = 0.5
    the rod extends onto the wall and presses it."""
    load_plugin()
    text = (ROOT / "docs" / "mujoco-plugin.md").read_text()
    xml = text.split("## A complete MJCF", 1)[1].split("```xml\n", 1)[1].split("```", 1)[0]
    assert xml == (Path(pneuflex.__file__).parent / "mjcf" / "cylinder.xml").read_text()
    cwd = os.getcwd()
    try:
        os.chdir(ROOT)
        m = mujoco.MjModel.from_xml_string(xml)
    finally:
        os.chdir(cwd)
    d = mujoco.MjData(m)
    assert d.plugin_state[1] == 351325.0, d.plugin_state[:2]
    d.ctrl[0] = 0.5
    mujoco.mj_step(m, d, nstep=5000)  # 0.5 s
    rod, wall = m.joint("extension").qposadr[0], m.joint("mount").qposadr[0]
    assert d.qpos[rod] > 0.02 and d.qpos[wall] > 1e-4, (d.qpos[rod], d.qpos[wall])
    assert d.sensor("cylinder_force").data[0] > 1.0, d.sensor("cylinder_force").data


@test
def a_shipped_mjcf_keeps_its_stroke():
    """pneuflex.mjcf("cylinder") (the package's MJCF, its sheet inside the package) loads from any directory; full
    supply both ways (1.5 s at u = +1, then -1, with and without the wall) keeps the piston within the sheet's
    stroke [0, 50 mm] (hard end stops: a limited joint, stiff solreflimit, 0.3 mm margin); the same model without
    the margin passes the stroke (0.2 mm), so the check can fail."""
    load_plugin()
    stroke = pneuflex.Actuator(SHEET).params()["stroke_m"]
    assert stroke == 0.05, stroke

    def extremes(xml: str, wall: bool) -> tuple[float, float]:
        if not wall:
            xml = xml.replace('stiffness="700"', 'stiffness="0"').replace('pos="0.04 0 0"', 'pos="0.5 0 0"')
        m = mujoco.MjModel.from_xml_string(xml)
        d = mujoco.MjData(m)
        x = []
        for u in (1.0, -1.0):
            d.ctrl[0] = u
            for _ in range(15000):
                mujoco.mj_step(m, d)
                x.append(d.qpos[m.joint("extension").qposadr[0]])
        return min(x), max(x)

    cwd = os.getcwd()
    with tempfile.TemporaryDirectory() as tmp:
        os.chdir(tmp)
        try:
            xml = pneuflex.mjcf("cylinder")
            for wall in (True, False):
                lo, hi = extremes(xml, wall)
                assert 0 <= lo and hi <= stroke and hi > stroke - 1e-3, (wall, lo, hi)
            lo, hi = extremes(xml.replace(' margin="0.0003"', ""), wall=False)
            assert hi > stroke, hi
        finally:
            os.chdir(cwd)
    try:
        pneuflex.mjcf("cylinders")
    except FileNotFoundError as e:
        assert "no shipped MJCF 'cylinders'; the shipped ones are cylinder" in str(e), e
    else:
        raise AssertionError("an unknown MJCF name was accepted")


@test
def a_c_host_loads_the_plugin():
    """crates/mujoco-plugin/tests/host.c, compiled against the wheel's headers and libmujoco.so.4.0.0: the
    plugin registers (its functions found in the host's libmujoco), steps as from Python, and a bad key is
    the load error."""
    cc = shutil.which(os.environ.get("CC", "cc")) or shutil.which("gcc")
    assert cc, "no C compiler (cc) to build the C host"
    mj = Path(mujoco.__file__).parent
    path = pneuflex.mujoco_plugin_path()
    with tempfile.TemporaryDirectory() as tmp:
        host = Path(tmp) / "host"
        subprocess.run([cc, "-I", str(mj / "include"), str(ROOT / "crates/mujoco-plugin/tests/host.c"), "-o", str(host),
                        "-L", str(mj), "-l:libmujoco.so.4.0.0", f"-Wl,-rpath,{mj}"], check=True)
        good, bad = Path(tmp) / "good.xml", Path(tmp) / "bad.xml"
        good.write_text(rig())
        bad.write_text(rig({"valve.critical_pressure_ratio": "1.5"}))
        r = subprocess.run([str(host), path, str(good), "300", "0.4"], capture_output=True, text=True, timeout=60)
        assert r.returncode == 0 and r.stdout.startswith("ok "), (r.returncode, r.stdout, r.stderr)
        vals = dict(kv.split("=") for kv in r.stdout.split()[1:])
        py = plugin_run(rig(), 300, ctrl=lambda k: 0.4, x0=None)[-1]  # the host starts at qpos0
        # The same library on the same model: the same numbers (printed with 17 digits).
        assert float(vals["force"]) == py[1] and float(vals["p_a"]) == py[2] and float(vals["p_b"]) == py[3], (vals, py)
        r = subprocess.run([str(host), path, str(bad), "1", "0"], capture_output=True, text=True, timeout=60,
                           cwd=tmp)
        # The key and the reason in mj_loadXML's error buffer, which the host prints; nothing else printed.
        assert r.returncode == 2 and r.stdout.startswith(
            "load error: Error: engine error: pneuflex.cylinder: instance 'cyl': config key "
            "'valve.critical_pressure_ratio': must be in [0, 1), got 1.5"), (r.returncode, r.stdout, r.stderr)
        assert r.stdout.count("\n") == 1 and r.stderr == "", (r.stdout, r.stderr)


if __name__ == "__main__":
    sys.exit(main())
