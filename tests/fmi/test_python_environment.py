"""The Python an ordinary FMU runs in, and what a standalone build needs before it writes anything.

An ordinary FMU carries `resources/requirements.txt` (the distributions its sources import, pinned to the build
environment's versions: pythonfmu's own `deploy` command reads it); in a host without Python it starts the
build environment's interpreter, or the one $WINGSIM_PYTHON names; a Python that lacks packages gets one
message naming them all and the interpreter. It carries binaries for linux64 only. `wingsim build --standalone`
is refused, before anything is written, where its C compiler or shared libpython is missing.
"""
import importlib.metadata
import shutil
import subprocess
import sys
import zipfile
from pathlib import Path

import pytest

from fmi_hosts import assert_clean, check
from orchestrator.build import native_binary
from orchestrator.cli import main
from repository import SCENES

SCENE = SCENES / "deploy_rigid.toml"


@pytest.fixture(scope="module")
def fmus(built_fmus):
    return built_fmus("deploy_rigid")


@pytest.fixture
def moved(fmus, tmp_path):
    """The structure FMU with a build environment that is gone (its python and libpython paths)."""
    fmu = tmp_path / "structure.fmu"
    shutil.copyfile(fmus / "structure.fmu", fmu)
    native_binary.install_shim(fmu, python=str(tmp_path / "gone" / "bin" / "python"))
    return fmu


def test_requirements_name_what_the_sources_import_at_this_environment_s_versions(fmus):
    for unit in ("structure", "aero"):
        with zipfile.ZipFile(fmus / f"{unit}.fmu") as z:
            lines = z.read("resources/requirements.txt").decode().split()
        expected = {f"{name}=={importlib.metadata.version(name)}" for name in ("numpy", "scipy", "threadpoolctl")}
        assert set(lines) == expected, unit


def test_pythonfmu_deploy_accepts_the_fmu(fmus, tmp_path):
    """`pythonfmu deploy` installs the requirements into the running environment (here all present)."""
    proc = subprocess.run([sys.executable, "-m", "pythonfmu", "deploy", "-f", str(fmus / "structure.fmu")],
                          cwd=tmp_path, capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stdout + proc.stderr


def test_an_ordinary_fmu_carries_linux64_binaries_only(fmus):
    for unit in ("structure", "aero"):
        with zipfile.ZipFile(fmus / f"{unit}.fmu") as z:
            platforms = {n.split("/")[1] for n in z.namelist() if n.startswith("binaries/") and n.count("/") > 1}
        assert platforms == {"linux64"}, unit


def test_wingsim_python_starts_another_environment(fmu_checker, moved):
    refused = check(fmu_checker, moved, None, 0.001, 0.002)
    assert "WINGSIM_PYTHON" in refused.stdout + refused.stderr
    ran = check(fmu_checker, moved, None, 0.001, 0.01, env={"WINGSIM_PYTHON": sys.executable})
    assert_clean(ran)


def test_a_python_without_the_packages_gets_one_message_naming_them_all(fmu_checker, moved, tmp_path):
    bare = tmp_path / "bare"
    subprocess.run([sys.executable, "-m", "venv", "--without-pip", str(bare)], check=True, timeout=300)
    proc = check(fmu_checker, moved, None, 0.001, 0.002, env={"WINGSIM_PYTHON": str(bare / "bin" / "python")})
    text = proc.stdout + proc.stderr
    assert proc.returncode == 1, text
    assert f"needs numpy, scipy, threadpoolctl, which the Python it runs in cannot import ({bare}/bin/python" in text
    assert text.count("cannot import") == 1, text


def test_standalone_build_without_a_compiler_is_refused_before_anything_is_written(tmp_path, monkeypatch, capsys):
    monkeypatch.setenv("CC", str(tmp_path / "no-such-cc"))
    monkeypatch.chdir(tmp_path)
    assert main(["build", str(SCENE), "--standalone"]) == 2
    assert f"standalone FMUs cannot be built here: no C compiler: {tmp_path / 'no-such-cc'}" in capsys.readouterr().err
    assert list(tmp_path.iterdir()) == []


def test_standalone_build_without_a_shared_libpython_is_refused_before_anything_is_written(tmp_path, monkeypatch,
                                                                                           capsys):
    def static_python():
        raise native_binary.ShimUnavailable(f"this Python ({sys.executable}) has no shared libpython")
    monkeypatch.setattr(native_binary, "shared_libpython", static_python)
    monkeypatch.chdir(tmp_path)
    for command in (["build", str(SCENE), "--standalone"], ["export", str(SCENE), "--standalone"],
                    ["run", str(SCENE), "--standalone"]):
        assert main(command) == 2
        assert "standalone FMUs cannot be built here: this Python" in capsys.readouterr().err
    assert list(tmp_path.iterdir()) == []


def test_standalone_build_says_what_each_fmu_needs(standalone_fmus, tmp_path):
    """The build prints each FMU's size and the oldest glibc its binaries run on (read from them)."""
    from orchestrator.build import runtime
    from orchestrator.build import standalone
    folder = standalone_fmus("deploy_rigid")
    for unit in ("structure", "aero"):
        line = standalone.describe(folder / f"{unit}.fmu")
        unpacked = tmp_path / unit
        with zipfile.ZipFile(folder / f"{unit}.fmu") as z:
            z.extractall(unpacked)
        assert line.endswith(f"glibc >= {runtime.glibc_needed(unpacked / 'binaries' / 'linux64')}")
        assert f"{(folder / f'{unit}.fmu').stat().st_size / 1e6:.1f} MB" in line
        assert Path(folder / f"{unit}.fmu").is_file()
