"""pneuflex's coupled tick vs MuJoCo's mj_step on the same rig, in one process, interleaved (scripts/bench).

Each round times, in alternating order:
- pneuflex: `ticks` control ticks of the scene's `run` through `pneuflex.bench_scene_ticks` (Rust loop, no
  Python per tick): sense -> controller update -> actuate -> advance(dt). On paper-fig7-wood-to-iron that is
  one Rapier step + 10 chamber substeps + the adaptive controller per 1 ms tick;
- MuJoCo (C loop): the same simulated time of `mj_step` on the rig's MJCF from crossval (the scene's physics
  step), looped in C by `mujoco.mj_step(model, data, nstep=...)` with a constant push on the flange;
- MuJoCo (Python loop): the same, one `mujoco.mj_step` call per step from Python (what a Python-side coupling
  pays before it does anything);
- MuJoCo + Rust force element from Python: per step `ForceElement.step` (the pneuflex chambers and valve,
  fixed valve command, no controller) + `mj_step`, as crossval couples them;
- MuJoCo with the native plugin `pneuflex.cylinder` (C loop, the same chambers, substeps and command), against
  its parts timed alone: the bare `mj_step` of the rig under the plugin's settled force as a constant push, and
  the chamber model's steps in a Rust loop (`ForceElement.bench_steps`); the three and the Python coupling
  alternate in ten slices per round, and the ratios are taken per round.
Both sides settle into steady contact (1 s) before timing. Rates are simulated steps (control ticks for
pneuflex, mj_steps for MuJoCo; equal at the scene's 1 ms) per wall-clock second; the ratio is taken per round.
Then the Gymnasium task's env-steps per second (Rust batch, vector env, single env; `gym_rates`), and the peak RSS
of whole `pneuflex run` processes (fig3, fig7; GNU time's %M). Nothing here asserts anything about speed.
"""

from __future__ import annotations

import argparse
import os
import platform
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

import mujoco  # noqa: E402

import pneuflex  # noqa: E402
from crossval import couple  # noqa: E402


def machine() -> dict:
    model = platform.processor() or "?"
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                model = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    return {"cpus": os.cpu_count(), "model": model, "load": os.getloadavg()}


class Mujoco:
    """The scene's rig in MuJoCo (crossval's MJCF), settled in steady contact under a constant push."""

    def __init__(self, c: couple.Coupled, push_n: float):
        self.c = c
        self.model = mujoco.MjModel.from_xml_string(c.xml)
        self.data = mujoco.MjData(self.model)
        m = self.model
        self.dof = int(m.jnt_dofadr[m.joint("flange_slide").id])
        self.qadr = int(m.jnt_qposadr[m.joint("flange_slide").id])
        self.data.qpos[self.qadr] = c.spec.x0_m
        self.data.qfrc_applied[self.dof] = push_n
        mujoco.mj_forward(self.model, self.data)
        self.c_loop(round(1.0 / m.opt.timestep))

    def c_loop(self, n: int) -> float:
        t0 = time.perf_counter()
        mujoco.mj_step(self.model, self.data, nstep=n)
        return time.perf_counter() - t0

    def python_loop(self, n: int) -> float:
        step, m, d = mujoco.mj_step, self.model, self.data
        t0 = time.perf_counter()
        for _ in range(n):
            step(m, d)
        return time.perf_counter() - t0

    def warned(self) -> bool:
        return any(self.data.warning[i].number for i in range(int(mujoco.mjtWarning.mjNWARNING)))


class MujocoForceElement:
    """MuJoCo stepped from Python with the Rust pneumatic force element on the flange (fixed valve command)."""

    def __init__(self, c: couple.Coupled, u: float):
        self.sim = Mujoco(c, 0.0)
        act = pneuflex.Actuator.from_scene(c.scene_path)
        init = pneuflex.initial_state(c.scene_path)
        self.fe = pneuflex.ForceElement(act, p_a=init["p_a"], p_b=init["p_b"], substeps=c.chamber_substeps)
        self.u = u
        self.h = float(self.sim.model.opt.timestep)
        self.run(round(1.0 / self.h))

    def run(self, n: int) -> float:
        m, d = self.sim.model, self.sim.data
        qpos, qvel, qfrc = d.qpos, d.qvel, d.qfrc_applied
        iq, dof, u, h = self.sim.qadr, self.sim.dof, self.u, self.h
        fstep, friction, step = self.fe.step, self.fe.friction_force, mujoco.mj_step
        t0 = time.perf_counter()
        for _ in range(n):
            v = qvel[dof]
            f = fstep(qpos[iq], v, u, h)
            qfrc[dof] = f - friction(v, f)
            step(m, d)
        return time.perf_counter() - t0


class MujocoPlugin:
    """The same rig with the cylinder as MuJoCo's native actuator (`pneuflex.cylinder`, crossval's plugin MJCF,
    the scene's chamber substeps per step, fixed valve command), next to what it is made of: the rig without
    the actuator under a constant push equal to the plugin's settled force (the same contact), and the chamber
    model's own steps in a Rust loop (`ForceElement.bench_steps`, the same substeps and command)."""

    def __init__(self, c: couple.Coupled, u: float, library: str):
        from crossval import mjcf

        mujoco.mj_loadPluginLibrary(library)
        self.model = mujoco.MjModel.from_xml_string(mjcf.with_cylinder_plugin(c.xml, couple.plugin_config(c)))
        self.data = mujoco.MjData(self.model)
        m = self.model
        jnt = m.joint("flange_slide").id
        self.data.qpos[int(m.jnt_qposadr[jnt])] = c.spec.x0_m
        self.data.ctrl[0] = u
        n = round(1.0 / m.opt.timestep)
        self.c_loop(n)
        # The bare model's push: the plugin's mean force over the next settled second (its PWM ripple
        # averages out), so that both press the face alike.
        forces = []
        for _ in range(n):
            mujoco.mj_step(self.model, self.data)
            forces.append(float(self.data.actuator_force[0]))
        self.push = sum(forces) / len(forces)
        self.bare = Mujoco(c, self.push)
        act = pneuflex.Actuator.from_scene(c.scene_path)
        init = pneuflex.initial_state(c.scene_path)
        self.fe = pneuflex.ForceElement(act, p_a=init["p_a"], p_b=init["p_b"], substeps=c.chamber_substeps)
        self.x, self.u, self.h = c.spec.x0_m, u, float(m.opt.timestep)
        self.chambers(round(1.0 / self.h))

    def c_loop(self, n: int) -> float:
        t0 = time.perf_counter()
        mujoco.mj_step(self.model, self.data, nstep=n)
        return time.perf_counter() - t0

    def chambers(self, n: int) -> float:
        return self.fe.bench_steps(n, self.x, 0.0, self.u, self.h)

    def slices(self, n: int, coupling=None, chunks: int = 10, reverse: bool = False) -> list[float]:
        """Wall times of n steps each of the plugin, the bare model, the chambers alone and (when given) the
        Python coupling, taken in `chunks` alternating slices so that a burst of another process's load falls
        on all of them alike (a 2-core machine shared with builds)."""
        parts = [self.c_loop, self.bare.c_loop, self.chambers] + ([coupling] if coupling else [])
        t = [0.0] * len(parts)
        order = list(range(len(parts)))[:: -1 if reverse else 1]
        k = n // chunks
        for _ in range(chunks):
            for i in order:
                t[i] += parts[i](k)
        return t

    def warned(self) -> bool:
        d = self.data
        return any(d.warning[i].number for i in range(int(mujoco.mjtWarning.mjNWARNING))) or self.bare.warned()


def stats(xs: list[float]) -> tuple[float, float, float]:
    return min(xs), statistics.median(xs), max(xs)


def fmt_rate(xs: list[float]) -> str:
    lo, med, hi = stats(xs)
    return f"{med:>10,.0f} steps/s  ({1e6 / med:6.2f} us/step)   min {lo:>10,.0f}  max {hi:>10,.0f}"


def gym_rates(rounds: int, quick: bool) -> None:
    """Env-steps per second of the Gymnasium force-control task (docs/gymnasium.md) on paper-fig3, interleaved
    over rounds: the Rust batch alone (`ForceControlBatch.step`, both cores), the same through the vector
    environment (`gymnasium.make_vec`), at 256 episodes (issue 45's targets: 1.5 M and 200 k on 2 cores), and
    the single environment's Python step, with its layers: the unwrapped environment's step (without
    Gymnasium's wrappers) and the Rust call alone (`ForceControlBatch.step_single` of a batch of one), so the
    Python overhead per step is the first minus the last. Random valve commands, domain randomisation on,
    next-step autoreset."""
    try:
        import gymnasium

        import pneuflex.envs  # noqa: F401
    except ImportError as e:
        print(f"\n(Gymnasium rows skipped: {e})")
        return
    n = 256
    scene = str(ROOT / "scenes" / "paper-fig3.toml")
    batch = pneuflex.ForceControlBatch(scene, n, randomize=True, autoreset=True)
    batch.reset(1)
    vec = gymnasium.make_vec("pneuflex/ForceControl-v0", num_envs=n, vectorization_mode="vector_entry_point")
    vec.reset(seed=1)
    single = gymnasium.make("pneuflex/ForceControl-v0")
    single.reset(seed=1)
    unwrapped = gymnasium.make("pneuflex/ForceControl-v0").unwrapped
    unwrapped.reset(seed=1)
    one = pneuflex.ForceControlBatch(scene, 1, randomize=True, autoreset=True)
    one.reset(1)
    import numpy as np

    rng = np.random.default_rng(0)
    actions = rng.uniform(-0.2, 0.2, (8, n))
    steps = 20 if quick else 100
    # The batched rows time 1,000 steps a round (about 0.2 s): a round of 100 (18 ms) also timed the helper
    # thread's wake-up after the single-environment rows and the scheduler's noise.
    batch_steps = 20 if quick else 1000

    def timed(f, k: int, per: int) -> float:
        t0 = time.perf_counter()
        for i in range(k):
            f(i)
        return k * per / (time.perf_counter() - t0)

    def single_step(i: int) -> None:
        # An episode that ended (an end stop, or the 10 s run's end) is reset, as a training loop would.
        _, _, terminated, truncated, _ = single.step(actions[i % 8, :1])
        if terminated or truncated:
            single.reset()

    def unwrapped_step(i: int) -> None:
        _, _, terminated, truncated, _ = unwrapped.step(actions[i % 8, :1])
        if terminated or truncated:
            unwrapped.reset()

    rates: dict[str, list[float]] = {"batch": [], "vector": [], "single": [], "unwrapped": [], "rust": []}
    for _ in range(rounds):
        rates["batch"].append(timed(lambda i: batch.step(actions[i % 8]), batch_steps, n))
        rates["vector"].append(timed(lambda i: vec.step(actions[i % 8, :, None]), batch_steps, n))
        rates["single"].append(timed(single_step, steps * 50, 1))
        rates["unwrapped"].append(timed(unwrapped_step, steps * 50, 1))
        rates["rust"].append(timed(lambda i: one.step_single(actions[i % 8, :1]), steps * 50, 1))
    print(f"\nGymnasium force-control task on paper-fig3 (1 ms tick, 10 RK4 substeps; {n} episodes, "
          f"{rounds} rounds, interleaved), env-steps per wall-clock second:")
    print(f"  Rust batch (ForceControlBatch.step)      {fmt_rate(rates['batch'])}")
    print(f"  vector env (gymnasium.make_vec)          {fmt_rate(rates['vector'])}")
    print(f"  single env (gymnasium.make, Python step) {fmt_rate(rates['single'])}")
    print(f"    its unwrapped env (no wrappers)        {fmt_rate(rates['unwrapped'])}")
    print(f"    its Rust call (step_single, 1 episode) {fmt_rate(rates['rust'])}")
    over = [1e6 / a - 1e6 / b for a, b in zip(rates["single"], rates["rust"])]
    lo, med, hi = stats(over)
    print(f"  Python overhead per single-env step (make's step - the Rust call): {med:.2f} us (min {lo:.2f}, max {hi:.2f})")


def peak_rss(binary: Path, scene: str, out_root: Path) -> dict:
    """Peak RSS (MiB) and wall time (s) of one whole `pneuflex run` process.

    Measured by GNU time (/usr/bin/time -f %M), which forks from its own small image: a child forked straight
    from this Python process counts the Python pages it inherited before exec (Linux folds the pre-exec
    high-water mark into ru_maxrss), so os.wait4 here would report ~60 MiB for any command. Without GNU time
    the wait4 figure is printed as an upper bound."""
    out = out_root / Path(scene).stem
    cmd = [str(binary), "run", scene, "--out", str(out), "--quiet"]
    gnu_time = Path("/usr/bin/time")
    t0 = time.perf_counter()
    if gnu_time.exists():
        rss_file = out_root / (Path(scene).stem + ".rss")
        p = subprocess.run([str(gnu_time), "-f", "%M", "-o", str(rss_file), *cmd], cwd=ROOT, stdout=subprocess.DEVNULL)
        wall = time.perf_counter() - t0
        text = rss_file.read_text().strip().splitlines()
        kib, exact = float(text[-1]), True
        code = p.returncode
    else:
        p = subprocess.Popen(cmd, cwd=ROOT, stdout=subprocess.DEVNULL)
        _, status, ru = os.wait4(p.pid, 0)
        wall = time.perf_counter() - t0
        kib, exact = float(ru.ru_maxrss), False
        code = os.waitstatus_to_exitcode(status)
        p.returncode = code
    return {"scene": scene, "rss_mib": kib / 1024.0, "exact": exact, "wall_s": wall, "exit": code}


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--quick", action="store_true", help="CI: 5 rounds of 5000 ticks, RSS with --rss-binary if given")
    ap.add_argument("--scene", default="scenes/paper-fig7-wood-to-iron.toml")
    ap.add_argument("--run", default="adaptive", help="the scene's run whose controller ticks (name)")
    ap.add_argument("--rounds", type=int, default=15)
    ap.add_argument("--ticks", type=int, default=20000, help="control ticks per round (MuJoCo: the same simulated time)")
    ap.add_argument("--push", type=float, default=10.0, help="MuJoCo's constant flange push, N")
    ap.add_argument("--u", type=float, default=0.05, help="valve command of the force-element coupling")
    ap.add_argument("--rss-binary", default=None, help="pneuflex binary for the RSS runs (default target/release/pneuflex)")
    ap.add_argument("--no-rss", action="store_true")
    ap.add_argument("--no-plugin", action="store_true", help="skip the native plugin's rows (pneuflex.mujoco_plugin_path())")
    ap.add_argument("--gym-only", action="store_true", help="only the Gymnasium environments' rows (gym_rates)")
    args = ap.parse_args()
    if args.quick:
        args.rounds, args.ticks = min(args.rounds, 5), min(args.ticks, 5000)
    if args.gym_only:
        m0 = machine()
        print(f"machine: {m0['cpus']} CPUs, {m0['model']}; load average {m0['load'][0]:.2f} {m0['load'][1]:.2f} "
              f"{m0['load'][2]:.2f}")
        gym_rates(args.rounds, args.quick)
        m1 = os.getloadavg()
        print(f"  load average after: {m1[0]:.2f} {m1[1]:.2f} {m1[2]:.2f}")
        return 0

    scene_path = str(ROOT / args.scene)
    c = couple.prepare(scene_path)
    scene = c.scene
    dt = float(scene["dt_s"])
    h = c.spec.timestep_s
    mj_per_tick = c.substeps
    plant = scene["plant"]
    m0 = machine()
    print(f"machine: {m0['cpus']} CPUs, {m0['model']}; load average {m0['load'][0]:.2f} {m0['load'][1]:.2f} {m0['load'][2]:.2f}")
    print(f"python {platform.python_version()}, mujoco {mujoco.__version__}, pneuflex {pneuflex.__version__}")
    print(
        f"scene {args.scene} run {args.run!r}: control tick {dt * 1e3:g} ms, plant {plant['kind']}"
        + (f" (physics {float(plant['physics_dt_s']) * 1e3:g} ms, {plant.get('chamber_substeps')} chamber substeps, "
           f"{plant.get('solver_iterations')} solver iterations)" if plant["kind"] == "multibody" else "")
    )
    print(f"MuJoCo: crossval MJCF of the same rig, timestep {h * 1e3:g} ms, {mj_per_tick} mj_step per tick")
    print(f"{args.rounds} rounds x {args.ticks} ticks ({args.ticks * dt:g} s simulated per engine and round), interleaved\n")

    mj = Mujoco(c, args.push)
    try:
        mjfe = MujocoForceElement(c, args.u)
    except Exception as e:  # informative only
        print(f"(MuJoCo + force element from Python skipped: {e})")
        mjfe = None
    plugin, plugin_note = None, ""
    if not args.no_plugin:
        try:
            library = pneuflex.mujoco_plugin_path()
            plugin = MujocoPlugin(c, args.u, library)
            if "debug" in Path(library).parts:
                plugin_note = " (a debug build of the plugin: not the release figure)"
            print(f"plugin: {library}{plugin_note}; its mean force {plugin.push:.2f} N over a settled second (the bare "
                  f"model's push); contacts: plugin {plugin.data.ncon}, bare {plugin.bare.data.ncon}\n")
        except (FileNotFoundError, ValueError) as e:  # informative only
            print(f"(MuJoCo with the native plugin skipped: {e})\n")
    n_mj = args.ticks * mj_per_tick
    rates = {"pneuflex": [], "mj_c": [], "mj_py": [], "mj_fe": [], "mj_plugin": [], "mj_bare": [], "chambers": []}
    ratios, plugin_ratios = [], []
    last = None

    def pf() -> float:
        nonlocal last
        last = pneuflex.bench_scene_ticks(scene_path, args.run, ticks=args.ticks, settle_s=1.0)
        return last["wall_s"]

    # A warm-up round (caches, lazy loading), not counted.
    pf(), mj.c_loop(n_mj)
    for r in range(args.rounds):
        # With the plugin the Python coupling is timed in its slices (the two are compared).
        order = ["pf", "mj_c", "mj_py"] + (["plugin"] if plugin else ["mj_fe"])
        if r % 2:
            order.reverse()
        t = {}
        for k in order:
            if k == "pf":
                t[k] = pf()
            elif k == "mj_c":
                t[k] = mj.c_loop(n_mj)
            elif k == "mj_py":
                t[k] = mj.python_loop(n_mj)
            elif k == "plugin":
                ts = plugin.slices(n_mj - n_mj % 10, mjfe.run if mjfe else None, reverse=bool(r % 2))
                t["mj_plugin"], t["mj_bare"], t["chambers"] = ts[:3]
                if mjfe is not None:
                    t["mj_fe"] = ts[3] * n_mj / (n_mj - n_mj % 10)
            elif mjfe is not None:
                t[k] = mjfe.run(n_mj)
        rates["pneuflex"].append(args.ticks / t["pf"])
        rates["mj_c"].append(n_mj / t["mj_c"])
        rates["mj_py"].append(n_mj / t["mj_py"])
        if "mj_fe" in t:
            rates["mj_fe"].append(n_mj / t["mj_fe"])
        if plugin:
            for k in ("mj_plugin", "mj_bare", "chambers"):
                rates[k].append((n_mj - n_mj % 10) / t[k])
            # A step with the plugin over the bare step plus the chamber model's own step: 1 = no overhead.
            plugin_ratios.append(t["mj_plugin"] / (t["mj_bare"] + t["chambers"]))
        # pneuflex tick rate over MuJoCo's, both per simulated second: > 1 means pneuflex is faster.
        ratios.append((args.ticks / t["pf"]) / (args.ticks / t["mj_c"]))
    if mj.warned():
        print("warning: MuJoCo reported a warning during the benchmark (it reset its state)")

    rt = 1.0 / dt
    print("steps per wall-clock second (median, min, max over rounds):")
    print(f"  pneuflex coupled tick (Rust loop)        {fmt_rate(rates['pneuflex'])}   real-time x{statistics.median(rates['pneuflex']) / rt:.0f}")
    print(f"  MuJoCo mj_step (C loop, nstep)           {fmt_rate(rates['mj_c'])}")
    print(f"  MuJoCo mj_step (Python loop)             {fmt_rate(rates['mj_py'])}")
    if rates["mj_fe"]:
        print(f"  MuJoCo + Rust force element (Python)     {fmt_rate(rates['mj_fe'])}")
    if plugin_ratios:
        print(f"  MuJoCo with the native plugin (C loop)   {fmt_rate(rates['mj_plugin'])}{plugin_note}")
        print(f"  its parts: MuJoCo bare, same push        {fmt_rate(rates['mj_bare'])}")
        print(f"             chamber model's own step      {fmt_rate(rates['chambers'])}")
    lo, med, hi = stats(ratios)
    print(f"\nratio pneuflex tick / MuJoCo mj_step (C loop), per round: median {med:.3f}  min {lo:.3f}  max {hi:.3f}")
    print(f"  (MuJoCo's C-loop step is {1 / med:.2f}x pneuflex's coupled tick; MuJoCo has no chambers or controller here)")
    print(f"  pneuflex end state: x = {last['x'] * 1e3:.2f} mm, f_e = {last['f_e']:.2f} N; MuJoCo: x = {mj.data.qpos[mj.qadr] * 1e3:.2f} mm")
    if plugin_ratios:
        lo, med, hi = stats(plugin_ratios)
        print(f"\nplugin step / (bare mj_step + chamber step), per round: median {med:.3f}  min {lo:.3f}  max {hi:.3f}"
              f"  (the target: <= 1.10){plugin_note}")
        if rates["mj_fe"]:
            fe_over = [b / a for a, b in zip(rates["mj_fe"], rates["mj_plugin"])]
            lo, med, hi = stats(fe_over)
            print(f"  the Python coupling's step / the plugin's step, per round: median {med:.2f}  min {lo:.2f}  max {hi:.2f}")
        if plugin.warned():
            print("warning: MuJoCo reported a warning in the plugin's models (it reset their state)")
    m1 = os.getloadavg()
    print(f"  load average after: {m1[0]:.2f} {m1[1]:.2f} {m1[2]:.2f}")

    gym_rates(args.rounds, args.quick)

    if not args.no_rss:
        binary = Path(args.rss_binary) if args.rss_binary else Path("target/release/pneuflex")
        binary = binary if binary.is_absolute() else ROOT / binary
        if args.quick and not args.rss_binary:
            print("\npeak RSS: skipped in --quick mode (pass --rss-binary to measure it)")
        elif not binary.exists():
            print(f"\npeak RSS: {binary} missing, skipped")
        else:
            note = "; a debug build: not the release figure" if "debug" in binary.parts else ""
            print(f"\npeak RSS of whole `pneuflex run` processes ({binary}{note}):")
            with tempfile.TemporaryDirectory(prefix="pneuflex-bench-") as tmp:
                for s in ("scenes/paper-fig3.toml", "scenes/paper-fig7-wood-to-iron.toml"):
                    r = peak_rss(binary, s, Path(tmp))
                    status = "" if r["exit"] == 0 else f"  (exit {r['exit']})"
                    if not r["exact"]:
                        status += "  (upper bound: no /usr/bin/time; includes the pages inherited from this process)"
                    print(f"  {s:<40} {r['rss_mib']:7.1f} MiB   wall {r['wall_s'] * 1e3:7.1f} ms{status}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
