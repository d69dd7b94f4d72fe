"""Cost per simulated second of a scene with [[actuators]] against MuJoCo's bare mj_step at 1 ms on the same
mechanism (docs/multibody.md "Speed").

    .venv/bin/python -m crossval.bench_mechanism <pneuflex executable> <scene.toml> [rounds]

Interleaved, per round: the whole `pneuflex run -q` of the scene (wall time over runs x duration: start-up,
every run, traces and figures included), then `mj_step(nstep=20000)` in C on the MJCF crossval/mechanism.py
derives from the scene's URDF at a 1 ms step (held links as mocap bodies; no pads, cylinders, springs or
controller). Prints min / median / max of each and of their ratio.
"""

from __future__ import annotations

import statistics
import subprocess
import sys
import tempfile
import time
import tomllib
from pathlib import Path

import mujoco

from . import mjcf
from .mechanism import mechanism_mjcf


def mj_step_cost(scene: Path, n_steps: int = 20000) -> float:
    """Seconds of bare mj_step per simulated second at a 1 ms step."""
    doc = tomllib.loads(scene.read_text())
    urdf = (scene.parent / doc["urdf"]).resolve()
    held = doc.get("held_links", [])
    orig = mjcf.urdf_to_mjcf

    def with_mocap(u, opt):
        opt.mocap = {link: (0.0, 0.0, 0.0) for link in held}
        return orig(u, opt)

    mjcf.urdf_to_mjcf = with_mocap
    try:
        xml = mechanism_mjcf(urdf, doc, 0.001)
    finally:
        mjcf.urdf_to_mjcf = orig
    m = mujoco.MjModel.from_xml_string(xml)
    d = mujoco.MjData(m)
    mujoco.mj_step(m, d, nstep=100)
    t0 = time.perf_counter()
    mujoco.mj_step(m, d, nstep=n_steps)
    return (time.perf_counter() - t0) / (n_steps * 0.001)


def main() -> None:
    exe, scene = sys.argv[1], Path(sys.argv[2])
    rounds = int(sys.argv[3]) if len(sys.argv) > 3 else 5
    doc = tomllib.loads(scene.read_text())
    sim_s = doc["duration_s"] * len(doc["runs"])
    ours, mj, ratio = [], [], []
    with tempfile.TemporaryDirectory() as out:
        for _ in range(rounds):
            t0 = time.perf_counter()
            subprocess.run([exe, "run", "-q", "--out", out, str(scene)], check=True, capture_output=True)
            a = (time.perf_counter() - t0) / sim_s
            b = mj_step_cost(scene)
            ours.append(a)
            mj.append(b)
            ratio.append(a / b)

    def f(v: list[float]) -> str:
        return f"{min(v):.3g} / {statistics.median(v):.3g} / {max(v):.3g}"

    print(f"{scene.stem}: pneuflex {f([x * 1e3 for x in ours])} ms per simulated s; "
          f"mj_step at 1 ms {f([x * 1e3 for x in mj])} ms; ratio {f(ratio)} (min / median / max, {rounds} rounds)")


if __name__ == "__main__":
    main()
