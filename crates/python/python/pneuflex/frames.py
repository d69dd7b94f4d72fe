"""pandas views of pneuflex's results.

``pneuflex.run(scene)`` returns a :class:`Results`: still the ``{run: {column: ndarray}}`` dict it always was,
and also ``.summary`` (summary.json as a dict), ``.claims``, ``.trace(run)`` / ``.traces`` (a DataFrame per run,
indexed by ``t``), ``.metrics`` (one row per run and metric window) and ``.claims_frame``. ``pneuflex.sweep``
returns a :class:`SweepTable`: sweep.csv's text as before, and ``.frame`` (the table as a DataFrame). pandas is
imported only when a DataFrame is asked for (``pip install pandas``). ``pneuflex.tune`` returns a :class:`TuneResult`:
tune.json as before, and ``.history``.
"""

import io

_PANDAS = "this needs pandas (pip install pandas)"


def _pandas():
    try:
        import pandas
    except ImportError as e:  # pragma: no cover - the project's venv has pandas
        raise ImportError(_PANDAS) from e
    return pandas


class Results(dict):
    """The runs of a scene: ``{run: {column: ndarray}}``, with the summary, the claims and DataFrames."""

    def __init__(self, traces, summary, wall_s, units=None):
        super().__init__(traces)
        #: Each run's column units, ``{run: {column: unit}}`` (trace.csv's; "1" for a dimensionless one).
        self.units = units or {}
        #: summary.json as a dict (the metrics of every window, the claims, the Lyapunov checks).
        self.summary = summary
        #: The runner's wall time, s.
        self.wall_s = wall_s

    @property
    def claims(self):
        """The scene's claims checked on these runs (summary.json ``claims``): a list of dicts."""
        return self.summary.get("claims", [])

    def trace(self, run):
        """Run ``run``'s trace as a DataFrame indexed by ``t`` (s), one column per signal, SI units; the units in
        ``frame.attrs["units"]`` ({column: unit}, ``t`` included)."""
        pd = _pandas()
        if run not in self:
            raise KeyError(f"no run named {run!r}, expected one of {list(self)}")
        columns = dict(self[run])
        t = columns.pop("t")
        frame = pd.DataFrame(columns, index=pd.Index(t, name="t"))
        frame.attrs["units"] = dict(self.units.get(run, {}))
        return frame

    @property
    def traces(self):
        """Every run's trace as a DataFrame: ``{run: DataFrame}``."""
        return {name: self.trace(name) for name in self}

    @property
    def metrics(self):
        """One row per run and metric window, indexed by (run, window): the window's metrics as summary.json
        gives them, an event window's response flattened into its columns (``settling_time_s``, ...). A scene
        with several actuators has a row per run, window and actuator, indexed by (run, window, actuator), with
        the window's ``force_imbalance_n`` on each."""
        pd = _pandas()
        rows = []
        if "actuators" in self.summary:
            for r in self.summary["runs"]:
                for w in r.get("windows", []):
                    for actuator, m in w["actuators"]:
                        row = {"run": r["name"], "controller": r["controller"], "window": w["window"]}
                        row["actuator"] = actuator
                        row.update(m)
                        row["force_imbalance_n"] = w["force_imbalance_n"]
                        rows.append(row)
            return pd.DataFrame(rows).set_index(["run", "window", "actuator"]) if rows else pd.DataFrame()
        for r in self.summary["runs"]:
            for w in r.get("windows", []):
                row = {"run": r["name"], "controller": r["controller"]}
                row.update({k: v for k, v in w.items() if k not in ("name", "event")})
                row["window"] = w["name"]
                for k, v in (w.get("event") or {}).items():
                    if not isinstance(v, (list, dict)):
                        row[k] = v
                rows.append(row)
        return pd.DataFrame(rows).set_index(["run", "window"]) if rows else pd.DataFrame()

    @property
    def claims_frame(self):
        """The claims as a DataFrame, one row per claim (the adaptation verdict's ``earned_by`` as a column
        where the scene has frozen runs)."""
        pd = _pandas()
        rows = []
        for c in self.claims:
            row = {k: v for k, v in c.items() if k != "adaptation"}
            a = c.get("adaptation")
            if a:
                row["earned_by"] = a["earned_by"]
            rows.append(row)
        return pd.DataFrame(rows)


class TuneResult(dict):
    """tune.json as a dict, with every evaluated candidate (history.csv) as a DataFrame in ``.history``."""

    def __init__(self, record, out):
        super().__init__(record)
        #: The output directory the tune wrote.
        self.out = out

    @property
    def history(self):
        """One row per evaluation: its generation, the free keys' values, the objective J, its rank and J at
        each environment of ``over``."""
        import os

        return _pandas().read_csv(os.path.join(self.out, "history.csv"))


class SweepTable(str):
    """sweep.csv's text, with the table as a DataFrame in ``.frame``."""

    @property
    def frame(self):
        """The table: one row per point and run, the swept keys and every metric as columns."""
        return _pandas().read_csv(io.StringIO(str(self)))
