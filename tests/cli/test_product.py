"""The package as a product: shipped scenes found by name from any folder, listed, copied to edit; --version;
the optional cluster extra; the wheel carries the scenes and C sources, and, installed into a fresh virtual
environment, runs a shipped scene from an empty folder."""
import importlib.metadata
import importlib.util
import json
import os
import shutil
import subprocess
import sys
import tomllib
import venv
import zipfile
from pathlib import Path

import pytest

import orchestrator.output.plots

from orchestrator.cli import main
from orchestrator.scene.load import load_scene
from repository import SCENES
from subprocesses import CODE_ROOT

STILL = ["--set", "aero.model=none", "--set", "time.stop=0.02", "--backend", "direct"]
# every C source of the packages: the kernels compiled at first use and into the FMUs, the FMUs' native binaries
C_SOURCES = sorted(str(p.relative_to(CODE_ROOT)) for package in ("aero_fmu", "structure_fmu", "orchestrator")
                   for p in (CODE_ROOT / package).rglob("*.c"))


def first_comment(path: Path) -> str:
    return path.read_text().splitlines()[0].lstrip("#").strip()


def test_scenes_lists_every_shipped_scene_with_its_headline(capsys):
    assert main(["scenes"]) == 0
    lines = capsys.readouterr().out.splitlines()
    shipped = sorted(SCENES.glob("*.toml"))
    assert [line.split()[0] for line in lines] == [p.stem for p in shipped]
    for line, path in zip(lines, shipped):
        assert line.split(maxsplit=1)[1] == first_comment(path)


def test_a_shipped_scene_runs_by_name_from_an_empty_folder(tmp_path, capsys, monkeypatch):
    # the folder is the point
    monkeypatch.setattr(orchestrator.output.plots, "write_plots", lambda result, out, workers=1: [])
    monkeypatch.chdir(tmp_path)
    assert main(["run", "deploy_rigid", *STILL]) == 0
    out = tmp_path / "results" / "deploy_rigid" / "aero.model=none,time.stop=0.02"
    summary = json.loads((out / "summary.json").read_text())
    assert summary["status"] == "ok" and summary["scene"] == load_scene(SCENES / "deploy_rigid.toml",
                                                                         ["aero.model=none", "time.stop=0.02"])


def test_a_file_in_the_folder_wins_over_a_shipped_scene_and_a_missing_name_lists_them(tmp_path, capsys,
                                                                                       monkeypatch):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "deploy_rigid").write_text("not toml [")
    assert main(["run", "deploy_rigid", *STILL]) == 2
    assert "not valid TOML" in capsys.readouterr().err
    assert main(["run", "no_such_scene", *STILL]) == 2
    err = capsys.readouterr().err
    assert "no such file, and no shipped scene of that name" in err and "deploy_flexible" in err
    assert not (tmp_path / "results").exists()


def test_init_copies_a_scene_under_its_new_name_and_never_overwrites(tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    assert main(["init", "my_wing", "--from", "deploy_flexible"]) == 0
    copy = tmp_path / "my_wing.toml"
    original = (SCENES / "deploy_flexible.toml").read_text()
    assert tomllib.loads(copy.read_text())["name"] == "my_wing"
    assert copy.read_text() == original.replace('name = "deploy_flexible"', 'name = "my_wing"')
    assert load_scene(copy) == {**load_scene(SCENES / "deploy_flexible.toml"), "name": "my_wing"}
    copy.write_text(copy.read_text() + "# my edit\n")
    assert main(["init", "my_wing"]) == 2
    assert "my_wing.toml exists: nothing is overwritten" in capsys.readouterr().err
    assert copy.read_text().endswith("# my edit\n")
    assert main(["init", "../elsewhere"]) == 2 and not (tmp_path.parent / "elsewhere.toml").exists()
    assert main(["init", "rigid_copy"]) == 0   # default: deploy_rigid
    assert tomllib.loads((tmp_path / "rigid_copy.toml").read_text())["structure"] == \
        tomllib.loads((SCENES / "deploy_rigid.toml").read_text())["structure"]


def test_version_is_the_installed_distributions(capsys):
    with pytest.raises(SystemExit) as exit_:
        main(["--version"])
    assert exit_.value.code == 0
    assert capsys.readouterr().out.strip() == f"wingsim {importlib.metadata.version('wingsim')}"


def test_a_sweep_on_a_cluster_without_dask_names_the_extra(tmp_path, capsys, monkeypatch):
    real = importlib.util.find_spec
    monkeypatch.setattr(importlib.util, "find_spec", lambda name, *a: None if name.startswith("dask") else
                        real(name, *a))
    monkeypatch.chdir(tmp_path)
    code = main(["sweep", "deploy_rigid", "--grid", "flow.speed=0,10", "--scheduler", "tcp://127.0.0.1:1"])
    assert code == 2
    assert "pip install 'wingsim[cluster]'" in capsys.readouterr().err
    assert not (tmp_path / "results").exists()


def test_dask_and_numba_are_not_required_dependencies():
    requires = importlib.metadata.requires("wingsim")
    required = [r for r in requires if "extra ==" not in r]
    assert not [r for r in required if r.lower().startswith(("dask", "numba"))]
    assert any(r.startswith("dask") and 'extra == "cluster"' in r for r in requires)


def build_wheel(into: Path) -> Path:
    """The wheel of the repository's tracked files (copied first, so that the build leaves the tree as it is)."""
    source = into / "source"
    files = subprocess.run(["git", "ls-files", "-z"], cwd=CODE_ROOT, capture_output=True, check=True).stdout
    for name in filter(None, files.decode().split("\0")):
        if (CODE_ROOT / name).is_file():
            (source / name).parent.mkdir(parents=True, exist_ok=True)
            shutil.copy2(CODE_ROOT / name, source / name)
    subprocess.run([sys.executable, "-m", "pip", "wheel", "--no-deps", "-q", "-w",
                    str(into / "dist"), str(source)], check=True, capture_output=True)
    return next((into / "dist").glob("wingsim-*.whl"))


def test_the_wheel_carries_the_scenes_the_c_sources_and_the_licence(tmp_path):
    with zipfile.ZipFile(build_wheel(tmp_path)) as wheel:
        names = set(wheel.namelist())
        metadata = next(wheel.read(n).decode() for n in names if n.endswith(".dist-info/METADATA"))
    assert {f"orchestrator/scenes/{p.name}" for p in SCENES.glob("*.toml")} <= names
    assert set(C_SOURCES) <= names
    assert "License: MIT" in metadata or "License-Expression: MIT" in metadata
    assert "Requires-Dist: dask[distributed]; extra == \"cluster\"" in metadata


@pytest.mark.slow
def test_the_wheel_in_a_fresh_environment_runs_a_shipped_scene_from_an_empty_folder(tmp_path):
    wheel = build_wheel(tmp_path)
    env_dir = tmp_path / "env"
    venv.create(env_dir, with_pip=True)
    python = env_dir / "bin" / "python"
    subprocess.run([python, "-m", "pip", "install", "-q", str(wheel)], check=True, capture_output=True)
    empty = tmp_path / "empty"
    empty.mkdir()
    clean_env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "VIRTUAL_ENV")}
    proc = subprocess.run([env_dir / "bin" / "wingsim", "run", "deploy_rigid", "--set", "time.stop=0.05"],
                          cwd=empty, env=clean_env, capture_output=True, text=True, timeout=900)
    assert proc.returncode == 0, proc.stderr
    summary = json.loads((empty / "results" / "deploy_rigid" / "time.stop=0.05" / "summary.json").read_text())
    assert summary["status"] == "ok" and summary["simulated_time_s"] == 0.05
    assert summary["scene"] == load_scene(SCENES / "deploy_rigid.toml", ["time.stop=0.05"])
    assert sorted(p.name for p in empty.iterdir()) == ["fmus", "results"]
