"""Sweeps and tuning from Python, on the local Rust thread pool or on a Ray cluster (docs/sweeps.md).

``sweep(scene, sets, ...)`` returns the same table as ``pneuflex sweep`` writes to ``sweep.csv`` (the same bytes,
whatever the executor); ``tune(scene, free, over, out=...)`` writes the same files as ``pneuflex tune``.

Executors:

- ``"local"`` / ``LocalExecutor(threads=0)``: the Rust thread pool of this process (rayon), the GIL released.
- ``RayExecutor(chunk_size=None)``: Ray tasks. A sweep is cut into chunks of consecutive points, one Ray task per
  chunk (each task runs its points one after another on one CPU, ``num_cpus=1``); the driver gathers the chunks'
  rows in point order into the table. The default chunk size gives about four tasks per CPU of the cluster (load
  balance against per-task overhead). A tune keeps the CMA-ES search in this process and evaluates every candidate
  of a generation as one Ray task each (all in flight at once). The caller starts Ray (``ray.init(...)``): locally
  ``ray.init(num_cpus=2, include_dashboard=False)``, or ``ray.init(address="ray://head:10001")`` for a cluster whose
  workers have ``pneuflex`` installed and the scene files at the same (or, with
  ``runtime_env={"working_dir": "."}``, the same relative) paths.
"""

import math
import os

from . import _checks as c
from . import _native
from .frames import SweepTable, TuneResult


class LocalExecutor:
    """The Rust thread pool of this process; ``threads=0``: one per core."""

    def __init__(self, threads=0):
        self.threads = c.integer(threads, "threads", "LocalExecutor", 0)


class RayExecutor:
    """Ray tasks, one chunk of ``chunk_size`` points per task (default: about four tasks per cluster CPU)."""

    def __init__(self, chunk_size=None):
        self.chunk_size = c.optional_integer(chunk_size, "chunk_size", "RayExecutor", 1)


def _executor(executor, threads, where):
    threads = c.integer(threads, "threads", where, 0)
    if isinstance(executor, (LocalExecutor, RayExecutor)):
        return executor
    if executor is None or executor == "local":
        return LocalExecutor(threads)
    if executor == "ray":
        return RayExecutor()
    error = ValueError if isinstance(executor, str) else TypeError
    raise error(f"{where}: executor must be 'local', 'ray', LocalExecutor or RayExecutor, got {c.kind(executor)}")


def _sweep_chunk(scene, sets, indices, samples, seed):
    # Runs in a Ray worker: one CPU per task.
    from pneuflex import _native as native

    return native.sweep_rows(scene, sets, indices, samples, seed, 1)


def _tune_candidate(scene, free, over, x, run, terms):
    from pneuflex import _native as native

    return native.tune_evaluate(scene, free, over, x, run, terms)


def chunks(n, size):
    """Consecutive point indices 0..n in chunks of ``size`` (the last one shorter)."""
    return [list(range(i, min(i + size, n))) for i in range(0, n, size)]


def sweep(scene, sets, samples=None, seed=0, executor="local", threads=0, out=None):
    """The scene at every point of ``sets`` (``["KEY=SPEC", ...]``, as ``pneuflex sweep --set``); returns the
    table (sweep.csv's text, a ``SweepTable`` whose ``.frame`` is the table as a DataFrame). Every point is checked before anything runs (``PneuflexError`` naming the file, the
    key and the point). ``out``: also write it to ``out/sweep.csv`` (created whole: written beside, then renamed;
    the folder's other files are left as they are)."""
    at = "pneuflex.sweep"
    scene = c.path(scene, "scene", at)
    sets = c.strings(sets, "sets", at, '"KEY=SPEC" strings', nonempty=True)
    samples = c.optional_integer(samples, "samples", at, 1)
    seed = c.seed(seed, "seed", at)
    out = c.optional_path(out, "out", at)
    ex = _executor(executor, threads, at)
    if out is not None:
        # Before anything runs: a file where the folder goes.
        for p in (out, os.path.join(out, "sweep.csv")):
            if os.path.exists(p) and os.path.isdir(p) != (p == out):
                raise (NotADirectoryError if p == out else IsADirectoryError)(
                    f"{at}: out: {p} is {'not a folder' if p == out else 'a folder'}")
    n, header = _native.sweep_plan(scene, sets, samples, seed)
    if isinstance(ex, LocalExecutor):
        rows = _native.sweep_rows(scene, sets, list(range(n)), samples, seed, ex.threads)
    else:
        import ray

        size = ex.chunk_size
        if size is None:
            cpus = max(1, int(ray.cluster_resources().get("CPU", 1)))
            size = max(1, math.ceil(n / (4 * cpus)))
        task = ray.remote(num_cpus=1)(_sweep_chunk)
        futures = [task.remote(scene, sets, chunk, samples, seed) for chunk in chunks(n, size)]
        rows = "".join(ray.get(futures))
    table = SweepTable(header + rows)
    if out is not None:
        import tempfile

        os.makedirs(out, exist_ok=True)
        # Whole or not at all: written beside, then renamed over sweep.csv.
        fd, tmp = tempfile.mkstemp(prefix=".sweep.csv.", dir=out)
        try:
            with os.fdopen(fd, "w", encoding="utf-8", newline="") as f:
                f.write(table)
            os.replace(tmp, os.path.join(out, "sweep.csv"))
        except BaseException:
            os.unlink(tmp)
            raise
    return table


def tune(scene, free, over=(), out="out/tune", run=None, terms=(), budget=200, seed=0, population=None,
         sigma0=0.3, executor="local", threads=0):
    """CMA-ES over ``free`` (``["KEY=[LO,HI]", ...]``) minimising the worst case over ``over``
    (``["KEY=V1,V2,..."]``) of the objective of ``pneuflex tune``; writes the tuned scene, report.md,
    convergence.png, history.csv and tune.json into ``out`` and returns tune.json as a dict (a ``TuneResult``, whose
    ``.history`` is history.csv as a DataFrame)."""
    import json

    at = "pneuflex.tune"
    scene, out = c.path(scene, "scene", at), c.path(out, "out", at)
    free = c.strings(free, "free", at, '"KEY=[LO,HI]" strings', nonempty=True)
    over = c.strings(over, "over", at, '"KEY=V1,V2,..." strings')
    terms = c.strings(terms, "terms", at, "objective terms")
    run = c.optional_string(run, "run", at)
    # Here the types and signs; the ranges are the search's own checks (the CLI's messages).
    budget, seed = c.integer(budget, "budget", at, 0), c.seed(seed, "seed", at)
    population = c.optional_integer(population, "population", at, 0)
    sigma0 = c.number(sigma0, "sigma0", at)
    ex = _executor(executor, threads, at)
    evaluate = None
    n_threads = ex.threads if isinstance(ex, LocalExecutor) else 0
    if isinstance(ex, RayExecutor):
        import ray

        task = ray.remote(num_cpus=1)(_tune_candidate)

        def evaluate(x):
            return ray.get(task.remote(scene, free, over, list(x), run, terms))

        # One waiting thread per candidate of a generation: all of them in flight at once.
        n_threads = population or (4 + int(math.floor(3 * math.log(len(free)))))
    command = "pneuflex.tune(" + ", ".join(
        [repr(scene), f"free={free!r}", f"over={over!r}"]
        + ([f"run={run!r}"] if run else [])
        + ([f"terms={terms!r}"] if terms else [])
        + [f"budget={budget}", f"seed={seed}"]
        + ([f"population={population}"] if population else [])
    ) + ")"
    text = _native.tune_run(scene, free, over, out, run, terms, budget, seed, population, sigma0, n_threads,
                            evaluate, command)
    return TuneResult(json.loads(text), str(out))
