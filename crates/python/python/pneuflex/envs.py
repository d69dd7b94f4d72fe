"""Gymnasium environments on pneuflex's plants (``pip install gymnasium``; importing this module registers them).

``pneuflex/ForceControl-v0`` (:class:`ForceControl`) is the paper's force-control task on the 1-DOF pneumatic
plant of a scene (default ``scenes/paper-fig3.toml``): the flange starts touching a spring environment and must
follow the scene's force reference while the environment's stiffness changes under it.

- **Action**: the valve command u in [-1, 1] (``Box(1)``), held over one control tick of the scene's ``dt_s``.
- **Observation** (``Box(6)``, float32, scaled to order one): contact force f_e / 10 N, reference f_ref / 10 N,
  (x - x_e) / 10 mm, velocity / (0.1 m/s), p_a / 1 bar, p_b / 1 bar (absolute).
- **Reward**: -((f_ref - f_e) / 10 N)^2 per tick: the squared force error the paper's RMS metric sums.
- **Episode**: the scene's duration (10 s = 10,000 ticks for fig3), then truncated; terminated early if the
  flange reaches either end of the stroke.
- **Domain randomisation** (on by default, off with ``reset(options={"randomize": False})``, which gives the
  scene's own values): the stiffness before and after the change, each log-uniform in 350-2800 N/m, and the
  time of the change, uniform in 4-8 s. Seeded through ``reset(seed=...)``: the same seed and actions give the
  same episode.

The plant is ``pneuflex.OneDof`` (the pneumatics crate's model: chambers, valve, mass, friction) stepped with
the scene's substeps, the spring force held over each substep. The moving mass and the friction are the sheet's
(not randomised: the bindings load a sheet as it is written).
"""

from __future__ import annotations

import math
from pathlib import Path

import gymnasium
import numpy as np

import pneuflex

_DEFAULT_SCENE = Path(__file__).resolve().parents[4] / "scenes" / "paper-fig3.toml"

#: Observation scales: f_e and f_ref in 10 N, x - x_e in 10 mm, velocity in 0.1 m/s, pressures in bar.
SCALES = np.array([10.0, 10.0, 0.01, 0.1, 1e5, 1e5])


class ForceControl(gymnasium.Env):
    """The paper's force-control task on the 1-DOF pneumatic plant (see the module doc)."""

    metadata = {"render_modes": []}

    def __init__(self, scene: str | Path | None = None, randomize: bool = True):
        scene = Path(scene) if scene is not None else _DEFAULT_SCENE
        if not scene.is_file():
            raise FileNotFoundError(f"{scene}: no such scene (pass scene=PATH to a 1-DOF pneumatic scene)")
        self.scene_path = str(scene)
        s = pneuflex.load_scene(self.scene_path)
        if s["plant"]["kind"] != "pneumatic":
            raise pneuflex.PneuflexError(
                f"{scene}: plant.kind is {s['plant']['kind']!r}; ForceControl needs a pneumatic (1-DOF) plant"
            )
        self.dt = float(s["dt_s"])
        self.duration = float(s["duration_s"])
        self.substeps = int(s["plant"].get("substeps") or 1)
        self.x_e = float(s["environment"]["x_e_m"])
        self.k0 = float(s["environment"]["stiffness_n_per_m"])
        changes = [e for e in s.get("events", []) if e.get("kind") == "stiffness"]
        self.k1 = float(changes[0]["stiffness_n_per_m"]) if changes else self.k0
        self.t_change = float(changes[0]["t_s"]) if changes else math.inf
        actuator = (Path(s["base_dir"]) / s["plant"]["actuator"]).resolve()
        self.actuator = pneuflex.Actuator(str(actuator))
        self.stroke = float(self.actuator.params()["stroke_m"])
        self.setpoints = pneuflex.Setpoints(self.scene_path)
        self.initial = pneuflex.initial_state(self.scene_path)
        self.randomize = randomize
        self.action_space = gymnasium.spaces.Box(-1.0, 1.0, shape=(1,), dtype=np.float32)
        # Far beyond any reading of the plant (the scaled values are of order one).
        self.observation_space = gymnasium.spaces.Box(-1e4, 1e4, shape=(6,), dtype=np.float32)
        self.plant = None

    def _contact(self, x: float, k: float) -> float:
        """The spring environment's force on the flange's push, N (positive while pressed)."""
        return k * (x - self.x_e) if x > self.x_e else 0.0

    def _stiffness(self) -> float:
        return self.k_after if self.t >= self.t_switch else self.k_before

    def _obs(self) -> np.ndarray:
        m = self.plant
        f_ref, _ = self.setpoints.at(self.t)
        raw = np.array([self.f_e, f_ref, m.x - self.x_e, m.x_dot, m.p_a, m.p_b])
        return (raw / SCALES).astype(np.float32)

    def reset(self, *, seed=None, options=None):
        super().reset(seed=seed)
        randomize = (options or {}).get("randomize", self.randomize)
        if randomize:
            lo, hi = math.log(350.0), math.log(2800.0)
            self.k_before = float(math.exp(self.np_random.uniform(lo, hi)))
            self.k_after = float(math.exp(self.np_random.uniform(lo, hi)))
            self.t_switch = float(self.np_random.uniform(4.0, 8.0))
        else:
            self.k_before, self.k_after, self.t_switch = self.k0, self.k1, self.t_change
        i = self.initial
        self.plant = pneuflex.OneDof(self.actuator, i["x"], p_a=i["p_a"], p_b=i["p_b"])
        self.t = 0.0
        self.f_e = self._contact(self.plant.x, self.k_before)
        info = {"stiffness_n_per_m": self.k_before, "t_change_s": self.t_switch,
                "stiffness_after_n_per_m": self.k_after}
        return self._obs(), info

    def step(self, action):
        if self.plant is None:
            raise RuntimeError("call reset() before step()")
        u = float(np.clip(np.asarray(action, dtype=float).reshape(-1)[0], -1.0, 1.0))
        h = self.dt / self.substeps
        k = self._stiffness()
        for _ in range(self.substeps):
            self.plant.step(u, -self._contact(self.plant.x, k), h)
        self.t += self.dt
        self.f_e = self._contact(self.plant.x, self._stiffness())
        f_ref, _ = self.setpoints.at(self.t)
        reward = -(((f_ref - self.f_e) / SCALES[0]) ** 2)
        x = self.plant.x
        terminated = bool(x <= 0.0 or x >= self.stroke or not math.isfinite(x))
        truncated = self.t >= self.duration - 0.5 * self.dt
        return self._obs(), float(reward), terminated, truncated, {"f_e_n": self.f_e, "u": u}


def adaptive_baseline(env: ForceControl, run: str = "adaptive"):
    """The scene's own controller (its ``run``, by default the adaptive one) as a policy: ``policy(obs) -> action``
    reading the plant's state through ``env`` (a baseline a learned policy should beat)."""
    c = pneuflex.Controller.from_scene(env.scene_path, run)

    def policy(_obs):
        m = env.plant
        f_ref, x_d = env.setpoints.at(env.t)
        u = c.update(env.t, m.x, m.x_dot, env.f_e, m.p_a, m.p_b, f_ref, x_d, env.dt)
        return np.array([u], dtype=np.float32)

    policy.reset = c.reset
    return policy


gymnasium.register(id="pneuflex/ForceControl-v0", entry_point="pneuflex.envs:ForceControl")
