"""Gymnasium environments on pneuflex's plants (``pip install gymnasium``; importing this module registers them).

``pneuflex/ForceControl-v0`` (:class:`ForceControl`) is the paper's force-control task on the 1-DOF pneumatic
plant of a scene (default the shipped ``paper-fig3``): the flange starts touching a spring environment and must
follow the scene's force reference while the environment's stiffness changes under it.

- **Action**: the valve command u in [-1, 1] (``Box(1)``), held over one control tick of the scene's ``dt_s``.
  Finite values outside [-1, 1] are clipped (as Gymnasium's continuous-control environments clip); another
  shape than the space's, values that are not real numbers, NaN or infinity are refused (ValueError or
  TypeError naming the environment and the value), as is a step before ``reset()`` or after the episode ended
  (docs/gymnasium.md, "What an environment refuses").
  ``pneuflex/ForceControlPressure-v0`` (``action="pressure"``): a pressure regulator in front of each chamber in
  place of the valve; the action is the two chambers' set-points (p_a, p_b) in Pa absolute within [atmosphere,
  supply] (``Box(2)``, 101325-601325 Pa on fig3; set-points outside are refused), held over a tick. Each
  regulator follows its set-point with the time constant ``regulator_time_constant_s`` (default 0.01 s), its
  flow limited by the valve's ISO 6358 paths fully open (``pneuflex_pneumatics::regulator``). A scene of one
  ``[plant]``, pneumatic or multibody (``gymnasium.wrappers.RescaleAction(env, -1, 1)`` normalises it).
  ``pneuflex/ForceControlImpedance-v0`` (``action="impedance"``): (a_m, a_b) in [-1, 1]^2 (``Box(2)``) retune
  the scene's impedance controller, m_d = m_d0 4^a_m and b_d = b_d0 4^a_b (k_d kept, the filter's state kept),
  which then runs ``decision_ticks`` control ticks (default 10); the reward is the sum over them.
- **Observation** (``Box(6)``, float32, scaled to order one): contact force f_e / 10 N, reference f_ref / 10 N,
  (x - x_e) / 10 mm, velocity / (0.1 m/s), p_a / 1 bar, p_b / 1 bar (absolute).
- **Reward**: 1 - min(((f_ref - f_e) / 10 N)^2, 1) per tick, in [0, 1]: the squared force error the paper's
  RMS metric sums, subtracted from 1 and clipped at a 10 N error (the paper's reference: pressing nothing). An
  impedance action's step sums its ticks, in [0, decision_ticks]. Never negative, so an episode that ends at
  an end stop forgoes the ticks it no longer lives: ending early never pays, with no terminal penalty.
- **Plant**: ``pneuflex/MultibodyForceControl-v0`` is the same task on the shipped ``paper-fig3-multibody``
  Rapier rig (its mass and friction not drawn); any pneumatic or multibody scene with ``scene=PATH`` or a
  shipped scene's name (``pneuflex.scenes()``).
- **Several actuators**: ``pneuflex/GripperForceControl-v0`` is the task on the shipped ``gripper`` (two
  fingers squeeze an object), and any scene with ``[[actuators]]`` runs the same way: the action is each
  actuator's action, the observation each actuator's block of six, flat and actuator by actuator
  (``Box(N k)``, ``Box(6 N)``; one actuator is the N = 1 case), the reward the mean of the actuators' rewards,
  x - x_e measured from each actuator's ``x_d_m``. An episode terminates when any actuator passes the scene's
  ``[divergence]`` limits or the plant an invariant (a chamber, the stroke); randomisation scales every
  contact's and spring's stiffness, before and after the events, log-uniform 0.5-2x (:data:`MECHANISM_PARAMS`).
- **Episode**: the scene's duration (10 s = 10,000 ticks for fig3), then truncated; terminated early if the
  1-DOF plant's flange reaches either end of the stroke, or where a multibody or several-actuator scene's run
  stops as diverged (its ``[divergence]`` limits, the plant's invariants; its end stops hold the flange);
  ``max_episode_steps`` (``gymnasium.make``/``make_vec``) truncates it sooner.
- **Render**: ``render_mode="rgb_array"``: ``render()`` is a (320, 480, 3) uint8 frame of the episode's force
  (f_ref grey, f_e blue) and position (x - x_e, green) traces; the vector environment's is a tuple of one frame
  per episode, over its last ``RENDER_STEPS`` steps.
- **Pickling and copies**: an environment pickles and deep-copies (rebuilt from its constructor's arguments,
  then each episode's draw and its actions since it started replayed: the plants are deterministic).
- **Processes**: the batch's threads are a pool per process, made again in a child after ``fork``.
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

from . import _checks as c
from . import _data, _frame

#: The default scene: the shipped paper-fig3 (``pneuflex.scenes()``).
DEFAULT_SCENE = "paper-fig3"
#: Steps a vector environment's frames show (a ring of the last observations, kept only when rendering).
RENDER_STEPS = 2000

#: Observation scales: f_e and f_ref in 10 N, x - x_e in 10 mm, velocity in 0.1 m/s, pressures in bar.
SCALES = np.array([10.0, 10.0, 0.01, 0.1, 1e5, 1e5])  # the batch's `scales`
#: The actions: the valve command, the chambers' pressure set-points, or the impedance controller's retune.
ACTIONS = ("valve", "pressure", "impedance")
#: The pressure regulators' time constant unless given, s (``action="pressure"``).
REGULATOR_TIME_CONSTANT_S = 0.01
# The dtypes the batch reads as they are (numpy's builtin dtypes are singletons: `is` compares them).
_F32, _F64 = np.dtype(np.float32), np.dtype(np.float64)

#: What a reset's info (or a vector reset's infos, as arrays) carries: each episode's drawn parameters.
PARAMS = ("stiffness_n_per_m", "stiffness_after_n_per_m", "t_change_s", "mass_scale", "friction_scale",
          "switching_delay_scale")
#: The same on a scene of several actuators: its contacts' and springs' stiffness before and after their
#: events, as multiples of the scene's.
MECHANISM_PARAMS = ("stiffness_scale", "stiffness_after_scale")


def _scene(scene, where: str) -> str:
    """A path, or a shipped scene's name (FileNotFoundError listing them when it is neither)."""
    scene = Path(_data.resolve(c.path(scene, "scene", where) if scene is not None else DEFAULT_SCENE))
    if not scene.exists():
        raise FileNotFoundError(f"{scene}: no such scene (pass scene=PATH to a pneumatic, multibody or "
                                f"several-actuator scene)")
    if not scene.is_file():
        raise IsADirectoryError(f"{scene}: not a scene file (pass scene=PATH to a pneumatic, multibody or "
                                f"several-actuator scene)")
    return str(scene)


def _action_kind(action, where: str) -> str:
    """The ``action`` argument: a str (the batch says which ones, naming the scene)."""
    if not isinstance(action, str):
        raise TypeError(f'{where}: action must be "valve", "pressure" or "impedance", got {c.kind(action)}')
    return action


def _regulator(tau, where: str) -> float:
    """``regulator_time_constant_s``: a number in seconds (the batch checks its range)."""
    return c.number(tau, "regulator_time_constant_s", where, lambda v: v > 0, "a time constant > 0 s")


#: The keys ``reset(options=...)`` takes.
OPTIONS = ("randomize",)


def _randomize(options, default: bool, where: str) -> bool:
    """``options["randomize"]`` (a bool) or ``default``; another key (a typo such as "randomise") is refused, not
    ignored."""
    if options is None:
        return default
    if not isinstance(options, dict):
        raise TypeError(f"{where}: options must be a dict or None, got {c.kind(options)}")
    unknown = [k for k in options if k not in OPTIONS]
    if unknown:
        raise ValueError(f"{where}: options: unknown key {unknown[0]!r}; the keys are {', '.join(OPTIONS)}")
    return c.flag(options.get("randomize", default), 'options["randomize"]', where)


def _actions(action, shape: tuple, where: str) -> np.ndarray:
    """An action (or a batch of them) as a float64 array the Rust batch steps (the environments' steps call this
    for anything but a float32 or float64 array of the space's shape, which the batch reads as it is). Refused:
    another shape than the action space's (no truncation, no broadcasting), values that are not real numbers
    (bool, complex, str, None). Non-finite values are refused by the batch, naming the environment and the value;
    finite ones outside [-1, 1] are clipped there, as Gymnasium's continuous-control environments clip (a
    pressure set-point outside [atmosphere, supply] is refused)."""
    if type(action) is not np.ndarray or action.dtype.kind != "f":
        try:
            action = np.asarray(action)
        except (ValueError, TypeError) as e:
            raise ValueError(f"{where}: the action is not an array of shape {shape}: {e}") from None
        if action.dtype.kind not in "iuf":
            raise TypeError(f"{where}: the action must hold real numbers (the action space is float32), got "
                            f"dtype {action.dtype}: {c.kind(action)}")
    if action.shape != shape:
        raise ValueError(f"{where}: the action has shape {action.shape}; the action space's is {shape}")
    # No copy of a float64 action; the batch reads a strided one as it is.
    return action.astype(np.float64, copy=False).reshape(-1)


def _spaces(batch):
    """The action and observation spaces of one episode: flat, each actuator's values in turn (one actuator:
    Box(1) or Box(2), and Box(6)); the valve and impedance actions in [-1, 1], the pressure set-points in
    [atmosphere, supply] Pa absolute."""
    low, high = np.array(batch.action_low, np.float32), np.array(batch.action_high, np.float32)
    action = gymnasium.spaces.Box(low, high, shape=(batch.action_width,), dtype=np.float32)
    # Far beyond any reading of the plant (the scaled values are of order one).
    observation = gymnasium.spaces.Box(-1e4, 1e4, shape=(batch.observation_width,), dtype=np.float32)
    return action, observation


def _render_mode(mode, where: str):
    if mode is not None and mode != "rgb_array":
        raise ValueError(f'{where}: render_mode must be None or "rgb_array", got {c.kind(mode)}')
    return mode


def _frame_of(rows, actuators: int = 1) -> np.ndarray:
    """The frame of observations ``rows`` (n, 6 actuators): each actuator's force and position traces in N and
    mm, one (320, 480) panel pair per actuator stacked top to bottom."""
    rows = np.asarray(rows, dtype=float).reshape(-1, actuators, 6)
    return np.concatenate([_frame.traces(r[:, 1] * SCALES[1], r[:, 0] * SCALES[0], r[:, 2] * SCALES[2] * 1e3)
                           for r in rows.transpose(1, 0, 2)], axis=0)


def _base_seed(rng: np.random.Generator) -> int:
    """A seed for the Rust batch's generators, drawn from the environment's own generator."""
    return int(rng.integers(0, 2**63))


class ForceControl(gymnasium.Env):
    """The paper's force-control task on the 1-DOF pneumatic plant (see the module doc): a batch of one."""

    metadata = {"render_modes": ["rgb_array"], "render_fps": 30}

    def __init__(self, scene: str | Path | None = None, randomize: bool = True, action: str = "valve",
                 decision_ticks: int = 10, render_mode: str | None = None,
                 regulator_time_constant_s: float = REGULATOR_TIME_CONSTANT_S):
        at = "ForceControl"
        self.render_mode = _render_mode(render_mode, at)
        self.scene_path = _scene(scene, at)
        randomize, action = c.flag(randomize, "randomize", at), _action_kind(action, at)
        self.batch = pneuflex.ForceControlBatch(self.scene_path, 1, randomize=randomize, action=action,
                                                decision_ticks=c.integer(decision_ticks, "decision_ticks", at, 1),
                                                regulator_time_constant_s=_regulator(regulator_time_constant_s, at))
        self.dt, self.duration = self.batch.dt, self.batch.duration
        #: The actuators' names, the order of the action's and the observation's blocks ([] for one [plant]).
        self.actuators = list(self.batch.actuator_names)
        self.setpoints = self._setpoints()
        self.randomize = randomize
        self.action_space, self.observation_space = _spaces(self.batch)
        self._shape = self.action_space.shape
        # Not reset yet, or the last step ended the episode: a step is refused until reset().
        self._ended = "call reset() before step()"
        # The episode's observations, kept for render() only.
        self._seen: list = []

    def __getstate__(self):
        # The batch pickles itself (its arguments, each episode's seed and actions); the schedule is rebuilt.
        state = dict(self.__dict__)
        del state["setpoints"]
        return state

    def __setstate__(self, state):
        self.__dict__.update(state)
        self.setpoints = self._setpoints()

    def _setpoints(self):
        """The reference schedule of a scene of one [plant] (None for several actuators: ``batch.setpoint``)."""
        return None if self.actuators else pneuflex.Setpoints(self.scene_path)

    def render(self):
        """``render_mode="rgb_array"``: the episode's force and position traces, (320, 480, 3) uint8; else None."""
        if self.render_mode != "rgb_array":
            return None
        return _frame_of(self._seen, self.batch.num_actuators)

    @property
    def t(self) -> float:
        """The episode's time, s."""
        return self.batch.sensors(0)[0]

    def sensors(self, actuator: int = 0) -> tuple[float, float, float, float, float, float]:
        """(t, x, x_dot, f_e, p_a, p_b) of actuator ``actuator`` in SI, pressures absolute: what a controller
        reads."""
        return self.batch.sensors(0, actuator)

    def reset(self, *, seed=None, options=None):
        randomize = _randomize(options, self.randomize, "ForceControl.reset")
        super().reset(seed=seed)
        obs = self.batch.reset(_base_seed(self.np_random), randomize=randomize)
        self._ended = None
        if self.render_mode is not None:
            self._seen = [obs[0]]
        info = {k: float(v[0]) for k, v in self.batch.params().items()}
        return obs[0], info

    def step(self, action):
        if self._ended:
            raise RuntimeError(f"ForceControl.step: {self._ended}")
        # A float32 or float64 array of the space's shape goes to the batch as it is; anything else is checked
        # and converted (or refused) by _actions.
        if type(action) is not np.ndarray or action.shape != self._shape or (action.dtype is not _F32
                                                                             and action.dtype is not _F64):
            action = _actions(action, self._shape, "ForceControl.step")
        try:
            obs, reward, terminated, truncated, t, f_e = self.batch.step_single(action)
        except ValueError as e:
            raise ValueError(f"ForceControl.step: {e}") from None
        if self.render_mode is not None:
            self._seen.append(obs)
        if terminated or truncated:
            why = (f"terminated ({self.batch.why(0) or 'an end of the stroke'})" if terminated
                   else "truncated (the scene's duration)")
            self._ended = f"the episode ended at t = {t:.6g} s, {why}: call reset() before step()"
        if self.actuators:  # each actuator's contact force, in the order of the blocks
            return obs, reward, terminated, truncated, {
                "f_e_n": np.array([self.batch.sensors(0, i)[3] for i in range(len(self.actuators))])}
        return obs, reward, terminated, truncated, {"f_e_n": f_e}


class ForceControlVector(gymnasium.vector.VectorEnv):
    """``num_envs`` episodes of :class:`ForceControl` stepped together in Rust (``pneuflex.ForceControlBatch``:
    parallel over the cores, the GIL released), with Gymnasium's next-step autoreset: an episode that ended
    at one step is reset by the next, whose action it ignores, returning its first observation with reward 0.
    Each reset draws new parameters when ``randomize`` (see the module doc); ``reset(seed=s)`` repeats.

    ``gymnasium.make_vec("pneuflex/ForceControl-v0", num_envs=N, vectorization_mode="vector_entry_point")``
    builds one."""

    metadata = {"render_modes": ["rgb_array"], "render_fps": 30,
                "autoreset_mode": gymnasium.vector.AutoresetMode.NEXT_STEP}

    def __init__(self, num_envs: int = 64, scene: str | Path | None = None, randomize: bool = True,
                 action: str = "valve", decision_ticks: int = 10, max_episode_steps: int | None = None,
                 render_mode: str | None = None, regulator_time_constant_s: float = REGULATOR_TIME_CONSTANT_S):
        at = "ForceControlVector"
        self.render_mode = _render_mode(render_mode, at)
        self.scene_path = _scene(scene, at)
        num_envs = c.integer(num_envs, "num_envs", at, 1)
        randomize, action = c.flag(randomize, "randomize", at), _action_kind(action, at)
        self.max_episode_steps = c.optional_integer(max_episode_steps, "max_episode_steps", at, 1)
        self.batch = pneuflex.ForceControlBatch(self.scene_path, num_envs, randomize=randomize, autoreset=True,
                                                action=action,
                                                decision_ticks=c.integer(decision_ticks, "decision_ticks", at, 1),
                                                max_episode_steps=self.max_episode_steps,
                                                regulator_time_constant_s=_regulator(regulator_time_constant_s, at))
        self.num_envs = num_envs
        self.actuators = list(self.batch.actuator_names)
        self.single_action_space, self.single_observation_space = _spaces(self.batch)
        self.action_space = gymnasium.vector.utils.batch_space(self.single_action_space, num_envs)
        self.observation_space = gymnasium.vector.utils.batch_space(self.single_observation_space, num_envs)
        self._shape = self.action_space.shape
        self.randomize = randomize
        self._started = False
        # The last RENDER_STEPS observations (steps, num_envs, 6), kept for render() only.
        self._seen: list = []

    def render(self):
        """``render_mode="rgb_array"``: a tuple of one (320, 480, 3) uint8 frame per episode, its force and
        position over the last ``RENDER_STEPS`` steps (across its autoresets); else None."""
        if self.render_mode != "rgb_array":
            return None
        width = self.batch.observation_width
        seen = np.asarray(self._seen, dtype=float).reshape(-1, self.num_envs, width)
        return tuple(_frame_of(seen[:, i], self.batch.num_actuators) for i in range(self.num_envs))

    def _remember(self, obs) -> None:
        if self.render_mode is not None:
            self._seen.append(np.array(obs))
            del self._seen[:-RENDER_STEPS]

    def reset(self, *, seed=None, options=None):
        """``seed``: None, an int (the batch's draws from it), or a list of one int per episode (episode i then
        draws exactly what ``ForceControl().reset(seed=seed[i])`` draws)."""
        at = "ForceControlVector.reset"
        randomize = _randomize(options, self.randomize, at)
        if isinstance(seed, (list, tuple, np.ndarray)):
            if np.ndim(seed) != 1 or len(seed) != self.num_envs:
                raise ValueError(f"{at}: seed: {np.shape(seed)} seeds for {self.num_envs} environments "
                                 f"(one int per environment)")
            seeds = [_base_seed(gymnasium.utils.seeding.np_random(c.seed(s, f"seed[{i}]", at))[0])
                     for i, s in enumerate(seed)]
            obs = self.batch.reset(seeds, randomize=randomize)
        elif seed is None or (isinstance(seed, (int, np.integer)) and not isinstance(seed, bool)):
            super().reset(seed=None if seed is None else c.seed(seed, "seed", at))
            obs = self.batch.reset(_base_seed(self.np_random), randomize=randomize)
        else:
            raise TypeError(f"{at}: seed must be None, an int or a list of ints, got {c.kind(seed)}")
        self._started = True
        self._seen = []
        self._remember(obs)
        return obs, dict(self.batch.params())

    def step(self, actions):
        if not self._started:
            raise RuntimeError("ForceControlVector.step: call reset() before step()")
        if type(actions) is not np.ndarray or actions.shape != self._shape or (actions.dtype is not _F32
                                                                               and actions.dtype is not _F64):
            actions = _actions(actions, self._shape, "ForceControlVector.step")
        try:
            obs, rewards, terminated, truncated = self.batch.step(actions)
        except ValueError as e:
            raise ValueError(f"ForceControlVector.step: {e}") from None
        if self.render_mode is not None:
            self._remember(obs)
        return obs, rewards, terminated, truncated, {}


def rollout(env: gymnasium.Env, policy, seed: int | None = None, options: dict | None = None) -> dict:
    """One episode of ``policy(obs) -> action`` on a force-control environment (any action variant):
    ``{"return": sum of rewards, "rms_force_error_n": RMS of f_ref - f_e over the steps (and the actuators),
    "steps": n, "draw": the reset's info}``."""
    obs, draw = env.reset(seed=seed, options=options)
    total, sq, n = 0.0, 0.0, 0
    while True:
        obs, reward, terminated, truncated, info = env.step(policy(obs))
        total += reward
        f_ref = np.asarray(obs, dtype=float).reshape(-1, 6)[:, 1] * SCALES[1]
        sq, n = sq + float(np.mean((f_ref - info["f_e_n"]) ** 2)), n + 1
        if terminated or truncated:
            return {"return": total, "rms_force_error_n": (sq / n) ** 0.5, "steps": n, "draw": draw}


def adaptive_baseline(env: gymnasium.Env, run: str = "adaptive"):
    """The scene's own controller (its ``run``, by default the adaptive one) as a policy: ``policy(obs) -> action``
    reading the plant's state through ``env`` (a baseline a learned policy should beat): a :class:`ForceControl`,
    ``gymnasium.make(...).unwrapped``."""
    if not isinstance(env, ForceControl):
        raise TypeError(f"adaptive_baseline: env must be a ForceControl (gymnasium.make(...).unwrapped), got "
                        f"{c.kind(env)}")
    if env.actuators:
        raise ValueError(f"adaptive_baseline: {env.scene_path} has several actuators ({', '.join(env.actuators)}); "
                         f"the baseline is one controller: use the impedance action at 0 for the scene's gains")
    controller = pneuflex.Controller.from_scene(env.scene_path, run)

    def policy(_obs):
        t, x, x_dot, f_e, p_a, p_b = env.sensors()
        f_ref, x_d = env.setpoints.at(t)
        u = controller.update(t, x, x_dot, f_e, p_a, p_b, f_ref, x_d, env.dt)
        return np.array([u], dtype=np.float32)

    policy.reset = controller.reset
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
# The same task, a pressure regulator in front of each chamber: the action is the set-points (p_a, p_b) in Pa.
gymnasium.register(
    id="pneuflex/ForceControlPressure-v0",
    entry_point="pneuflex.envs:ForceControl",
    vector_entry_point="pneuflex.envs:ForceControlVector",
    kwargs={"action": "pressure"},
)
# The same task on the Rapier rig of paper-fig3-multibody (URDF, contact on the wood mount).
gymnasium.register(
    id="pneuflex/MultibodyForceControl-v0",
    entry_point="pneuflex.envs:ForceControl",
    vector_entry_point="pneuflex.envs:ForceControlVector",
    kwargs={"scene": "paper-fig3-multibody"},
)
# The task on several actuators: the shipped gripper's two fingers, one action and one block each.
gymnasium.register(
    id="pneuflex/GripperForceControl-v0",
    entry_point="pneuflex.envs:ForceControl",
    vector_entry_point="pneuflex.envs:ForceControlVector",
    kwargs={"scene": "gripper"},
)
