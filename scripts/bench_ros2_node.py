#!/usr/bin/env python3
"""Measure `pneuflex ros2` on loopback against Eclipse Cyclone DDS (docs/ros2.md, "Rates and latencies"): the
rate at which a Cyclone reader receives each topic, the fraction of the ticks it receives, the latency from
publish to receive of the joint states, and the round trip of a joint command (written by Cyclone until the
node's force reference topic carries it back). A measurement, not a test: it asserts nothing.

Usage:
  python scripts/bench_ros2_node.py [--pneuflex target/release/pneuflex] [--scene scenes/paper-fig3.toml]
      [--run impedance] [--duration 10] [--domain N] [--out DIR]

Publish -> receive: the sample's source timestamp (RustDDS stamps it with the wall clock when the node
publishes) to the wall clock in the reader's data-available listener (Cyclone's receive thread, holding the
Python GIL), same host, same clock; Python's cyclic garbage collector is off, whose pauses would be the
reader's. Round trip: from Cyclone's write of a command (a value no other command
has) to the listener's receipt of the first /pneuflex/force_reference that carries it; it includes the wait
for the node's next tick (up to one control period). Commands go out every 200 ms from 1 s on.
"""
import argparse
import statistics
import sys
import tempfile
import threading
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
import ros2_dds  # noqa: E402
from ros2_dds import Clock, Float64MultiArray, FluidPressure, Header, JointState, Time, stamp_ns  # noqa: E402


def percentiles(v: list[float]) -> str:
    if not v:
        return "none"
    s = sorted(v)
    q = lambda p: s[min(len(s) - 1, int(p * len(s)))]  # noqa: E731
    return (f"min {s[0]:.3f}, median {statistics.median(s):.3f}, p99 {q(0.99):.3f}, max {s[-1]:.3f} ms "
            f"(N = {len(s)})")


def main() -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--pneuflex", default="target/release/pneuflex")
    ap.add_argument("--scene", default="scenes/paper-fig3.toml")
    ap.add_argument("--run", default="impedance")
    ap.add_argument("--duration", type=float, default=10.0)
    ap.add_argument("--domain", type=int, default=None)
    ap.add_argument("--out", type=Path, default=None)
    a = ap.parse_args()
    domain = ros2_dds.domain_of_pid() if a.domain is None else a.domain
    # The samples kept (tens of thousands of objects) would make Python's cyclic collector stop the listener
    # (it holds the GIL) for tens of ms now and then: a stall of this reader, not of the transport. Nothing
    # here makes cycles; counting references frees what is dropped.
    import gc
    gc.disable()
    ros2_dds.use_loopback()
    from cyclonedds.core import Listener, Policy, Qos
    from cyclonedds.domain import DomainParticipant
    from cyclonedds.pub import DataWriter
    from cyclonedds.sub import DataReader
    from cyclonedds.topic import Topic

    dp = DomainParticipant(domain)
    qos = Qos(Policy.Reliability.BestEffort, Policy.History.KeepLast(1000))
    lock = threading.Lock()
    got: dict[str, list[tuple[int, int, object]]] = {}

    def listen(key, ty):
        got[key] = []

        def on_data(reader):
            if reader is None:  # a callback before the reader's constructor returned: the next one takes these
                return
            samples = reader.take(N=1000)
            now = time.time_ns()
            with lock:
                # Data only: the writer's end comes as an invalid sample.
                got[key].extend((now, s.sample_info.source_timestamp, s) for s in samples if isinstance(s, ty))
        return Listener(on_data_available=on_data)

    readers = []
    for key, name, ty in [("joint_states", "/pneuflex/joint_states", JointState),
                          ("clock", "/clock", Clock),
                          ("force_reference", "/pneuflex/force_reference", Float64MultiArray)]:
        readers.append(DataReader(dp, Topic(dp, "rt" + name, ty), qos=qos, listener=listen(key, ty)))
    pressure_topics = []
    writer = DataWriter(dp, Topic(dp, "rt/pneuflex/joint_commands", JointState),
                        qos=Qos(Policy.Reliability.Reliable(max_blocking_time=0), Policy.History.KeepLast(1),
                                Policy.DataRepresentation(use_cdrv0_representation=True)))
    out = a.out or Path(tempfile.mkdtemp(prefix="bench-ros2-")) / "node"
    node = ros2_dds.start_node(a.pneuflex, a.scene, a.run, a.duration, domain, out)
    joints = None
    sent: dict[float, int] = {}
    started = time.monotonic()
    next_command = 1.0
    i = 0
    while node.poll() is None:
        time.sleep(0.002)
        with lock:
            js = got["joint_states"][-1][2] if got["joint_states"] else None
        if js is None:
            continue
        if joints is None:
            joints = list(js.name)
            for j in joints:
                for c in "ab":
                    key = f"p_{j}_{c}"
                    readers.append(DataReader(dp, Topic(dp, f"rt/pneuflex/pressures/{j}/{c}", FluidPressure),
                                              qos=qos, listener=listen(key, FluidPressure)))
                    pressure_topics.append(key)
        t = stamp_ns(js.header.stamp) * 1e-9
        if t >= next_command and t < a.duration - 1.0:
            i += 1
            value = 10.0 + 0.001 * i
            now = time.time_ns()
            writer.write(JointState(Header(Time(now // 1_000_000_000, now % 1_000_000_000), ""), joints,
                                    [], [], [value] * len(joints)))
            sent[value] = now
            next_command = t + 0.2
    node.wait()
    time.sleep(0.2)
    wall = time.monotonic() - started
    log = Path(f"{out}.log").read_text().strip().splitlines()
    rows = sum(1 for line in open(out / a.run / "trace.csv") if line[0].isdigit())
    print(f"scene {a.scene}, run {a.run}, {a.duration} s, domain {domain}, {wall:.1f} s wall; node: {log[-2]}")
    with lock:
        for key in ["joint_states", "clock", "force_reference", *pressure_topics]:
            g = got.get(key, [])
            if len(g) < 2:
                print(f"{key}: {len(g)} samples")
                continue
            span = (g[-1][0] - g[0][0]) * 1e-9
            gaps = [(b[0] - a_[0]) * 1e-6 for a_, b in zip(g, g[1:])]
            print(f"{key}: {len(g)} of {rows} ticks ({100 * len(g) / rows:.1f} %), {(len(g) - 1) / span:.0f} /s "
                  f"over {span:.2f} s; gap between receipts {percentiles(gaps)}")
        lat = [(recv - src) * 1e-6 for recv, src, _ in got["joint_states"]]
        print(f"joint_states publish -> receive: {percentiles(lat)}")
        trips = []
        for value, at in sent.items():
            back = next((recv for recv, _, s in got["force_reference"] if s.data and s.data[0] == value), None)
            if back is not None:
                trips.append((back - at) * 1e-6)
        print(f"joint command -> force reference round trip: {percentiles(trips)}; {len(trips)} of {len(sent)} "
              f"commands came back")
    return 0


if __name__ == "__main__":
    sys.exit(main())
