"""The Python API (``import wingsim``, docs/api.md) used as a notebook uses it: a shipped scene loaded by name,
overridden, run in-process and through the FMUs, its summary read as attributes and its samples as a structured
array with units, and a sweep; the rigid pendulum's numbers against its exact period and energy conservation, the
units against timeseries.csv's header read with the csv module."""
import csv
import subprocess
import sys

import numpy as np
import pytest
from scipy.special import ellipk

import wingsim
from repository import ROOT, SCENES

G, LENGTH = 9.81, 1.0
PERIOD = 4 * np.sqrt(2 * LENGTH / (3 * G)) * ellipk(np.sin(np.pi / 4) ** 2)
"""The bar of pendulum_rigid released from 90 deg: T = 4 sqrt(I / (m g d)) K(sin(45 deg)), I = m L^2 / 3, d = L / 2
(1.933 s)."""


def crossings(time, x, downward: bool):
    """Times where x crosses zero going negative (downward) or positive, linearly interpolated."""
    i = np.flatnonzero((x[:-1] > 0) & (x[1:] <= 0) if downward else (x[:-1] < 0) & (x[1:] >= 0))
    return time[i] + x[i] / (x[i] - x[i + 1]) * (time[i + 1] - time[i])


@pytest.fixture(scope="module")
def swing(tmp_path_factory):
    """pendulum_rigid through 1.6 s (0.83 periods), in-process, its outputs kept in a folder: (Result, folder)."""
    folder = tmp_path_factory.mktemp("swing")
    scene = wingsim.load_scene("pendulum_rigid")
    scene.set("time.stop", 1.6)
    return wingsim.run(scene, out=folder), folder


def test_a_shipped_scene_runs_by_name_and_swings_with_its_exact_period(swing):
    result, _ = swing
    assert result.status == "ok" and result.simulated_time_s == pytest.approx(1.6)
    samples = result.timeseries
    # the tip crosses below the pin at T/4 and again, swinging back, at 3T/4
    down = crossings(samples["time"], samples["tip_x"], downward=True)
    up = crossings(samples["time"], samples["tip_x"], downward=False)
    assert len(down) == 1 and down[0] == pytest.approx(PERIOD / 4, rel=1e-3)
    assert len(up) == 1 and up[0] == pytest.approx(3 * PERIOD / 4, rel=1e-3)
    # a conservative system: the summary's energy drift and the recorded energy both say so
    assert abs(result.energy_drift) < 1e-6
    energy = samples["energy"]
    assert np.ptp(energy) < 1e-6 * np.max(samples["kinetic_energy"])
    assert result.deployment_time_s is None and result.probes["tip"]["initial"] == pytest.approx([1.0, 0, 0])


def test_the_units_are_those_of_the_csv_header(swing):
    result, folder = swing
    with (folder / "timeseries.csv").open() as handle:
        header = next(csv.reader(handle))
    from_csv = dict(cell[:-1].split(" [") for cell in header)
    assert result.units == from_csv and result.columns == list(from_csv)
    assert result.units["time"] == "s" and result.units["tip_z"] == "m" and result.units["tip_vz"] == "m/s"
    assert result.units["energy"] == "J" and result.units["constraint_residual"] == "-"
    again = wingsim.load_result(folder)
    np.testing.assert_array_equal(again.timeseries, result.timeseries)


def test_the_fmu_backend_builds_and_agrees_with_the_exact_quarter_period(swing):
    direct, _ = swing
    result = wingsim.run("pendulum_rigid", overrides={"time.stop": 0.6}, backend="fmu")
    assert result.status == "ok" and result.folder is None        # no out: read back from a temporary folder
    down = crossings(result.timeseries["time"], result.timeseries["tip_x"], downward=True)
    assert down[0] == pytest.approx(PERIOD / 4, rel=1e-3)
    n = len(result.timeseries)
    for name in ("tip_x", "tip_z", "energy"):   # the same slave code in an FMU: the same numbers
        np.testing.assert_allclose(result.timeseries[name], direct.timeseries[name][:n], rtol=0, atol=1e-12)


def test_overrides_are_checked_when_set_and_name_their_key():
    scene = wingsim.load_scene(SCENES / "deploy_rigid.toml", {"flow.speed": 10})
    assert scene.get("flow.speed") == 10.0 and scene.overrides == ["flow.speed=10"]
    with pytest.raises(wingsim.SceneError, match="flow.speed"):
        scene.set("flow.speed", -5.0)
    assert scene.get("flow.speed") == 10.0                            # unchanged by the refusal
    assert scene.set("aero.model", "strip").get("aero.model") == "strip"
    assert scene.get("structure.bodies.outer.length") == scene.resolved["structure"]["bodies"][1]["length"]
    with pytest.raises(wingsim.SceneError, match="no_such_scene"):
        wingsim.load_scene("no_such_scene")
    with pytest.raises(wingsim.SceneError, match="backend"):
        wingsim.run(scene, backend="gpu")
    with pytest.raises(wingsim.SceneError, match="animate"):         # it would be written nowhere
        wingsim.run(scene, animate=True)
    assert "deploy_rigid" in wingsim.shipped_scenes()


def test_to_pandas_or_a_message_saying_how(swing, monkeypatch):
    result, _ = swing
    try:
        import pandas  # noqa: F401
    except ImportError:
        pass
    else:
        frame = result.to_pandas()
        np.testing.assert_array_equal(frame["tip_z"].to_numpy(), result.timeseries["tip_z"])
        assert frame.attrs["units"]["tip_z"] == "m"
    monkeypatch.setitem(sys.modules, "pandas", None)                  # as where pandas is not installed
    with pytest.raises(ImportError, match="pip install pandas"):
        result.to_pandas()


def test_a_sweep_returns_each_runs_figures_and_result():
    """A probe at span s of the pendulum released horizontal has moved by 2 s along x once it has swung through
    (half a period, 0.97 s): its largest displacement."""
    sweep = wingsim.sweep("pendulum_rigid", grid={"probes.tip.span": [0.5, 1.0]}, overrides={"time.stop": 1.0},
                          jobs=2)
    assert [row["status"] for row in sweep.rows] == ["ok", "ok"]
    np.testing.assert_allclose(sweep.column("probes.tip.span"), [0.5, 1.0])
    np.testing.assert_allclose(sweep.column("probes.tip.max_abs_displacement"), [1.0, 2.0], rtol=1e-4)
    assert [r.scene["probes"][0]["span"] for r in sweep.results] == [0.5, 1.0]
    assert sweep.folder is None


def test_import_wingsim_from_an_empty_folder(tmp_path):
    """The installed package imports without the repository on the path and finds its shipped scenes."""
    code = "import wingsim; print(wingsim.__file__); print(len(wingsim.shipped_scenes()))"
    proc = subprocess.run([sys.executable, "-I", "-c", code], cwd=tmp_path, capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr
    path, count = proc.stdout.split()
    assert path.startswith(str(ROOT)) and int(count) == len(list(SCENES.glob("*.toml")))


def test_outputs_kept_in_a_folder_are_complete_and_a_sweep_there_resumes(tmp_path, capsys):
    from orchestrator.output.run_record import complete_record

    result = wingsim.run("pendulum_rigid", {"time.stop": 0.05}, out=tmp_path / "run", vtk=True)
    assert result.folder == tmp_path / "run" and complete_record(result.folder) is not None
    assert "vtk/structure.pvd" in complete_record(result.folder)["files"]
    grid = {"probes.tip.span": [1.0]}
    first = wingsim.sweep("pendulum_rigid", grid, overrides={"time.stop": 0.05}, out=tmp_path / "sweep", jobs=1)
    again = wingsim.sweep("pendulum_rigid", grid, overrides={"time.stop": 0.05}, out=tmp_path / "sweep", jobs=1)
    assert "1/1 runs already done" in capsys.readouterr().err             # the second found the first's run
    assert again.rows == first.rows and (tmp_path / "sweep" / "sweep.png").is_file()


def test_a_failed_fmu_build_returns_a_result_that_says_why(monkeypatch):
    import orchestrator.build.fmus

    def no_compiler(*args, **kwargs):
        raise OSError("no C compiler")

    monkeypatch.setattr(orchestrator.build.fmus, "build_fmus", no_compiler)
    result = wingsim.run("pendulum_rigid", {"time.stop": 0.05}, backend="fmu")
    assert result.status == "error" and "building the FMUs" in result.message and "no C compiler" in result.message
    assert len(result.timeseries) == 0 and result.columns[0] == "time"
