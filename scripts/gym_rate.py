"""One process's env-steps per second of the Gymnasium force-control task, for comparing two builds of the
bindings in alternating processes (docs/gymnasium.md, Throughput):

    farm-bench -n 16 --vs "sh -c 'PYTHONPATH=OLD_PACKAGE exec .venv/bin/python scripts/gym_rate.py >>/tmp/old.txt'" \\
        -- sh -c 'exec .venv/bin/python scripts/gym_rate.py >>/tmp/new.txt'

where OLD_PACKAGE is a folder holding the other build's `pneuflex` package (an unzipped wheel). Prints one line:
the Rust batch's rate (4,000 steps of 256 paper-fig3 episodes after 200 to warm up; random valve commands,
randomisation and autoreset on, both cores) and one episode's `step_single` rate (100,000 steps). The ratio of
the two files' lines, pair by pair, is the comparison."""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np

import pneuflex

SCENE = str(Path(__file__).resolve().parent.parent / "scenes" / "paper-fig3.toml")


def main() -> None:
    n = 256
    batch = pneuflex.ForceControlBatch(SCENE, n, randomize=True, autoreset=True)
    batch.reset(1)
    actions = np.random.default_rng(0).uniform(-0.2, 0.2, (8, n))
    for i in range(200):
        batch.step(actions[i % 8])
    k = 4000
    t0 = time.perf_counter()
    for i in range(k):
        batch.step(actions[i % 8])
    batch_rate = k * n / (time.perf_counter() - t0)
    one = pneuflex.ForceControlBatch(SCENE, 1, randomize=True, autoreset=True)
    one.reset(1)
    u = actions[:, :1].copy()
    t0 = time.perf_counter()
    for i in range(100_000):
        one.step_single(u[i % 8])
    single_rate = 100_000 / (time.perf_counter() - t0)
    print(f"{batch_rate:.0f} {single_rate:.0f}")


if __name__ == "__main__":
    main()
