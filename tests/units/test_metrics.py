"""orchestrator.studies.metrics against hand-computed cases and analytic series."""
import math

import numpy as np
import pytest

from orchestrator.studies import metrics
from orchestrator.run.timeseries import TimeSeries

T = np.round(np.arange(0, 101) * 0.01, 12)          # s, 0 ... 1 in 0.01 s steps
REF = np.sin(2 * np.pi * T)                          # max |CL_ref| = 1 at t = 0.25


def test_cl_error_of_a_constant_offset_is_the_offset_over_the_peak():
    assert metrics.cl_error_pct(T, REF + 0.01, T, REF) == pytest.approx(1.0, rel=1e-12)


def test_cl_error_of_a_scaled_sine_over_whole_periods():
    """CL = 1.1 CL_ref: RMS(0.1 sin) over 100 equally spaced samples of one period (t > 0) is 0.1 / sqrt(2)."""
    assert metrics.cl_error_pct(T, 1.1 * REF, T, REF) == pytest.approx(10 / math.sqrt(2), rel=1e-12)


def test_cl_error_reads_the_reference_at_the_runs_times_and_keeps_to_its_window():
    """A run on every second sample of the reference's grid (its times are a subset: interpolation is exact),
    off by 0.01 until 0.5 s and by 1 after: the window 0 < t <= 0.5 s sees the 1% only; samples up to
    `after` are left out."""
    t = T[::2]
    cl = np.sin(2 * np.pi * t) + np.where(t <= 0.5, 0.01, 1.0)
    assert metrics.cl_error_pct(t, cl, T, REF, until=0.5) == pytest.approx(1.0, rel=1e-12)
    assert metrics.cl_error_pct(t, cl, T, REF) > 50
    assert metrics.cl_error_pct(t, cl, T, REF, after=0.5) == pytest.approx(100.0, rel=1e-12)


def test_cl_error_without_lift_in_the_reference_is_none():
    assert metrics.cl_error_pct(T, REF, T, np.zeros_like(T)) is None


def test_relative_error():
    assert metrics.relative_error_pct(0.166, 0.160) == pytest.approx(3.75)
    assert metrics.relative_error_pct(0.154, 0.160) == pytest.approx(3.75)
    assert metrics.relative_error_pct(None, 0.16) is None and metrics.relative_error_pct(0.1, 0.0) is None


def series_with_probe_y(y):
    positions = np.zeros((len(y), 1, 3))
    positions[:, 0, 1] = y
    n = len(y)
    return TimeSeries.from_arrays(["p"], [], np.arange(n) * 0.1, positions, np.zeros((n, 0)), np.zeros(n), np.zeros(n))


def test_displacement_range_and_peak_from_the_first_sample_ignoring_nan():
    series = series_with_probe_y([0.1, 0.13, 0.05, np.nan])
    low, high = metrics.displacement_range(series, "p", "y")
    assert low == pytest.approx(-0.05) and high == pytest.approx(0.03)
    assert metrics.peak_displacement(series, "p", "y") == pytest.approx(0.05)


def test_displacement_during_deployment_stops_at_the_latch():
    """Otsuka et al. 2019, Fig. 15 takes the maximum bending during the deployment, Sec. VII.B's -28 mm comes after
    the latch. Samples every 0.1 s from 0.5 m; latched at 0.3 s: up to it the displacement is 0, -0.01, -0.02,
    -0.015 m (range -0.02 ... 0, peak 0.02 m); the -0.03 m at 0.5 s is after it. A latch time one round-off past
    0.3 still takes the 0.3 s sample; a window before the first sample has none (NaN)."""
    series = series_with_probe_y([0.5, 0.49, 0.48, 0.485, 0.505, 0.47, 0.51])
    assert metrics.displacement_range(series, "p", "y", until=0.3) == pytest.approx((-0.02, 0.0))
    assert metrics.peak_displacement(series, "p", "y", until=0.3) == pytest.approx(0.02)
    assert metrics.peak_displacement(series, "p", "y", until=0.1 + 0.2) == pytest.approx(0.02)   # 0.30000000000000004
    assert metrics.peak_displacement(series, "p", "y", until=0.25) == pytest.approx(0.02)
    assert metrics.peak_displacement(series, "p", "y", until=0.15) == pytest.approx(0.01)
    assert metrics.peak_displacement(series, "p", "y") == pytest.approx(0.03)               # the whole run
    assert math.isnan(metrics.peak_displacement(series, "p", "y", until=-0.1))


def test_deployment_torque_scale_is_the_constant_torque_over_the_largest_aero_moment_up_to_the_latch():
    # a moment that peaks at -0.02 N m before the latch at 0.3 s and at 0.05 N m after it (the latch bounce)
    t = np.linspace(0.0, 0.5, 51)
    moment = np.where(t <= 0.3, -0.02 * np.sin(np.pi * t / 0.3), 0.05 * np.sin(np.pi * (t - 0.3) / 0.2))
    assert metrics.deployment_torque_scale(t, moment, 0.043, until=0.3) == pytest.approx(0.043 / 0.02, rel=1e-12)
    assert metrics.deployment_torque_scale(t, moment, 0.043) == pytest.approx(0.043 / 0.05, rel=1e-12)
    assert math.isnan(metrics.deployment_torque_scale(t, 0.0 * t, 0.043, until=0.3))   # still air: no T_aero
    assert math.isnan(metrics.deployment_torque_scale(t, moment, 0.043, until=-1.0))   # no sample


def test_tip_deflection_is_the_distance_from_the_span_axis():
    t = np.array([0.0, 0.1, 0.2, 0.3])
    x, y = 3 * t, 4 * t                                   # distance 5 t
    assert metrics.tip_deflection(t, x, y, 0.2) == pytest.approx(1.0)
    assert metrics.tip_deflection(t, x, y, 0.25) == pytest.approx(1.25)   # between samples: interpolated
    assert math.isnan(metrics.tip_deflection(t, x, y, 0.4))
    assert metrics.largest_after(t, 5 * t, 0.15) == pytest.approx(1.5)
    assert math.isnan(metrics.largest_after(t, 5 * t, None)) and math.isnan(metrics.largest_after(t, 5 * t, 1.0))


def test_converged_from_is_the_coarsest_level_after_which_every_error_is_below_the_limit():
    levels = (1, 2, 3, 4, 5)
    assert metrics.converged_from(levels, (5, 2, 0.9, 0.5, 0.1)) == 3
    assert metrics.converged_from(levels, (5, 0.5, 2, 0.5, 0.1)) == 4       # 2 is not below: not from 2
    assert metrics.converged_from(levels, (0.1, 0.1, 0.1, 0.1, 1.0)) is None
    assert metrics.converged_from(levels, (0.1, math.nan, 0.1, 0.1, 0.1)) == 3


def test_pareto_front_keeps_the_points_no_other_beats_cheapest_first():
    points = [(1, 10, "a"), (2, 5, "b"), (3, 7, "c"), (4, 1, "d"), (2, 6, "e"), (1, 8, "f")]
    assert metrics.pareto_front(points) == ["f", "b", "d"]
