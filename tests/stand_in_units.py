"""For the tests' stand-in units, whose ``monitors()`` returns the dictionary a real unit's does: the vector and
layout the master records from (``Unit.monitor_values()``, ``Unit.monitor_layout``), laid out from that
dictionary as a real unit lays out its rows."""
import numpy as np

from orchestrator.run.recording import MonitorRow


def flat_monitors(monitors: dict) -> tuple[tuple[MonitorRow, ...], np.ndarray]:
    """(layout, vector) of a ``monitors()`` dictionary: a float is a row of one value; {item: float} a row of one
    value per item; {item: array (k,)} a row of k values per item."""
    layout, values = [], []
    for key, value in monitors.items():
        if isinstance(value, dict):
            parts = [np.atleast_1d(np.asarray(v, dtype=float)) for v in value.values()]
            width = parts[0].size if parts else 1
            layout.append(MonitorRow(key, tuple(value), width, slice(len(values), len(values) + width * len(parts))))
            values += [x for part in parts for x in part]
        else:
            layout.append(MonitorRow(key, None, 1, slice(len(values), len(values) + 1)))
            values.append(float(value))
    return tuple(layout), np.array(values, dtype=float)


class DictMonitors:
    """A mixin giving a stand-in unit with ``monitors()`` the master's ``monitor_layout`` and ``monitor_values()``."""

    @property
    def monitor_layout(self) -> tuple[MonitorRow, ...]:
        return flat_monitors(self.monitors())[0]

    def monitor_values(self) -> np.ndarray:
        return flat_monitors(self.monitors())[1]
