"""The body of scripts/bench_sweep (see there). Standard library only."""

import argparse
import json
import os
import resource
import shutil
import statistics
import subprocess
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
BIN = ROOT / "target" / "release" / "pneuflex"
EXAMPLE = ROOT / "target" / "release" / "examples" / "sweep_overhead"
OUT = ROOT / "target" / "bench-sweep"


def sweep(scene, points, threads, out, quiet=True):
    """Wall time of one whole `pneuflex sweep` process over `points` points."""
    cmd = [str(BIN), "sweep", scene, "--set", f"runs[*].impedance.b_d_ns_per_m=lin:52:53:{points}",
           "--threads", str(threads), "--out", str(out), "--quiet"]
    t = time.perf_counter()
    r0 = resource.getrusage(resource.RUSAGE_CHILDREN)
    subprocess.run(cmd, cwd=ROOT, check=True)
    r1 = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (r1.ru_utime - r0.ru_utime) + (r1.ru_stime - r0.ru_stime)
    return time.perf_counter() - t, cpu


def peak_rss_mib(scene, points, out):
    """Peak RSS of a whole sweep process, by GNU time (its own small image forks the child)."""
    rss = OUT / "rss.txt"
    cmd = ["/usr/bin/time", "-f", "%M", "-o", str(rss), str(BIN), "sweep", scene, "--set",
           f"runs[*].impedance.b_d_ns_per_m=lin:40:60:{points}", "--out", str(out), "--quiet"]
    t = time.perf_counter()
    subprocess.run(cmd, cwd=ROOT, check=True)
    wall = time.perf_counter() - t
    return float(rss.read_text().strip().splitlines()[-1]) / 1024.0, wall


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--rounds", type=int, default=None)
    ap.add_argument("--no-build", action="store_true")
    a = ap.parse_args()
    rounds = a.rounds or (1 if a.quick else 3)
    OUT.mkdir(parents=True, exist_ok=True)
    load0 = os.getloadavg()
    results = {"machine": {"cpus": os.cpu_count(), "loadavg_start": load0}, "throughput": [], "overhead": [],
               "rss": []}
    scenes = [("scenes/paper-fig3.toml", 6 if a.quick else 24, 2), ("scenes/paper-fig7-wood-to-iron.toml",
                                                                     4 if a.quick else 12, 2)]
    print(f"machine: {os.cpu_count()} CPUs, load average at start {load0[0]:.2f} {load0[1]:.2f} {load0[2]:.2f}")
    print("\n(scaling: wall time on 1 thread / on 2 threads, per round; CPU per scene-run: user + system time of the "
          "process over its scene-runs — equal on 1 and 2 threads means no parallel overhead, whatever else loads "
          "the machine)\n")
    print("| scene | points x runs | threads | scene-runs/s median (min, max) | scaling 2/1 (median, min, max) "
          "| CPU ms per scene-run (median) |")
    print("|---|---|---|---|---|---|")
    for scene, points, runs in scenes:
        walls = {1: [], 2: []}
        cpus = {1: [], 2: []}
        for r in range(rounds):
            for threads in ((1, 2) if r % 2 == 0 else (2, 1)):
                w, c = sweep(scene, points, threads, OUT / f"tp-{threads}")
                walls[threads].append(w)
                cpus[threads].append(c)
        rate = {t: [points * runs / w for w in walls[t]] for t in walls}
        ratios = [w1 / w2 for w1, w2 in zip(walls[1], walls[2])]
        for t in (1, 2):
            rs = rate[t]
            scal = (f"{statistics.median(ratios):.2f} ({min(ratios):.2f}, {max(ratios):.2f})" if t == 2 else "")
            cpu = 1e3 * statistics.median(cpus[t]) / (points * runs)
            print(f"| {Path(scene).stem} | {points} x {runs} | {t} | {statistics.median(rs):.1f} "
                  f"({min(rs):.1f}, {max(rs):.1f}) | {scal} | {cpu:.1f} |")
        results["throughput"].append({"scene": scene, "points": points, "runs": runs, "walls_s": walls,
                                      "cpu_s": cpus, "scaling": ratios})
    print("\nper-point cost, one thread, median over the points (sweep_overhead example):\n")
    print("| scene | scene build [ms] | plant build [ms] | simulation [ms] | row [ms] | overhead / simulation |")
    print("|---|---|---|---|---|---|")
    for scene, _, _ in scenes:
        p = subprocess.run([str(EXAMPLE), scene, "5" if a.quick else "15"], cwd=ROOT, check=True,
                           capture_output=True, text=True)
        o = json.loads(p.stdout)
        results["overhead"].append(o)
        print(f"| {Path(scene).stem} | {1e3 * o['scene_build_s']:.3f} | {1e3 * o['plant_build_s']:.3f} | "
              f"{1e3 * o['simulate_s']:.2f} | {1e3 * o['row_s']:.3f} | {o['overhead_pct']:.2f} % |")
    print("\npeak RSS of whole sweeps (paper-fig3-ideal, one swept key, 2 runs per point, default threads):\n")
    print("| points | peak RSS [MiB] | wall [s] |")
    print("|---|---|---|")
    for n in ((100, 1000) if a.quick else (100, 1000, 10000)):
        mib, wall = peak_rss_mib("scenes/paper-fig3-ideal.toml", n, OUT / f"rss-{n}")
        shutil.rmtree(OUT / f"rss-{n}", ignore_errors=True)
        results["rss"].append({"points": n, "peak_rss_mib": mib, "wall_s": wall})
        print(f"| {n} | {mib:.1f} | {wall:.1f} |")
    results["machine"]["loadavg_end"] = os.getloadavg()
    print(f"\nload average at the end {results['machine']['loadavg_end'][0]:.2f}")
    (OUT / "results.json").write_text(json.dumps(results, indent=1) + "\n")


if __name__ == "__main__":
    main()
