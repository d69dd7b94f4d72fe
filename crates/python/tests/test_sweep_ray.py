"""pneuflex.sweep / pneuflex.tune on a local Ray cluster give the same table and the same tune as the local Rust
pool, byte for byte (docs/sweeps.md). Run by scripts/ci_sweeps (it installs Ray from scripts/requirements.txt).

Ray is started on this machine only: 2 CPUs, no dashboard, bound to 127.0.0.1, token auth off
(RAY_AUTH_MODE=disabled, set before ray is imported), and shut down at the end.
"""

import os
import sys
import tempfile
import traceback
from pathlib import Path

os.environ.setdefault("RAY_AUTH_MODE", "disabled")
os.environ.setdefault("RAY_USAGE_STATS_ENABLED", "0")

import pneuflex  # noqa: E402
import ray  # noqa: E402

ROOT = Path(__file__).resolve().parents[3]
FIG3_IDEAL = str(ROOT / "scenes" / "paper-fig3-ideal.toml")
FIG3 = str(ROOT / "scenes" / "paper-fig3.toml")
STEP = str(ROOT / "crates" / "sweep" / "tests" / "data" / "ideal-step.toml")
SETS = ["environment.stiffness_n_per_m=log:300:3000:3", "runs[*].inner.kp_per_m=100,200"]


def test_ray_table_equals_local_table():
    local = pneuflex.sweep(FIG3_IDEAL, SETS, executor="local")
    assert local.count("\n") == 1 + 6 * 2, local
    for chunk in (1, 4, None):
        remote = pneuflex.sweep(FIG3_IDEAL, SETS, executor=pneuflex.RayExecutor(chunk_size=chunk))
        assert remote == local, f"chunk_size={chunk}: the Ray table differs from the local one"


def test_ray_table_equals_the_cli_table():
    # The same sweep as scripts/ci_sweeps runs with the CLI (when it ran first).
    cli = ROOT / "target" / "ci-sweeps" / "grid-1" / "sweep.csv"
    if not cli.exists():
        print("  (no CLI table to compare: run scripts/ci_sweeps)")
        return
    remote = pneuflex.sweep(FIG3_IDEAL, SETS, executor="ray")
    assert remote == cli.read_text(encoding="utf-8")


def test_ray_sampled_pwm_sweep_equals_local():
    # A sample on the PWM plant (one key sampled, one listed): chunks of 3 points.
    sets = ["runs[adaptive].inner.kp_per_m=lhs:5:15", "events[0].stiffness_n_per_m=700,2800"]
    local = pneuflex.sweep(FIG3, sets, samples=3, seed=4, executor=pneuflex.LocalExecutor(threads=2))
    remote = pneuflex.sweep(FIG3, sets, samples=3, seed=4, executor=pneuflex.RayExecutor(chunk_size=3))
    assert remote == local


def test_bad_key_is_the_scenes_error_before_any_task():
    try:
        pneuflex.sweep(FIG3, ["environment.stiffness_n_per_m=700,-5"], executor="ray")
    except pneuflex.PneuflexError as e:
        msg = str(e)
        assert "paper-fig3.toml:17:" in msg and "sweep point #1 of 2" in msg, msg
    else:
        raise AssertionError("a refused value must raise")


def test_ray_tune_equals_local_tune():
    args = dict(free=["runs[impedance].impedance.b_d_ns_per_m=[10,100]"], over=["environment.stiffness_n_per_m=700"],
                terms=["step.rms_force_error_n=1"], budget=24, seed=5)
    with tempfile.TemporaryDirectory() as d:
        a = pneuflex.tune(STEP, out=os.path.join(d, "local"), executor="local", **args)
        b = pneuflex.tune(STEP, out=os.path.join(d, "ray"), executor="ray", **args)
        assert a == b, (a, b)
        # history.csv as a DataFrame: one row per evaluation.
        h = a.history
        assert len(h) == a["evaluations"] and list(h.columns[:3]) == ["evaluation", "generation",
                                                                       "runs[impedance].impedance.b_d_ns_per_m"]
        for f in ("history.csv", "report.md", "ideal-step-tuned.toml", "tune.json", "convergence.png"):
            x = Path(d, "local", f).read_bytes()
            y = Path(d, "ray", f).read_bytes()
            assert x == y, f"{f} differs between the local and the Ray tune"


def main():
    ray.init(num_cpus=2, include_dashboard=False, _node_ip_address="127.0.0.1", log_to_driver=False,
             configure_logging=False)
    tests = [v for k, v in sorted(globals().items()) if k.startswith("test_") and callable(v)]
    passed = failed = 0
    try:
        for t in tests:
            try:
                t()
                passed += 1
                print(f"ok   {t.__name__}")
            except Exception:  # noqa: BLE001
                failed += 1
                print(f"FAIL {t.__name__}")
                traceback.print_exc()
    finally:
        ray.shutdown()
    print(f"{passed} passed, {failed} failed")
    return 0 if failed == 0 else 1


if __name__ == "__main__":
    sys.exit(main())
