"""The cache of the compiled C kernels (fmu_common.c_library) verifies what it loads and falls back as documented.

Each case runs the victim in its own Python process, so that a crash shows as a signal exit (a negative return
code) instead of killing pytest. The victim computes the velocity a straight vortex segment induces, checked
against the Biot-Savart law of a straight segment in closed form (Katz and Plotkin 2001): the segment from the
origin to (1, 0, 0) with circulation 1 m^2/s induces at (0.5, 1, 0) the velocity
(0, 0, (cos a1 - cos a2) / (4 pi h)), h = 1 m, cos a1 = -cos a2 = 0.5 / sqrt(1.25).
"""
import hashlib
import os
import shutil
import subprocess
import sys
import zipfile
from pathlib import Path

import numpy as np
import pytest

from repository import SCENES
from subprocesses import CODE_ROOT, wingsim

VELOCITY = 2 * 0.5 / np.sqrt(1.25) / (4 * np.pi)      # m/s, along +z
VICTIM = """
import sys
import numpy as np
from aero_fmu.biot_savart import C_SOURCE, induced_velocity
from structure_fmu import element
from fmu_common import c_library
v = induced_velocity(np.array([[0.5, 1.0, 0.0]]), np.zeros((1, 3)), np.array([[1.0, 0.0, 0.0]]), [1.0])
if "element" in sys.argv:
    element.c_kernels()
print(repr(v.ravel().tolist()))
print(c_library.load(C_SOURCE)._name if c_library.kernels(C_SOURCE, {}) is not None else "numpy")
"""
BIOT_SAVART = CODE_ROOT / "aero_fmu" / "biot_savart.c"


def _victim(cache, *, command=(), element=False, timeout=120, **env):
    """Run VICTIM with the cache folder `cache` (prefixed by `command`, e.g. a namespace with a mount; `element`:
    the element kernels loaded too); returns (the process, the velocity it printed or None, the library it loaded
    or "numpy")."""
    env = {**os.environ, "PYTHONPATH": str(CODE_ROOT), "WINGSIM_CACHE_DIR": str(cache), "WINGSIM_KERNELS": "compiled",
           **env}
    arguments = ["element"] if element else []
    run = subprocess.run([*command, sys.executable, "-c", VICTIM, *arguments], env=env, capture_output=True,
                         text=True, timeout=timeout)
    lines = run.stdout.splitlines()
    if run.returncode != 0 or len(lines) < 2:
        return run, None, None
    return run, np.array(eval(lines[-2])), lines[-1]        # noqa: S307 - our own victim's repr of a list


def _check_velocity(run, velocity):
    assert run.returncode == 0, f"exit {run.returncode} (negative: killed by a signal)\n{run.stderr}"
    assert velocity == pytest.approx([0.0, 0.0, VELOCITY], rel=1e-12, abs=1e-15)


def _damage(library: Path, how: str) -> None:
    data = library.read_bytes()
    if how == "truncated":
        library.write_bytes(data[:len(data) // 3])
    else:           # one byte in the middle of the code flipped: the file is whole, its bytes are not the compiled
        middle = len(data) // 2
        library.write_bytes(data[:middle] + bytes([data[middle] ^ 0xFF]) + data[middle + 1:])


@pytest.mark.parametrize("how", ["truncated", "altered"])
def test_a_damaged_cached_library_is_reported_by_name_deleted_and_compiled_again(tmp_path, how):
    cache = tmp_path / "cache"
    run, velocity, _ = _victim(cache)
    _check_velocity(run, velocity)
    [library] = cache.glob("biot_savart-*.so")
    size = library.stat().st_size
    _damage(library, how)
    run, velocity, loaded = _victim(cache)
    _check_velocity(run, velocity)
    assert f"{library} is not the library compiled from biot_savart.c" in run.stderr, run.stderr
    assert "compiled again" in run.stderr
    assert loaded == str(library) and library.stat().st_size == size


def test_a_damaged_library_carried_beside_its_source_is_reported_and_not_loaded(tmp_path):
    """An FMU's copy of a kernel library (beside its source) that does not match its record is never mapped: the
    warning names it and the kernel is compiled into the cache folder."""
    source = tmp_path / "fmu" / "aero_fmu" / "biot_savart.c"
    source.parent.mkdir(parents=True)
    shutil.copyfile(BIOT_SAVART, source)
    probe = VICTIM.replace("from aero_fmu.biot_savart import C_SOURCE, induced_velocity",
                           "from aero_fmu.biot_savart import induced_velocity\n"
                           f"from pathlib import Path\nC_SOURCE = Path({str(source)!r})")
    env = {**os.environ, "PYTHONPATH": str(CODE_ROOT), "WINGSIM_CACHE_DIR": str(tmp_path / "cache")}
    subprocess.run([sys.executable, "-c", "import sys\nfrom fmu_common import c_library\n"
                    "c_library.compile_into(sys.argv[1], sys.argv[2])", str(source), str(source.parent)], env=env,
                   check=True)
    [carried] = source.parent.glob("biot_savart-*.so")
    _damage(carried, "truncated")
    run = subprocess.run([sys.executable, "-c", probe], env=env, capture_output=True, text=True, timeout=120)
    assert run.returncode == 0, f"exit {run.returncode} (negative: killed by a signal)\n{run.stderr}"
    assert f"{carried} is not the library compiled from biot_savart.c" in run.stderr, run.stderr
    assert run.stdout.splitlines()[-1] == str(tmp_path / "cache" / carried.name)


def _namespace_with(mount_options: str, folder: Path, seed: Path | None = None) -> list[str]:
    """A command prefix: the victim runs in its own user and mount namespace where `folder` is a fresh tmpfs
    mounted with `mount_options`, holding the files of `seed` if given (root is not needed, and root cannot write
    there either)."""
    unshare = shutil.which("unshare")
    assert unshare, "unshare (util-linux) is needed to give the victim a read-only or full cache folder"
    mount = f"mount -t tmpfs -o {mount_options} tmpfs {folder}"
    if seed is not None:        # filled, then made read-only
        mount = (f"mount -t tmpfs tmpfs {folder} && cp -a {seed}/. {folder}/ "
                 f"&& mount -o remount,{mount_options} {folder}")
    if "size" in mount_options:
        mount += f" && (head -c 1M /dev/zero > {folder}/filler; true)"
    return [unshare, "--user", "--map-root-user", "--mount", "sh", "-c", f"{mount} && exec \"$0\" \"$@\""]


@pytest.mark.parametrize("cache_is", ["read-only", "read-only, holding a truncated library", "full"])
def test_a_cache_folder_that_cannot_be_written_gives_the_documented_warning_and_the_run_goes_on(tmp_path,
                                                                                              cache_is):
    """docs/fmu.md: a host whose user cannot write the cache folder gets a warning and compiles in each process;
    a damaged library there, which cannot be deleted, is reported and never loaded."""
    cache, seed = tmp_path / "cache", None
    cache.mkdir()
    if "truncated" in cache_is:
        run, velocity, _ = _victim(tmp_path / "scratch")
        _check_velocity(run, velocity)
        seed = tmp_path / "scratch"
        [damaged] = seed.glob("biot_savart-*.so")
        _damage(damaged, "truncated")
    options = "size=64k" if cache_is == "full" else "ro"
    run, velocity, loaded = _victim(cache, command=_namespace_with(options, cache, seed))
    _check_velocity(run, velocity)
    assert f"cannot write the cache folder {cache}" in run.stderr, run.stderr
    assert "compiled in every process" in run.stderr
    if seed is not None:
        assert f"{cache / damaged.name} is not the library compiled from biot_savart.c" in run.stderr
        assert "not deleted" in run.stderr
    assert loaded != "numpy" and not loaded.startswith(str(cache))
    assert not Path(loaded).exists()        # the process's own copy is gone with it


def test_a_compiler_that_never_returns_is_stopped_at_the_time_limit_and_the_numpy_kernels_run(tmp_path):
    hanging = tmp_path / "hanging-cc"
    pid_file = tmp_path / "sleep.pid"
    hanging.write_text(f"#!/bin/sh\nsleep 300 &\necho $! > {pid_file}\nwait\n")
    hanging.chmod(0o755)
    cache = tmp_path / "cache"
    run, velocity, loaded = _victim(cache, CC=str(hanging), WINGSIM_COMPILE_SECONDS="2")
    _check_velocity(run, velocity)
    assert "did not finish within 2 s and was stopped" in run.stderr, run.stderr
    assert run.stderr.count("C kernels unavailable, the numpy kernels run instead") == 1
    assert loaded == "numpy"
    assert not list(cache.glob("*.so"))
    # the compiler's own children were stopped with it
    pid = int(pid_file.read_text())
    state = Path(f"/proc/{pid}/stat")
    assert not state.exists() or state.read_text().split(")")[-1].split()[0] in ("Z", "X")


def test_without_a_compiler_the_numpy_kernels_run_with_one_warning(tmp_path):
    """Two C kernels (Biot-Savart, element) and no compiler: one warning, naming the missing compiler and the
    numpy choice; with WINGSIM_KERNELS=numpy no warning at all."""
    run, velocity, loaded = _victim(tmp_path / "cache", CC=str(tmp_path / "no-such-cc"), element=True)
    _check_velocity(run, velocity)
    assert run.stderr.count("C kernels unavailable, the numpy kernels run instead") == 1, run.stderr
    assert "no C compiler" in run.stderr and "WINGSIM_KERNELS=numpy" in run.stderr
    assert loaded == "numpy"
    run, velocity, loaded = _victim(tmp_path / "cache", CC=str(tmp_path / "no-such-cc"), WINGSIM_KERNELS="numpy",
                                    element=True)
    _check_velocity(run, velocity)
    assert "C kernels" not in run.stderr and loaded == "numpy"


def test_a_build_never_carries_a_damaged_library_into_an_fmu(tmp_path, monkeypatch):
    """`wingsim build` with a truncated Biot-Savart library in the cache: the FMU carries the library compiled
    again, whose bytes are those of a fresh compilation in another folder."""
    from fmu_common import c_library

    cache = tmp_path / "cache"
    run, velocity, _ = _victim(cache)
    _check_velocity(run, velocity)
    [library] = cache.glob("biot_savart-*.so")
    _damage(library, "truncated")
    monkeypatch.setenv("WINGSIM_CACHE_DIR", str(cache))
    build = wingsim("build", SCENES / "heaving_wing.toml", "--unit", "aero", "--out", tmp_path / "fmus",
                    cwd=tmp_path)
    assert build.returncode == 0, build.stderr
    assert str(library) in build.stderr
    fresh = c_library.compile_into(BIOT_SAVART, tmp_path / "fresh")
    with zipfile.ZipFile(tmp_path / "fmus" / "aero.fmu") as z:
        carried = z.read(f"resources/aero_fmu/{library.name}")
    assert hashlib.sha256(carried).digest() == hashlib.sha256(fresh.read_bytes()).digest()
