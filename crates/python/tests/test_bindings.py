"""Tests of the pneuflex Python bindings and of the MuJoCo equivalent model (plain asserts; non-zero exit on
failure). Run: scripts/test_python.sh (installs the bindings into .venv first)."""

from __future__ import annotations

import functools
import math
import os
import sys
import tempfile
from pathlib import Path

import numpy as np

import pneuflex
from plain_tests import main, test

ROOT = Path(__file__).resolve().parents[3]
sys.path.insert(0, str(ROOT))
SCENE = str(ROOT / "scenes" / "paper-fig3.toml")
SHEET = str(ROOT / "pneumatics" / "paper-actuator.toml")


@test
def force_element_equals_one_dof_at_the_stop():
    """Pinned at the retracted stop (u = -1 pushes the piston into it, x = x_dot = 0), the 1-DOF RK4 step and
    the force element integrate the same chamber equations along the same (still) piston: same pressures."""
    a = pneuflex.Actuator(SHEET, alpha_deg=0.0)
    od = pneuflex.OneDof(a, 0.0, p_a=2.0e5, p_b=3.0e5)
    fe = pneuflex.ForceElement(a, p_a=2.0e5, p_b=3.0e5, substeps=1)
    for _ in range(2000):
        od.step(-1.0, 0.0, 1e-4)
        fe.step(0.0, 0.0, -1.0, 1e-4)
        assert od.x == 0.0 and od.x_dot == 0.0, (od.x, od.x_dot)
    assert abs(od.p_a - fe.p_a) <= 1e-9 * od.p_a, (od.p_a, fe.p_a)
    assert abs(od.p_b - fe.p_b) <= 1e-9 * od.p_b, (od.p_b, fe.p_b)
    assert abs(od.piston_force() - fe.force()) < 1e-9
    # The valve drove B towards supply and A towards atmosphere: the chambers really moved.
    assert fe.p_b > 5.5e5 and fe.p_a < 1.2e5, (fe.p_a, fe.p_b)


@test
def force_element_with_euler_mechanics_tracks_one_dof():
    """Free motion (no contact) under a steady command: the force element coupled to a semi-implicit Euler
    integration of eq. (1) in Python follows the 1-DOF RK4 model (a different integrator of the same ODE)."""
    a = pneuflex.Actuator(SHEET)
    p = a.params()
    m, kv, g = p["moving_mass_kg"], p["viscous_n_s_per_m"], a.gravity_force()
    od = pneuflex.OneDof(a, 0.01)
    fe = pneuflex.ForceElement(a, p_a=od.p_a, p_b=od.p_b, substeps=1)
    x, v, h = 0.01, 0.0, 1e-5
    worst = 0.0
    for k in range(30000):  # 0.3 s
        u = 0.2 if k < 15000 else -0.2
        od.step(u, 0.0, h)
        f = fe.step(x, v, u, h)
        acc = (f + g - fe.friction_force(v, f + g) - kv * v) / m
        v += h * acc
        x += h * v
        if x <= 0.0 or x >= p["stroke_m"]:  # inelastic end stops, as OneDof
            x, v = min(max(x, 0.0), p["stroke_m"]), 0.0
        worst = max(worst, abs(x - od.x))
    assert od.x > 0.011 or od.x < 0.009, "the flange must have moved"
    assert worst < 5e-5, f"largest |x_euler - x_rk4| = {worst} m"
    assert abs(fe.p_a - od.p_a) < 2e-3 * od.p_a, (fe.p_a, od.p_a)


@test
def piston_and_gravity_forces_closed_form():
    a = pneuflex.Actuator(SHEET, alpha_deg=30.0)
    p = a.params()
    sa = math.pi / 4 * p["bore_m"] ** 2
    sr = math.pi / 4 * p["rod_m"] ** 2
    want = 4e5 * sa - 3e5 * (sa - sr) - p["atmosphere_pressure_pa"] * sr
    assert abs(a.piston_force(4e5, 3e5) - want) < 1e-9 * abs(want) + 1e-12
    assert abs(a.gravity_force() - p["moving_mass_kg"] * p["gravity_m_per_s2"] * 0.5) < 1e-12
    tf = a.transfer_function()
    a3, a2, a1, _ = tf["den"]
    assert abs(tf["omega_n"] - math.sqrt(a1 / a3)) < 1e-9 * tf["omega_n"]
    assert abs(tf["k_n"] - tf["num"] / a1) < 1e-12 * abs(tf["k_n"])
    assert 0.0 < tf["operating_point"]["x_m"] < p["stroke_m"]


@test
def impedance_filter_matches_closed_form():
    """With k_d = 0 and a constant force error e, eq. (19) gives x_f(t) = e/b (t - m/b (1 - exp(-b t / m)))."""
    m, b, e, dt = 2.0, 52.4, 3.0, 1e-3
    c = pneuflex.Controller("impedance", {"m_d_kg": m, "b_d_ns_per_m": b, "k_d_n_per_m": 0.0}, {"kp_per_m": 100.0})
    for k in range(500):
        u = c.update(k * dt, 0.0, 0.0, 10.0 - e, 3e5, 3e5, 10.0, 0.0, dt)
    t = 500 * dt
    want = e / b * (t - m / b * (1.0 - math.exp(-b * t / m)))
    tel = c.telemetry()
    assert abs(tel["x_f"] - want) < 1e-9, (tel["x_f"], want)
    assert abs(tel["x_r"] - want) < 1e-9 and tel["e"] == e
    assert abs(u - min(1.0, 100.0 * want)) < 1e-9


@test
def controller_from_dicts_equals_from_scene():
    scene = pneuflex.load_scene(SCENE)
    run = next(r for r in scene["runs"] if r["controller"] == "adaptive")
    c1 = pneuflex.Controller("adaptive", run["impedance"], run["inner"], run["adaptive"])
    c2 = pneuflex.Controller.from_scene(SCENE, run["name"])
    rng = np.random.default_rng(1)
    for k in range(300):
        s = (k * 1e-3, 0.02 + 1e-3 * rng.standard_normal(), 0.01 * rng.standard_normal(), 10 + rng.standard_normal(), 3e5, 3e5, 10.0, 0.02, 1e-3)
        assert c1.update(*s) == c2.update(*s)
    assert c1.telemetry() == c2.telemetry() and c1.kind == "adaptive"


@test
def run_returns_traces_and_summarize_reproduces_the_runner_metrics():
    traces, summary, wall = pneuflex.run_with_summary(SCENE)
    scene = pneuflex.load_scene(SCENE)
    assert set(traces) == {r["name"] for r in scene["runs"]}
    for name, tr in traces.items():
        assert len(tr["t"]) == scene["n_steps"] + 1 and tr["f_e"].dtype == np.float64
        assert abs(tr["t"][-1] - scene["duration_s"]) < 1e-9
    again = pneuflex.summarize(SCENE, {k: dict(v) for k, v in traces.items()})
    assert [r["windows"] for r in again["runs"]] == [r["windows"] for r in summary["runs"]]
    # run() and run_with_summary() are the same deterministic runner.
    plain = pneuflex.run(SCENE)
    for name in traces:
        assert np.array_equal(plain[name]["f_e"], traces[name]["f_e"])


@test
def run_gives_dataframes_the_summary_and_the_claims():
    """pneuflex.run's Results: the dict of arrays as before, and each run's trace as a DataFrame indexed by t,
    the window metrics as a table equal to summary.json's, the claims with the adaptation verdict; a sweep's
    table as a DataFrame with a row per point and run."""
    import pandas as pd

    r = pneuflex.run(SCENE)
    scene = pneuflex.load_scene(SCENE)
    names = [x["name"] for x in scene["runs"]]
    assert list(r) == names and isinstance(r["adaptive"]["f_e"], np.ndarray)
    df = r.trace("adaptive")
    assert isinstance(df, pd.DataFrame) and df.index.name == "t" and len(df) == scene["n_steps"] + 1
    assert {"f_e", "x", "u", "g", "p", "d"} <= set(df.columns) and "t" not in df.columns
    assert np.array_equal(df["f_e"].to_numpy(), r["adaptive"]["f_e"])
    assert set(r.traces) == set(names)
    m = r.metrics
    run0 = next(x for x in r.summary["runs"] if x["name"] == "adaptive")
    sine = next(w for w in run0["windows"] if w["name"] == "sine")
    assert m.loc[("adaptive", "sine"), "rms_force_error_n"] == sine["rms_force_error_n"]
    settle = m.loc[("impedance", "stiffness_change"), "settling_time_s"]
    assert 0.5 < settle < 2.0, settle
    c = r.claims_frame
    assert len(c) == len(r.claims) == 5 and set(c["earned_by"]) <= {"adaptation", "projection_bound",
                                                                      "parameter_values", "no_win"}
    assert list(c["holds"]) == [x["holds"] for x in r.claims]
    try:
        r.trace("nope")
        raise AssertionError("an unknown run was accepted")
    except KeyError as e:
        assert "nope" in str(e) and "adaptive" in str(e), e
    ideal = str(ROOT / "scenes" / "paper-fig3-ideal.toml")
    table = pneuflex.sweep(ideal, ["environment.stiffness_n_per_m=700,1400"])
    assert isinstance(table, str) and table.startswith("point,")
    f = table.frame
    assert len(f) == 2 * 2 and list(f["environment.stiffness_n_per_m"]) == [700, 700, 1400, 1400], f


@test
def the_force_control_environment_is_the_scene_run_by_a_policy():
    """pneuflex/ForceControl-v0 passes Gymnasium's env_checker; with the scene's values and the scene's adaptive
    controller as the policy it reproduces pneuflex.run's adaptive run (RMS force error within 1e-6); seeded
    episodes repeat exactly; the adaptive baseline beats doing nothing and a random policy."""
    import warnings

    import gymnasium
    from gymnasium.utils.env_checker import check_env

    import pneuflex.envs as envs

    env = gymnasium.make("pneuflex/ForceControl-v0").unwrapped
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        check_env(env, skip_render_check=True)

    def episode(policy, seed=0, randomize=False, cap=None):
        obs, info = env.reset(seed=seed, options={"randomize": randomize})
        err, rewards, seen = [], [], []
        while True:
            obs, r, term, trunc, step = env.step(policy(obs))
            err.append(obs[1] * envs.SCALES[0] - step["f_e_n"])
            rewards.append(r)
            seen.append(obs)
            if term or trunc or (cap and len(rewards) >= cap):
                return np.array(err), np.mean(rewards), np.array(seen), info

    base = envs.adaptive_baseline(env)
    err, reward, _, _ = episode(base)
    a = pneuflex.run(SCENE)["adaptive"]
    scene_rms = np.sqrt(np.mean((a["f_ref"] - a["f_e"])[1:] ** 2))
    assert len(err) == len(a["t"]) - 1, len(err)
    assert abs(np.sqrt(np.mean(err ** 2)) / scene_rms - 1) < 1e-6, (np.sqrt(np.mean(err ** 2)), scene_rms)
    _, zero, _, _ = episode(lambda o: np.zeros(1, np.float32))
    rng = np.random.default_rng(0)
    _, rand, _, _ = episode(lambda o: rng.uniform(-1, 1, 1).astype(np.float32))
    # The reward is 1 - min(e^2, 1) per tick (e in 10 N): the baseline's shortfall from 1 is its mean squared
    # error, more than 5x smaller than doing nothing's or a random policy's.
    assert 5 * (1 - reward) < min(1 - zero, 1 - rand), (reward, zero, rand)
    # Seeded domain randomisation: the same seed and actions, the same episode; another seed, other values.
    wave = lambda o: np.array([0.3 * math.sin(7 * o[1])], np.float32)  # noqa: E731
    _, _, one, i1 = episode(wave, seed=5, randomize=True, cap=500)
    _, _, two, i2 = episode(wave, seed=5, randomize=True, cap=500)
    _, _, _, i3 = episode(wave, seed=6, randomize=True, cap=500)
    assert i1 == i2 and np.array_equal(one, two) and i3 != i1, (i1, i3)
    assert 350 <= i1["stiffness_n_per_m"] <= 2800 and 4 <= i1["t_change_s"] <= 8, i1
    scaled = ("mass_scale", "friction_scale", "switching_delay_scale")
    assert all(0.5 <= i[k] <= 2 for i in (i1, i3) for k in scaled), (i1, i3)
    assert i1["mass_scale"] != i3["mass_scale"] and i1["friction_scale"] != i3["friction_scale"], (i1, i3)


def _impedance_episode(env, cap=None):
    """The RMS force error of one episode of the impedance action held at (0, 0): the scene's own gains."""
    env.reset(seed=0, options={"randomize": False})
    err = []
    while True:
        obs, _, term, trunc, step = env.step(np.zeros(2, np.float32))
        err.append(obs[1] * 10.0 - step["f_e_n"])
        if term or trunc or (cap and len(err) >= cap):
            return np.sqrt(np.mean(np.square(err))), len(err)


@test
def the_impedance_action_at_zero_is_the_scene_impedance_run():
    """pneuflex/ForceControlImpedance-v0 passes check_env; held at (0, 0) the controller keeps the scene's
    m_d and b_d and the episode is pneuflex.run's impedance run, sampled every 10 ticks (RMS within 1e-6 of
    the same samples of the trace); other adjustments change the force."""
    import warnings

    import gymnasium
    from gymnasium.utils.env_checker import check_env

    import pneuflex.envs  # noqa: F401

    env = gymnasium.make("pneuflex/ForceControlImpedance-v0").unwrapped
    assert env.action_space.shape == (2,)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        check_env(env, skip_render_check=True)
    rms, n = _impedance_episode(env)
    r = pneuflex.run(SCENE)["impedance"]
    sampled = (r["f_ref"] - r["f_e"])[10::10]
    assert n == len(sampled), (n, len(sampled))
    want = np.sqrt(np.mean(sampled ** 2))
    assert abs(rms / want - 1) < 1e-6, (rms, want)
    # Softer target inertia, more damping: another response.
    env.reset(seed=0, options={"randomize": False})
    obs = [env.step(np.array([-1.0, 1.0], np.float32))[0] for _ in range(300)]
    env.reset(seed=0, options={"randomize": False})
    same = [env.step(np.zeros(2, np.float32))[0] for _ in range(300)]
    assert np.abs(np.array(obs)[:, 0] - np.array(same)[:, 0]).max() > 0.05


@test
def a_batch_shared_by_the_threads_is_each_episode_alone():
    """A batch large enough to be split over the calling thread and the helpers (67 randomised episodes:
    chunks of 16, the last with three episodes outside a pack) steps each episode as the single
    environment does alone, to the bit, step after step (to its first end): which thread runs an episode
    changes nothing."""
    import gymnasium

    import pneuflex.envs as envs

    n, steps = 67, 150
    vec = gymnasium.make_vec("pneuflex/ForceControl-v0", num_envs=n, vectorization_mode="vector_entry_point")
    seeds = [100 + i for i in range(n)]
    u = np.linspace(-0.15, 0.15, n)[:, None]
    obs0, _ = vec.reset(seed=seeds, options={"randomize": True})
    got, ended = [obs0], np.full(n, steps)
    for k in range(steps):
        obs, _, term, trunc, _ = vec.step(u * math.sin(0.07 * k + 0.3))
        got.append(obs)
        ended = np.where((term | trunc) & (ended == steps), k + 1, ended)
    got = np.array(got)
    assert (ended == steps).sum() > n // 2, ended
    single = envs.ForceControl()
    for i in range(n):
        o, _ = single.reset(seed=seeds[i], options={"randomize": True})
        want = [o] + [single.step(u[i] * math.sin(0.07 * k + 0.3))[0] for k in range(ended[i])]
        assert np.array_equal(got[: ended[i] + 1, i], np.array(want)), i


@test
def the_vector_environment_is_many_single_ones():
    """gymnasium.make_vec(..., vectorization_mode="vector_entry_point") gives the Rust batch: each of its
    episodes, fed its own actions, is the single environment fed the same ones, to the bit; a seed repeats
    the batch's draws; an episode that ends is reset by the next step (reward 0, its first observation)."""
    import gymnasium

    import pneuflex.envs as envs

    n = 6
    vec = gymnasium.make_vec("pneuflex/ForceControl-v0", num_envs=n, vectorization_mode="vector_entry_point")
    assert isinstance(vec.unwrapped, envs.ForceControlVector), type(vec.unwrapped)
    assert vec.observation_space.shape == (n, 6) and vec.action_space.shape == (n, 1)
    single = envs.ForceControl()
    u = np.linspace(-0.15, 0.15, n)[:, None]
    obs0, _ = vec.reset(seed=1, options={"randomize": False})
    got = [obs0]
    for k in range(200):
        obs, r, term, trunc, _ = vec.step(u * math.sin(0.05 * k))
        got.append(obs)
        assert not (term.any() or trunc.any())
    got = np.array(got)
    for i in range(n):
        o, _ = single.reset(seed=1, options={"randomize": False})
        want = [o] + [single.step(u[i] * math.sin(0.05 * k))[0] for k in range(200)]
        assert np.array_equal(got[:, i], np.array(want)), i
    # Randomised episodes (each its own mass, friction and valve delay), their plants stepped eight at a
    # time in packed arithmetic (a batch of 11: one pack and three alone): each still the single
    # environment fed the same actions, to the bit.
    wide = gymnasium.make_vec("pneuflex/ForceControl-v0", num_envs=11, vectorization_mode="vector_entry_point")
    seeds = [40 + i for i in range(11)]
    u11 = np.linspace(-0.15, 0.15, 11)[:, None]
    obs0, _ = wide.reset(seed=seeds, options={"randomize": True})
    got = [obs0]
    for k in range(250):
        obs, _, term, trunc, _ = wide.step(u11 * math.sin(0.05 * k + 1.0))
        got.append(obs)
        assert not (term.any() or trunc.any())
    got = np.array(got)
    for i in range(11):
        o, _ = single.reset(seed=seeds[i], options={"randomize": True})
        want = [o] + [single.step(u11[i] * math.sin(0.05 * k + 1.0))[0] for k in range(250)]
        assert np.array_equal(got[:, i], np.array(want)), i
    assert len({tuple(got[-1, i]) for i in range(11)}) == 11
    # Seeds: the same seed the same draws, another seed others, all within their ranges.
    _, a = vec.reset(seed=7)
    _, b = vec.reset(seed=7)
    _, c = vec.reset(seed=8)
    assert all(np.array_equal(a[k], b[k]) for k in envs.PARAMS)
    assert not np.array_equal(a["stiffness_n_per_m"], c["stiffness_n_per_m"])
    assert len(set(a["mass_scale"])) == n and ((0.5 <= a["mass_scale"]) & (a["mass_scale"] <= 2)).all()
    # A list of seeds: episode i draws what the single environment draws for seed[i].
    _, d = vec.reset(seed=[30 + i for i in range(n)])
    for i in range(n):
        _, info = single.reset(seed=30 + i)
        assert all(d[k][i] == info[k] for k in envs.PARAMS), (i, info)
    # Full retraction: the flange reaches its end stop, terminated; the next step starts a new episode.
    vec.reset(seed=2)
    for k in range(5000):
        obs, r, term, trunc, _ = vec.step(-np.ones((n, 1)))
        if term.any():
            break
    assert term.any(), "full retraction never reached the end stop"
    ended = term.copy()
    # The end stop's step is rewarded as any tick, 1 - min(((f_ref - f_e) / 10 N)^2, 1) (f_ref = 10 N before
    # 3 s, paper-fig3), with no terminal penalty: the ticks it no longer lives earn nothing.
    t_end = (k + 1) * 1e-3
    f_now = 10.0 if t_end < 3.0 else 10.0 + 2.0 * math.sin(2 * math.pi * (t_end - 3.0))
    want = 1 - np.minimum(((f_now - obs[ended, 0] * 10.0) / 10.0) ** 2, 1)
    assert np.allclose(r[ended], want, rtol=1e-6, atol=1e-6) and (0 <= r).all() and (r <= 1).all(), (r[ended], want)
    obs, r, term, trunc, _ = vec.step(-np.ones((n, 1)))
    assert (r[ended] == 0).all() and not term[ended].any()
    assert (np.abs(obs[ended, 2]) < 1e-6).all(), obs[ended]  # x = x_e: the scene's start, touching
    try:
        vec.step(np.zeros(n + 1))
    except ValueError as e:
        assert "the action has shape (7,); the action space's is (6, 1)" in str(e), e
    else:
        raise AssertionError("a wrong number of actions was accepted")
    try:
        pneuflex.ForceControlBatch(SCENE, 2, action="torque")
    except pneuflex.PneuflexError as e:
        assert "paper-fig3.toml" in str(e) and "action" in str(e), e
    else:
        raise AssertionError("an unknown action was accepted")


@test
def gymnasiums_conventions_hold():
    """gymnasium.make / make_vec with max_episode_steps truncate at that step; render_mode="rgb_array" gives an
    HxWx3 uint8 frame with the force (blue) and position (green) traces; every reward lies in [0, 1], an end
    stop's episode included; the default scene and the multibody one are found in the package (shipped names);
    check_env passes with rendering; AsyncVectorEnv with spawned workers runs the environment."""
    import gymnasium

    import pneuflex.envs as envs

    env = gymnasium.make("pneuflex/ForceControl-v0", max_episode_steps=50, render_mode="rgb_array")
    env.reset(seed=0, options={"randomize": False})
    steps = [env.step(np.zeros(1, np.float32)) for _ in range(50)]
    assert [s[3] for s in steps] == [False] * 49 + [True] and not any(s[2] for s in steps)
    frame = env.render()
    assert frame.shape == (320, 480, 3) and frame.dtype == np.uint8, (frame.shape, frame.dtype)
    colours = {tuple(c) for c in frame.reshape(-1, 3)}
    assert {(31, 119, 180), (44, 160, 44), (150, 150, 150)} <= colours, colours
    assert envs.ForceControl().render() is None
    import warnings

    from gymnasium.utils.env_checker import check_env

    with warnings.catch_warnings():
        warnings.simplefilter("error")  # any complaint of the checker about rendering fails
        check_env(gymnasium.make("pneuflex/ForceControl-v0", render_mode="rgb_array").unwrapped)
    # Workers started by spawn: "module:id" imports pneuflex.envs there (it registers the ids).
    spawned = gymnasium.vector.AsyncVectorEnv(
        [lambda: gymnasium.make("pneuflex.envs:pneuflex/ForceControl-v0")] * 2, context="spawn")
    try:
        o, _ = spawned.reset(seed=0, options={"randomize": False})
        o2, _, _, _, _ = spawned.step(np.zeros((2, 1), np.float32))
        assert o.shape == (2, 6) and np.array_equal(o2[0], o2[1]), o2
    finally:
        spawned.close()
    vec = gymnasium.make_vec("pneuflex/ForceControl-v0", num_envs=3, vectorization_mode="vector_entry_point",
                             max_episode_steps=50, render_mode="rgb_array")
    vec.reset(seed=0, options={"randomize": False})
    for k in range(50):
        _, r, term, trunc, _ = vec.step(np.zeros((3, 1), np.float32))
        assert trunc.all() == (k == 49) and not term.any(), (k, trunc)
    _, r, term, trunc, _ = vec.step(np.zeros((3, 1), np.float32))
    assert (r == 0).all() and not trunc.any(), (r, trunc)  # the autoreset step
    frames = vec.render()
    assert len(frames) == 3 and all(f.shape == (320, 480, 3) for f in frames)
    # Full retraction onto the end stop: terminated, and every reward of the episode in [0, 1].
    full = envs.ForceControl()
    full.reset(seed=1)
    rewards = []
    while True:
        _, rew, term, trunc, _ = full.step(-np.ones(1, np.float32))
        rewards.append(rew)
        if term or trunc:
            break
    assert term and 0 <= min(rewards) and max(rewards) <= 1, (term, min(rewards), max(rewards))
    assert Path(env.unwrapped.scene_path).parent.parent.name == "data", env.unwrapped.scene_path
    multi = gymnasium.make("pneuflex/MultibodyForceControl-v0").unwrapped
    assert multi.scene_path.endswith("data/scenes/paper-fig3-multibody.toml"), multi.scene_path


@test
def environments_pickle_copy_and_survive_a_fork():
    """A pickled or deep-copied environment, single or vector, continues bit for bit as the original fed the
    same actions (its episodes replayed from their seeds and actions); a process that stepped a batch and
    then forks can step in the child (a pool per process)."""
    import copy
    import pickle
    import subprocess

    import pneuflex.envs as envs

    env = envs.ForceControl(render_mode="rgb_array")
    env.reset(seed=3, options={"randomize": False})
    acts = [np.array([0.05 * math.sin(0.03 * k)], np.float32) for k in range(300)]
    for a in acts[:150]:
        env.step(a)
    again, copied = pickle.loads(pickle.dumps(env)), copy.deepcopy(env)
    want = [env.step(a) for a in acts[150:]]
    for other in (again, copied):
        got = [other.step(a) for a in acts[150:]]
        assert all(np.array_equal(w[0], g[0]) and w[1:] == g[1:] for w, g in zip(want, got))
    assert np.array_equal(again.render(), env.render())
    vec = envs.ForceControlVector(num_envs=5, max_episode_steps=100)
    vec.reset(seed=1)
    for k in range(250):  # past two autoresets
        vec.step(np.full((5, 1), 0.1 * math.sin(0.1 * k), np.float32))
    twin = pickle.loads(pickle.dumps(vec))
    for k in range(120):
        a, b = vec.step(np.full((5, 1), -0.3, np.float32)), twin.step(np.full((5, 1), -0.3, np.float32))
        assert all(np.array_equal(x, y) for x, y in zip(a[:4], b[:4])), k
    # Fork after a batch step: the child steps and exits (it hung before the pool per process). The timeout
    # only stops a hang.
    code = ("import os, numpy as np, pneuflex.envs as envs\n"
            "v = envs.ForceControlVector(num_envs=64); v.reset(seed=0); v.step(np.zeros((64, 1)))\n"
            "pid = os.fork()\n"
            "if pid == 0:\n"
            "    v.step(np.zeros((64, 1))); os._exit(7)\n"
            "print(os.waitstatus_to_exitcode(os.waitpid(pid, 0)[1]))\n")
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert r.returncode == 0 and r.stdout.strip() == "7", (r.returncode, r.stdout, r.stderr)


@test
def shipped_scenes_are_taken_by_name():
    """pneuflex.scenes() lists the package's scenes; a shipped name goes wherever a scene path does (run, the
    controller, the setpoints, the batch), and an unknown name is a FileNotFoundError listing them."""
    names = pneuflex.scenes()
    assert {"paper-fig3", "paper-fig3-multibody", "gripper"} <= set(names), names
    by_name = pneuflex.run("paper-fig3")["adaptive"]
    by_path = pneuflex.run(SCENE)["adaptive"]
    assert np.array_equal(by_name["f_e"], by_path["f_e"])
    assert pneuflex.Setpoints("paper-fig3").at(0.5) == pneuflex.Setpoints(SCENE).at(0.5)
    pneuflex.Controller.from_scene("paper-fig3", "adaptive")
    assert pneuflex.ForceControlBatch("paper-fig3", 2).num_envs == 2
    try:
        pneuflex.run("paper-fig9")
    except FileNotFoundError as e:
        assert f"paper-fig9: no such file, nor a shipped scene; the shipped scenes are {', '.join(names)}" in str(e), e
    else:
        raise AssertionError("an unknown scene name was accepted")


@test
def trace_columns_carry_their_units():
    """pneuflex.run's DataFrames carry each column's unit in attrs["units"]: the loop's as loop_signals() declares
    them, the adaptive law's g, p, d and the plant's spool; a scene with several actuators, each prefixed column."""
    r = pneuflex.run(SCENE)
    units = r.trace("adaptive").attrs["units"]
    assert {name: unit for name, unit, _group in pneuflex.loop_signals()}.items() <= units.items(), units
    assert (units["g"], units["p"], units["d"], units["spool"]) == ("m", "m/N", "s", "1"), units
    assert set(units) == set(r["adaptive"]) and "g" not in r.trace("impedance").attrs["units"], units
    g = pneuflex.run(str(ROOT / "scenes" / "gripper.toml"))
    run = next(iter(g))
    gu = g.trace(run).attrs["units"]
    assert set(gu) == set(g[run]) and gu["left.f_e"] == "N" and gu["left.p_a"] == "Pa", gu


@test
def the_gymnasium_examples_run():
    """crates/python/examples: the random policy, the adaptive baseline (on the scene's own values it is the
    scene's adaptive run: RMS 1.699 N) and a small CEM over the impedance gains run to their end."""
    import subprocess

    ex = ROOT / "crates" / "python" / "examples"
    runs = {
        "random_policy.py": ["--episodes", "1"],
        "adaptive_baseline.py": ["--episodes", "1"],
        "cem_impedance.py": ["--iterations", "1", "--population", "4", "--episodes", "1"],
    }
    out = {}
    for name, argv in runs.items():
        r = subprocess.run([sys.executable, str(ex / name), *argv], capture_output=True, text=True, cwd=ex,
                           timeout=300)
        assert r.returncode == 0, (name, r.stderr)
        out[name] = r.stdout
    assert "RMS force error 1.699 N" in out["adaptive_baseline.py"], out["adaptive_baseline.py"]
    assert "held-out return" in out["cem_impedance.py"] and "seed 0:" in out["random_policy.py"], out


@test
def the_multibody_environment_is_the_multibody_scene():
    """pneuflex/MultibodyForceControl-v0 runs the Rapier rig: it passes check_env, and the impedance action at
    (0, 0) over the first 2 s follows the multibody scene's impedance run (RMS within 1e-6)."""
    import warnings

    import gymnasium
    from gymnasium.utils.env_checker import check_env

    import pneuflex.envs  # noqa: F401

    env = gymnasium.make("pneuflex/MultibodyForceControl-v0").unwrapped
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        check_env(env, skip_render_check=True)
    scene = str(ROOT / "scenes" / "paper-fig3-multibody.toml")
    imp = gymnasium.make("pneuflex/MultibodyForceControl-v0", action="impedance").unwrapped
    rms, n = _impedance_episode(imp, cap=200)
    r = pneuflex.run(scene)["impedance"]
    sampled = (r["f_ref"] - r["f_e"])[10:10 * n + 1:10]
    want = np.sqrt(np.mean(sampled ** 2))
    assert len(sampled) == n and abs(rms / want - 1) < 1e-6, (rms, want, n)


@functools.cache
def _gripper_runs():
    """pneuflex.run_mechanism and pneuflex.run of scenes/gripper.toml, once for the tests that read them
    (each is two 8 s runs of the mechanism: about 3.5 s in the dev build)."""
    gripper = str(ROOT / "scenes" / "gripper.toml")
    return pneuflex.run_mechanism(gripper), pneuflex.run(gripper)


def _impedance_forces(env, cap=None):
    """Each actuator's contact force after every step of an episode of the impedance action held at 0 (each
    actuator keeps the scene's gains), as (steps, actuators), and the RMS of f_ref - f_e from the
    observations (float32) over the steps and actuators."""
    env.reset(seed=0, options={"randomize": False})
    width = env.observation_space.shape[0]
    f_e, err = [], []
    while True:
        obs, _, term, trunc, info = env.step(np.zeros(env.action_space.shape, np.float32))
        f_e.append(np.atleast_1d(info["f_e_n"]))
        err.append(obs.reshape(width // 6, 6)[:, 1] * 10.0 - f_e[-1])
        if term or trunc or (cap and len(f_e) >= cap):
            return np.array(f_e), float(np.sqrt(np.mean(np.square(err))))


@test
def the_gripper_environment_drives_both_fingers_as_the_scene_does():
    """pneuflex/GripperForceControl-v0 (scenes/gripper.toml, two cylinders): the action is one valve command
    per finger, Box(2) (impedance: Box(4)), the observation each finger's block, Box(12); check_env passes
    with rendering; held at 0, the impedance action is the scene's impedance run on both fingers over the
    whole 8 s episode (foam, the sine, the stiffening to rubber at 5 s): every finger's f_e at every 10th tick
    equals the trace's to 1e-9 N (the same plant and controllers in the same order: measured equal to the
    bit; a tick's shift of the event alone moves f_e by newtons), the RMS through the float32 observation
    within 1e-6; a step's reward is the mean of the fingers' 1 - min(((f_ref - f_e) / 10 N)^2, 1); a seed
    repeats its draw of the pads' stiffness; a 1e12 N/m pad ends the episode, terminated, naming the finger."""
    import warnings

    import gymnasium
    from gymnasium.utils.env_checker import check_env

    import pneuflex.envs as envs

    env = gymnasium.make("pneuflex/GripperForceControl-v0", render_mode="rgb_array").unwrapped
    assert env.action_space.shape == (2,) and env.observation_space.shape == (12,), env.action_space
    assert env.actuators == ["left", "right"] and env.scene_path.endswith("scenes/gripper.toml")
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        check_env(env)
    assert env.render().shape == (640, 480, 3), "one panel pair per finger"
    imp = gymnasium.make("pneuflex/GripperForceControl-v0", action="impedance").unwrapped
    assert imp.action_space.shape == (4,)
    f_e, rms = _impedance_forces(imp)
    run = _gripper_runs()[1]["impedance"]
    assert f_e.shape == (800, 2), f_e.shape
    for i, side in enumerate(("left", "right")):
        want = run[f"{side}.f_e"][10::10]
        assert np.abs(f_e[:, i] - want).max() <= 1e-9, (side, np.abs(f_e[:, i] - want).max())
    want = np.sqrt(np.mean([(run[f"{s}.f_ref"] - run[f"{s}.f_e"])[10::10] ** 2 for s in ("left", "right")]))
    assert abs(rms / want - 1) < 1e-6, (rms, want)
    # The reward of one tick (an impedance step of one tick, the fingers retuned apart so that their errors
    # differ), from the sensors and the references the batch reports.
    one = envs.ForceControl(scene="gripper", action="impedance", decision_ticks=1, randomize=False)
    one.reset(seed=0)
    for _ in range(1500):
        _, reward, *_ = one.step(np.array([1.0, -1.0, -1.0, 1.0], np.float32))
    each = [1 - min(((one.batch.setpoint(one.t, i)[0] - one.sensors(i)[3]) / 10.0) ** 2, 1) for i in (0, 1)]
    assert abs(reward - np.mean(each)) < 1e-12 and abs(each[0] - each[1]) > 1e-3, (reward, each)
    # Randomised: the pads' stiffness before and after the event, as multiples of the scene's.
    _, a = env.reset(seed=5)
    _, b = env.reset(seed=5)
    _, c = env.reset(seed=6)
    assert set(a) == set(envs.MECHANISM_PARAMS) and a == b and a != c, (a, c)
    assert all(0.5 <= v <= 2 for v in (*a.values(), *c.values())), (a, c)
    # A pad of 1e12 N/m at 0.05 s: the left finger leaves its stroke; the episode (the scene's gains, one
    # tick a step) terminates at the tick the scene's impedance run stops as diverged, for the same reason.
    text = (ROOT / "scenes" / "gripper.toml").read_text().replace('"../', f'"{ROOT}/')
    text = text.replace("t_s = 5.0", "t_s = 0.05").replace("stiffness_n_per_m = 20000.0   # rubber",
                                                          "stiffness_n_per_m = 1e12")
    with tempfile.TemporaryDirectory() as d:
        stiff = Path(d) / "stiff.toml"
        stiff.write_text(text)
        bad = envs.ForceControl(scene=stiff, randomize=False, action="impedance", decision_ticks=1)
        bad.reset(seed=0)
        for k in range(200):
            _, _, term, trunc, _ = bad.step(np.zeros(4))
            if term or trunc:
                break
        diverged = pneuflex.run(stiff).summary["runs"][0]["diverged"]
    assert term and not trunc and bad.batch.why(0) == diverged, (term, trunc, bad.batch.why(0), diverged)
    assert diverged.startswith("left: piston position") and abs(bad.t - 0.057) < 1e-9, (diverged, bad.t)
    refused(lambda: bad.step(np.zeros(4)), RuntimeError, "terminated (left: piston position", "outside the stroke")


@test
def the_gripper_environment_refuses_a_wrong_shape_and_pickles():
    """An action of one finger's shape (or a flat batch) is refused naming both shapes, and no finger moves;
    a pickled or deep-copied gripper environment, and a pickled vector one past an autoreset, go on bit for
    bit as the original fed the same actions."""
    import copy
    import pickle

    import pneuflex.envs as envs

    env = envs.ForceControl(scene="gripper", action="impedance")
    env.reset(seed=2)
    for a in (np.zeros(2), np.zeros((2, 2)), np.zeros(5), 0.0):
        refused(lambda: env.step(a), ValueError, "ForceControl.step: the action has shape",
                "the action space's is (4,)")
    assert env.t == 0.0
    acts = [np.array([0.3 * math.sin(0.1 * k), -0.2, 0.1, 0.4 * math.cos(0.2 * k)], np.float32) for k in range(60)]
    for a in acts[:30]:
        env.step(a)
    again, copied = pickle.loads(pickle.dumps(env)), copy.deepcopy(env)
    want = [env.step(a) for a in acts[30:]]
    for other in (again, copied):
        got = [other.step(a) for a in acts[30:]]
        assert all(np.array_equal(w[0], g[0]) and w[1:4] == g[1:4] and np.array_equal(w[4]["f_e_n"], g[4]["f_e_n"])
                   for w, g in zip(want, got))
    vec = envs.ForceControlVector(num_envs=2, scene="gripper", max_episode_steps=20)
    vec.reset(seed=1)
    refused(lambda: vec.step(np.zeros((2, 1))), ValueError, "the action space's is (2, 2)")
    refused(lambda: vec.step(np.zeros(4)), ValueError, "the action space's is (2, 2)")
    for k in range(30):  # past an autoreset
        vec.step(np.full((2, 2), 0.2 * math.sin(0.3 * k), np.float32))
    twin = pickle.loads(pickle.dumps(vec))
    for k in range(15):
        a, b = vec.step(np.full((2, 2), -0.1, np.float32)), twin.step(np.full((2, 2), -0.1, np.float32))
        assert all(np.array_equal(x, y) for x, y in zip(a[:4], b[:4])), k
    assert a[0].shape == (2, 12)


@test
def the_fig7_environment_is_the_fig7_scene():
    """The paper's fig7 scene (paper-fig7-wood-to-iron: the multibody rig, the carriage swapping wood for iron
    at 3 s) by name: check_env passes; held at 0, the impedance action is the scene's impedance run over the
    whole 8 s (f_e at every 10th tick to 1e-9 N, the RMS within 1e-6); a pickled environment goes on bit for
    bit."""
    import pickle
    import warnings

    import gymnasium
    from gymnasium.utils.env_checker import check_env

    import pneuflex.envs  # noqa: F401

    env = gymnasium.make("pneuflex/ForceControl-v0", scene="paper-fig7-wood-to-iron").unwrapped
    assert env.action_space.shape == (1,) and env.observation_space.shape == (6,)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        check_env(env, skip_render_check=True)
    imp = gymnasium.make("pneuflex/ForceControl-v0", scene="paper-fig7-wood-to-iron", action="impedance").unwrapped
    f_e, rms = _impedance_forces(imp)
    run = pneuflex.run("paper-fig7-wood-to-iron")["impedance"]
    assert f_e.shape == (800, 1) and np.abs(f_e[:, 0] - run["f_e"][10::10]).max() <= 1e-9
    want = np.sqrt(np.mean((run["f_ref"] - run["f_e"])[10::10] ** 2))
    assert abs(rms / want - 1) < 1e-6, (rms, want)
    env.reset(seed=4)
    for k in range(400):
        env.step(np.array([0.1 * math.sin(0.05 * k)], np.float32))
    twin = pickle.loads(pickle.dumps(env))
    for k in range(100):
        a, b = env.step(np.array([0.2], np.float32)), twin.step(np.array([0.2], np.float32))
        assert np.array_equal(a[0], b[0]) and a[1:4] == b[1:4], k


def _sheets() -> dict:
    """The paper actuator's sheets as numbers, read here (independent of the bindings)."""
    import tomllib

    d = ROOT / "pneumatics"
    act = tomllib.loads((d / "paper-actuator.toml").read_text())
    comp = act["components"]
    cyl = tomllib.loads((d / comp["cylinder"]).read_text())["cylinder"]
    sup = tomllib.loads((d / comp["supply"]).read_text())
    a_a = math.pi / 4 * cyl["bore_m"] ** 2
    a_rod = math.pi / 4 * cyl["rod_m"] ** 2
    m = act["mechanics"]
    return {"a_a": a_a, "a_b": a_a - a_rod, "a_rod": a_rod, "p_atm": sup["atmosphere"]["pressure_abs_pa"],
            "p_s": sup["supply"]["pressure_abs_pa"], "stroke": cyl["stroke_m"],
            "gravity_n": m["moving_mass_kg"] * m["gravity_m_per_s2"] * math.sin(math.radians(m["alpha_deg"]))}


@test
def the_pressure_action_holds_its_set_points_and_the_force_follows():
    """pneuflex/ForceControlPressure-v0: the action is the two chambers' set-points in Pa absolute, Box(2) over
    [atmosphere, supply] from the sheets. Held, the chambers converge to them (to 1e-3 Pa) and the flange comes
    to rest where the contact force is p_a A_a - p_b A_b - p_atm A_rod + m g sin(alpha) (areas, atmosphere,
    mass and incline from the sheets, computed here); stepped to a second pair, the force follows to the new
    balance. A pickled environment goes on bit for bit; the vector environment's episodes equal the single
    one's."""
    import pickle

    import gymnasium

    import pneuflex.envs  # noqa: F401

    k = _sheets()
    env = gymnasium.make("pneuflex/ForceControlPressure-v0").unwrapped
    assert env.action_space.shape == (2,) and env.action_space.dtype == np.float32
    assert list(env.action_space.low) == [k["p_atm"]] * 2 and list(env.action_space.high) == [k["p_s"]] * 2
    assert env.batch.action == "pressure" and env.batch.regulator_time_constant_s == 0.01
    env.reset(seed=0, options={"randomize": False})
    # The first pair until 5.5 s (the spring at 700 N/m: the flange creeps in, time constant about 0.46 s with
    # the friction's slope), the second until 9.95 s (1400 N/m from 6 s: about 0.23 s).
    rewards = []
    for (p_a, p_b), steps, k_e, tol in [((2.7e5, 2.5e5), 5500, 700.0, 1e-3), ((3.1e5, 2.6e5), 4450, 1400.0, 1e-6)]:
        action = np.array([p_a, p_b], np.float32)
        for _ in range(steps):
            obs, reward, terminated, truncated, info = env.step(action)
        rewards.append(reward)
        assert not (terminated or truncated)
        t, x, x_dot, f_e, pa, pb = env.sensors()
        assert abs(pa - p_a) < 1e-3 and abs(pb - p_b) < 1e-3, (pa, pb)
        want = p_a * k["a_a"] - p_b * k["a_b"] - k["p_atm"] * k["a_rod"] + k["gravity_n"]
        assert abs(f_e - want) < tol and abs(info["f_e_n"] - want) < tol, (t, f_e, want)
        assert abs(x - (0.02 + want / k_e)) < tol / k_e, (x, 0.02 + want / k_e)
        assert abs(obs[4] - p_a / 1e5) < 1e-6 and abs(obs[0] - want / 10.0) < 1e-5, obs
    # The first pair presses about the reference's 10 N (reward near 1), the second 15.9 N against 10-12 N.
    assert rewards[0] > 0.99 and rewards[1] < 0.9, rewards
    env.reset(seed=5)
    rng = np.random.default_rng(1)
    for _ in range(300):
        env.step(rng.uniform(k["p_atm"], k["p_s"], 2).astype(np.float32))
    twin = pickle.loads(pickle.dumps(env))
    for _ in range(100):
        a = rng.uniform(k["p_atm"], k["p_s"], 2).astype(np.float32)
        o1, o2 = env.step(a), twin.step(a)
        assert np.array_equal(o1[0], o2[0]) and o1[1:4] == o2[1:4]
    vec = gymnasium.make_vec("pneuflex/ForceControlPressure-v0", num_envs=2, vectorization_mode="vector_entry_point")
    vec.reset(seed=[3, 4])
    singles = [gymnasium.make("pneuflex/ForceControlPressure-v0").unwrapped for _ in range(2)]
    for e, s in zip(singles, [3, 4]):
        e.reset(seed=s)
    for _ in range(200):
        a = rng.uniform(k["p_atm"], k["p_s"], (2, 2)).astype(np.float32)
        vo, vr, _, _, _ = vec.step(a)
        for i, e in enumerate(singles):
            so, sr, _, _, _ = e.step(a[i])
            assert np.array_equal(vo[i], so) and vr[i] == sr


@test
def the_pressure_action_refuses_bad_set_points_and_passes_check_env():
    """A set-point that is NaN or infinite, below the atmosphere or above the supply, or an action of another
    shape is refused naming the environment, the value and the bounds, and no episode moves; check_env passes
    (its one remark: the Box in Pa is not normalised, as RescaleAction(env, -1, 1) makes it); the multibody rig
    takes the pressure action, a scene of several actuators refuses it naming why."""
    import warnings

    import gymnasium
    from gymnasium.utils.env_checker import check_env

    import pneuflex.envs as envs

    k = _sheets()
    env = envs.ForceControl(action="pressure")
    env.reset(seed=0)
    t0 = env.t
    refused(lambda: env.step(np.array([np.nan, 2e5])), ValueError,
            "ForceControl.step: actions[0] (environment 0, value 0) is NaN: a pressure set-point must be finite")
    refused(lambda: env.step(np.array([2e5, np.inf], np.float32)), ValueError, "is inf")
    refused(lambda: env.step(np.array([9e4, 2e5], np.float32)), ValueError,
            "actions[0] (environment 0, value 0: actuator 0's p_a set-point) is 90000 Pa: a set-point must be within "
            "[101325, 601325] Pa absolute (the atmosphere and the supply)")
    refused(lambda: env.step(np.array([2e5, 7e5])), ValueError, "actuator 0's p_b set-point) is 700000 Pa")
    refused(lambda: env.step(np.array([2e5], np.float32)), ValueError,
            "ForceControl.step: the action has shape (1,); the action space's is (2,)")
    refused(lambda: env.step(np.array(["2e5", "3e5"])), TypeError, "the action must hold real numbers")
    assert env.t == t0, "a refused action moved the episode"
    # At the bounds (the space's float32 values) it steps.
    env.step(np.array([k["p_atm"], k["p_s"]], np.float32))
    vec = envs.ForceControlVector(num_envs=3, action="pressure")
    vec.reset(seed=0)
    bad = np.full((3, 2), 2e5)
    bad[2, 1] = 6.5e5
    refused(lambda: vec.step(bad), ValueError, "ForceControlVector.step: actions[5] (environment 2, value 1: "
            "actuator 0's p_b set-point) is 650000 Pa")
    assert all(vec.batch.sensors(i)[0] == 0.0 for i in range(3))
    refused(lambda: envs.ForceControl(action="pressure", regulator_time_constant_s=0.0), ValueError,
            "regulator_time_constant_s must be a time constant > 0 s")
    refused(lambda: envs.ForceControl(action="pressure", regulator_time_constant_s=100.0), ValueError,
            "regulator_time_constant_s: the regulator's time constant must be in [1e-5, 10] s, got 100")
    refused(lambda: envs.ForceControl(scene="gripper", action="pressure"), pneuflex.PneuflexError,
            "gripper.toml", 'action = "pressure"', "several actuators")
    with warnings.catch_warnings(record=True) as seen:
        warnings.simplefilter("always")
        check_env(gymnasium.make("pneuflex/ForceControlPressure-v0", render_mode="rgb_array").unwrapped)
    remarks = {str(w.message) for w in seen}
    assert all("symmetric and normalized space" in r for r in remarks), remarks
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # Gymnasium's own remark on its float64 bounds cast to the float32 space
        rescaled = gymnasium.wrappers.RescaleAction(gymnasium.make("pneuflex/ForceControlPressure-v0"), -1.0, 1.0)
    assert list(rescaled.action_space.low) == [-1, -1] and list(rescaled.action_space.high) == [1, 1]
    rescaled.reset(seed=0)
    rescaled.step(np.zeros(2, np.float32))
    assert abs(rescaled.unwrapped.batch.sensors(0)[4] - (k["p_atm"] + k["p_s"]) / 2) < 3e5
    multi = gymnasium.make("pneuflex/MultibodyForceControl-v0", action="pressure").unwrapped
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        check_env(multi, skip_render_check=True)
    multi.reset(seed=0, options={"randomize": False})
    for _ in range(500):
        multi.step(np.array([2.7e5, 2.5e5], np.float32))
    _, _, _, _, pa, pb = multi.sensors()
    assert abs(pa - 2.7e5) < 1e-2 and abs(pb - 2.5e5) < 1e-2, (pa, pb)


@test
def every_native_name_has_a_type_stub():
    """pneuflex/_native.pyi declares every function, class and method the native module exports, with the
    parameter names the module's own signatures give (a function added without its stub fails here)."""
    import ast
    import inspect

    from pneuflex import _native

    tree = ast.parse((Path(pneuflex.__file__).parent / "_native.pyi").read_text())
    stubs = {}
    for node in tree.body:
        if isinstance(node, ast.FunctionDef):
            stubs[node.name] = [a.arg for a in node.args.args]
        elif isinstance(node, ast.ClassDef):
            stubs[node.name] = {n.name: [a.arg for a in n.args.args] for n in node.body
                                if isinstance(n, ast.FunctionDef)}
    for name in (n for n in dir(_native) if not n.startswith("__") and n != "_workspace_dir"):
        assert name in stubs, f"_native.{name} has no stub"
        value = getattr(_native, name)
        if isinstance(value, type):
            for m in (m for m in vars(value) if not m.startswith("_")):
                sig = getattr(getattr(value, m), "__text_signature__", None)
                if sig:
                    assert m in stubs[name], f"_native.{name}.{m} has no stub"
                    params = [p for p in inspect.signature(getattr(value, m)).parameters if p != "self"]
                    assert [a for a in stubs[name][m] if a != "self"] == params, (name, m, stubs[name][m], params)
        elif callable(value):
            params = list(inspect.signature(value).parameters)
            assert stubs[name] == params, (name, stubs[name], params)


@test
def run_to_writes_what_the_cli_writes():
    """run_to goes through the CLI's output pipeline: the same trace files and summary.json, byte for byte,
    as `pneuflex run --out` (the debug binary the test command builds first); a directory pneuflex did not
    write is refused, naming the file, and left as it was."""
    import subprocess

    cli = ROOT / "target" / "debug" / "pneuflex"
    assert cli.is_file(), f"{cli}: build the CLI first (cargo build)"
    with tempfile.TemporaryDirectory() as d:
        ours, theirs = Path(d) / "py", Path(d) / "cli"
        assert pneuflex.run_to(SCENE, str(ours)) == str(ours)
        subprocess.run([str(cli), "run", SCENE, "--out", str(theirs), "--quiet"], check=True)
        files = sorted(p.relative_to(theirs) for p in theirs.rglob("*.csv")) + [Path("summary.json")]
        # A trace per run (fig3: impedance, adaptive and its two frozen runs) and the summary.
        assert len(files) == len(pneuflex.load_scene(SCENE)["runs"]) + 1 == 5, files
        for f in files:
            assert (ours / f).read_bytes() == (theirs / f).read_bytes(), f
        assert (ours / "force.png").is_file()
        foreign = Path(d) / "mine"
        foreign.mkdir()
        (foreign / "notes.txt").write_text("keep")
        try:
            pneuflex.run_to(SCENE, str(foreign))
            raise AssertionError("a foreign directory was replaced")
        except pneuflex.PneuflexError as e:
            assert "notes.txt" in str(e), e
        assert (foreign / "notes.txt").read_text() == "keep"
        assert sorted(p.name for p in foreign.iterdir()) == ["notes.txt"]


@test
def bench_scene_ticks_is_the_runners_tick():
    # scripts/bench times this loop: before the first event it must reproduce the runner's trace bit for bit.
    for scene_path in (SCENE, str(ROOT / "scenes" / "paper-fig7-wood-to-iron.toml")):
        traces = pneuflex.run(scene_path)
        for run in ("impedance", 1):
            name = run if isinstance(run, str) else list(traces)[run]
            b = pneuflex.bench_scene_ticks(scene_path, run, ticks=500, settle_s=0.0)
            assert b["ticks"] == 500 and b["wall_s"] > 0.0, b
            assert b["x"] == traces[name]["x"][500] and b["f_e"] == traces[name]["f_e"][500], (scene_path, name, b)


@test
def bad_inputs_raise_python_exceptions_naming_the_file():
    missing = str(ROOT / "scenes" / "no-such-scene.toml")
    for f in (pneuflex.load_scene, pneuflex.run, pneuflex.Setpoints):
        try:
            f(missing)
        except FileNotFoundError as e:
            assert "no-such-scene.toml" in str(e), str(e)
        else:
            raise AssertionError(f"{f} accepted a missing file")
    with tempfile.TemporaryDirectory() as d:
        bad = Path(d) / "bad.toml"
        bad.write_text(Path(SCENE).read_text().replace("stiffness_n_per_m = 700.0", "stifness_n_per_m = 700.0"))
        try:
            pneuflex.run(str(bad))
        except pneuflex.PneuflexError as e:
            assert "bad.toml" in str(e) and "stifness_n_per_m" in str(e), str(e)
            assert isinstance(e, ValueError)
        else:
            raise AssertionError("unknown key accepted")
    try:
        pneuflex.Controller("impedance", {"m_d_kg": 2.0, "b_d_ns_per_m": 1.0, "k_d_n_per_m": 0.0, "typo": 1}, {"kp_per_m": 1.0})
    except pneuflex.PneuflexError as e:
        assert "typo" in str(e), str(e)
    else:
        raise AssertionError("unknown controller key accepted")
    try:
        pneuflex.Controller("impedance", {"m_d_kg": -2.0, "b_d_ns_per_m": 1.0, "k_d_n_per_m": 0.0}, {"kp_per_m": 1.0})
    except pneuflex.PneuflexError as e:
        assert "m_d_kg" in str(e), str(e)
    else:
        raise AssertionError("negative mass accepted")
    try:
        pneuflex.Controller.from_scene(SCENE, "nope")
    except pneuflex.PneuflexError as e:
        assert "nope" in str(e) and "paper-fig3.toml" in str(e), str(e)
    else:
        raise AssertionError("unknown run accepted")
    try:
        pneuflex.ForceElement(pneuflex.Actuator(SHEET)).step(0.01, 0.0, 0.0, 0.0)
    except ValueError as e:
        assert "dt_s" in str(e)
    else:
        raise AssertionError("dt = 0 accepted")


def refused(f, error, *says) -> str:
    """Calls ``f``, which must raise ``error``; each of ``says`` must be in the text (the message and PyO3's
    notes, which name a native function's argument: "while processing 'path'"). Returns the text."""
    try:
        f()
    except error as e:
        text = "\n".join([str(e), *getattr(e, "__notes__", [])])
        for want in says:
            assert want in text, (want, text)
        return text
    except BaseException as e:
        raise AssertionError(f"{type(e).__name__}: {e}; expected {error.__name__} saying {says}") from e
    raise AssertionError(f"accepted; expected {error.__name__} saying {says}")


FREE = ["runs[adaptive].inner.kp_per_m=[2,20]"]
MASS = ["mechanics.moving_mass_kg"]


@test
def a_path_of_another_type_is_a_type_error_naming_the_argument():
    """run(42) was FileNotFoundError("42") (str() made the number a file name): a number, None or bytes of no
    path where a file goes is a TypeError naming the function and the argument, before anything is read or
    written; an empty path is a ValueError."""
    import pneuflex.envs as envs

    refused(lambda: pneuflex.run(42), TypeError, "pneuflex.run: scene_path must be a path (str or os.PathLike), got int 42")
    refused(lambda: pneuflex.run(None), TypeError, "pneuflex.run: scene_path", "NoneType")
    refused(lambda: pneuflex.run(""), ValueError, "pneuflex.run: scene_path is an empty path")
    refused(lambda: pneuflex.sweep(42, ["environment.stiffness_n_per_m=700"]), TypeError, "pneuflex.sweep: scene must be a path")
    refused(lambda: pneuflex.identify(42, SHEET, MASS), TypeError, "pneuflex.identify: logs must be a list of paths, got int 42")
    refused(lambda: pneuflex.identify(["rig.csv", 42], SHEET, MASS), TypeError, "pneuflex.identify: logs[1] must be a path")
    refused(lambda: pneuflex.identify("rig.csv", 42, MASS), TypeError, "pneuflex.identify: actuator must be a path")
    refused(lambda: pneuflex.identify("rig.csv", SHEET, MASS, log_format=1), TypeError, "pneuflex.identify: log_format must be a path")
    refused(lambda: envs.ForceControl(scene=42), TypeError, "ForceControl: scene must be a path")
    refused(lambda: envs.ForceControlVector(4, scene=[SCENE]), TypeError, "ForceControlVector: scene must be a path")
    # The native functions: PyO3's TypeError, the argument in its note.
    refused(lambda: pneuflex.load_scene(42), TypeError, "while processing 'path'")
    refused(lambda: pneuflex.ForceControlBatch(None), TypeError, "while processing 'scene_path'")
    with tempfile.TemporaryDirectory() as d:
        here = os.getcwd()
        os.chdir(d)
        try:
            # An `out` of 3 would have been the directory "3" here.
            refused(lambda: pneuflex.sweep(SCENE, ["environment.stiffness_n_per_m=700"], out=3), TypeError,
                    "pneuflex.sweep: out must be a path")
            refused(lambda: pneuflex.tune(SCENE, FREE, out=3), TypeError, "pneuflex.tune: out must be a path")
            refused(lambda: pneuflex.identify("rig.csv", SHEET, MASS, out=3), TypeError, "pneuflex.identify: out")
        finally:
            os.chdir(here)
        assert os.listdir(d) == [], os.listdir(d)


@test
def a_string_where_a_list_belongs_is_one_entry_not_its_characters():
    """sweep(scene, "KEY=...") iterated the string's characters: one string is the one entry it reads as (as
    identify's `free` already was), the same table as the list of it. A dict or a set (no order a user chose),
    a number, or an element that is not a str is a TypeError naming the argument and the element."""
    with tempfile.TemporaryDirectory() as d:
        servo = Path(d) / "servo.toml"
        servo.write_text(SERVO_SCENE)
        one = "environment.stiffness_n_per_m=700,1400"
        table = pneuflex.sweep(servo, one)
        assert table == pneuflex.sweep(servo, [one]) and len(table.frame) == 2 * 2, table
    refused(lambda: pneuflex.sweep(SCENE, [one, 42]), TypeError, 'pneuflex.sweep: sets[1] must be a str ("KEY=SPEC" strings), got int 42')
    refused(lambda: pneuflex.sweep(SCENE, {one: 1}), TypeError, "pneuflex.sweep: sets must be a list", "got dict")
    refused(lambda: pneuflex.sweep(SCENE, {one}), TypeError, "pneuflex.sweep: sets must be a list", "got set")
    refused(lambda: pneuflex.sweep(SCENE, 700), TypeError, "pneuflex.sweep: sets must be a list")
    refused(lambda: pneuflex.sweep(SCENE, [b"environment.stiffness_n_per_m=700"]), TypeError, "sets[0] must be a str")
    refused(lambda: pneuflex.tune(SCENE, 42, out="unused"), TypeError, "pneuflex.tune: free must be a list")
    refused(lambda: pneuflex.tune(SCENE, FREE, over=[700], out="unused"), TypeError, "pneuflex.tune: over[0] must be a str")
    refused(lambda: pneuflex.tune(SCENE, FREE, terms=None, out="unused"), TypeError, "pneuflex.tune: terms must be a list")
    refused(lambda: pneuflex.identify("rig.csv", SHEET, [b"mechanics.moving_mass_kg"]), TypeError, "pneuflex.identify: free[0] must be a str")
    refused(lambda: pneuflex.identify("rig.csv", SHEET, MASS, bounds=5), TypeError, "pneuflex.identify: bounds must be a list")
    # An empty list: nothing to do, said in the package's words before the engine's.
    refused(lambda: pneuflex.sweep(SCENE, []), ValueError, "pneuflex.sweep: sets is empty")
    refused(lambda: pneuflex.tune(SCENE, [], out="unused"), ValueError, "pneuflex.tune: free is empty")
    refused(lambda: pneuflex.identify([], SHEET, MASS), ValueError, "pneuflex.identify: logs is empty")
    refused(lambda: pneuflex.identify("rig.csv", SHEET, []), ValueError, "pneuflex.identify: free is empty")
    assert not Path("unused").exists()


@test
def an_out_folder_is_checked_before_the_work_and_never_overwritten_when_foreign():
    """tune(out=...) wrote into any folder (a user's report.md or tune.json replaced): it is staged as
    `pneuflex tune --out` is, so a folder holding files pneuflex did not write is refused, naming a file, before
    the search, and left as it was. sweep(out=...) refuses a file where the folder goes before anything runs,
    and writes sweep.csv whole (renamed into place), leaving the folder's other files alone."""
    with tempfile.TemporaryDirectory() as d:
        mine = Path(d) / "mine"
        mine.mkdir()
        (mine / "report.md").write_text("my notes")
        refused(lambda: pneuflex.tune(SCENE, FREE, out=mine, budget=8), pneuflex.PneuflexError, "report.md")
        assert sorted(p.name for p in mine.iterdir()) == ["report.md"] and (mine / "report.md").read_text() == "my notes"
        a_file = Path(d) / "a-file"
        a_file.write_text("keep")
        s = ["environment.stiffness_n_per_m=700"]
        refused(lambda: pneuflex.sweep(SCENE, s, out=a_file), NotADirectoryError, "pneuflex.sweep: out:", "a-file")
        (mine / "sweep.csv").mkdir()
        refused(lambda: pneuflex.sweep(SCENE, s, out=mine), IsADirectoryError, "sweep.csv is a folder")
        (mine / "sweep.csv").rmdir()
        assert a_file.read_text() == "keep"
        servo = Path(d) / "servo.toml"
        servo.write_text(SERVO_SCENE)
        table = pneuflex.sweep(servo, s, out=mine)
        assert (mine / "sweep.csv").read_text() == table
        assert sorted(p.name for p in mine.iterdir()) == ["report.md", "sweep.csv"], list(mine.iterdir())


@test
def a_number_of_the_wrong_type_or_sign_is_refused_by_name():
    """Counts, seeds and the search's numbers: a float, a str or a bool where an integer goes is a TypeError, a
    negative count or seed or a NaN a ValueError, each naming the argument; nothing runs and nothing is written.
    (The ranges beyond the sign are the Rust engine's own checks, the CLI's messages.)"""
    s = ["environment.stiffness_n_per_m=700"]
    refused(lambda: pneuflex.sweep(SCENE, s, seed=-1), ValueError, "pneuflex.sweep: seed must be at least 0, got -1")
    refused(lambda: pneuflex.sweep(SCENE, s, seed=2**64), ValueError, "pneuflex.sweep: seed must be below 2^64")
    refused(lambda: pneuflex.sweep(SCENE, s, seed=1.5), TypeError, "pneuflex.sweep: seed must be an integer, got float 1.5")
    refused(lambda: pneuflex.sweep(SCENE, s, samples=0), ValueError, "pneuflex.sweep: samples must be at least 1, got 0")
    refused(lambda: pneuflex.sweep(SCENE, s, samples="4"), TypeError, "pneuflex.sweep: samples must be an integer")
    refused(lambda: pneuflex.sweep(SCENE, s, threads=-2), ValueError, "pneuflex.sweep: threads must be at least 0")
    refused(lambda: pneuflex.sweep(SCENE, s, executor="dask"), ValueError, "pneuflex.sweep: executor must be 'local', 'ray'")
    refused(lambda: pneuflex.sweep(SCENE, s, executor=4), TypeError, "pneuflex.sweep: executor must be")
    refused(lambda: pneuflex.LocalExecutor(threads=-1), ValueError, "LocalExecutor: threads must be at least 0")
    refused(lambda: pneuflex.RayExecutor(chunk_size="8"), TypeError, "RayExecutor: chunk_size must be an integer")
    refused(lambda: pneuflex.RayExecutor(chunk_size=0), ValueError, "RayExecutor: chunk_size must be at least 1")
    with tempfile.TemporaryDirectory() as d:
        out = Path(d) / "tune"
        refused(lambda: pneuflex.tune(SCENE, FREE, out=out, budget=-1), ValueError, "pneuflex.tune: budget must be at least 0")
        refused(lambda: pneuflex.tune(SCENE, FREE, out=out, budget=True), TypeError, "pneuflex.tune: budget must be an integer")
        refused(lambda: pneuflex.tune(SCENE, FREE, out=out, population=2.0), TypeError, "pneuflex.tune: population")
        refused(lambda: pneuflex.tune(SCENE, FREE, out=out, sigma0=float("nan")), ValueError, "pneuflex.tune: sigma0 must be finite")
        refused(lambda: pneuflex.tune(SCENE, FREE, out=out, sigma0="0.3"), TypeError, "pneuflex.tune: sigma0 must be a number")
        refused(lambda: pneuflex.tune(SCENE, FREE, out=out, sigma0=0.0), ValueError, "--sigma0")
        refused(lambda: pneuflex.tune(SCENE, FREE, out=out, run=0), TypeError, "pneuflex.tune: run must be a str or None")
        assert not out.exists()
    refused(lambda: pneuflex.identify("rig.csv", SHEET, MASS, validation="0.2"), TypeError, "pneuflex.identify: validation must be a number")
    refused(lambda: pneuflex.identify("rig.csv", SHEET, MASS, segment=float("inf")), ValueError, "pneuflex.identify: segment must be finite")
    refused(lambda: pneuflex.identify("rig.csv", SHEET, MASS, select="yes"), TypeError, "pneuflex.identify: select must be True or False")


@test
def a_bad_scene_is_refused_naming_the_file_the_line_and_the_key():
    """A misspelt key: every entry point that reads a scene (run, sweep, tune, the Gymnasium environments, a
    controller from the scene) names the file, the line and the key, and writes nothing."""
    import pneuflex.envs as envs

    text = Path(SCENE).read_text()
    line = text[: text.index("stiffness_n_per_m = 700.0")].count("\n") + 1
    with tempfile.TemporaryDirectory() as d:
        bad = Path(d) / "bad.toml"
        bad.write_text(text.replace("stiffness_n_per_m = 700.0", "stifness_n_per_m = 700.0", 1))
        where = f"bad.toml:{line}:"
        out = Path(d) / "out"
        for f in (lambda: pneuflex.run(bad), lambda: pneuflex.sweep(bad, ["environment.x_e_m=0"], out=out),
                  lambda: pneuflex.tune(bad, FREE, out=out), lambda: envs.ForceControl(scene=bad),
                  lambda: envs.ForceControlVector(2, scene=bad), lambda: pneuflex.Controller.from_scene(bad, 0)):
            refused(f, pneuflex.PneuflexError, where, "stifness_n_per_m")
        assert sorted(os.listdir(d)) == ["bad.toml"], os.listdir(d)
        refused(lambda: envs.ForceControl(scene=Path(d) / "none.toml"), FileNotFoundError, "none.toml: no such scene")
        refused(lambda: envs.ForceControl(scene=d), IsADirectoryError, "not a scene file")
    refused(lambda: envs.ForceControl(scene=ROOT / "scenes" / "paper-fig3-ideal.toml"), pneuflex.PneuflexError,
            "paper-fig3-ideal.toml:", "plant.kind", "needs a pneumatic or multibody plant")
    # A scene of the other kind was "unknown field `actuators`" (or `environment`): it says what the scene is
    # and where it runs; a broken scene of several cylinders gets its own loader's file, line and key.
    gripper = ROOT / "scenes" / "gripper.toml"
    # The environment takes a scene of several cylinders (the_gripper_environment_...); a muscle has no
    # chambers p_a, p_b to observe: refused naming the actuator, not observed as NaN.
    refused(lambda: envs.ForceControl(scene="antagonist"), pneuflex.PneuflexError,
            "antagonist.toml", "actuators[0].sheet", "has no chamber pressures p_a, p_b")
    # pneuflex.run takes it (run_mechanism_gives_each_actuator_...); what takes one actuator says so.
    refused(lambda: pneuflex.summarize(gripper, {}), pneuflex.PneuflexError,
            "gripper.toml: a scene with several actuators ([[actuators]])", "pneuflex.run")
    refused(lambda: pneuflex.run_mechanism(SCENE), pneuflex.PneuflexError,
            "paper-fig3.toml: a scene with one [plant], not [[actuators]]: run it with pneuflex.run")
    with tempfile.TemporaryDirectory() as d:
        text = gripper.read_text()
        broken = Path(d) / "broken.toml"
        broken.write_text(text.replace("duration_s", "durration_s", 1))
        line = text[: text.index("duration_s")].count("\n") + 1
        refused(lambda: pneuflex.run(broken), pneuflex.PneuflexError, f"broken.toml:{line}:", "durration_s")


@test
def the_model_and_the_controller_refuse_what_no_state_or_reading_can_be():
    """A NaN valve command was read as some command, a NaN force as a controller output of 0, dt = 0 as a
    tick, a start 1 m outside a 50 mm stroke as a state: each is a ValueError naming the argument. NaN
    pressures stay the documented "no chambers" of a plant without them; u outside [-1, 1] is clamped."""
    a = pneuflex.Actuator(SHEET)
    refused(lambda: pneuflex.OneDof(a, -1.0), ValueError, "x0_m must be within the stroke [0, 0.05] m, got -1")
    refused(lambda: pneuflex.OneDof(a, 0.01, f_ext_n=math.inf), ValueError, "f_ext_n must be finite")
    od = pneuflex.OneDof(a, 0.01)
    refused(lambda: od.step(math.nan, 0.0, 1e-4), ValueError, "u must be finite, got NaN")
    refused(lambda: od.step(0.0, math.nan, 1e-4), ValueError, "f_ext_n must be finite")
    assert od.t == 0.0 and od.x == 0.01
    fe = pneuflex.ForceElement(a)
    refused(lambda: fe.step(0.01, 0.0, math.nan, 1e-4), ValueError, "u must be finite, got NaN")
    refused(lambda: fe.bench_steps(10, 0.01, 0.0, math.inf, 1e-4), ValueError, "u must be finite, got inf")
    assert fe.t == 0.0
    c = pneuflex.Controller.from_scene(SCENE, "adaptive")
    ok = (0.0, 0.02, 0.0, 10.0, 3e5, 3e5, 10.0, 0.02, 1e-3)
    names = ("t", "x", "x_dot", "f_e", "p_a", "p_b", "f_ref", "x_d", "dt")
    for i, name in enumerate(names):
        args = list(ok)
        args[i] = math.inf
        refused(lambda: c.update(*args), ValueError, f"{name} must be finite")
        if name not in ("p_a", "p_b"):
            args[i] = math.nan
            refused(lambda: c.update(*args), ValueError, f"{name} must be finite")
    refused(lambda: c.update(*ok[:8], 0.0), ValueError, "dt must be finite and > 0, got 0")
    assert math.isfinite(c.update(*ok[:4], math.nan, math.nan, *ok[6:]))  # no chambers
    refused(lambda: pneuflex.Setpoints(SCENE).at(math.nan), ValueError, "t must be finite, got NaN")


def _single(action="valve"):
    import pneuflex.envs as envs

    env = envs.ForceControl(action=action)
    env.reset(seed=0, options={"randomize": False})
    return env


@test
def an_action_of_another_shape_is_refused_not_cut():
    """A (4,) action for Box(1) was cut to its first value: any shape other than the action space's (no
    truncation, no broadcasting, no scalar for Box(1), as Gymnasium's Box.contains) is a ValueError giving both
    shapes, and the episode does not move. The vector environment wants (num_envs, width): a flat or transposed
    batch is refused, not reinterpreted."""
    import pneuflex.envs as envs

    env = _single()
    for a in (np.zeros(4, np.float32), np.float32(0.3), 0.3, np.zeros((1, 1)), np.zeros(0), [[0.1], [0.2]]):
        refused(lambda: env.step(a), ValueError, "ForceControl.step: the action has shape", "the action space's is (1,)")
    assert env.t == 0.0
    imp = _single("impedance")
    refused(lambda: imp.step(np.zeros(1)), ValueError, "the action has shape (1,); the action space's is (2,)")
    refused(lambda: imp.step(np.zeros(3)), ValueError, "the action has shape (3,)")
    refused(lambda: env.step([[1.0], [1.0, 2.0]]), ValueError, "ForceControl.step: the action is not an array of shape (1,)")
    vec = envs.ForceControlVector(3, action="impedance")
    vec.reset(seed=0)
    for a in (np.zeros(6), np.zeros((2, 3)), np.zeros((3, 1)), np.zeros((4, 2))):
        refused(lambda: vec.step(a), ValueError, f"ForceControlVector.step: the action has shape {a.shape}; "
                                                 "the action space's is (3, 2)")
    assert all(vec.batch.sensors(i)[0] == 0.0 for i in range(3))
    env.step(np.zeros(1, np.float32))
    assert env.t > 0.0, "a good action after the refusals steps"


@test
def an_action_that_is_not_real_numbers_is_a_type_error():
    """A str, None, a bool, a complex number or an object array is not a valve command: a TypeError with the
    dtype, nothing stepped. Integers and float64 are real numbers and taken (as float32 would be)."""
    env = _single()
    for a in (np.array(["0.5"]), ["0.5"], None, np.array([True]), np.array([0.5j]), np.array([object()])):
        refused(lambda: env.step(a), TypeError, "ForceControl.step: the action must hold real numbers", "got dtype")
    assert env.t == 0.0
    env.step(np.array([1]))
    env.step(np.array([0.5]))
    refused(lambda: pneuflex.ForceControlBatch(SCENE, 2).step([0.0, 0.0]), TypeError,
            "actions must be a float64 or float32 numpy array (num_envs x action_width values), got list")
    refused(lambda: pneuflex.ForceControlBatch(SCENE, 2).step(np.zeros(2, np.float16)), TypeError,
            "got ndarray of dtype float16 and shape (2,)")
    # float32 (the action space's dtype) and float64 are read as they are, in C order.
    b32, b64 = pneuflex.ForceControlBatch(SCENE, 2), pneuflex.ForceControlBatch(SCENE, 2)
    for b in (b32, b64):
        b.reset(3)
    u = np.array([[0.25], [-0.5]])
    o32, o64 = b32.step(u.astype(np.float32)), b64.step(u.ravel())
    assert all(np.array_equal(x, y) for x, y in zip(o32, o64))


@test
def a_non_finite_action_is_refused_and_one_out_of_range_clipped():
    """NaN was read as 0 (the valve closed): a NaN or an infinity is a ValueError naming the environment and the
    value, in the single, the vector and the raw batch environments, and no episode moves. A finite value outside
    [-1, 1] is clipped (Gymnasium's continuous-control convention; the valve saturates): 5 steps as 1, and
    (3, -7) retunes as (1, -1)."""
    import pneuflex.envs as envs

    env = _single()
    for bad, says in ((np.nan, "NaN"), (np.inf, "inf"), (-np.inf, "-inf")):
        refused(lambda: env.step(np.array([bad], np.float32)), ValueError,
                f"ForceControl.step: actions[0] (environment 0, value 0) is {says}: an action must be finite")
    assert env.t == 0.0
    vec = envs.ForceControlVector(3, action="impedance")
    vec.reset(seed=0)
    a = np.zeros((3, 2))
    a[2, 1] = np.nan
    refused(lambda: vec.step(a), ValueError, "ForceControlVector.step: actions[5] (environment 2, value 1) is NaN")
    assert all(vec.batch.sensors(i)[0] == 0.0 for i in range(3))
    batch = pneuflex.ForceControlBatch(SCENE, 2)
    refused(lambda: batch.step(np.array([0.0, np.inf])), ValueError, "actions[1] (environment 1, value 0) is inf")
    clipped, one = _single(), _single()
    for _ in range(20):
        assert np.array_equal(clipped.step(np.array([5.0]))[0], one.step(np.array([1.0]))[0])
    clipped, one = _single("impedance"), _single("impedance")
    for _ in range(5):
        assert np.array_equal(clipped.step(np.array([3.0, -7.0]))[0], one.step(np.array([1.0, -1.0]))[0])


@test
def a_step_outside_an_episode_is_refused():
    """Stepping before reset() (the vector environment too), or after the step that ended the episode, is a
    RuntimeError saying to reset: an ended episode ran on past its end stop or its duration before. reset()
    starts a new one."""
    import pneuflex.envs as envs

    refused(lambda: envs.ForceControl().step(np.zeros(1)), RuntimeError, "ForceControl.step: call reset() before step()")
    refused(lambda: envs.ForceControlVector(2).step(np.zeros((2, 1))), RuntimeError,
            "ForceControlVector.step: call reset() before step()")
    env = _single()
    for _ in range(10000):
        _, _, terminated, truncated, _ = env.step(-np.ones(1))
        if terminated or truncated:
            break
    assert terminated, "full retraction never reached the end stop"
    t = env.t
    refused(lambda: env.step(np.zeros(1)), RuntimeError, "the episode ended at t =", "terminated", "call reset()")
    assert env.t == t
    env.reset(seed=0)
    env.step(np.zeros(1))
    assert env.t > 0.0


@test
def reset_options_and_seeds_are_checked():
    """options={"randomise": False} (a typo) was ignored and {"randomize": "no"} read as True: an unknown key is
    a ValueError listing the keys, a non-bool a TypeError. A vector reset's seeds: one int per environment, each
    in [0, 2^64), else an error naming the seed; so for the raw batch."""
    import pneuflex.envs as envs

    env = envs.ForceControl()
    refused(lambda: env.reset(seed=0, options={"randomise": False}), ValueError,
            "ForceControl.reset: options: unknown key 'randomise'; the keys are randomize")
    refused(lambda: env.reset(seed=0, options={"randomize": "no"}), TypeError,
            "ForceControl.reset: options[\"randomize\"] must be True or False, got str 'no'")
    refused(lambda: env.reset(options=["randomize"]), TypeError, "ForceControl.reset: options must be a dict or None")
    vec = envs.ForceControlVector(3)
    refused(lambda: vec.reset(seed=[1, 2]), ValueError, "ForceControlVector.reset: seed: (2,) seeds for 3 environments")
    refused(lambda: vec.reset(seed=[1, 2.5, 3]), TypeError, "ForceControlVector.reset: seed[1] must be an integer")
    refused(lambda: vec.reset(seed=[1, -2, 3]), ValueError, "ForceControlVector.reset: seed[1] must be at least 0")
    refused(lambda: vec.reset(seed="7"), TypeError, "ForceControlVector.reset: seed must be None, an int or a list of ints")
    refused(lambda: vec.reset(seed=True), TypeError, "ForceControlVector.reset: seed must be None")
    refused(lambda: vec.reset(seed=-1), ValueError, "ForceControlVector.reset: seed must be at least 0")
    refused(lambda: vec.reset(seed=0, options={"randomize": 1}), TypeError, "options[\"randomize\"] must be True or False")
    batch = pneuflex.ForceControlBatch(SCENE, 2)
    refused(lambda: batch.reset(-1), ValueError, "seed must be in [0, 2^64), got -1")
    refused(lambda: batch.reset([1, -2]), ValueError, "seed[1] must be in [0, 2^64), got -2")
    refused(lambda: batch.reset("1"), TypeError, "seed must be an int or a list of ints (one per environment), got str")
    refused(lambda: batch.reset([1, 2, 3]), ValueError, "seed: 3 seeds for 2 environments")


@test
def environment_arguments_are_checked():
    """The environments' own arguments: num_envs and decision_ticks at least 1 and integers (decision_ticks=0
    was read as 1), randomize a bool (randomize="no" was True), action a str the batch knows (naming the
    scene); each an error naming the argument, through gymnasium.make too."""
    import gymnasium

    import pneuflex.envs as envs

    refused(lambda: envs.ForceControlVector(0), ValueError, "ForceControlVector: num_envs must be at least 1, got 0")
    refused(lambda: envs.ForceControlVector(2.0), TypeError, "ForceControlVector: num_envs must be an integer, got float 2.0")
    refused(lambda: envs.ForceControl(action="impedance", decision_ticks=0), ValueError,
            "ForceControl: decision_ticks must be at least 1, got 0")
    refused(lambda: envs.ForceControlVector(2, decision_ticks=2.5), TypeError, "ForceControlVector: decision_ticks must be an integer")
    refused(lambda: pneuflex.ForceControlBatch(SCENE, 1, action="impedance", decision_ticks=0), ValueError,
            "decision_ticks must be at least 1")
    refused(lambda: envs.ForceControl(randomize="no"), TypeError, "ForceControl: randomize must be True or False, got str 'no'")
    refused(lambda: envs.ForceControl(action=None), TypeError, 'ForceControl: action must be "valve", "pressure" or "impedance", got NoneType')
    refused(lambda: envs.ForceControl(action="torque"), pneuflex.PneuflexError, "paper-fig3.toml", 'action = "torque"')
    refused(lambda: gymnasium.make("pneuflex/ForceControl-v0", randomize="no"), TypeError, "randomize must be True or False")
    refused(lambda: gymnasium.make_vec("pneuflex/ForceControl-v0", num_envs=-1, vectorization_mode="vector_entry_point"),
            ValueError, "num_envs must be at least 1, got -1")


# A scene for plants written in Python: 10 N step against a spring whose stiffness doubles at 2 s; k_d > 0
# leaves a static force error with a closed form. Its [plant] is not built by run_plant (the Python plant
# replaces it); it only has to be a valid scene.
SERVO_SCENE = """
name = "python-servo"
duration_s = 4.0
dt_s = 0.001

[plant]
kind = "ideal"
omega_rad_per_s = 200.0
zeta = 1.0
x0_m = 0.0

[environment]
stiffness_n_per_m = 700.0
x_e_m = 0.0

[reference]
x_d_m = 0.0

[[reference.force]]
kind = "step"
start_s = 0.0
value_n = 10.0

[[events]]
kind = "stiffness"
t_s = 2.0
stiffness_n_per_m = 1400.0

[[runs]]
name = "impedance"
controller = "impedance"
impedance = { m_d_kg = 2.0, b_d_ns_per_m = 52.4, k_d_n_per_m = 300.0 }
inner = { kp_per_m = 200.0, ki_per_m_s = 50.0, kd_s_per_m = 2.0 }

[[runs]]
name = "adaptive"
controller = "adaptive"
impedance = { m_d_kg = 2.0, b_d_ns_per_m = 52.4, k_d_n_per_m = 300.0 }
inner = { kp_per_m = 200.0, ki_per_m_s = 50.0, kd_s_per_m = 2.0 }
adaptive = { position_unit_m = 1.0, force_unit_n = 1.0, lambda_d_sign = "from_edot", sigma1_sign = "leakage", lambda_p = 1.0, lambda_d = 8.0, mu1 = 0.01, mu2 = 0.0001, mu3 = 0.01, sigma1 = 0.1, sigma2 = 0.1, sigma3 = 0.1 }

[[metrics]]
name = "soft"
t0_s = 1.5
t1_s = 2.0
kind = "step"

[[metrics]]
name = "stiff"
t0_s = 3.5
t1_s = 4.0
kind = "step"
"""


class Servo:
    """A first-order position servo (time constant tau, exact step) against a linear spring f_e = k (x - x_e):
    a plant for pneuflex.run_plant, in pure Python."""

    def __init__(self, tau: float = 0.01, k: float = 700.0, x_e: float = 0.0):
        self.tau, self.k0, self.x_e = tau, k, x_e
        self.reset()

    def reset(self):
        self.x = self.v = self.x_r = 0.0
        self.k = self.k0
        self.ticks = 0
        self.events = []

    def apply(self, ev):
        self.events.append(ev)
        if ev["kind"] != "stiffness":
            raise NotImplementedError(ev["kind"])
        self.k = ev["stiffness_n_per_m"]

    def sense(self):
        return self.x, self.v, self.k * max(self.x - self.x_e, 0.0), math.nan, math.nan

    def actuate(self, u, x_r):
        self.x_r = x_r

    def advance(self, dt):
        x1 = self.x + (self.x_r - self.x) * (1.0 - math.exp(-dt / self.tau))
        self.v = (x1 - self.x) / dt
        self.x = x1
        self.ticks += 1


def python_loop(scene_path: str, run: str, plant) -> dict:
    """The scene loop written out in Python (events, sense, update, record, actuate, advance), to check run_plant
    against: the same controller and setpoints through the bindings."""
    scene = pneuflex.load_scene(scene_path)
    dt, n = scene["dt_s"], scene["n_steps"]
    ctl = pneuflex.Controller.from_scene(scene_path, run)
    sp = pneuflex.Setpoints(scene_path)
    events = sorted(scene["events"], key=lambda e: e["t_s"])
    names = [name for name, _unit, _group in pneuflex.loop_signals()] + list(ctl.signals)
    rows = []
    plant.reset()
    for k in range(n + 1):
        t = k * dt
        while events and events[0]["t_s"] <= t + 0.5 * dt:
            plant.apply(events.pop(0))
        x, xd, f_e, p_a, p_b = plant.sense()
        f_ref, x_d = sp.at(t)
        u = ctl.update(t, x, xd, f_e, p_a, p_b, f_ref, x_d, dt)
        rows.append([t, f_ref, f_e, x, ctl.x_r, p_a, p_b, u] + ctl.record())
        if k == n:
            break
        plant.actuate(u, ctl.x_r)
        plant.advance(dt)
    return {name: np.array(col) for name, col in zip(names, zip(*rows))}


@test
def run_plant_drives_a_python_plant_in_the_scene_loop():
    """pneuflex.run_plant runs the scene crate's loop with a plant written in Python: the same numbers as the
    loop written out in Python, the event handed over as the scene's dict, the columns the controller
    declares (g, p, d for the adaptive run), and, for impedance control with k_d > 0 on a servo against a
    spring, the closed-form static force error e = k_d (f_r - k_e (x_d - x_e)) / (k_d + k_e) before and after
    the stiffness doubles."""
    with tempfile.TemporaryDirectory() as d:
        path = str(Path(d) / "servo.toml")
        Path(path).write_text(SERVO_SCENE)
        loop_names = [name for name, _unit, _group in pneuflex.loop_signals()]
        assert loop_names == ["t", "f_ref", "f_e", "x", "x_r", "p_a", "p_b", "u"], loop_names
        for run, own in (("impedance", []), ("adaptive", ["g", "p", "d"])):
            plant = Servo()
            trace, summary, wall = pneuflex.run_plant(path, run, plant)
            assert isinstance(summary, dict), f"{run} diverged: {summary}"
            assert wall > 0.0
            assert list(trace) == loop_names + own, list(trace)
            assert list(pneuflex.Controller.from_scene(path, run).signals) == own
            assert len(trace["t"]) == 4001 and plant.ticks == 4000
            assert len(plant.events) == 1 and plant.events[0]["kind"] == "stiffness", plant.events
            assert plant.events[0]["t_s"] == 2.0 and plant.events[0]["stiffness_n_per_m"] == 1400.0
            expected = python_loop(path, run, Servo())
            for name, col in expected.items():
                assert np.array_equal(trace[name], col, equal_nan=True), (run, name, np.nanmax(np.abs(trace[name] - col)))
            (r,) = summary["runs"]
            assert r["name"] == run and not r["diverged"]
            if run == "impedance":
                windows = {w["name"]: w for w in r["windows"]}
                for window, k_e in (("soft", 700.0), ("stiff", 1400.0)):
                    e_ss = 300.0 * 10.0 / (300.0 + k_e)  # x_d = x_e = 0
                    got = windows[window]["steady_state_error_n"]
                    assert abs(got - e_ss) < 1e-5, (window, got, e_ss)


@test
def run_plant_stops_a_raising_plant_as_diverged_naming_the_exception():
    """An exception in advance (or a bad sense) stops the run as diverged: the reason names the method, the
    time, the exception's type, message and line; the trace ends with the tick that could not be sensed. An
    exception in apply is the runner's event error with the exception as its cause; an object without the
    plant's methods is a TypeError naming them."""

    class Stuck(Servo):
        def advance(self, dt):
            if self.ticks == 500:
                raise RuntimeError("valve stuck")
            super().advance(dt)

    class BadSense(Servo):
        def sense(self):
            return (self.x, self.v)

    class NoEvents(Servo):
        def apply(self, ev):
            raise NotImplementedError("no stiffness events here")

    with tempfile.TemporaryDirectory() as d:
        path = str(Path(d) / "servo.toml")
        Path(path).write_text(SERVO_SCENE)
        trace, reason, _ = pneuflex.run_plant(path, "impedance", Stuck())
        assert isinstance(reason, str), reason
        for part in ("advance(dt)", "t = 0.5000 s", "RuntimeError: valve stuck", "test_bindings.py:"):
            assert part in reason, (part, reason)
        assert len(trace["t"]) == 502 and math.isnan(trace["x"][-1]) and np.all(np.isfinite(trace["x"][:-1])), len(trace["t"])
        _, reason, _ = pneuflex.run_plant(path, 0, BadSense())
        assert isinstance(reason, str) and "sense()" in reason and "5 floats" in reason, reason
        try:
            pneuflex.run_plant(path, "adaptive", NoEvents())
        except pneuflex.PneuflexError as e:
            assert "servo.toml" in str(e) and "events[0]" in str(e), str(e)
            assert "NotImplementedError: no stiffness events here" in str(e), str(e)
            assert isinstance(e.__cause__, NotImplementedError), repr(e.__cause__)
        else:
            raise AssertionError("a failing apply went unnoticed")
        try:
            pneuflex.run_plant(path, "impedance", object())
        except TypeError as e:
            assert "reset, apply, sense, actuate, advance" in str(e), str(e)
        else:
            raise AssertionError("an object without the plant's methods was accepted")


@test
def mujoco_face_mount_obeys_eq21_at_three_inclines():
    """The generated MJCF (crossval/mjcf.py): under a constant push the steady contact force equals the push
    plus the flange's weight along the axis, and f_e = k_e (x - x_e) within 0.05 N, at three inclines."""
    import mujoco

    from crossval import mjcf

    for alpha in (0.0, 30.0, 60.0):
        for k in (700.0, 1400.0):
            face = mjcf.Face("env", k, 5.0, 0.009, 0.005, 0.02)
            spec = mjcf.RigSpec("t", 1e-3, 0.05, 0.6, 20.0, 0.01, math.radians(alpha), 9.80665, 0.02, [face])
            model = mujoco.MjModel.from_xml_string(mjcf.build_mjcf(spec))
            data = mujoco.MjData(model)
            data.qpos[0] = 0.02
            data.qfrc_applied[0] = 8.0
            for _ in range(5000):
                mujoco.mj_step(model, data)
            force = np.zeros(6)
            f_e = 0.0
            for i in range(data.ncon):
                mujoco.mj_contactForce(model, data, i, force)
                f_e += force[0]
            push = 8.0 + 0.6 * 9.80665 * math.sin(math.radians(alpha))
            assert abs(f_e - push) < 0.05, (alpha, k, f_e, push)
            assert abs(f_e - k * (data.qpos[0] - 0.02)) < 0.05, (alpha, k, f_e, data.qpos[0])
            assert sum(data.warning[i].number for i in range(len(data.warning))) == 0


@test
def mujoco_rig_swaps_wood_for_iron():
    """The URDF rig in MuJoCo (mjcf.spec_from_urdf, mocap carriage): x_e = 0.02 m for both faces as in the
    URDF; under a constant push the flange loses contact during the swap, runs to its stroke end, and the
    iron face takes the push: f_e = push + m g sin(alpha) = k_iron (x - x_e) after the swap."""
    from crossval import couple, mjcf

    mats = {"wood": ("wood_mount", 700.0, 2.0), "iron": ("iron_mount", 1400.0, 2.0)}
    spec = mjcf.spec_from_urdf(str(ROOT / "urdf" / "rig.urdf"), mats, 0.3, 1e-4, x0_m=0.02)
    assert [round(f.x_e_m, 12) for f in spec.faces] == [0.02, 0.02]
    sim = couple.Sim(couple.Coupled("rig", {}, spec, mjcf.build_mjcf(spec), 1))
    sim.data.qfrc_applied[sim.flange_dof] = 5.0
    push = 5.0 + spec.flange_mass_kg * 9.80665 * math.sin(0.3)
    f, x = [], []
    for k in range(25000):
        if k == 5000:
            sim.apply({"kind": "swap", "to": "iron", "duration_s": 0.6})
        sim.step(1e-4)
        f.append(sim.contact_force())
        x.append(sim.x()[0])
    sim.check(2.5)
    assert abs(f[4999] - push) < 0.01 and abs(f[4999] - 700.0 * (x[4999] - 0.02)) < 0.05, (f[4999], x[4999])
    assert min(f[5000:11000]) == 0.0 and max(x[5000:11000]) > 0.0499, "contact must be lost during the swap"
    assert max(x) < 0.0505, f"the stroke end must hold: {max(x)}"
    assert sim.active == "iron"
    assert abs(f[-1] - push) < 0.01 and abs(f[-1] - 1400.0 * (x[-1] - 0.02)) < 0.05, (f[-1], x[-1])


@test
def mujoco_divergence_is_detected():
    """A run MuJoCo cannot integrate is reported as diverged, never compared."""
    import mujoco

    from crossval import couple

    c = couple.prepare(SCENE, substeps=1)
    sim = couple.Sim(c)
    sim.data.qfrc_applied[sim.flange_dof] = 1e300
    for _ in range(5):
        mujoco.mj_step(sim.model, sim.data)
    try:
        sim.check(0.005)
    except couple.DivergedError as e:
        assert "MuJoCo" in str(e)
    else:
        raise AssertionError("MuJoCo's reset went unnoticed")

    # In the coupled run, the warning raised by MujocoPlant.advance stops the Rust loop as diverged.
    class Blowup(couple.MujocoPlant):
        def advance(self, dt):
            self.sim.data.qfrc_applied[self.sim.flange_dof] = 1e300
            for _ in range(5):
                mujoco.mj_step(self.sim.model, self.sim.data)
            self.sim.check(dt)

    trace, reason, _ = pneuflex.run_plant(c.scene_path, "impedance", Blowup(c))
    assert isinstance(reason, str) and "DivergedError: MuJoCo warning" in reason and "advance(dt)" in reason, reason
    assert len(trace["t"]) == 2, len(trace["t"])


@test
def identify_recovers_a_mass_from_a_simulated_log():
    """pneuflex.identify on a log simulated with OneDof (the rig's timing: row k's command over the next 1 ms,
    10 RK4 substeps) from a sheet whose moving mass is 0.75 kg: fitted from the shipped 0.6 kg within 0.5 %,
    dicts and arrays as documented; an unknown key raises PneuflexError naming it."""
    import shutil

    with tempfile.TemporaryDirectory() as d:
        d = Path(d)
        for f in (ROOT / "pneumatics").glob("*.toml"):
            shutil.copy(f, d / f.name)
        sheet = d / "paper-actuator.toml"
        text = sheet.read_text()
        assert "moving_mass_kg = 0.6" in text
        sheet.write_text(text.replace("moving_mass_kg = 0.6", "moving_mass_kg = 0.75"))
        m = pneuflex.OneDof(pneuflex.Actuator(str(sheet)), 0.0, p_a=101325.0, p_b=101325.0)
        rows = ["t,f_ref,f_e,x,x_r,p_a,p_b,u"]
        for k in range(3000):
            t = k * 1e-3
            centre = 0.025 * min(t, 1.0)
            u = max(-1.0, min(1.0, 15.0 * (centre - m.x) + 0.05 * (1 if math.sin(2 * math.pi * 3 * t) > 0 else -1)))
            rows.append(f"{t!r},0,0,{m.x!r},{centre!r},{m.p_a!r},{m.p_b!r},{u!r}")
            for _ in range(10):
                m.step(u, 0.0, 1e-4)
        log = d / "trace.csv"
        log.write_text("\n".join(rows) + "\n")
        r = pneuflex.identify(log, SHEET, ["mechanics.moving_mass_kg"], validation=0.25, out=d / "fit")
        e = r["estimates"]["mechanics.moving_mass_kg"]
        assert abs(e["value"] / 0.75 - 1) < 5e-3, e
        assert e["ci95"][0] < e["value"] < e["ci95"][1], e
        assert r["keys"] == ["mechanics.moving_mass_kg"] and r["correlation"].shape == (1, 1)
        assert r["rms_validation"]["x"] < 0.5e-3 and r["rms_validation"]["p_a"] < 0.02 * 601325.0, r["rms_validation"]
        v = r["validation"][0]
        assert isinstance(v["t"], np.ndarray) and len(v["t"]) == len(v["x_model"]) > 500
        assert (d / "fit" / "paper-actuator.toml").is_file() and (d / "fit" / "report.json").is_file()
        try:
            pneuflex.identify(log, SHEET, ["mechanics.mass"])
            raise AssertionError("accepted an unknown key")
        except pneuflex.PneuflexError as err:
            assert "--free: mechanics.mass" in str(err), err
        # The same log as another tool exports it (';', ms, mm, kPa), read through a log format file: the
        # same estimate.
        export = ["Zeit;Ventil;Weg;pA;pB;Kraft"]
        for row in rows[1:]:
            t, _, f_e, x, _, p_a, p_b, u = (float(v) for v in row.split(","))
            export.append(f"{t * 1e3!r};{u!r};{x * 1e3!r};{p_a * 1e-3!r};{p_b * 1e-3!r};{f_e!r}")
        theirs = d / "export.csv"
        theirs.write_text("\n".join(export) + "\n")
        fmt = d / "logger.toml"
        fmt.write_text(
            'separator = ";"\n[columns]\nt = { name = "Zeit", unit = "ms" }\nu = { name = "Ventil", unit = "1" }\n'
            'x = { name = "Weg", unit = "mm" }\np_a = { name = "pA", unit = "kPa" }\n'
            'p_b = { name = "pB", unit = "kPa" }\nf_e = { name = "Kraft", unit = "N" }\n'
        )
        r2 = pneuflex.identify(theirs, SHEET, ["mechanics.moving_mass_kg"], validation=0.25, log_format=fmt)
        e2 = r2["estimates"]["mechanics.moving_mass_kg"]
        assert abs(e2["value"] / e["value"] - 1) < 1e-6, (e2, e)
        fmt.write_text(fmt.read_text().replace('unit = "ms"', 'unit = "min"'))
        try:
            pneuflex.identify(theirs, SHEET, ["mechanics.moving_mass_kg"], log_format=fmt)
            raise AssertionError("accepted a unit time does not take")
        except OSError as err:
            assert "logger.toml:3:" in str(err) and "columns.t.unit" in str(err), err



@test
def run_mechanism_gives_each_actuator_its_prefixed_columns_and_the_summary():
    """A scene with [[actuators]] from Python: per run, `t` and each actuator's columns under its name, the
    squeeze the scene asks for on both fingers, and the summary's claims (docs/multibody.md)."""
    traces, summary, wall_s = _gripper_runs()[0]
    assert set(traces) == {"impedance", "adaptive"}, list(traces)
    tr = traces["adaptive"]
    for side in ("left", "right"):
        for c in ("f_ref", "f_e", "x", "x_r", "u", "p_a", "p_b", "x_dot", "force", "p"):
            assert f"{side}.{c}" in tr, (side, c, list(tr))
    t = tr["t"]
    assert len(t) == 8001 and abs(t[-1] - 8.0) < 1e-9
    squeeze = (t >= 2.5) & (t <= 3.0)
    for side in ("left", "right"):
        assert abs(float(np.mean(tr[f"{side}.f_e"][squeeze])) - 10.0) < 0.1
    assert summary["actuators"] == ["left", "right"] and len(summary["claims"]) == 4
    assert wall_s > 0.0
    # pneuflex.run takes every scene kind: the same runs as Results, metrics per actuator, the claims.
    res = _gripper_runs()[1]
    assert isinstance(res, pneuflex.Results) and set(res) == {"impedance", "adaptive"}
    assert np.array_equal(res["adaptive"]["left.f_e"], tr["left.f_e"]), "the one loop is deterministic"
    assert res.summary["runs"][1]["controller"] == "adaptive" and len(res.claims) == 4
    try:
        import pandas  # noqa: F401
    except ImportError:
        pass
    else:
        m = res.metrics
        assert list(m.index.names) == ["run", "window", "actuator"], m.index.names
        assert m.loc[("adaptive", "sine_rubber", "right"), "rms_force_error_n"] > 0.0
    try:
        pneuflex.run_mechanism(str(ROOT / "scenes" / "no-such.toml"))
    except FileNotFoundError as e:
        assert "no-such.toml" in str(e)
    else:
        raise AssertionError("a missing scene was accepted")

if __name__ == "__main__":
    sys.exit(main())
