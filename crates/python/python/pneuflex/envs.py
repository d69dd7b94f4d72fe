"""Gymnasium environments on pneuflex's plants (``pip install gymnasium``; importing this module registers them).

``pneuflex/ForceControl-v0`` (:class:`ForceControl`) is the paper's force-control task on the 1-DOF pneumatic
plant of a scene (default ``scenes/paper-fig3.toml``): the flange starts touching a spring environment and must
follow the scene's force reference while the environment's stiffness changes under it.

- **Action**: the valve command u in [-1, 1] (``Box(1)``), held over one control tick of the scene's ``dt_s``.
  ``pneuflex/ForceControlImpedance-v0`` (``action="impedance"``): (a_m, a_b) in [-1, 1]^2 (``Box(2)``) retune
  the scene's impedance controller, m_d = m_d0 4^a_m and b_d = b_d0 4^a_b (k_d kept, the filter's state kept),
  which then runs ``decision_ticks`` control ticks (default 10); the reward is the sum over them.
- **Observation** (``Box(6)``, float32, scaled to order one): contact force f_e / 10 N, reference f_ref / 10 N,
  (x - x_e) / 10 mm, velocity / (0.1 m/s), p_a / 1 bar, p_b / 1 bar (absolute).
- **Reward**: -((f_ref - f_e) / 10 N)^2 per tick: the squared force error the paper's RMS metric sums. An
  episode that ends at an end stop is also charged, on its last step, every remaining tick as if the force
  were zero (-Σ (f_ref / 10 N)^2 to the scene's end), so ending early never pays.
- **Plant**: ``pneuflex/MultibodyForceControl-v0`` is the same task on ``scenes/paper-fig3-multibody.toml``'s
  Rapier rig (its mass and friction not drawn); any pneumatic or multibody scene with ``scene=PATH``.
- **Episode**: the scene's duration (10 s = 10,000 ticks for fig3), then truncated; terminated early if the
  flange reaches either end of the stroke.
- **Domain randomisation** (on by default, off with ``reset(options={"randomize": False})``, which gives the
  scene's own values): the stiffness before and after the change, each log-uniform in 350-2800 N/m; the time
  of the change, uniform in 4-8 s; the moving mass, the seal friction (Coulomb and break-away forces) and an
  on/off valve's switching delay, each log-uniform in 0.5-2x the sheet's. Seeded through ``reset(seed=...)``: the same seed and actions give
  the same episode. The reset's info gives the draw (:data:`PARAMS`).

The dynamics are Rust's (``pneuflex.ForceControlBatch``): the scene crate's 1-DOF pneumatic plant, the one
``pneuflex.run`` simulates (chambers, valve, eq. (1) mechanics, the scene's RK4 substeps), with the scene's
events. :class:`ForceControl` is a batch of one; :class:`ForceControlVector` (``gymnasium.make_vec``) steps
many episodes in parallel over the cores.
"""

from __future__ import annotations

from pathlib import Path

import gymnasium
import numpy as np

import pneuflex

_SCENES = Path(__file__).resolve().parents[4] / "scenes"
_DEFAULT_SCENE = _SCENES / "paper-fig3.toml"

#: Observation scales: f_e and f_ref in 10 N, x - x_e in 10 mm, velocity in 0.1 m/s, pressures in bar.
SCALES = np.array([10.0, 10.0, 0.01, 0.1, 1e5, 1e5])  # the batch's `scales`

#: What a reset's info (or a vector reset's infos, as arrays) carries: each episode's drawn parameters.
PARAMS = ("stiffness_n_per_m", "stiffness_after_n_per_m", "t_change_s", "mass_scale", "friction_scale",
          "switching_delay_scale")


def _scene(scene) -> str:
    scene = Path(scene) if scene is not None else _DEFAULT_SCENE
    if not scene.is_file():
        raise FileNotFoundError(f"{scene}: no such scene (pass scene=PATH to a 1-DOF pneumatic scene)")
    return str(scene)


def _spaces(width: int):
    action = gymnasium.spaces.Box(-1.0, 1.0, shape=(width,), dtype=np.float32)
    # Far beyond any reading of the plant (the scaled values are of order one).
    observation = gymnasium.spaces.Box(-1e4, 1e4, shape=(6,), dtype=np.float32)
    return action, observation


def _base_seed(rng: np.random.Generator) -> int:
    """A seed for the Rust batch's generators, drawn from the environment's own generator."""
    return int(rng.integers(0, 2**63))


class ForceControl(gymnasium.Env):
    """The paper's force-control task on the 1-DOF pneumatic plant (see the module doc): a batch of one."""

    metadata = {"render_modes": []}

    def __init__(self, scene: str | Path | None = None, randomize: bool = True, action: str = "valve",
                 decision_ticks: int = 10):
        self.scene_path = _scene(scene)
        self.batch = pneuflex.ForceControlBatch(self.scene_path, 1, randomize=randomize, action=action,
                                                decision_ticks=decision_ticks)
        self.dt, self.duration = self.batch.dt, self.batch.duration
        self.setpoints = pneuflex.Setpoints(self.scene_path)
        self.randomize = randomize
        self.action_space, self.observation_space = _spaces(self.batch.action_width)
        self._started = False

    @property
    def t(self) -> float:
        """The episode's time, s."""
        return self.batch.sensors(0)[0]

    def sensors(self) -> tuple[float, float, float, float, float, float]:
        """(t, x, x_dot, f_e, p_a, p_b) in SI, pressures absolute: what a controller reads."""
        return self.batch.sensors(0)

    def reset(self, *, seed=None, options=None):
        super().reset(seed=seed)
        randomize = (options or {}).get("randomize", self.randomize)
        obs = self.batch.reset(_base_seed(self.np_random), randomize=bool(randomize))
        self._started = True
        info = {k: float(v[0]) for k, v in self.batch.params().items()}
        return obs[0], info

    def step(self, action):
        if not self._started:
            raise RuntimeError("call reset() before step()")
        a = np.ascontiguousarray(np.asarray(action, dtype=np.float64).reshape(-1)[: self.batch.action_width])
        obs, reward, terminated, truncated = self.batch.step(a)
        f_e = self.batch.sensors(0)[3]
        return obs[0], float(reward[0]), bool(terminated[0]), bool(truncated[0]), {"f_e_n": f_e}


class ForceControlVector(gymnasium.vector.VectorEnv):
    """``num_envs`` episodes of :class:`ForceControl` stepped together in Rust (``pneuflex.ForceControlBatch``:
    parallel over the cores, the GIL released), with Gymnasium's next-step autoreset: an episode that ended
    at one step is reset by the next, whose action it ignores, returning its first observation with reward 0.
    Each reset draws new parameters when ``randomize`` (see the module doc); ``reset(seed=s)`` repeats.

    ``gymnasium.make_vec("pneuflex/ForceControl-v0", num_envs=N, vectorization_mode="vector_entry_point")``
    builds one."""

    metadata = {"render_modes": [], "autoreset_mode": gymnasium.vector.AutoresetMode.NEXT_STEP}

    def __init__(self, num_envs: int = 64, scene: str | Path | None = None, randomize: bool = True,
                 action: str = "valve", decision_ticks: int = 10):
        self.scene_path = _scene(scene)
        self.batch = pneuflex.ForceControlBatch(self.scene_path, num_envs, randomize=randomize, autoreset=True,
                                                action=action, decision_ticks=decision_ticks)
        self.num_envs = num_envs
        self.single_action_space, self.single_observation_space = _spaces(self.batch.action_width)
        self.action_space = gymnasium.vector.utils.batch_space(self.single_action_space, num_envs)
        self.observation_space = gymnasium.vector.utils.batch_space(self.single_observation_space, num_envs)
        self.randomize = randomize

    def reset(self, *, seed=None, options=None):
        """``seed``: None, an int (the batch's draws from it), or a list of one int per episode (episode i then
        draws exactly what ``ForceControl().reset(seed=seed[i])`` draws)."""
        randomize = bool((options or {}).get("randomize", self.randomize))
        if isinstance(seed, (list, tuple, np.ndarray)):
            if len(seed) != self.num_envs:
                raise ValueError(f"seed: {len(seed)} seeds for {self.num_envs} environments")
            seeds = [_base_seed(gymnasium.utils.seeding.np_random(int(s))[0]) for s in seed]
            obs = self.batch.reset(seeds, randomize=randomize)
        elif seed is None or isinstance(seed, (int, np.integer)):
            super().reset(seed=None if seed is None else int(seed))
            obs = self.batch.reset(_base_seed(self.np_random), randomize=randomize)
        else:
            raise TypeError(f"seed must be None, an int or a list of ints, got {type(seed).__name__}")
        return obs, dict(self.batch.params())

    def step(self, actions):
        u = np.ascontiguousarray(actions, dtype=np.float64).reshape(-1)
        if u.size != self.num_envs * self.batch.action_width:
            raise ValueError(f"actions: {u.size} values for {self.num_envs} environments of "
                             f"{self.batch.action_width} each (shape {self.action_space.shape})")
        obs, rewards, terminated, truncated = self.batch.step(u)
        return obs, rewards, terminated, truncated, {}


def rollout(env: gymnasium.Env, policy, seed: int | None = None, options: dict | None = None) -> dict:
    """One episode of ``policy(obs) -> action`` on a force-control environment (any action variant):
    ``{"return": sum of rewards, "rms_force_error_n": RMS of f_ref - f_e over the steps, "steps": n,
    "draw": the reset's info}``."""
    obs, draw = env.reset(seed=seed, options=options)
    total, sq, n = 0.0, 0.0, 0
    while True:
        obs, reward, terminated, truncated, info = env.step(policy(obs))
        total += reward
        sq, n = sq + (float(obs[1]) * SCALES[1] - info["f_e_n"]) ** 2, n + 1
        if terminated or truncated:
            return {"return": total, "rms_force_error_n": (sq / n) ** 0.5, "steps": n, "draw": draw}


def adaptive_baseline(env: ForceControl, run: str = "adaptive"):
    """The scene's own controller (its ``run``, by default the adaptive one) as a policy: ``policy(obs) -> action``
    reading the plant's state through ``env`` (a baseline a learned policy should beat)."""
    c = pneuflex.Controller.from_scene(env.scene_path, run)

    def policy(_obs):
        t, x, x_dot, f_e, p_a, p_b = env.sensors()
        f_ref, x_d = env.setpoints.at(t)
        u = c.update(t, x, x_dot, f_e, p_a, p_b, f_ref, x_d, env.dt)
        return np.array([u], dtype=np.float32)

    policy.reset = c.reset
    return policy


gymnasium.register(
    id="pneuflex/ForceControl-v0",
    entry_point="pneuflex.envs:ForceControl",
    vector_entry_point="pneuflex.envs:ForceControlVector",
)
# The same task, the action retuning the scene's impedance controller (m_d, b_d) every 10 ticks.
gymnasium.register(
    id="pneuflex/ForceControlImpedance-v0",
    entry_point="pneuflex.envs:ForceControl",
    vector_entry_point="pneuflex.envs:ForceControlVector",
    kwargs={"action": "impedance"},
)
# The same task on the Rapier rig of paper-fig3-multibody (URDF, contact on the wood mount).
gymnasium.register(
    id="pneuflex/MultibodyForceControl-v0",
    entry_point="pneuflex.envs:ForceControl",
    vector_entry_point="pneuflex.envs:ForceControlVector",
    kwargs={"scene": str(_SCENES / "paper-fig3-multibody.toml")},
)
