#!/usr/bin/env python3
"""Check `pneuflex ros2` (the native ROS 2 node, docs/ros2.md) against a DDS nobody here wrote: Eclipse
Cyclone DDS (the `cyclonedds` package, pinned in scripts/requirements.txt; the DDS ROS 2 ships), on the
loopback interface, on a domain from this process's id.

Usage:
  python scripts/check_ros2_node.py [--pneuflex target/debug/pneuflex] [--out DIR] [--domain N]

Two nodes, one after the other:

1. paper-fig3, run `impedance`, 7 s at 1 kHz. A Cyclone reader of `rt/pneuflex/joint_states`
   (sensor_msgs::msg::dds_::JointState_) receives at least half the ticks, each named `cylinder`, its position
   and effort equal to trace.csv's x and f_e at the row of its stamp, its velocity finite and under 2 m/s;
   the chamber pressures and /clock likewise. A Cyclone writer publishes joint commands (effort 16 N for
   `cylinder`, the hardware interface's QoS: reliable, keep-last 1) while the stamps are in [1.5, 4.5) s:
   the trace's f_ref is 16 N for at least 1 s of ticks and only from the first command on, the force
   reference topic carries it, and the measured force moves from the scene's 10 N to within 1.5 N of 16 N;
   0.5 s (the command timeout) after the last command the scene's reference is back.
2. the gripper (two joints), run `impedance`, 3 s: each joint state names `left`, `right`, with the
   trace's `left.x`, `right.f_e`, ... and the trace's velocities `x_dot`; a command to `right` alone
   (30 N, in [1, 2) s) replaces right's reference and leaves left's.

No timing is asserted beyond these generous counts: a loaded machine makes late ticks, not failures.
Exits 0 when every check holds, 1 with the failed checks otherwise.
"""
from __future__ import annotations

import argparse
import csv
import math
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
import ros2_dds  # noqa: E402
from ros2_dds import Clock, Float64MultiArray, FluidPressure, Header, JointState, Time, stamp_ns  # noqa: E402

failed: list[str] = []


def check(ok: bool, what: str) -> None:
    if not ok and len(failed) < 30:
        failed.append(what)


def read_trace(path: Path) -> dict[str, list[float]]:
    with open(path, newline="") as f:
        rows = list(csv.reader(line for line in f if not line.startswith("#")))
    def number(v: str) -> float:
        # A rig's trace has empty cells and a text column (`fault`).
        try:
            return float(v)
        except ValueError:
            return math.nan
    header, data = rows[0], [[number(v) for v in r] for r in rows[1:]]
    return {name: [r[i] for r in data] for i, name in enumerate(header)}


class Session:
    """A Cyclone participant with readers of the node's topics and a writer of joint commands."""

    def __init__(self, domain: int, joints: list[str]):
        from cyclonedds.core import Policy, Qos
        from cyclonedds.domain import DomainParticipant
        from cyclonedds.pub import DataWriter
        from cyclonedds.sub import DataReader
        from cyclonedds.topic import Topic

        self.dp = DomainParticipant(domain)
        keep = Qos(Policy.Reliability.BestEffort, Policy.History.KeepLast(4000))

        def reader(name, ty):
            return DataReader(self.dp, Topic(self.dp, "rt" + name, ty), qos=keep)

        self.joint_states = reader("/pneuflex/joint_states", JointState)
        self.pressures = reader(f"/pneuflex/pressures/{joints[0]}/a", FluidPressure)
        self.force_reference = reader("/pneuflex/force_reference", Float64MultiArray)
        self.clock = reader("/clock", Clock)
        # As topic_based_ros2_control publishes them: rclcpp::QoS(1), reliable; plain CDR as ROS 2 writes it.
        self.commands = DataWriter(
            self.dp, Topic(self.dp, "rt/pneuflex/joint_commands", JointState),
            qos=Qos(Policy.Reliability.Reliable(max_blocking_time=0), Policy.History.KeepLast(1),
                    Policy.DataRepresentation(use_cdrv0_representation=True)))
        self.received: dict[str, list] = {"joint_states": [], "pressures": [], "force_reference": [], "clock": []}

    def poll(self) -> None:
        for key, ty in [("joint_states", JointState), ("pressures", FluidPressure),
                        ("force_reference", Float64MultiArray), ("clock", Clock)]:
            # Data only: the node's end comes as an invalid sample.
            self.received[key].extend(s for s in getattr(self, key).take(N=4000) if isinstance(s, ty))

    def command(self, names: list[str], efforts: list[float]) -> None:
        now = time.time_ns()
        self.commands.write(JointState(Header(Time(now // 1_000_000_000, now % 1_000_000_000), ""),
                                       names, [], [], efforts))


def run_node(a, scene: str, run: str, duration_s: float, out: Path, joints: list[str],
             command: tuple[list[str], list[float], float, float]) -> tuple[Session, int, dict]:
    """Starts the node, receives until it exits, commands `command` = (names, efforts, from_s, to_s) while
    the latest stamp is in [from_s, to_s). Returns the session, the node's exit code and its trace."""
    session = Session(a.domain, joints)
    node = ros2_dds.start_node(a.pneuflex, scene, run, duration_s, a.domain, out)
    names, efforts, t0, t1 = command
    deadline = time.monotonic() + duration_s + 30
    last_command = 0.0
    while node.poll() is None and time.monotonic() < deadline:
        session.poll()
        js = session.received["joint_states"]
        t = stamp_ns(js[-1].header.stamp) * 1e-9 if js else 0.0
        if t0 <= t < t1 and time.monotonic() - last_command >= 0.01:
            session.command(names, efforts)
            last_command = time.monotonic()
        time.sleep(0.005)
    if node.poll() is None:
        node.kill()
        check(False, f"{scene}: the node did not end within {duration_s + 30} s")
    code = node.wait()
    session.poll()
    log = Path(f"{out}.log").read_text()
    check(code == 0, f"{scene}: the node exited {code}: {log[-2000:]}")
    trace = read_trace(out / run / "trace.csv") if (out / run / "trace.csv").exists() else {}
    check(bool(trace), f"{scene}: no {out / run / 'trace.csv'}")
    print(f"{scene}: {log.strip().splitlines()[-2] if log.strip() else ''}")
    return session, code, trace


def joint_states_equal_the_trace(scene: str, session: Session, trace: dict, joints: list[str],
                                 velocity_column: bool) -> dict[int, int]:
    """Each received joint state against the trace's row of its stamp; returns stamp -> row."""
    t = trace.get("t", [])
    n = len(t)
    dt = t[1] - t[0] if n > 1 else 1e-3
    js = session.received["joint_states"]
    check(len(js) >= n // 2, f"{scene}: {len(js)} joint states received of {n} ticks (under half)")
    prefix = {j: "" if len(joints) == 1 else f"{j}." for j in joints}
    rows: dict[int, int] = {}
    previous = -1
    for m in js:
        ns = stamp_ns(m.header.stamp)
        k = round(ns * 1e-9 / dt)
        check(0 <= k < n and abs(ns * 1e-9 - t[k]) <= 1e-9, f"{scene}: a stamp {ns} ns off the trace's ticks")
        if not 0 <= k < n:
            continue
        rows[ns] = k
        check(ns > previous, f"{scene}: stamp {ns} ns after {previous} ns")
        previous = ns
        check(list(m.name) == joints, f"{scene}: names {list(m.name)}")
        for i, j in enumerate(joints):
            p = prefix[j]
            check(m.position[i] == trace[p + "x"][k], f"{scene} t={t[k]} {j}: position {m.position[i]} != x")
            check(m.effort[i] == trace[p + "f_e"][k], f"{scene} t={t[k]} {j}: effort {m.effort[i]} != f_e")
            v = m.velocity[i]
            check(math.isfinite(v) and abs(v) < 2.0, f"{scene} t={t[k]} {j}: velocity {v} m/s")
            if velocity_column:
                check(v == trace[p + "x_dot"][k], f"{scene} t={t[k]} {j}: velocity {v} != x_dot")
    return rows


def check_fig3(a) -> None:
    scene, joints, command = "paper-fig3", ["cylinder"], 16.0
    out = a.out / "fig3"
    session, _, trace = run_node(a, "scenes/paper-fig3.toml", "impedance", 7.0, out, joints,
                                 (joints, [command], 1.5, 4.5))
    if not trace:
        return
    t, n = trace["t"], len(trace["t"])
    joint_states_equal_the_trace(scene, session, trace, joints, velocity_column=False)
    pressures = session.received["pressures"]
    check(len(pressures) >= n // 2, f"{scene}: {len(pressures)} pressures of {n} ticks")
    for m in pressures:
        k = round(stamp_ns(m.header.stamp) * 1e-9 / 1e-3)
        check(0 <= k < n and m.fluid_pressure == trace["p_a"][k], f"{scene}: pressure {m.fluid_pressure} != p_a")
        check(5e4 < m.fluid_pressure < 1.5e6, f"{scene}: pressure {m.fluid_pressure} Pa")
    clock = [stamp_ns(m.clock) for m in session.received["clock"]]
    check(len(clock) >= n // 2 and clock == sorted(clock), f"{scene}: {len(clock)} clock samples, in order")

    # The command: in the trace from the first commanded tick, for at least 1 s, never before.
    f_ref, f_e = trace["f_ref"], trace["f_e"]
    commanded = [k for k in range(n) if f_ref[k] == command]
    check(len(commanded) >= 1000, f"{scene}: f_ref = {command} N at {len(commanded)} ticks (under 1 s)")
    if not commanded:
        return
    c0, c1 = commanded[0], commanded[-1]
    check(t[c0] >= 1.5 and all(f_ref[k] == command for k in range(c0, c1 + 1)),
          f"{scene}: commanded ticks from t = {t[c0]} s, not one stretch to {t[c1]} s")
    check(any(m.data and m.data[0] == command for m in session.received["force_reference"]),
          f"{scene}: the force reference topic never carried {command} N")
    mean = lambda k0, k1: sum(f_e[k0:k1]) / max(1, k1 - k0)  # noqa: E731
    before, end = mean(max(0, c0 - 500), c0), mean(max(c0, c1 - 500), c1)
    print(f"{scene}: f_e {before:.2f} N in the 0.5 s before the command, {end:.2f} N in its last 0.5 s "
          f"(commanded {command} N from t = {t[c0]:.3f} to {t[c1]:.3f} s)")
    check(abs(before - command) > 4.0, f"{scene}: f_e already {before:.2f} N before the command")
    check(abs(end - command) < 1.5, f"{scene}: f_e {end:.2f} N at the command's end, not near {command} N")
    back = [k for k in range(c1 + 1, n) if t[k] > t[c1] + 0.05]
    check(bool(back) and all(f_ref[k] != command for k in back),
          f"{scene}: f_ref still {command} N after the commands stopped (timeout 0.5 s)")


def check_gripper(a) -> None:
    scene, joints, command = "gripper", ["left", "right"], 30.0
    out = a.out / "gripper"
    session, _, trace = run_node(a, "scenes/gripper.toml", "impedance", 3.0, out, joints,
                                 (["right"], [command], 1.0, 2.0))
    if not trace:
        return
    joint_states_equal_the_trace(scene, session, trace, joints, velocity_column=True)
    right = [k for k, f in enumerate(trace["right.f_ref"]) if f == command]
    check(len(right) >= 300, f"{scene}: right.f_ref = {command} N at {len(right)} ticks (under 0.3 s)")
    check(command not in trace["left.f_ref"], f"{scene}: a command to `right` changed left's reference")


def check_rig(a) -> None:
    """`rig run --ros2` on the emulated rig (a pseudo-terminal, real time, its watchdog loosened): the rows it
    traces are published, and a command replaces the force reference. A machine loaded past that may still end
    the run on a fault (the supervisor's watchdog): then the rows up to its end are checked, and the command
    only if it came before."""
    import re
    import subprocess
    scene, joints, command = "rig", ["cylinder"], 16.0
    out = a.out / "rig"
    emulator_log = a.out / "emulator.txt"
    # rigs/emulated.toml with a watchdog ten times looser (its sheets named from here): a machine loaded by
    # other builds deschedules the loop or the emulator for tens of ms, which this check is not about.
    repo = Path(__file__).resolve().parent.parent
    text = (repo / "rigs" / "emulated.toml").read_text().replace('"../', f'"{repo}/')
    for key, value in [("timeout_ms", "200.0"), ("stale_ms", "500.0"), ("board_watchdog_ms", "500")]:
        text = re.sub(rf"^{key} = [0-9.]+", f"{key} = {value}", text, flags=re.M)
    rig_file = a.out / "emulated-loose.toml"
    rig_file.write_text(text)
    emulator = subprocess.Popen([a.pneuflex, "rig", "emulate", "--rig", str(rig_file), "--duration", "15"],
                                stdout=open(emulator_log, "w"), stderr=subprocess.STDOUT)
    try:
        pty = None
        for _ in range(100):
            m = re.search(r"/dev/pts/[0-9]+", emulator_log.read_text(errors="replace"))
            if m:
                pty = m.group(0)
                break
            time.sleep(0.1)
        check(pty is not None, f"{scene}: the emulator printed no pseudo-terminal")
        if pty is None:
            return
        session = Session(a.domain, joints)
        log = open(f"{out}.log", "w")
        node = subprocess.Popen(
            [a.pneuflex, "rig", "run", "--rig", str(rig_file), "--port", pty, "--scene", "scenes/paper-fig3.toml",
             "--run", "impedance",
             "--duration", "4", "--out", str(out), "--ros2", "--domain-id", str(a.domain), "--localhost"],
            stdout=log, stderr=subprocess.STDOUT)
        deadline = time.monotonic() + 40
        last_command = 0.0
        while node.poll() is None and time.monotonic() < deadline:
            session.poll()
            js = session.received["joint_states"]
            t = stamp_ns(js[-1].header.stamp) * 1e-9 if js else 0.0
            if 1.0 <= t < 3.0 and time.monotonic() - last_command >= 0.01:
                session.command(joints, [command])
                last_command = time.monotonic()
            time.sleep(0.005)
        if node.poll() is None:
            node.kill()
            check(False, f"{scene}: rig run did not end within 40 s")
        code = node.wait()
        session.poll()
    finally:
        emulator.kill()
        emulator.wait()
    text = Path(f"{out}.log").read_text()
    fault = "fault:" in text and "no fault" not in text
    check(code == 0 or fault, f"{scene}: rig run exited {code} without a fault: {text[-2000:]}")
    trace_path = out / "trace.csv"
    check(trace_path.exists(), f"{scene}: no {trace_path}")
    if not trace_path.exists():
        return
    trace = read_trace(trace_path)
    t, n = trace["t"], len(trace["t"])
    js = session.received["joint_states"]
    print(f"{scene}: {n} rows traced{' (ended on a fault)' if fault else ''}, {len(js)} joint states received")
    check(len(js) >= n // 2, f"{scene}: {len(js)} joint states received of {n} traced rows (under half)")
    row = {round(v * 1e6): k for k, v in enumerate(t)}
    for m in js:
        k = row.get(round(stamp_ns(m.header.stamp) * 1e-3))
        check(k is not None, f"{scene}: a stamp {stamp_ns(m.header.stamp)} ns on no traced row")
        if k is None:
            continue
        check(list(m.name) == joints and m.position[0] == trace["x"][k] and m.effort[0] == trace["f_e"][k],
              f"{scene} t={t[k]}: joint state {list(m.name)} {m.position} {m.effort} != the trace's x, f_e")
        check(len(m.velocity) == 0, f"{scene}: a velocity the rig's row does not have")
    commanded = [k for k in range(n) if trace["f_ref"][k] == command]
    if fault and not commanded:
        print(f"{scene}: the run ended on a fault before the command took (a loaded machine): not checked")
        return
    check(len(commanded) >= 500, f"{scene}: f_ref = {command} N at {len(commanded)} ticks (under 0.5 s)")
    check(not commanded or t[commanded[0]] >= 1.0, f"{scene}: f_ref = {command} N before the first command")
    if len(commanded) >= 500:
        f_e, c0, c1 = trace["f_e"], commanded[0], commanded[-1]
        before = sum(f_e[max(0, c0 - 300):c0]) / max(1, c0 - max(0, c0 - 300))
        end = sum(f_e[c1 - 300:c1]) / 300
        print(f"{scene}: f_e {before:.2f} N before the command, {end:.2f} N at its end (commanded {command} N)")
        check(abs(end - command) < abs(before - command) - 2.0, f"{scene}: f_e did not move toward {command} N")


def main() -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--pneuflex", default="target/debug/pneuflex")
    ap.add_argument("--out", type=Path, default=Path("target/ci-ros2-node"))
    ap.add_argument("--domain", type=int, default=None)
    a = ap.parse_args()
    a.domain = ros2_dds.domain_of_pid() if a.domain is None else a.domain
    a.out.mkdir(parents=True, exist_ok=True)
    for sub in ("fig3", "gripper", "rig"):
        if (a.out / sub).exists():
            sys.exit(f"{a.out / sub} exists: give an empty --out")
    ros2_dds.use_loopback()
    print(f"Cyclone DDS on 127.0.0.1, domain {a.domain}")
    check_fig3(a)
    check_gripper(a)
    check_rig(a)
    if failed:
        print("FAILED:\n  " + "\n  ".join(failed))
        return 1
    print("ros2 node: every check holds")
    return 0


if __name__ == "__main__":
    sys.exit(main())
