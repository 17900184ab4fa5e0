"""Fixtures shared by the test folders: units/ (the numerical kernels and solvers), fmi/ (the FMUs in fmpy, a
C host, the Compliance Checker, libcosim, SSP), validation/ (whole runs against the papers and references
computed another way), cli/ (the command line and scenes).

Paths are absolute (tests/repository.py). Every test, and every module- or session-scoped fixture, runs in an
empty temporary working folder: a relative path in a test fails wherever pytest was started, and what a
command writes by default (fmus/<scene>/, results/) lands there, never in the working tree. Helpers that
several test modules use are modules beside this file (repository.py, subprocesses.py, fmi_hosts.py,
flat_wing.py), importable because pytest puts this folder on sys.path.
"""
from __future__ import annotations

import subprocess
from pathlib import Path

import pytest

from repository import FMU_CHECKER, SCENES


@pytest.fixture(scope="session", autouse=True)
def _fixtures_in_a_temporary_folder(tmp_path_factory):
    """The working folder of the fixtures scoped wider than a test (session, module, class)."""
    with pytest.MonkeyPatch.context() as patch:
        patch.chdir(tmp_path_factory.mktemp("fixtures_cwd"))
        yield


@pytest.fixture(autouse=True)
def _test_in_a_temporary_folder(tmp_path_factory, monkeypatch):
    """Each test's own empty working folder (not its tmp_path, which some tests list)."""
    monkeypatch.chdir(tmp_path_factory.mktemp("cwd"))


@pytest.fixture(scope="session")
def built_fmus(tmp_path_factory):
    """built_fmus(scene, *overrides) -> the folder holding the FMUs of scenes/<scene>.toml with the `--set`
    overrides (structure.fmu, and aero.fmu where the scene has an aero model), built once per pytest run and
    shared by every test that asks for the same scene and overrides: read them, copy before changing."""
    from orchestrator.build.fmus import build_fmus
    from orchestrator.scene.load import load_scene

    folders: dict[tuple, Path] = {}

    def built(scene: str, *overrides: str) -> Path:
        if (scene, overrides) not in folders:
            out = tmp_path_factory.mktemp(f"fmus_{scene}")
            build_fmus(load_scene(SCENES / f"{scene}.toml", list(overrides)), out)
            folders[scene, overrides] = out
        return folders[scene, overrides]
    return built


@pytest.fixture(scope="session")
def standalone_fmus(tmp_path_factory):
    """standalone_fmus(scene, *overrides) -> the folder holding the standalone FMUs (`wingsim build --standalone`)
    of scenes/<scene>.toml with the `--set` overrides, built once per pytest run as `built_fmus` does."""
    from orchestrator.build.fmus import build_fmus
    from orchestrator.scene.load import load_scene

    folders: dict[tuple, Path] = {}

    def built(scene: str, *overrides: str) -> Path:
        if (scene, overrides) not in folders:
            out = tmp_path_factory.mktemp(f"standalone_{scene}")
            build_fmus(load_scene(SCENES / f"{scene}.toml", list(overrides)), out, standalone=True)
            folders[scene, overrides] = out
        return folders[scene, overrides]
    return built


@pytest.fixture(scope="session")
def c_compiler() -> list[str]:
    """The C compiler `wingsim build` uses ($CC, else cc), as a command; the test is skipped without one."""
    from orchestrator.build import native_binary
    try:
        return native_binary.c_compiler()
    except native_binary.ShimUnavailable as missing:
        pytest.skip(str(missing))


@pytest.fixture(scope="session")
def c_host(c_compiler, tmp_path_factory) -> Path:
    """The C FMI 2.0 host of tests/fmi/c_host/, compiled against fmpy's FMI headers, linked with -ldl only."""
    from orchestrator.build import native_binary
    source = Path(__file__).resolve().parent / "fmi" / "c_host" / "fmi2_host.c"
    exe = tmp_path_factory.mktemp("c_host") / "fmi2_host"
    build = subprocess.run([*c_compiler, "-std=c99", "-O2", "-Wall", "-Wextra", "-I", str(native_binary.fmi_headers()),
                            str(source), "-o", str(exe), "-ldl"], capture_output=True, text=True, timeout=120)
    assert build.returncode == 0, f"compiling the C host failed:\n{build.stdout}{build.stderr}"
    return exe


@pytest.fixture(scope="session")
def fmu_checker() -> Path:
    """The FMI Compliance Checker's executable; the test is skipped where it is not installed."""
    if not FMU_CHECKER.is_file():
        pytest.skip(f"the FMI Compliance Checker is not installed at {FMU_CHECKER}")
    return FMU_CHECKER


@pytest.fixture
def kernels(monkeypatch):
    """kernels(kind): the process runs the `kind` kernels ("numpy" or "compiled", $WINGSIM_KERNELS) until the
    test ends."""
    def select(kind):
        monkeypatch.setenv("WINGSIM_KERNELS", kind)
    return select
