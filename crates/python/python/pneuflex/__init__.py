"""pneuflex: force and position control of pneumatic compliant actuators (Python bindings).

The classes and functions come from the Rust crates through the native module ``pneuflex._native``:

- ``Actuator(path, alpha_deg=None)``: an actuator sheet (cylinder, valve, supply, gas, mechanics);
  ``params()``, ``piston_force(p_a, p_b)``, ``transfer_function(x_m=None, f_ext_n=0)`` (eqs. (16)-(17)).
- ``OneDof(actuator, x0_m, p_a=None, p_b=None, f_ext_n=0)``: the 1-DOF model of eq. (1); ``step(u, f_ext_n, dt_s)``.
- ``ForceElement(actuator, p_a=None, p_b=None, substeps=1, ...)``: the pneumatics crate's pneumatic force
  element (chambers + valve); ``step(x, x_dot, u, dt_s) -> force`` on the flange, for an external
  rigid-body engine (MuJoCo in crossval/).
- ``Controller(kind, impedance, inner, adaptive=None)`` / ``Controller.from_scene(path, run)``;
  ``update(t, x, x_dot, f_e, p_a, p_b, f_ref, x_d, dt) -> u``, ``telemetry()``.
- ``ForceControlBatch(scene_path, num_envs=1, randomize=True, autoreset=False, action="valve")``: episodes of the
  force-control task stepped in Rust, in parallel (``step(actions) -> (obs, rewards, terminated, truncated)``;
  ``action`` "valve", "pressure" (the chambers' set-points behind pressure regulators) or "impedance");
  the Gymnasium environments of ``pneuflex.envs`` stand on it.
- ``Setpoints(scene_path).at(t) -> (f_ref, x_d)``; ``load_scene(path) -> dict``; ``initial_state(path)``.
- ``run(scene_path) -> Results``: ``{run: {column: ndarray}}`` with ``.summary``, ``.claims``, ``.trace(run)``
  (a pandas DataFrame indexed by t), ``.metrics`` and ``.claims_frame`` (``pneuflex.frames``); ``run_with_summary``; ``summarize(scene_path, traces)``
  (summary.json of any traces); ``run_to(scene_path, out_dir) -> dir``: the output directory
  ``pneuflex run --out`` writes, through the same pipeline; ``write_figures(scene_path, out_dir, runs)``; ``bench_rapier(urdf_path, ...)``;
  ``bench_scene_ticks(scene_path, run, ticks=10000, settle_s=1.0) -> {wall_s, ...}``: the runner's control tick
  timed in a Rust loop (scripts/bench).
- ``run_plant(scene_path, run, plant) -> (trace, summary or diverged reason, wall_s)``: the scene runner's loop
  driving a plant written in Python (methods ``reset()``, ``apply(event)``, ``sense() -> (x, x_dot, f_e, p_a,
  p_b)``, ``actuate(u, x_r)``, ``advance(dt)``; MuJoCo in crossval/). ``loop_signals()``: the loop's recorded
  signals [(name, unit, group)]; ``Controller.signals`` / ``Controller.record()``: the controller's own.

- ``sweep(scene, sets, samples=None, seed=0, executor="local")`` -> sweep.csv's table (a ``SweepTable``: the
  text, and ``.frame``, the table as a DataFrame);
  ``tune(scene, free, over, out=...)`` -> tune.json as a dict; executors ``"local"`` / ``LocalExecutor(threads)``
  (the Rust pool) or ``"ray"`` / ``RayExecutor(chunk_size)`` (Ray tasks; the same table). See ``pneuflex.sweeps``.
- ``identify(logs, actuator, free, bounds=[], validation=0.2, segment=0.1, settle=0.015, out=None)``: the fit of
  ``pneuflex identify`` (docs/identification.md) -> dict: ``estimates`` (key -> value, std_error, ci95, ...),
  ``correlation`` (ndarray, in the order of ``keys``), ``rms_fit`` / ``rms_validation`` ({p_a, p_b, x}),
  ``warnings``, ``report`` (report.json as a dict) and ``validation`` (per log: ndarrays of the held-out
  measured and model signals, NaN where not compared); writes the CLI's outputs into ``out`` when given.

- ``mujoco_plugin_path() -> str``: the MuJoCo plugin library ``libpneuflex_mujoco.so`` (``pneuflex.cylinder``, an
  actuator any MJCF can declare; docs/mujoco-plugin.md), for ``mujoco.mj_loadPluginLibrary``: the one inside the
  installed package. ``mjcf(name)``: a shipped MJCF using it (``"cylinder"``), as text for
  ``mujoco.MjModel.from_xml_string``, its sheets' paths inside the package.

- ``scenes() -> list[str]``: the scenes shipped inside the package (the repository's ``scenes/``, with the sheets,
  URDFs and meshes they name). Wherever a scene is taken, a path or a shipped name (``"paper-fig3"``) will do: a
  name without a folder or ``.toml`` that is no file in the working directory is the shipped scene's file.

SI units everywhere, pressures absolute. Errors: ``FileNotFoundError``/``OSError`` for unreadable files,
``PneuflexError`` (a ``ValueError``) for bad content; messages name the file and the key. An argument of the wrong
type (a number where a path goes, a number where a list of strings goes) is a ``TypeError`` naming the function and
the argument, a count or seed out of range a ``ValueError``; nothing is converted with ``str()`` (``run(42)`` is not
a file named "42"), and one string where a list of them goes is that one entry.
"""

import os

from ._native import *  # noqa: F401,F403
from ._native import PneuflexError, __version__  # noqa: F401
from . import _native
from ._data import scenes  # noqa: F401
from .frames import Results, SweepTable  # noqa: F401
from .sweeps import LocalExecutor, RayExecutor, sweep, tune  # noqa: F401,E402


def run(scene_path: str | os.PathLike[str]) -> Results:
    """Runs every controller of the scene file (a path or a shipped scene's name): a :class:`Results`, the
    ``{run: {column: ndarray}}`` dict of the traces (trace.csv's columns), with ``.summary`` (summary.json),
    ``.units`` (``{run: {column: unit}}``), ``.claims``, ``.trace(run)`` (a DataFrame, its units in ``attrs["units"]``),
    ``.metrics`` and ``.claims_frame`` (pneuflex.frames; pandas for the DataFrames)."""
    from ._checks import path

    traces, summary, wall_s, units = _native.run_results(path(scene_path, "scene_path", "pneuflex.run"))
    return Results(traces, summary, wall_s, units)


MUJOCO_PLUGIN_FILE = "libpneuflex_mujoco.so"


def mujoco_plugin_path() -> str:
    """The path of the MuJoCo plugin library (``pneuflex.cylinder``), for ``mujoco.mj_loadPluginLibrary``.

    Looked up, first found: ``$PNEUFLEX_MUJOCO_PLUGIN``; ``libpneuflex_mujoco.so`` inside this package (every wheel
    and ``scripts/build_python`` put it there: ``scripts/stage_python_data``); the cargo target directory of the workspace these bindings were built in
    (``$CARGO_TARGET_DIR`` or ``target/``), release before debug. Raises FileNotFoundError naming the places
    and the build command (``cargo build --release -p pneuflex-mujoco``) when there is none.
    """
    import os
    from pathlib import Path

    from . import _native

    env = os.environ.get("PNEUFLEX_MUJOCO_PLUGIN")
    if env:
        if not Path(env).is_file():
            if Path(env).exists():
                raise IsADirectoryError(f"PNEUFLEX_MUJOCO_PLUGIN={env}: not a file (name the library, {MUJOCO_PLUGIN_FILE})")
            raise FileNotFoundError(f"PNEUFLEX_MUJOCO_PLUGIN={env}: no such file")
        return str(Path(env).resolve())
    workspace = Path(getattr(_native, "_workspace_dir", Path(__file__).resolve().parents[3]))
    target = Path(os.environ.get("CARGO_TARGET_DIR") or workspace / "target")
    if not target.is_absolute():
        target = workspace / target
    places = [Path(__file__).resolve().parent / MUJOCO_PLUGIN_FILE] + [target / p / MUJOCO_PLUGIN_FILE for p in ("release", "debug")]
    for p in places:
        if p.is_file():
            return str(p.resolve())
    raise FileNotFoundError(
        "the MuJoCo plugin is not built: none of " + ", ".join(str(p) for p in places)
        + f" exists; build it with `cargo build --release -p pneuflex-mujoco` in {workspace.resolve()}"
        " (or set PNEUFLEX_MUJOCO_PLUGIN)"
    )


def identify(logs, actuator, free, bounds=(), validation=0.2, segment=0.1, settle=0.015, out=None, log_format=None,
             select=False):
    """Fits the ``free`` keys of the actuator sheet to rig logs (see the module doc and docs/identification.md);
    ``log_format`` names a format file for logs another tool wrote (docs/identification.md, "Other people's logs");
    ``select=True`` is ``identify --select``: every candidate structure fitted, the best kept, and the table in
    ``["selection"]`` (report.json's ``structure_selection``)."""
    import json

    import numpy as np

    from . import _checks as c
    from ._native import identify_json

    at = "pneuflex.identify"
    raw = json.loads(
        identify_json(
            c.paths(logs, "logs", at, nonempty=True), c.path(actuator, "actuator", at),
            c.strings(free, "free", at, "sheet keys", nonempty=True), c.strings(bounds, "bounds", at, '"KEY=[LO,HI]" strings'),
            # The ranges are the fit's own checks (the CLI's messages); here the types.
            c.number(validation, "validation", at), c.number(segment, "segment", at), c.number(settle, "settle", at),
            c.optional_path(out, "out", at), c.optional_path(log_format, "log_format", at), c.flag(select, "select", at),
        )
    )
    rep = raw["report"]
    fit = rep["fit"]
    names = ("p_a", "p_b", "x")
    nan = float("nan")
    return {
        "keys": [e["key"] for e in fit["estimates"]],
        "estimates": {e["key"]: e for e in fit["estimates"]},
        "correlation": np.array([[nan if v is None else v for v in row] for row in fit["correlation"]]),
        "rms_fit": dict(zip(names, fit["rms_fit"])),
        "rms_validation": dict(zip(names, [nan if v is None else v for v in fit["rms_validation"]])),
        "warnings": rep["warnings"],
        "selection": rep.get("structure_selection"),
        "report": rep,
        "validation": [
            {k: (v if k == "log" else np.array([nan if x is None else x for x in v], dtype=float))
             for k, v in d.items()}
            for d in raw["validation"]
        ],
    }


def mjcf(name: str = "cylinder") -> str:
    """The shipped MJCF ``pneuflex/mjcf/<name>.xml`` as text, each relative ``sheet`` of the ``pneuflex.cylinder``
    plugin made absolute inside the package's data (MuJoCo gives a plugin no model folder: a relative sheet
    would be read from the working directory). For ``mujoco.MjModel.from_xml_string`` after
    ``mujoco.mj_loadPluginLibrary(mujoco_plugin_path())``. ``"cylinder"``: the paper's cylinder pushing a
    compliant wall, its stroke held by hard end stops (docs/mujoco-plugin.md); ``"cylinder-pressure"``: the same
    rig under ``command="pressure"``, its two actuators' ctrl the chambers' set-points in Pa absolute."""
    import os
    import xml.etree.ElementTree as ET
    from pathlib import Path

    from . import _checks, _data

    name = _checks.optional_string(name, "name", "pneuflex.mjcf")
    shipped = sorted(p.stem for p in (_data.PACKAGE / "mjcf").glob("*.xml"))
    path = _data.PACKAGE / "mjcf" / f"{name}.xml"
    if name not in shipped:
        raise FileNotFoundError(f"pneuflex.mjcf: no shipped MJCF {name!r}; the shipped ones are {', '.join(shipped)}")
    root = ET.parse(path).getroot()
    for config in root.iter("config"):
        value = config.get("value", "")
        if config.get("key") == "sheet" and not os.path.isabs(value):
            sheet = _data.DATA / value
            if not sheet.is_file():
                raise FileNotFoundError(f"{path}: sheet {value!r}: {sheet} is missing (a build of the package without "
                                        "scripts/stage_python_data)")
            config.set("value", str(sheet))
    return ET.tostring(root, encoding="unicode")
