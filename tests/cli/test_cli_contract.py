"""The command line contract (README: command line, outputs): summary.json and timeseries.csv contents, the run loop's
statuses, plots, and the CLI's exit codes and error messages."""

import csv
import io
import json
import os
from types import SimpleNamespace

import numpy as np
import pytest

from orchestrator.run.master import RunResult, communication_times, run_scene
from orchestrator.scene.overrides import apply_overrides
from orchestrator.output.plots import fold_angles_figure, write_plots
from orchestrator.run.progress import Progress
from orchestrator.output.results import deployment_time, energy_drift, read_timeseries, summarize, write_results
from orchestrator.scene.load import read_scene_file, resolve_scene
from orchestrator.run.timeseries import TimeSeries
from subprocesses import wingsim
from repository import ROOT, SCENES
from stand_in_units import DictMonitors

EXAMPLE = SCENES / "deploy_rigid.toml"
CONTRACT_SUMMARY_FIELDS = {"status", "message", "wall_time_s", "simulated_time_s", "scene", "deployment_time_s",
                         "max_constraint_residual", "energy_drift", "probes"}
# ours: the communication steps' wall time, the size of the structural equations
SUMMARY_FIELDS = CONTRACT_SUMMARY_FIELDS | {"stepping_wall_time_s", "structure_counts"}


@pytest.fixture
def scene():
    """The example scene, structure only (the fake units below are one structure unit)."""
    return resolve_scene(apply_overrides(read_scene_file(EXAMPLE), ["aero.model=none"]), "deploy_rigid")


# A synthetic deployment: the fold angle crosses its stop (0 deg) between t = 0.03 s (+10 deg) and
# t = 0.04 s (-5 deg); the structure unit reports the latch at 0.0331 s (inside its own internal step,
# where the samples, interpolated, would say 0.03 + 0.01 * 10 / (10 + 5) = 0.036667 s).
LATCH = 0.0331
TIME = np.array([0.0, 0.01, 0.02, 0.03, 0.04, 0.05])
FOLD = np.array([170.0, 150.0, 90.0, 10.0, -5.0, 0.5])
TIP = np.array([[0.0, 0.0, 0.30], [0.01, 0.0, 0.28], [0.05, -0.01, 0.20],
                [0.10, 0.02, 0.25], [0.12, 0.01, 0.29], [0.11, 0.0, 0.30]])
TIP_V = np.array([[1.0, 0.0, -2.0], [1.5, -0.5, -4.0], [5.0, 0.5, 1.0],
                  [2.0, 3.0, 4.5], [0.5, -1.5, 3.0], [-1.0, -0.5, 0.5]])          # m/s
TIP_A = np.array([[50.0, 0.0, -200.0], [100.0, -50.0, 80.0], [300.0, 250.0, 500.0],
                  [-200.0, 10.0, 50.0], [-150.0, -200.0, -100.0], [-100.0, 50.0, -250.0]])   # m/s^2
ENERGY = np.array([2.0, 1.9, 1.8, 1.7, 1.6, 1.5])
KINETIC = np.array([0.0, 0.4, 1.2, 0.9, 0.3, 0.1])  # peak 1.2 J < |E_0| = 2 J: the drift is relative to E_0
RESIDUAL = np.array([0.0, 1e-12, 3e-10, 2e-11, 1e-12, 5e-12])


def synthetic(scene, status="ok", samples=None):
    samples = len(TIME) if samples is None else samples
    series = TimeSeries.from_arrays(["tip"], ["fold"], TIME[:samples], TIP[:samples, None, :],
                                    FOLD[:samples, None], ENERGY[:samples], RESIDUAL[:samples],
                                    kinetic_energy=KINETIC[:samples], external_work=np.zeros(samples),
                                    velocities=TIP_V[:samples, None, :], accelerations=TIP_A[:samples, None, :])
    reached = float(TIME[samples - 1]) if samples else 0.0
    latch_times = {"fold": LATCH} if reached > LATCH else {}
    return RunResult(status, "a message", 1.25, reached, scene, series, latch_times=latch_times)


# --- summary.json and timeseries.csv --------------------------------------------------------------

def test_summary_has_exactly_the_design_fields(scene, tmp_path):
    write_results(synthetic(scene), tmp_path)
    summary = json.loads((tmp_path / "summary.json").read_text())
    assert set(summary) == SUMMARY_FIELDS
    assert summary["status"] == "ok" and summary["message"] == "a message"
    assert summary["wall_time_s"] == 1.25 and summary["simulated_time_s"] == 0.05
    assert summary["scene"] == scene


def test_deployment_time_is_the_structure_units_latch_time(scene):
    assert summarize(synthetic(scene))["deployment_time_s"] == LATCH


def test_monitor_summaries(scene):
    summary = summarize(synthetic(scene))
    assert summary["max_constraint_residual"] == 3e-10
    assert summary["energy_drift"] == pytest.approx((1.5 - 2.0) / 2.0)


def test_energy_drift_from_zero_initial_energy_is_relative_to_peak_kinetic_energy(scene):
    # A pendulum released at rest at its potential datum: E_0 = 0, the energy it exchanges is the peak
    # kinetic energy, 0.8 J here. By hand: (E_final - E_0) / max(|E_0|, 0.8 J) = (-0.002 - 0) / 0.8
    # = -2.5e-3 (relative to the 1e-12 J floor it would be -2e9).
    time = np.array([0.0, 0.1, 0.2, 0.3, 0.4])
    energy = np.array([0.0, 0.001, -0.001, 0.0005, -0.002])
    kinetic = np.array([0.0, 0.3, 0.8, 0.5, 0.1])
    series = TimeSeries.from_arrays(["tip"], ["fold"], time, np.zeros((5, 1, 3)), np.full((5, 1), 90.0),
                                    energy, np.zeros(5), kinetic_energy=kinetic, external_work=np.zeros(5))
    result = RunResult("ok", "", 1.0, 0.4, scene, series)
    assert summarize(result)["energy_drift"] == pytest.approx(-2.5e-3, rel=1e-12)
    assert energy_drift(energy, kinetic, None) == pytest.approx(-2.5e-3, rel=1e-12)


def test_energy_drift_scale_and_floor():
    # |E_0| = 3 J exceeds the peak kinetic energy 1 J: (2.7 - 3) / 3 = -0.1
    assert energy_drift(np.array([3.0, 2.9, 2.7]), np.array([0.0, 1.0, 0.5]), None) == pytest.approx(-0.1)
    # NaN/inf samples are skipped, also the kinetic energy of a sample without a finite energy:
    # (0.01 - 0) / max(0, 0.5) = 0.02 (the 40 J at the NaN energy sample does not count)
    assert energy_drift(np.array([0.0, 0.005, np.nan, 0.01]),
                        np.array([np.nan, 0.5, 40.0, 0.2]), None) == pytest.approx(0.02)
    # at rest throughout (E_0 = 0, no kinetic energy): the 1e-12 J floor, no division by zero
    assert energy_drift(np.array([0.0, 3e-15]), np.zeros(2), None) == pytest.approx(3e-3)
    assert energy_drift(np.array([0.0, 3e-15]), None, None) == pytest.approx(3e-3)   # no kinetic energy recorded
    assert energy_drift(np.array([np.nan]), np.array([1.0]), None) is None


def test_probe_displacements_relative_to_initial(scene):
    tip = summarize(synthetic(scene))["probes"]["tip"]
    assert tip["initial"] == [0.0, 0.0, 0.30]
    assert tip["final"] == [0.11, 0.0, 0.30]
    assert tip["min_displacement"] == pytest.approx([0.0, -0.01, -0.10])
    assert tip["max_displacement"] == pytest.approx([0.12, 0.02, 0.0])


def test_timeseries_csv_columns_and_rows(scene, tmp_path):
    write_results(synthetic(scene), tmp_path)
    with (tmp_path / "timeseries.csv").open() as f:
        rows = list(csv.reader(f))
    # each header cell is the column's name and its unit, as the units' interface tables declare it
    assert rows[0] == ["time [s]", "tip_x [m]", "tip_y [m]", "tip_z [m]", "tip_vx [m/s]", "tip_vy [m/s]",
                       "tip_vz [m/s]", "tip_ax [m/s2]", "tip_ay [m/s2]", "tip_az [m/s2]", "fold_angle_fold [deg]",
                       "energy [J]", "kinetic_energy [J]", "constraint_residual [-]", "external_work [J]"]
    data = np.array(rows[1:], dtype=float)
    assert data.shape == (len(TIME), 15)
    column = {name.partition(" [")[0]: data[:, k] for k, name in enumerate(rows[0])}
    np.testing.assert_allclose(column["time"], TIME)
    np.testing.assert_allclose(data[:, 1:4], TIP)
    np.testing.assert_allclose(np.column_stack([column[f"tip_v{axis}"] for axis in "xyz"]), TIP_V)
    np.testing.assert_allclose(np.column_stack([column[f"tip_a{axis}"] for axis in "xyz"]), TIP_A)
    np.testing.assert_allclose(column["fold_angle_fold"], FOLD)
    np.testing.assert_allclose(column["energy"], ENERGY)
    np.testing.assert_allclose(column["kinetic_energy"], KINETIC)
    np.testing.assert_allclose(column["constraint_residual"], RESIDUAL)


def test_failed_run_still_writes_strict_json(scene, tmp_path):
    result = synthetic(scene, status="diverged", samples=4)
    result.series.append(0.04, np.full((1, 3), np.nan), {"fold": np.nan}, np.nan, np.inf, kinetic_energy=np.inf)
    write_results(result, tmp_path)
    summary = json.loads((tmp_path / "summary.json").read_text())  # strict: no NaN/Infinity tokens
    assert "NaN" not in (tmp_path / "summary.json").read_text()
    assert summary["status"] == "diverged"
    assert summary["deployment_time_s"] is None               # reached +10 deg, never latched
    assert summary["probes"]["tip"]["final"] == [None, None, None]
    assert summary["energy_drift"] == pytest.approx((1.7 - 2.0) / 2.0)
    assert len((tmp_path / "timeseries.csv").read_text().splitlines()) == 1 + 5


def test_aero_scene_adds_CL_and_lift_columns_summary_and_plot(scene, tmp_path):
    scene["aero"]["model"] = "uvlm-flat"
    cl, lift = np.array([0.0, 0.5, 0.45, 0.4, 0.41, 0.42]), np.array([0.0, 5.0, 4.5, 4.0, 4.1, 4.2])
    moment = np.array([0.0, 0.02, -0.01, 0.03, 0.025, 0.015])
    series = TimeSeries.from_arrays(["tip"], ["fold"], TIME, TIP[:, None, :], FOLD[:, None], ENERGY, RESIDUAL,
                                    kinetic_energy=KINETIC, aero={"CL": cl, "lift": lift, "hinge_moment_fold": moment})
    result = RunResult("ok", "", 1.0, 0.05, scene, series)
    write_results(result, tmp_path)
    with (tmp_path / "timeseries.csv").open() as f:
        rows = list(csv.reader(f))
    assert rows[0][0] == "time [s]" and rows[0][-3:] == ["hinge_moment_fold [N.m]", "CL [-]", "lift [N]"]
    np.testing.assert_allclose(np.array(rows[1:], dtype=float)[:, -2], cl)
    np.testing.assert_allclose(np.array(rows[1:], dtype=float)[:, -3], moment)
    summary = json.loads((tmp_path / "summary.json").read_text())
    assert set(summary) == SUMMARY_FIELDS | {"aero"}
    # over the samples after t = 0: the start (no circulation shed yet) does not count
    assert summary["aero"] == {"model": "uvlm-flat", "CL_final": 0.42, "CL_min": 0.4, "CL_max": 0.5,
                               "lift_final": 4.2,
                               "hinge_moments": {"fold": {"final": 0.015, "min": -0.01, "max": 0.03}}}
    written = {p.name for p in write_plots(result, tmp_path)}
    assert "lift_coefficient.png" in written and (tmp_path / "lift_coefficient.png").stat().st_size > 1000
    # a structure-only run in the same folder removes the stale aero plot
    write_plots(synthetic(scene), tmp_path)
    assert not (tmp_path / "lift_coefficient.png").exists()


def test_run_without_samples_writes_nulls(scene, tmp_path):
    write_results(synthetic(scene, status="error", samples=0), tmp_path)
    summary = json.loads((tmp_path / "summary.json").read_text())
    assert set(summary) == SUMMARY_FIELDS
    assert summary["deployment_time_s"] is None and summary["energy_drift"] is None
    assert summary["probes"] == {"tip": {"initial": None, "final": None,
                                         "min_displacement": None, "max_displacement": None}}
    assert (tmp_path / "timeseries.csv").read_text().splitlines() == [
        "time [s],tip_x [m],tip_y [m],tip_z [m],tip_vx [m/s],tip_vy [m/s],tip_vz [m/s],tip_ax [m/s2],tip_ay [m/s2],"
        "tip_az [m/s2],fold_angle_fold [deg],energy [J],kinetic_energy [J],constraint_residual [-],external_work [J]"]


def test_deployment_time_waits_for_every_latched_hinge(scene):
    scene["structure"]["joints"].append({"type": "revolute", "name": "tip_fold", "stop_angle_deg": 5.0})
    scene["structure"]["joints"].append({"type": "revolute", "name": "free"})   # no stop: ignored
    assert deployment_time({"fold": 0.1, "tip_fold": 0.15}, scene) == 0.15
    assert deployment_time({"fold": 0.1}, scene) is None                  # tip_fold has not latched yet
    assert deployment_time({}, {"structure": {"joints": [{"type": "revolute", "name": "free"}]}}) is None


# --- the run loop, with a stand-in unit -----------------------------------------------------------

class FakeUnitError(RuntimeError):
    def __init__(self, message, diverged=False):
        super().__init__(message)
        self.diverged = diverged


class FakeUnit(DictMonitors):
    """Moves every coordinate (e_k = t + k) and every probe of the example scene (along x, y and z at 1 m/s each,
    from (0, 1, 2) m, without acceleration); fails at ``fail_at`` (s) with ``reason``, reporting a divergence if
    ``diverged``."""

    n = 18

    def __init__(self, fail_at=None, reason="", diverged=False):
        self.t, self.fail_at, self.reason, self.steps, self.terminated = 0.0, fail_at, reason, [], False
        self.diverged = diverged

    def get_outputs(self):
        return self.t + np.arange(self.n, dtype=float), np.ones(self.n)

    def set_inputs(self, q):
        assert q.shape == (self.n,) and not q.any()

    def do_step(self, t, h):
        assert t == pytest.approx(self.t)
        if self.fail_at is not None and t + h > self.fail_at + 1e-12:
            raise FakeUnitError(self.reason, diverged=self.diverged)
        self.steps.append(h)
        self.t = t + h

    def monitors(self):
        return {"energy": 1.0 + self.t, "kinetic_energy": 0.5 * self.t, "constraint_residual": 1e-12,
                "fold_angles_deg": {"fold": 170 - 1000 * self.t},
                "probe_positions": {p: self.t + np.arange(3.0) for p in ("bending_100mm", "tip")},
                "probe_velocities": {p: np.ones(3) for p in ("bending_100mm", "tip")},
                "probe_accelerations": {p: np.zeros(3) for p in ("bending_100mm", "tip")},
                "strains": {"strain_20mm": 0.0}}

    def terminate(self):
        self.terminated = True


class FakeTopology:
    n_coordinates = 18


def fake_run(scene, unit, stop=0.0105, progress=None):
    scene["time"]["stop"] = stop
    units = SimpleNamespace(make_unit=lambda **kw: unit, UnitError=FakeUnitError)
    return run_scene(scene, backend="direct", units=units, topology=FakeTopology(), progress=progress)


def test_communication_times_land_on_stop():
    np.testing.assert_allclose(communication_times(0.0105, 1e-3), [*np.arange(11) * 1e-3, 0.0105])
    assert len(communication_times(0.3, 1e-3)) == 301
    assert communication_times(0.3, 1e-3)[-1] == 0.3


def test_run_ok_records_every_communication_point(scene):
    unit = FakeUnit()
    result = fake_run(scene, unit)
    assert result.status == "ok" and unit.terminated
    assert result.simulated_time_s == 0.0105
    assert unit.steps[-1] == pytest.approx(5e-4) and len(unit.steps) == 11
    np.testing.assert_allclose(result.series.time, communication_times(0.0105, 1e-3))
    np.testing.assert_allclose(result.series.positions[:, 0, 0], result.series.time)
    assert np.all(result.series.velocities == 1.0) and np.all(result.series.accelerations == 0.0)
    np.testing.assert_allclose(result.series.fold_angles_deg[:, 0], 170 - 1000 * result.series.time)
    np.testing.assert_allclose(result.series.energy, 1.0 + result.series.time)
    np.testing.assert_allclose(result.series.kinetic_energy, 0.5 * result.series.time)
    assert np.all(result.series.constraint_residual == 1e-12)


@pytest.mark.parametrize("row", ["probe_positions", "probe_velocities", "probe_accelerations"])
def test_a_unit_without_a_probe_output_stops_the_run_naming_the_probe(scene, row):
    class Blind(FakeUnit):
        def monitors(self):
            out = super().monitors()
            del out[row]["tip"]
            return out
    result = fake_run(scene, Blind())
    assert result.status == "error" and len(result.series) == 0
    assert f"no {row} output for the probe 'tip'" in result.message


def test_diverged_unit_keeps_its_message_and_the_samples(scene, tmp_path):
    reason = "structure: diverged at t = 0.005 s: constraint residual 3.2. Hint: reduce structure.step"
    result = fake_run(scene, FakeUnit(fail_at=0.005, reason=reason, diverged=True))
    assert result.status == "diverged" and result.message == reason
    assert result.simulated_time_s == pytest.approx(0.005) and len(result.series) == 6
    write_results(result, tmp_path)
    assert json.loads((tmp_path / "summary.json").read_text())["status"] == "diverged"


def test_a_reported_divergence_is_diverged_whatever_its_message_says(scene):
    reason = "structure: constraint residual 3.2 over its limit at t = 0.005 s"
    result = fake_run(scene, FakeUnit(fail_at=0.005, reason=reason, diverged=True))
    assert result.status == "diverged" and result.message == reason


class PlainFailure(FakeUnit):
    """Fails with a RuntimeError, not the units' error type."""

    def do_step(self, t, h):
        if t + h > self.fail_at + 1e-12:
            raise RuntimeError(self.reason)
        super().do_step(t, h)


@pytest.mark.parametrize("unit_class", [FakeUnit, PlainFailure])
def test_a_failure_whose_message_says_diverged_is_an_error(scene, unit_class):
    reason = "aero: the wake file diverged from its checksum"
    result = fake_run(scene, unit_class(fail_at=0.005, reason=reason))
    assert result.status == "error" and reason in result.message and "t = 0.005" in result.message


def test_other_unit_failure_is_an_error(scene):
    result = fake_run(scene, FakeUnit(fail_at=0.002, reason="fmi2DoStep returned fmi2Error: Q[3] is NaN"))
    assert result.status == "error"
    assert "Q[3] is NaN" in result.message and "t = 0.002" in result.message
    assert len(result.series) == 3


def test_progress_is_silent_off_a_terminal_except_the_final_line(scene):
    stream = io.StringIO()
    fake_run(scene, FakeUnit(), progress=Progress(0.0105, label="deploy_rigid", stream=stream))
    lines = stream.getvalue().splitlines()
    assert len(lines) == 1 and "0.0105 / 0.0105 s" in lines[0] and lines[0].endswith(": ok")


def test_plots_are_written(scene, tmp_path):
    written = write_plots(synthetic(scene), tmp_path)
    assert {p.name for p in written} == {"fold_angles.png", "probe_displacements.png", "probe_velocities.png",
                                         "probe_accelerations.png", "energy_residual.png"}
    assert all(p.stat().st_size > 1000 for p in written)


def test_a_series_without_probe_rates_has_nan_columns_and_no_rate_plots(scene, tmp_path):
    # a series built from positions alone (TimeSeries.from_arrays without velocities): its rate columns are NaN,
    # and a plot of them would be empty, so none is written and a stale one of an earlier run goes
    write_plots(synthetic(scene), tmp_path)
    series = TimeSeries.from_arrays(["tip"], ["fold"], TIME, TIP[:, None, :], FOLD[:, None], ENERGY, RESIDUAL)
    assert np.isnan(series.velocities).all() and np.isnan(series.column("tip_az")).all()
    written = {p.name for p in write_plots(RunResult("ok", "", 1.0, 0.05, scene, series), tmp_path)}
    assert written == {"fold_angles.png", "probe_displacements.png", "energy_residual.png"}
    assert not (tmp_path / "probe_velocities.png").exists() and not (tmp_path / "probe_accelerations.png").exists()


def test_fold_angle_plot_marks_the_latch(scene):
    markers = [line for line in fold_angles_figure(synthetic(scene)).axes[0].lines if line.get_marker() == "o"]
    assert [(list(m.get_xdata()), list(m.get_ydata()), m.get_label()) for m in markers] == [
        ([LATCH], [0.0], "fold latched, 0.0331 s")]


# --- the command line -----------------------------------------------------------------------------

def test_bad_scene_exits_2_with_a_clear_message(tmp_path):
    bad = tmp_path / "bad.toml"
    bad.write_text(EXAMPLE.read_text().replace('fidelity = "rigid"', 'fidelity = "wobbly"'))
    proc = wingsim("run", bad, cwd=tmp_path)
    assert proc.returncode == 2
    assert proc.stderr.startswith("error: ") and "Traceback" not in proc.stderr
    assert "structure.fidelity" in proc.stderr and "'wobbly'" in proc.stderr and "'rigid'" in proc.stderr
    assert not (tmp_path / "results").exists()


def test_bad_override_and_missing_file_exit_2(tmp_path):
    proc = wingsim("run", EXAMPLE, "--set", "coupling.step=-1", cwd=tmp_path)
    assert proc.returncode == 2 and "coupling.step" in proc.stderr and "Traceback" not in proc.stderr
    proc = wingsim("run", tmp_path / "nope.toml", cwd=tmp_path)
    assert proc.returncode == 2 and "no such file" in proc.stderr and "Traceback" not in proc.stderr


def test_ci_runs_the_readme_test_command():
    readme = (ROOT / "README.md").read_text()
    blocks = [b.split("```", 1)[0].strip() for b in readme.split("```sh\n")[1:]]
    run_command, test_command = blocks[0], blocks[1]
    assert run_command.endswith(".venv/bin/wingsim run scenes/deploy_rigid.toml")
    assert test_command.endswith(".venv/bin/python -m pytest -q")
    ci = (ROOT / ".ci" / "run").read_text().splitlines()
    assert test_command in ci
    assert os.access(ROOT / ".ci" / "run", os.X_OK)


# --- end to end, with the real structure unit (structure_fmu, orchestrator.run.units) -----------------

@pytest.mark.parametrize("backend", ["direct", "fmu"])
def test_run_example_scene(tmp_path, backend):
    proc = wingsim("run", EXAMPLE, "--backend", backend, "--out", tmp_path / "out", cwd=tmp_path)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    summary = json.loads((tmp_path / "out" / "summary.json").read_text())
    assert summary["status"] == "ok" and summary["simulated_time_s"] == pytest.approx(0.3)
    # the example couples the uvlm-flat aero unit, has a strain gauge and a revolute joint between its bodies:
    # their summaries are added, the joint's monitors within round-off of zero (it shares the point and the axis)
    assert set(summary) == SUMMARY_FIELDS | {"aero", "strain_gauges", "joint_monitors"}
    assert set(summary["joint_monitors"]) == {"fold_point_mismatch", "fold_axis_error"}
    assert max(summary["joint_monitors"].values()) < 1e-12
    header = list(read_timeseries(tmp_path / "out" / "timeseries.csv")[0].dtype.names)
    assert header[0] == "time" and "fold_angle_fold" in header and "tip_z" in header
    assert {f"tip_{kind}{axis}" for kind in "va" for axis in "xyz"} <= set(header)   # every probe's rates
    assert "strain_20mm" in header and "CL" in header
    assert header[header.index("energy") + 1] == "kinetic_energy" and "constraint_residual" in header
    assert {p.name for p in (tmp_path / "out").glob("*.png")} == {
        "fold_angles.png", "probe_displacements.png", "probe_velocities.png", "probe_accelerations.png",
        "strain_gauges.png", "energy_residual.png", "lift_coefficient.png", "wake_3d.png", "mechanism.png",
        "planform.png"}
    assert "results in" in proc.stdout
    assert f"deployment time: {summary['deployment_time_s']:.6g} s" in proc.stdout


def test_diverging_run_exits_1_and_keeps_its_results(tmp_path):
    # rk4 at 1 ms with a 1e7 N m/rad actuator is far beyond the explicit stability limit
    proc = wingsim("run", EXAMPLE, "--backend", "direct", "--out", tmp_path / "out", "--set", "time.stop=0.05",
                   "--set", "structure.step=1e-3", "--set", "structure.joints.fold.stiffness=1e7", cwd=tmp_path)
    assert proc.returncode == 1 and "Traceback" not in proc.stderr
    summary = json.loads((tmp_path / "out" / "summary.json").read_text())
    assert summary["status"] == "diverged" and "diverged" in summary["message"]
    assert summary["simulated_time_s"] < 0.05
    assert (tmp_path / "out" / "timeseries.csv").read_text().startswith("time [s],")
    assert f"not deployed: fold had not latched at t = {summary['simulated_time_s']:g} s" in proc.stdout
