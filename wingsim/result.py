"""The result of a run for scripts and notebooks, read from the files the run wrote (``summary.json``,
``timeseries.csv``; README, Outputs): the summary's fields as attributes (``result.deployment_time_s``,
``result.energy_drift``, ``result.probes["tip"]["final"]``), the samples as a numpy structured array with each
column's unit (``result.timeseries["tip_z"]``, ``result.units["tip_z"] == "m"``), or a pandas DataFrame.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np

from orchestrator.output.results import SUMMARY_FILE, TIMESERIES_FILE, read_timeseries


class Result:
    """One run: its summary (summary.json) and its samples (timeseries.csv).

    Every field of the summary is an attribute: ``status``, ``message``, ``deployment_time_s`` (s, None when a
    hinge has not latched), ``energy_drift``, ``max_constraint_residual``, ``probes``, ``scene`` (the resolved
    scene), and ``aero``, ``strain_gauges``, ``joint_monitors``, ``coupling`` where the scene has them.

    Attributes:
        summary: summary.json as a dict.
        timeseries: the samples, a numpy structured array of shape (samples,), one float field per column of
            timeseries.csv (``time`` in s first).
        units: {column: unit} of the timeseries' columns, as timeseries.csv's header gives them ("-": none).
        folder: the folder the run wrote, or None when it was written to a temporary folder since removed.

    Args:
        summary: summary.json as a dict.
        timeseries: the samples (see Attributes).
        units: {column: unit}.
        folder: the run's folder, or None.
    """

    def __init__(self, summary: dict, timeseries: np.ndarray, units: dict[str, str], folder: Path | None = None):
        self.summary = summary
        self.timeseries = timeseries
        self.units = units
        self.folder = folder

    @classmethod
    def load(cls, folder: str | Path, keep_folder: bool = True) -> "Result":
        """Read a run's output folder (``wingsim run --out FOLDER``, or a run folder of a sweep).

        Args:
            folder: the folder holding summary.json and timeseries.csv.
            keep_folder: False: ``folder`` is None in the Result (the folder is about to be removed).

        Returns:
            The Result; FileNotFoundError naming the file when one is missing.
        """
        folder = Path(folder)
        summary = json.loads((folder / SUMMARY_FILE).read_text())
        timeseries, units = read_timeseries(folder / TIMESERIES_FILE)
        return cls(summary, timeseries, units, folder if keep_folder else None)

    def __getattr__(self, name: str) -> Any:
        summary = self.__dict__.get("summary", {})
        if name in summary:
            return summary[name]
        raise AttributeError(f"{type(self).__name__} has no attribute {name!r}; the summary's fields are "
                             f"{', '.join(summary)}")

    def __dir__(self) -> list[str]:
        return sorted({*super().__dir__(), *self.__dict__.get("summary", {})})

    @property
    def columns(self) -> list[str]:
        """The timeseries' column names, in timeseries.csv order."""
        return list(self.timeseries.dtype.names)

    def to_pandas(self):
        """The samples as a pandas DataFrame indexed by ``time`` (s), the units in ``frame.attrs["units"]``.

        Returns:
            The DataFrame. ImportError saying how to install pandas when it is missing (wingsim does not need it).
        """
        try:
            import pandas
        except ImportError:
            raise ImportError("Result.to_pandas needs pandas, which wingsim does not install: pip install pandas; "
                              "result.timeseries holds the same samples as a numpy structured array") from None
        frame = pandas.DataFrame({name: self.timeseries[name] for name in self.columns}).set_index("time")
        frame.attrs["units"] = dict(self.units)
        return frame

    def __repr__(self) -> str:
        deployed = self.summary.get("deployment_time_s")
        extra = f", deployment_time_s={deployed:.6g}" if deployed is not None else ""
        return (f"<Result {self.summary.get('scene', {}).get('name', '?')}: {self.summary.get('status')}, "
                f"{len(self.timeseries)} samples to t = {self.summary.get('simulated_time_s')} s{extra}>")


def load_result(folder: str | Path) -> Result:
    """Read the outputs a run wrote (``wingsim run --out FOLDER``) as a Result.

    Args:
        folder: the run's output folder.
    """
    return Result.load(folder)
