#!/usr/bin/env python3
"""Whole-process timing and peak RSS of `pneuflex run SCENE`, interleaved between binaries.

    python3 scripts/time_run.py SCENE N BIN [BIN ...]

Runs each BIN `run SCENE --out TMP -q` N times, alternating the binaries (and their order every round),
and prints per binary the min/median/max of wall time, CPU time (user + sys, wait4's rusage) and peak RSS
(GNU time's %M). Then N more runs per binary without -q, interleaved the same way: their wall time, the
simulation time the command reports (`simulated in`: 1 ms resolution, 10 ms in binaries older than the
commit after 720316c) and the ratio of the two per run (issue 14: fig7's whole process against its
simulation). Nothing is asserted: this machine is noisy; compare within one run.
"""
import os
import statistics
import subprocess
import sys
import tempfile
import time


GNU_TIME = "/usr/bin/time"


def once(binary, scene, out):
    # Peak RSS through GNU time: a child forked from this interpreter would report the interpreter's pages
    # in its ru_maxrss (Linux counts the pages held before exec). CPU: wait4's rusage, which includes the
    # reaped grandchild.
    rss_file = out + ".rss"
    cmd = [binary, "run", scene, "--out", out, "-q"]
    if os.path.exists(GNU_TIME):
        cmd = [GNU_TIME, "-f", "%M", "-o", rss_file] + cmd
    t0 = time.perf_counter()
    p = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    _, status, ru = os.wait4(p.pid, 0)
    wall = time.perf_counter() - t0
    if os.waitstatus_to_exitcode(status) != 0:
        sys.exit(f"{binary} run {scene}: exit {os.waitstatus_to_exitcode(status)}")
    rss = float(open(rss_file).read().split()[-1]) if os.path.exists(GNU_TIME) else float("nan")
    return wall, ru.ru_utime + ru.ru_stime, rss  # s, s, KiB


def sim_time(binary, scene, out):
    """(whole-process wall time, the simulation time the command reports) of one run without -q, s."""
    t0 = time.perf_counter()
    text = subprocess.run([binary, "run", scene, "--out", out], capture_output=True, text=True).stdout
    wall = time.perf_counter() - t0
    for line in text.splitlines():
        if "simulated in" in line:
            return wall, float(line.split("simulated in")[1].split("s;")[0])
    return wall, float("nan")


def main():
    scene, n, bins = sys.argv[1], int(sys.argv[2]), sys.argv[3:]
    rows = {b: [] for b in bins}
    with tempfile.TemporaryDirectory() as tmp:
        outs = {b: os.path.join(tmp, f"out{i}") for i, b in enumerate(bins)}
        for b in bins:  # warm the page cache
            once(b, scene, outs[b])
        for k in range(n):
            order = bins if k % 2 == 0 else bins[::-1]
            for b in order:
                rows[b].append(once(b, scene, outs[b]))
        sims = {b: [] for b in bins}
        for k in range(n):
            for b in bins if k % 2 == 0 else bins[::-1]:
                sims[b].append(sim_time(b, scene, outs[b]))
    fmt = lambda xs, s, d=1: "/".join(f"{x * s:.{d}f}" for x in (min(xs), statistics.median(xs), max(xs)))
    print(f"{scene}, {n} interleaved runs each (min/median/max)")
    for b in bins:
        wall, cpu, rss = zip(*rows[b])
        print(f"  {b}: wall {fmt(wall, 1e3)} ms, CPU {fmt(cpu, 1e3)} ms, peak RSS {fmt(rss, 1 / 1024)} MiB")
        whole, sim = zip(*sims[b])
        print(f"  {' ' * len(b)}  without -q: wall {fmt(whole, 1e3)} ms, reported simulation {fmt(sim, 1e3)} ms, "
              f"whole / simulation (per run) {fmt([w / s for w, s in sims[b]], 1, 2)}")


if __name__ == "__main__":
    main()
