"""Errors both units raise, each naming what was wrong, and the checks of unknown scene keys and of inputs that
raise them (the scene's values are checked by fmu_common.scene_schema)."""
import math

import numpy as np


class SceneError(ValueError):
    """A scene value is malformed or out of range.

    Carries the dotted key, the offending value and what is allowed, so that the
    command line can tell the user exactly what to change before anything runs.

    Args:
        key: the dotted scene key.
        value: the offending value.
        allowed: what is allowed, in words.
    """

    def __init__(self, key: str, value, allowed: str):
        self.key, self.value, self.allowed = key, value, allowed
        super().__init__(f"scene key '{key}' = {value!r}: {allowed}")


class InputError(ValueError):
    """A value crossing the unit boundary (e.g. the generalized force Q) is NaN or inf."""


class SolverDiverged(RuntimeError):
    """The state left the physical range (NaN, inf, constraint or Newton failure).

    Args:
        time: the last time reached, s.
        reason: what failed.
        hint: what to change.
    """

    def __init__(self, time: float, reason: str, hint: str):
        self.time, self.reason, self.hint = time, reason, hint
        super().__init__(f"diverged at t = {time:.6g} s: {reason}. Hint: {hint}")


def reject_unknown_keys(table: dict, prefix: str, allowed) -> None:
    """Raise SceneError for the first key of `table` not in `allowed`.

    Args:
        table: the table given.
        prefix: the table's dotted key.
        allowed: the keys it may have.
    """
    allowed = sorted(allowed) if isinstance(allowed, (set, frozenset)) else list(allowed)
    for key, value in table.items():
        if key not in allowed:
            where = f"in [{prefix}]" if prefix else "at the top level"
            raise SceneError(f"{prefix}.{key}" if prefix else key, value,
                             f"unknown key; allowed {where}: {', '.join(allowed)}")


def checked_input(name: str, value, n: int, time: float):
    """`value` as a float array of shape (n,); InputError naming the first NaN/inf entry or a wrong size.

    Args:
        name: the FMI variable name (entries named 1-based).
        value: the input's values.
        n: their expected number.
        time: where the unit stands, s, for the message.
    """
    value = np.asarray(value, dtype=float)
    if value.shape != (n,):
        raise InputError(f"{name} has shape {value.shape}, the topology has {n} coordinates")
    # the sum is finite when every entry is (one reduction, a third of isfinite's two calls); else find them
    if not math.isfinite(value.sum()) and not np.isfinite(value).all():
        bad = ~np.isfinite(value)
        k = int(np.flatnonzero(bad)[0])
        raise InputError(f"{name}[{k + 1}] = {value[k]} at t = {time:.6g} s: {int(bad.sum())} NaN/inf value(s) "
                         f"in the input {name}")
    return value
