"""`wingsim sweep`: local processes, resume, a Dask cluster on loopback, bad grids (docs/sweep.md)."""
import csv
import json
from pathlib import Path

import pytest

from orchestrator.run.master import run_scene
from orchestrator.output.results import summarize
from orchestrator.scene.load import load_scene
from orchestrator.sweep import combinations, parse_grid, split_values, summary_figures, time_left
from fmu_common.errors import SceneError
from subprocesses import wingsim
from repository import SCENES

SCENE = SCENES / "deploy_rigid.toml"
SETS = ["aero.model=none", "time.stop=0.08"]   # still air, short: each run deploys in ~0.06 s of simulated time
GRID = ["structure.joints.fold.stiffness=0.02,0.026", "structure.joints.fold.torque=0.3,0.4"]
KEYS = ["structure.joints.fold.stiffness", "structure.joints.fold.torque"]


def sweep_args(out, *extra):
    args = ["sweep", SCENE, "--out", out, "--jobs", "2"]
    for item in SETS:
        args += ["--set", item]
    for item in GRID:
        args += ["--grid", item]
    return [*args, *extra]


def read_rows(out):
    with (Path(out) / "sweep.csv").open(newline="") as handle:
        return list(csv.DictReader(handle))


def number(cell):
    return None if cell == "" else float(cell)


@pytest.fixture(scope="module")
def local_sweep(tmp_path_factory):
    out = tmp_path_factory.mktemp("sweep") / "local"
    done = wingsim(*sweep_args(out), cwd=out.parent)
    assert done.returncode == 0, done.stderr
    return out, done


def test_grid_parsing():
    assert split_values("0, 5,[0,0,-9.8],\"a,b\"") == ["0", "5", "[0,0,-9.8]", '"a,b"']
    grid = parse_grid(["flow.speed=0,10", "structure.joints[1].stiffness=0.02"])
    assert grid == [("flow.speed", ["0", "10"]), ("structure.joints.1.stiffness", ["0.02"])]
    runs = combinations(grid, ["aero.model=none"])
    assert [run.overrides for run in runs] == [
        ["aero.model=none", "flow.speed=0", "structure.joints.1.stiffness=0.02"],
        ["aero.model=none", "flow.speed=10", "structure.joints.1.stiffness=0.02"]]
    assert runs[1].name == "001_flow.speed=10_structure.joints.1.stiffness=0.02"
    for bad in ("flow.speed", "flow.speed=", "flow.speed=1,,2", "=1,2"):
        with pytest.raises(SceneError):
            parse_grid([bad])
    assert summary_figures({"status": "ok", "probes": {"tip": {"min_displacement": [0, -2.0, 1.0],
                                                               "max_displacement": [0.5, 0, 1.5]}}}) == {
        "probes.tip.min_displacement_x": 0, "probes.tip.min_displacement_y": -2.0,
        "probes.tip.min_displacement_z": 1.0, "probes.tip.max_displacement_x": 0.5,
        "probes.tip.max_displacement_y": 0, "probes.tip.max_displacement_z": 1.5,
        "probes.tip.max_abs_displacement": 2.0}


def test_local_sweep_rows_match_independent_runs(local_sweep):
    out, done = local_sweep
    rows = read_rows(out)
    assert len(rows) == 4
    assert list(rows[0])[:3] == ["index", *KEYS]
    assert {"status", "deployment_time_s", "wall_time_s", "message", "run_dir",
            "probes.tip.max_abs_displacement", "strain_gauges.strain_20mm.peak"} <= set(rows[0])
    assert [(row[KEYS[0]], row[KEYS[1]]) for row in rows] == [
        ("0.02", "0.3"), ("0.02", "0.4"), ("0.026", "0.3"), ("0.026", "0.4")]
    assert "4/4 runs done" in done.stderr
    lines = [line for line in done.stderr.splitlines() if "runs done" in line]
    assert len(lines) == 4 and all("left" in line for line in lines[:3]) and "left" not in lines[3]
    deployments = set()
    for row in rows:
        assert row["status"] == "ok", row
        overrides = [*SETS, f"{KEYS[0]}={row[KEYS[0]]}", f"{KEYS[1]}={row[KEYS[1]]}"]
        expected = summarize(run_scene(load_scene(SCENE, overrides), backend="direct"))   # independent run
        run_dir = out / row["run_dir"]
        assert (run_dir / "timeseries.csv").is_file()
        own = json.loads((run_dir / "summary.json").read_text())
        assert own["scene"] == expected["scene"]
        assert expected["deployment_time_s"] is not None
        deployments.add(expected["deployment_time_s"])
        for summary in (own, {k: v for k, v in row.items()}):
            got_deploy = summary["deployment_time_s"]
            assert float(got_deploy) == pytest.approx(expected["deployment_time_s"], rel=1e-12)
        assert number(row["strain_gauges.strain_20mm.peak"]) == pytest.approx(
            expected["strain_gauges"]["strain_20mm"]["peak"], rel=1e-12)
        for axis, value in zip("xyz", expected["probes"]["tip"]["max_displacement"]):
            assert number(row[f"probes.tip.max_displacement_{axis}"]) == pytest.approx(value, rel=1e-12, abs=1e-15)
        assert number(row["wall_time_s"]) == pytest.approx(own["wall_time_s"])
    assert len(deployments) == 4   # every combination is a different run


def test_the_time_left_is_the_remaining_runs_at_the_rate_so_far():
    # 2 runs in 10 s (parallel jobs included): 3 more take 15 s; a resumed sweep counts only what it ran
    assert time_left(10.0, 2, 3) == "; about 15 s left"
    assert time_left(600.0, 4, 2) == "; about 5.0 min left"
    assert time_left(1.0, 0, 3) == "" and time_left(10.0, 2, 0) == ""


def test_sweep_row_equals_wingsim_run(local_sweep, tmp_path):
    out, _ = local_sweep
    row = read_rows(out)[3]
    args = ["run", SCENE, "--backend", "direct", "--out", tmp_path / "run"]
    for item in [*SETS, f"{KEYS[0]}={row[KEYS[0]]}", f"{KEYS[1]}={row[KEYS[1]]}"]:
        args += ["--set", item]
    done = wingsim(*args, cwd=tmp_path)
    assert done.returncode == 0, done.stderr
    ran = json.loads((tmp_path / "run" / "summary.json").read_text())
    swept = json.loads((out / row["run_dir"] / "summary.json").read_text())
    for summary in (ran, swept):
        summary.pop("wall_time_s"), summary.pop("stepping_wall_time_s")
    assert swept == ran


def test_resume_runs_only_missing(tmp_path):
    out = tmp_path / "resume"
    first = wingsim(*sweep_args(out), cwd=tmp_path)
    assert first.returncode == 0, first.stderr
    runs = sorted((out / "runs").iterdir())
    assert len(runs) == 4
    mtimes = {run.name: (run / "summary.json").stat().st_mtime_ns for run in runs}
    # a killed sweep: run 1 was running (its summary still says so), run 2 was never started; sweep.csv
    # has 2 rows
    started = json.loads((runs[1] / "summary.json").read_text())
    (runs[1] / "summary.json").write_text(json.dumps({**started, "status": "running"}))
    for path in runs[2].iterdir():
        path.unlink()
    runs[2].rmdir()
    with (out / "sweep.csv").open() as handle:
        lines = handle.readlines()
    (out / "sweep.csv").write_text("".join(lines[:2] + lines[4:]))
    again = wingsim(*sweep_args(out), cwd=tmp_path)
    assert again.returncode == 0, again.stderr
    assert "2/4 runs already done" in again.stderr
    assert "4 runs, 2 run now (ok 2), 2 already done" in again.stdout
    for run in (runs[0], runs[3]):   # untouched
        assert (run / "summary.json").stat().st_mtime_ns == mtimes[run.name]
    for run in (runs[1], runs[2]):   # recomputed
        assert (run / "summary.json").is_file()
    rows = read_rows(out)
    assert [int(row["index"]) for row in rows] == [0, 1, 2, 3]
    assert all(row["status"] == "ok" for row in rows)
    # other common overrides are other runs: nothing is reused
    changed = wingsim(*sweep_args(out, "--set", "structure.joints.fold.damping=0.002"), cwd=tmp_path)
    assert changed.returncode == 0, changed.stderr
    assert "4 run now" in changed.stdout
    assert all((run / "summary.json").stat().st_mtime_ns > mtimes[run.name] for run in (runs[0], runs[3]))


def test_dask_cluster_on_loopback(local_sweep, tmp_path, monkeypatch):
    import distributed
    out = tmp_path / "dask"
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, host="127.0.0.1",
                                  dashboard_address=None) as cluster:
        done = wingsim(*sweep_args(out, "--scheduler", cluster.scheduler_address), cwd=tmp_path)
    assert done.returncode == 0, done.stderr
    assert "Dask cluster" in done.stderr
    local_rows, dask_rows = read_rows(local_sweep[0]), read_rows(out)
    for local, remote in zip(local_rows, dask_rows, strict=True):
        local.pop("wall_time_s"), remote.pop("wall_time_s")
        assert remote == local


@pytest.mark.parametrize("grid, names", [
    ("flow.speed", "'--grid'"),
    ("flow.speed=", "'flow.speed'"),
    ("flow.speed=0,,5", "'flow.speed'"),
    ("flow.sped=0,5", "'flow.sped'"),
    ("structure.joints.fold.stiffnes=0.02,0.03", "stiffnes'"),   # load_scene names it joints[1]
    ("flow.speed=0,fast", "'flow.speed'"),   # the second combination is bad: still nothing runs
])
def test_bad_grid_exits_2_before_running(tmp_path, grid, names):
    out = tmp_path / "bad"
    done = wingsim("sweep", SCENE, "--set", "aero.model=none", "--grid", grid, "--out", out, cwd=tmp_path)
    assert done.returncode == 2, done.stderr
    assert done.stderr.startswith("error: ") and names in done.stderr, done.stderr
    assert not out.exists()


def test_sweep_without_grid_exits_2(tmp_path):
    done = wingsim("sweep", SCENE, cwd=tmp_path)
    assert done.returncode == 2 and "--grid" in done.stderr


def test_fmu_backend_sweep_with_plots_matches_the_direct_runs(local_sweep, tmp_path):
    """--backend fmu builds each run's FMUs and runs them through fmpy; the figures equal the direct-backend
    sweep's (the same slave code: identical to round-off, docs/fmu.md); --plots writes each run's PNGs."""
    direct_rows = read_rows(local_sweep[0])
    out = tmp_path / "fmu"
    args = ["sweep", SCENE, "--out", out, "--jobs", "2", "--backend", "fmu", "--plots"]
    for item in SETS:
        args += ["--set", item]
    args += ["--grid", GRID[0], "--grid", "structure.joints.fold.torque=0.3"]   # two of the four runs
    done = wingsim(*args, cwd=tmp_path)
    assert done.returncode == 0, done.stderr
    rows = read_rows(out)
    assert [row["status"] for row in rows] == ["ok", "ok"]
    by_keys = {tuple(row[k] for k in KEYS): row for row in direct_rows}
    for row in rows:
        expected = by_keys[tuple(row[k] for k in KEYS)]
        assert number(row["deployment_time_s"]) == pytest.approx(number(expected["deployment_time_s"]), rel=1e-9)
        assert number(row["probes.tip.max_displacement_y"]) == pytest.approx(
            number(expected["probes.tip.max_displacement_y"]), rel=1e-9, abs=1e-15)
        run_dir = out / row["run_dir"]
        assert json.loads((run_dir / "run.json").read_text())["sweep"]["backend"] == "fmu"
        assert {"fold_angles.png", "probe_displacements.png"} <= {p.name for p in run_dir.glob("*.png")}
