"""The win64 binaries of standalone FMUs (`wingsim build --standalone --win64`, orchestrator/build/win64.py), run under
Wine (slow: the FMUs are built with their Windows runtime, a Wine prefix is made).

The host is our C FMI host (tests/fmi/c_host/fmi2_host.c) cross-compiled for Windows (LoadLibrary, GetProcAddress),
started by Wine's 64-bit loader in a prefix of its own, with Wine's Visual C++ runtime DLLs disabled
(msvcp140, vcruntime140, vcruntime140_1 native only), as on a Windows without Microsoft's redistributable: the
FMU must bring them. On the structure and aero FMUs of deploy_rigid:
- what the FMU holds: its win64 binaries, and every DLL they import is in the FMU or is one of Windows's own
  (read with mingw's objdump, not with the build's own reader);
- the two units coupled for 300 steps equal Linux's `wingsim run` (orchestrator.run.master with the ordinary FMUs, in
  this process), every output within 1e-12 of that output's largest magnitude: another C library, another
  OpenBLAS build, the kernels compiled by another compiler, so equal to the rounding, not bit for bit. The
  reference for the outputs the master does not record (e, de, Q, ...) is our C host on the ordinary FMUs on
  Linux, checked first to equal the master's numbers bit for bit where both have them;
- a worker killed with SIGKILL gives the host fmi2Fatal with the reason logged, and the host lives to report it;
- no worker is left after the host ends, or after the host is killed with SIGKILL (the Linux process table).

Test rig only, never in an FMU: Wine 8.0 has no implementation of the Universal C runtime's C99 complex
functions (cexp, crealf, ...; Windows has), and numpy calls one while it is imported. tests/fmi/wine/winecompat.c,
compiled here, replaces those stubs in a process. The test loads it into the workers through numpy's hook for
distributors (`numpy/_distributor_init_local.py`, which numpy imports first if it exists), written into the
test's own unpacked copy of each FMU. Wine, its tools and mingw-w64 are installed by .ci/run; without them the
tests fail, saying what is missing.
"""
from __future__ import annotations

import csv
import os
import shutil
import signal
import subprocess
import time
import urllib.parse
import zipfile
from pathlib import Path

import numpy as np
import pytest

from fmi_hosts import all_gone, coupled_units, processes, run_c_host
from orchestrator.build import native_binary
from orchestrator.build.fmus import build_fmus
from orchestrator.run.master import run_scene
from orchestrator.scene.load import load_scene
from repository import SCENES

pytestmark = pytest.mark.slow

HERE = Path(__file__).resolve().parent
MINGW = "x86_64-w64-mingw32-gcc"
STEPS = 300
FATAL = "fmi2Fatal"
ROUNDING_COLUMNS = {"structure.constraint_residual"}
"""Outputs that are rounding errors themselves (max |Phi| of the satisfied constraints, 1e-16 to 1e-13): compared
against the scale of the quantity whose rounding they are, the coordinates e (see the test)."""


def wine_loader() -> str:
    """Wine's 64-bit loader (Debian keeps it out of PATH); the test fails if Wine is missing."""
    for candidate in ("/usr/lib/wine/wine64", shutil.which("wine64")):
        if candidate and os.access(candidate, os.X_OK):
            return candidate
    pytest.fail("Wine is not installed (Debian: apt-get install --no-install-recommends wine64 wine; .ci/run does)")


@pytest.fixture(scope="module")
def wine(tmp_path_factory):
    """The environment of a fresh Wine prefix in a temporary folder (headless, no Mono or Gecko installers, the
    Visual C++ runtime taken from the FMU only); its server is stopped at the end."""
    loader = wine_loader()
    for tool in ("wineboot", "wineserver", MINGW):
        if shutil.which(tool) is None:
            pytest.fail(f"{tool} is not installed (Debian: wine, gcc-mingw-w64-x86-64; .ci/run installs them)")
    env = {k: v for k, v in os.environ.items() if k not in ("DISPLAY", "WAYLAND_DISPLAY")}
    env.update(WINEPREFIX=str(tmp_path_factory.mktemp("wine") / "prefix"), WINEARCH="win64", WINEDEBUG="-all",
               WINEDLLOVERRIDES="mscoree,mshtml=;winemenubuilder.exe=d;msvcp140,vcruntime140,vcruntime140_1=n")
    made = subprocess.run(["wineboot", "-i"], env=env, capture_output=True, text=True, timeout=300)
    assert made.returncode == 0, made.stderr[-3000:]
    env["WINE_LOADER_PATH"] = loader
    yield env
    subprocess.run(["wineserver", "-k"], env=env, capture_output=True, timeout=60)


@pytest.fixture(scope="module")
def windows_programs(tmp_path_factory) -> dict[str, Path]:
    """The C host and the test rig's winecompat.dll, compiled with mingw-w64."""
    folder = tmp_path_factory.mktemp("windows_programs")
    out = {"host": folder / "fmi2_host.exe", "winecompat": folder / "winecompat.dll"}
    for command in ([MINGW, "-std=c99", "-O2", "-Wall", "-D__USE_MINGW_ANSI_STDIO=1", "-static-libgcc", "-I",
                     str(native_binary.fmi_headers()), str(HERE / "c_host" / "fmi2_host.c"), "-o", str(out["host"])],
                    [MINGW, "-O2", "-Wall", "-shared", "-static-libgcc", str(HERE / "wine" / "winecompat.c"), "-o",
                     str(out["winecompat"])]):
        built = subprocess.run(command, capture_output=True, text=True, timeout=300)
        assert built.returncode == 0, built.stderr
    return out


@pytest.fixture(scope="module")
def fmus(tmp_path_factory) -> Path:
    """The folder of deploy_rigid's standalone FMUs with win64 binaries."""
    out = tmp_path_factory.mktemp("win64_fmus")
    build_fmus(load_scene(SCENES / "deploy_rigid.toml"), out, standalone=True, win64=True)
    return out


def unpacked(fmus: Path, folder: Path, winecompat: Path) -> dict[str, Path]:
    """{kind: the FMU unpacked into `folder`/kind, winecompat.dll hooked into its runtime's numpy}."""
    out = {}
    for kind in ("structure", "aero"):
        with zipfile.ZipFile(fmus / f"{kind}.fmu") as z:
            z.extractall(folder / kind)
        numpy = folder / kind / "binaries" / "win64" / "runtime" / "site-packages" / "numpy"
        (numpy / "_distributor_init_local.py").write_text(f"import ctypes\nctypes.CDLL({windows_path(winecompat)!r})\n")
        out[kind] = folder / kind
    return out


def windows_path(path: Path) -> str:
    """`path` as a Windows program under Wine sees it: drive Z: is the root of the Linux file system."""
    return "Z:" + str(path).replace("/", "\\")


def run_wine_host(wine: dict, host: Path, units, steps: int, step: float, mode: list[str], folder: Path,
                  stdin=None) -> subprocess.Popen | dict[str, np.ndarray]:
    """The Windows C host on `units` (their win64 binaries) under Wine, as run_c_host runs the Linux one; {phase:
    rows}. With `stdin`, the started process instead (the caller talks to it)."""
    lines = [f"steps {steps}", f"step {step!r}", f"stop {steps * step!r}"]
    for unit in units:
        uri = "file:///Z:" + urllib.parse.quote(str(unit.folder / "resources"))
        lines += [f"unit {unit.name}", f"location {windows_path(unit.folder)}", f"identifier {unit.identifier}",
                  f"guid {unit.guid}", f"resources {uri}"]
        lines += [f"output {vr} {name}" for vr, name in unit.outputs]
        lines += [f"input {vr} {source} {source_vr}" for vr, source, source_vr in unit.connected]
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "input.txt").write_text("\n".join(lines) + "\n", encoding="utf-8")
    command = [wine["WINE_LOADER_PATH"], str(host), windows_path(folder / "input.txt"),
               windows_path(folder / "out.csv"), *mode]
    if stdin is not None:
        return subprocess.Popen(command, env=wine, stdin=stdin, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                                text=True)
    # pipes, not files, as its standard streams: Wine hands a Windows program a Unix file in a way CPython's
    # start-up (a worker's) cannot use, and the host's streams are not the workers' anyway
    out = subprocess.run(command, env=wine, stdin=subprocess.DEVNULL, capture_output=True, text=True, timeout=600)
    assert out.returncode == 0, f"the Windows C host exited with {out.returncode}:\n{out.stderr[-4000:]}"
    return read_csv(folder / "out.csv")


def read_csv(path: Path) -> dict[str, np.ndarray]:
    with open(path, newline="", encoding="utf-8") as f:
        reader = csv.reader(f)
        next(reader)
        rows: dict[str, list[list[float]]] = {}
        for row in reader:
            rows.setdefault(row[0], []).append([float(x) for x in row[1:]])
    return {phase: np.array(r) for phase, r in rows.items()}


def workers(folder: Path) -> list[int]:
    """Linux pids of the running (not zombie) processes whose command line names a worker of the unpacked FMUs
    under `folder`: a Windows process under Wine is a Linux process with its Windows command line."""
    mark = windows_path(folder).encode()
    return processes(lambda command: mark in command and b"_worker.exe" in command, zombies=False)


def gone(folder: Path, patience: float = 20.0) -> bool:
    return all_gone(lambda: workers(folder), patience)


# ---- the tests --------------------------------------------------------------------------------------------

def test_the_fmu_carries_win64_binaries_and_every_dll_they_import(fmus, tmp_path):
    objdump = shutil.which("x86_64-w64-mingw32-objdump")
    assert objdump, "x86_64-w64-mingw32-objdump is missing (Debian: binutils-mingw-w64-x86-64)"
    windows_own = {"kernel32.dll", "msvcrt.dll", "advapi32.dll", "ws2_32.dll", "version.dll", "bcrypt.dll",
                   "user32.dll", "gdi32.dll", "shell32.dll", "ole32.dll", "oleaut32.dll", "crypt32.dll", "shlwapi.dll",
                   "rpcrt4.dll", "secur32.dll", "iphlpapi.dll", "psapi.dll", "mswsock.dll", "userenv.dll"}
    for kind in ("structure", "aero"):
        with zipfile.ZipFile(fmus / f"{kind}.fmu") as z:
            z.extractall(tmp_path / kind)
            platforms = {n.split("/")[1] for n in z.namelist() if n.startswith("binaries/") and n.count("/") > 1}
        assert platforms == {"linux64", "win64"}
        win64 = tmp_path / kind / "binaries" / "win64"
        for name in (f"{kind}.dll", f"{kind}_worker.exe", f"{kind}_pythonfmu.dll", "runtime/python311.dll",
                     "runtime/python311.zip", "runtime/msvcp140.dll"):
            assert (win64 / name).is_file(), name
        assert list((tmp_path / kind / "resources").rglob("*-*.dll")), "no C kernel compiled for Windows"
        files = [p for p in (tmp_path / kind).rglob("*") if p.is_file()]
        bundled = {p.name.lower() for p in files}
        for binary in (p for p in files if p.suffix in (".dll", ".pyd", ".exe")):
            table = subprocess.run([objdump, "-p", str(binary)], capture_output=True, text=True, check=True).stdout
            needed = [line.split("DLL Name:")[1].strip().lower() for line in table.splitlines() if "DLL Name:" in line]
            outside = [n for n in needed if n not in bundled and n not in windows_own
                       and not n.startswith("api-ms-win-")]
            assert not outside, f"{binary.relative_to(tmp_path)} imports {outside} from outside the FMU"


def test_the_coupled_deployment_under_wine_equals_wingsim_run(wine, windows_programs, fmus, built_fmus, c_host,
                                                             tmp_path):
    scene = load_scene(SCENES / "deploy_rigid.toml")
    h = scene["coupling"]["step"]
    assert round(scene["time"]["stop"] / h) == STEPS
    folders = unpacked(fmus, tmp_path / "fmus", windows_programs["winecompat"])
    units = coupled_units(folders)
    started = time.perf_counter()
    rows = run_wine_host(wine, windows_programs["host"], units, STEPS, h, ["run"], tmp_path / "wine")["run"]
    wine_seconds = time.perf_counter() - started
    assert gone(tmp_path / "fmus"), "a worker is left after the host ended"

    # the reference: wingsim run in this process, and for the outputs it does not record our C host on Linux
    result = run_scene(scene, "fmu", built_fmus("deploy_rigid"))
    assert result.status == "ok", result.message
    ordinary = {}
    for kind in ("structure", "aero"):
        with zipfile.ZipFile(built_fmus("deploy_rigid") / f"{kind}.fmu") as z:
            z.extractall(tmp_path / "ordinary" / kind)
            ordinary[kind] = tmp_path / "ordinary" / kind
    linux_units = coupled_units(ordinary)
    reference = run_c_host(c_host, linux_units, STEPS, h, scene["time"]["stop"], ["run"], tmp_path / "linux")["run"]
    names = [f"{u.name}.{n}" for u in units for _, n in u.outputs]
    assert names == [f"{u.name}.{n}" for u in linux_units for _, n in u.outputs]
    np.testing.assert_array_equal(reference[:, 0], result.series.column("time"))
    from_master = 0
    for column in result.series.columns:
        for unit in ("structure", "aero"):
            if f"{unit}.{column}" in names:
                index = 1 + names.index(f"{unit}.{column}")
                np.testing.assert_array_equal(reference[:, index], result.series.column(column), err_msg=column)
                from_master += 1
    assert from_master >= 5

    np.testing.assert_array_equal(rows[:, 0], reference[:, 0])
    worst = {}
    for index, name in enumerate(names, start=1):
        scale = np.max(np.abs(reference[:, index]))
        if name in ROUNDING_COLUMNS:
            # max |Phi| is 0 to 1e-13 on both systems, rounding alone: its own largest magnitude is no scale for
            # it; the coordinates it is the rounding of are (largest |e| about 1 m)
            coordinates = [k for k, n in enumerate(names, start=1) if n.startswith("structure.e[")]
            scale = np.max(np.abs(reference[:, coordinates]))
            assert np.max(np.abs(rows[:, index])) < 1e-12 * scale
        worst[name] = np.max(np.abs(rows[:, index] - reference[:, index])) / (scale or 1.0)
    outside = {name: value for name, value in worst.items() if value > 1e-12}
    assert not outside, f"outputs beyond 1e-12 of their largest magnitude: {outside}"
    # equal bit for bit is possible: both sides run the same numpy release and C kernels built without contraction
    # (the Windows side's arithmetic runs in the win64 binaries the Windows host loads; it cannot load Linux ones)
    # the wing deployed and latched (fold angle from 170 degrees to its stop at 0)
    fold = 1 + names.index("structure.fold_angle_fold")
    assert rows[0, fold] == pytest.approx(170.0) and abs(rows[-1, fold]) < 5.0
    print(f"\n{STEPS} steps under Wine in {wine_seconds:.1f} s; worst relative difference {max(worst.values()):.2e} "
          f"({max(worst, key=worst.get)})")


def test_a_killed_worker_gives_fmi2Fatal_with_the_reason(wine, windows_programs, fmus, tmp_path):
    folders = unpacked(fmus, tmp_path / "fmus", windows_programs["winecompat"])
    host = run_wine_host(wine, windows_programs["host"], coupled_units(folders), 20, 1e-3, ["pause", "5"],
                         tmp_path / "wine", stdin=subprocess.PIPE)
    try:
        assert host.stdout.readline().strip() == "paused", host.stderr.read()
        structure = [pid for pid in workers(folders["structure"])]
        assert len(structure) == 1 and len(workers(tmp_path / "fmus")) == 2, "one worker per instance"
        os.kill(structure[0], signal.SIGKILL)
        assert gone(folders["structure"])
        host.stdin.write("\n")
        host.stdin.flush()
        _, errors = host.communicate(timeout=120)
    finally:
        host.kill()
    assert host.returncode == 1, errors       # the C host stops at the first call that is not fmi2OK
    fatal = [line for line in errors.splitlines() if line.startswith("[structure] fmi2Fatal")]
    assert fatal and "the unit's worker process" in fatal[0] and "ended" in fatal[0], errors
    assert f"of unit structure at t = 0.0050000000000000001 s: {FATAL}" in errors, errors
    assert gone(tmp_path / "fmus"), "the aero unit's worker is left after its host ended"


def test_no_worker_is_left_after_the_host_is_killed(wine, windows_programs, fmus, tmp_path):
    folders = unpacked(fmus, tmp_path / "fmus", windows_programs["winecompat"])
    host = run_wine_host(wine, windows_programs["host"], coupled_units(folders), 20, 1e-3, ["pause", "3"],
                         tmp_path / "wine", stdin=subprocess.PIPE)
    try:
        assert host.stdout.readline().strip() == "paused", host.stderr.read()
        assert len(workers(tmp_path / "fmus")) == 2
        host.send_signal(signal.SIGKILL)
        host.wait(timeout=60)
    finally:
        host.kill()
    assert gone(tmp_path / "fmus"), "a worker is left after its host was killed with SIGKILL"
