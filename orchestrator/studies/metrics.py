"""Figures of merit of runs, shared by the tests and the studies in benchmarks/.

Each takes plain arrays or a ``TimeSeries`` and returns SI units unless the name says otherwise
(``_pct``: percent). A figure that does not apply (no sample, a failed run) is None or NaN, as documented.

- ``cl_error_pct``          the lift-coefficient error of Otsuka et al. 2019, Eqs. 28-30
- ``relative_error_pct``    |value - ref| / |ref|, e.g. the deployment-time error
- ``displacement_range``    smallest and largest displacement of a probe along one axis (peak bending),
                            over the run or up to a time (e.g. the latch: during the deployment)
- ``peak_displacement``     the largest |displacement| of a probe along one axis, likewise
- ``tip_deflection``        distance of a point from the undeformed span line (the global z axis)
- ``converged_from``        the coarsest level of a refinement from which every error is below a limit
- ``pareto_front``          the runs no other run beats in both cost and error
"""

from __future__ import annotations

import math
from collections.abc import Hashable, Iterable, Sequence

import numpy as np

TIME_TOLERANCE = 1e-9
"""s: a sample at most this far past a window's end still belongs to it (communication times are sums of
steps, so t = 0.2 can be 0.2000000000000001)."""


def cl_error_pct(t, cl, t_ref, cl_ref, after: float = 0.0, until: float = math.inf) -> float | None:
    """RMS(CL - CL_ref) / max|CL_ref| x 100 (%), Otsuka et al. 2019, Eqs. 28-30.

    The RMS runs over the run's samples with ``after < t <= until`` (s); CL_ref is read at those times by
    linear interpolation (exact where the run's times are a subset of the reference's); max|CL_ref| is
    over the reference's samples with ``0 < t <= until`` (at t = 0 no circulation has been shed).
    None when the reference has no nonzero CL in that window.
    """
    t, cl, t_ref, cl_ref = (np.asarray(a, dtype=float) for a in (t, cl, t_ref, cl_ref))
    window = until + TIME_TOLERANCE
    keep_ref = t_ref <= window
    scale_samples = cl_ref[keep_ref & (t_ref > 0)]
    if not scale_samples.size or not np.abs(scale_samples).max() > 0:
        return None
    keep = (t > after) & (t <= window)
    ref = np.interp(t[keep], t_ref[keep_ref], cl_ref[keep_ref])
    return 100.0 * float(np.sqrt(np.mean((cl[keep] - ref) ** 2))) / float(np.abs(scale_samples).max())


def relative_error_pct(value: float | None, ref: float | None) -> float | None:
    """|value - ref| / |ref| x 100 (%); None if either is None or ref is 0."""
    return None if value is None or ref is None or ref == 0 else 100.0 * abs(value - ref) / abs(ref)


def displacement_range(series, probe: str, axis: str, until: float = math.inf) -> tuple[float, float]:
    """(smallest, largest) displacement (m) of ``probe`` along global ``axis`` ("x", "y" or "z") from its
    first sample, NaN samples ignored (as ``summary.json``'s min/max_displacement), over the samples with
    t <= ``until`` (s; default the whole run). ``until`` = the latch time gives the range during the
    deployment (Otsuka et al. 2019, Fig. 15). (NaN, NaN) if no sample is in the window."""
    values = series.column(f"{probe}_{axis}")
    displacement = (values - values[:1])[np.asarray(series.time, dtype=float) <= until + TIME_TOLERANCE]
    if not np.any(~np.isnan(displacement)):
        return math.nan, math.nan
    return float(np.nanmin(displacement)), float(np.nanmax(displacement))


def peak_displacement(series, probe: str, axis: str, until: float = math.inf) -> float:
    """Largest |displacement| (m) of ``probe`` along global ``axis`` from its first sample, over the samples
    with t <= ``until`` (s; default the whole run); e.g. the peak bending of probe bending_100mm, axis "y"
    (out of the deployed plane). Otsuka et al. 2019, Fig. 15 plots it during the deployment: ``until`` = the
    latch time. NaN if no sample is in the window."""
    return max(abs(v) for v in displacement_range(series, probe, axis, until))


def deployment_torque_scale(t, hinge_moment, torque: float, until: float = math.inf) -> float:
    """The deployment torque scale F = T_const / T_aero of Otsuka et al. 2019, Sec. VII.A (Fig. 11b, after
    Fujita and Nagai): T_const the actuator's constant torque (N m), T_aero the maximum |aerodynamic moment about
    the hinge axis| (N m; the aero unit's ``hinge_moment_<hinge>``) over the samples with t <= ``until`` (s; the
    latch time: during the deployment). NaN if no sample is in the window or T_aero is 0 (no aerodynamic
    torque: F is unbounded)."""
    t, moment = np.asarray(t, dtype=float), np.asarray(hinge_moment, dtype=float)
    window = np.abs(moment[t <= until + TIME_TOLERANCE])
    if not window.size or not np.nanmax(window, initial=0.0) > 0.0:
        return math.nan
    return float(torque / np.nanmax(window))


def tip_deflection(t, x, y, at: float) -> float:
    """Distance (m) of a point with global coordinates x(t), y(t) from the global z axis (the undeformed
    span line), at time ``at`` (s, linear interpolation; NaN if the samples end before it)."""
    t = np.asarray(t, dtype=float)
    if not len(t) or t[-1] < at:
        return math.nan
    return float(np.interp(at, t, np.hypot(x, y)))


def largest_after(t, values, start: float | None) -> float:
    """Largest of ``values`` at the samples with t >= ``start`` (s); NaN if ``start`` is None or no sample."""
    if start is None:
        return math.nan
    later = np.asarray(values, dtype=float)[np.asarray(t, dtype=float) >= start]
    return float(later.max()) if later.size else math.nan


def converged_from(levels: Sequence, errors: Sequence[float], limit: float = 1.0):
    """The coarsest of ``levels`` (ordered coarse to fine) from which on every error is below ``limit``
    (same unit as the errors); None if the finest level's error is not."""
    found = None
    for level, error in zip(reversed(levels), reversed(errors)):
        if not error < limit:
            break
        found = level
    return found


def pareto_front(points: Iterable[tuple[float, float, Hashable]]) -> list:
    """Keys of the (cost, error, key) points that no other point beats: none is as cheap and as accurate
    with one of the two strictly better. Cheapest first."""
    front, best = [], math.inf
    for _, error, key in sorted(points, key=lambda p: (p[0], p[1])):
        if error < best:
            front.append(key)
            best = error
    return front
