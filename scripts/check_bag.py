#!/usr/bin/env python3
"""Check a rosbag2 folder of `pneuflex run --mcap` against the run's trace.csv with two readers nobody
here wrote: `rosbags` (AnyReader: the bag's metadata.yaml and the message definitions stored in it) and
`mcap-ros2-support` (the MCAP file alone, its ros2msg schemas), both pinned in scripts/requirements.txt.

Usage:
  python scripts/check_bag.py RUN_DIR [--joints NAME ...]

RUN_DIR holds trace.csv and bag/. Checks: one sensor_msgs/msg/JointState on /pneuflex/joint_states per
row of trace.csv, stamped with the row's t (to the bag's 1 ns); its names are the --joints given
(default: cylinder); each joint's position, effort (and velocity, when the trace has x_dot) equal the
trace's x, f_e (x_dot) exactly, for a trace of several actuators its `<joint>.x` ... columns; each
joint's chamber pressures (sensor_msgs/msg/FluidPressure) equal p_a and p_b; both readers decode the
same values. Exits 0 when every check holds, 1 with the failed checks otherwise.
"""
from __future__ import annotations

import argparse
import csv
import sys
from pathlib import Path

from mcap_ros2.reader import read_ros2_messages
from rosbags.highlevel import AnyReader


def main() -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("run_dir", type=Path)
    ap.add_argument("--joints", nargs="+", default=["cylinder"])
    a = ap.parse_args()
    with open(a.run_dir / "trace.csv", newline="") as f:
        rows = [r for r in csv.reader(line for line in f if not line.startswith("#"))]
    header, data = rows[0], [[float(v) for v in r] for r in rows[1:]]
    col = {name: [r[i] for r in data] for i, name in enumerate(header)}
    prefix = {j: "" if a.joints == ["cylinder"] else f"{j}." for j in a.joints}
    failed: list[str] = []

    def check(ok: bool, what: str) -> None:
        if not ok and len(failed) < 20:
            failed.append(what)

    bag = a.run_dir / "bag"
    joint_states = []
    pressures: dict[str, list[float]] = {}
    with AnyReader([bag]) as reader:
        for conn, t_ns, raw in reader.messages():
            msg = reader.deserialize(raw, conn.msgtype)
            if conn.topic == "/pneuflex/joint_states":
                check(conn.msgtype == "sensor_msgs/msg/JointState", f"joint_states type {conn.msgtype}")
                joint_states.append((t_ns, msg))
            elif conn.topic.startswith("/pneuflex/pressures/"):
                check(conn.msgtype == "sensor_msgs/msg/FluidPressure", f"{conn.topic} type {conn.msgtype}")
                pressures.setdefault(conn.topic, []).append(msg.fluid_pressure)
    n = len(data)
    check(len(joint_states) == n, f"{len(joint_states)} joint states, trace.csv has {n} rows")
    for k, (t_ns, m) in enumerate(joint_states[:n]):
        stamp = m.header.stamp.sec * 1_000_000_000 + m.header.stamp.nanosec
        check(stamp == t_ns, f"joint state {k}: stamp {stamp} ns, log time {t_ns} ns")
        check(abs(stamp * 1e-9 - col["t"][k]) <= 0.5e-9 + 1e-15 * col["t"][k],
              f"joint state {k}: stamp {stamp} ns, trace t {col['t'][k]}")
        check(list(m.name) == a.joints, f"joint state {k}: names {list(m.name)}")
        for i, j in enumerate(a.joints):
            p = prefix[j]
            check(m.position[i] == col[p + "x"][k], f"joint state {k} {j}: position {m.position[i]} != x {col[p + 'x'][k]}")
            check(m.effort[i] == col[p + "f_e"][k], f"joint state {k} {j}: effort {m.effort[i]} != f_e {col[p + 'f_e'][k]}")
            if p + "x_dot" in col:
                check(m.velocity[i] == col[p + "x_dot"][k], f"joint state {k} {j}: velocity != x_dot")
            else:
                check(len(m.velocity) == 0, f"joint state {k}: a velocity the trace does not have")
    for j in a.joints:
        for chamber in "ab":
            topic = f"/pneuflex/pressures/{j}/{chamber}"
            check(pressures.get(topic) == col[prefix[j] + f"p_{chamber}"], f"{topic} != trace p_{chamber}")
    # The second reader: the MCAP file and its stored definitions alone.
    second = [m.ros_msg for m in read_ros2_messages(str(next(bag.glob("*.mcap"))), topics=["/pneuflex/joint_states"])]
    check(len(second) == n, f"mcap-ros2-support: {len(second)} joint states")
    check(all(list(s.position) == list(m.position) and list(s.effort) == list(m.effort)
              for s, (_, m) in zip(second, joint_states)), "mcap-ros2-support decodes other values than rosbags")
    if failed:
        print("\n".join(f"FAIL {f}" for f in failed))
        return 1
    print(f"ok {a.run_dir}: {n} joint states of {', '.join(a.joints)} equal to trace.csv (rosbags and mcap-ros2-support), "
          f"{sum(len(v) for v in pressures.values())} pressures")
    return 0


if __name__ == "__main__":
    sys.exit(main())
