"""Env-steps per second of the Gymnasium force-control environments on a scene of several actuators (the
gripper) beside the paper's 1-DOF scene (docs/gymnasium.md, "Several actuators"): the Rust batch alone
(`ForceControlBatch.step`, over the cores), the vector environment (`gymnasium.make_vec`) and the single
environment's Python step, interleaved over rounds; random valve commands, randomisation on, next-step
autoreset. An env-step is one control tick of every actuator of one episode.

    .venv/bin/python scripts/bench_gym_scenes.py [--rounds 5] [--scenes gripper paper-fig3]
"""

from __future__ import annotations

import argparse
import statistics
import time

import gymnasium
import numpy as np

import pneuflex
import pneuflex.envs  # noqa: F401


def rates(scene: str, n: int, rounds: int, steps: int) -> dict[str, list[float]]:
    batch = pneuflex.ForceControlBatch(scene, n, randomize=True, autoreset=True)
    batch.reset(1)
    vec = gymnasium.make_vec("pneuflex/ForceControl-v0", num_envs=n, scene=scene,
                             vectorization_mode="vector_entry_point")
    vec.reset(seed=1)
    single = gymnasium.make("pneuflex/ForceControl-v0", scene=scene)
    single.reset(seed=1)
    width = batch.action_width
    actions = np.random.default_rng(0).uniform(-0.2, 0.2, (8, n, width))

    def timed(f, k: int, per: int) -> float:
        t0 = time.perf_counter()
        for i in range(k):
            f(i)
        return k * per / (time.perf_counter() - t0)

    def single_step(i: int) -> None:
        _, _, terminated, truncated, _ = single.step(actions[i % 8, 0])
        if terminated or truncated:
            single.reset()

    out: dict[str, list[float]] = {"batch": [], "vector": [], "single": []}
    for _ in range(rounds):
        out["batch"].append(timed(lambda i: batch.step(actions[i % 8].reshape(-1)), steps, n))
        out["vector"].append(timed(lambda i: vec.step(actions[i % 8]), steps, n))
        out["single"].append(timed(single_step, steps * 4, 1))
    return out


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--rounds", type=int, default=5)
    p.add_argument("--scenes", nargs="+", default=["gripper", "paper-fig3"])
    p.add_argument("--envs", type=int, default=64, help="episodes of the batch and the vector environment")
    p.add_argument("--steps", type=int, default=50, help="batch steps per round (the single env takes 4x)")
    a = p.parse_args()
    for scene in a.scenes:
        r = rates(scene, a.envs, a.rounds, a.steps)
        print(f"{scene}: {a.envs} episodes, {a.rounds} rounds, env-steps/s median (min-max)")
        for k, v in r.items():
            print(f"  {k:7s} {statistics.median(v):12,.0f} ({min(v):,.0f}-{max(v):,.0f})")


if __name__ == "__main__":
    main()
