"""The hosts that run our FMUs in the tests besides wingsim's master (not a test module).

- the C FMI 2.0 host of tests/fmi/c_host/ (compiled by the ``c_host`` fixture of conftest.py): ``run_c_host``;
- its reference, the same call sequence through fmpy's FMU2Slave in this process: ``FmpyHost``, ``fmpy_run``;
- the FMI Compliance Checker (the ``fmu_checker`` fixture): ``check``, ``assert_clean``, and
  ``assert_replayed_by_fmpy``, which replays the checker's output through fmpy (tests/fmi/fmpy_replay.py);
- the processes a standalone FMU starts, from the process table: ``processes``, ``all_gone``.
"""
from __future__ import annotations

import csv
import os
import re
import shutil
import subprocess
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from fmpy import read_model_description
from fmpy.fmi1 import calloc, free
from fmpy.fmi2 import (FMU2Slave, fmi2CallbackAllocateMemoryTYPE, fmi2CallbackFreeMemoryTYPE, fmi2CallbackFunctions,
                       fmi2CallbackLoggerTYPE)

REPLAY = Path(__file__).resolve().parent / "fmi" / "fmpy_replay.py"

# The host runs with no environment (as `env -i`) but for the variables that select numpy's and OpenBLAS's
# kernels and threads in this process: under another kernel the same arithmetic rounds differently, and
# the comparisons with this process are bit for bit (tests/fmi/test_c_host.py also runs it without them).
NUMERIC_PREFIXES = ("OPENBLAS_", "GOTO_", "OMP_", "MKL_", "NPY_")


# ---- what both hosts are given ----------------------------------------------------------------------
def numeric_env() -> dict[str, str]:
    """The variables of this process that select numeric kernels and threads (NUMERIC_PREFIXES)."""
    return {k: v for k, v in os.environ.items() if k.startswith(NUMERIC_PREFIXES)}


@dataclass
class UnitSpec:
    """One unit as the hosts drive it: every Real output is read, each input is set from another unit's
    output of the same name (``source``) or held at a fixed value."""

    name: str
    folder: Path
    identifier: str
    guid: str
    outputs: list[tuple[int, str]]                                   # (value reference, name)
    connected: list[tuple[int, str, int]] = field(default_factory=list)   # (vr, source unit, source vr)
    fixed: list[tuple[int, float]] = field(default_factory=list)          # (vr, value)

    @classmethod
    def read(cls, name: str, folder: Path) -> "UnitSpec":
        md = read_model_description(str(folder / "modelDescription.xml"))
        outputs = [(v.valueReference, v.name) for v in md.modelVariables
                   if v.type == "Real" and v.causality == "output"]
        return cls(name, folder, md.coSimulation.modelIdentifier, md.guid, outputs)

    def variables(self) -> dict[str, int]:
        md = read_model_description(str(self.folder / "modelDescription.xml"))
        return {v.name: v.valueReference for v in md.modelVariables}


def coupled_units(unzipped) -> list[UnitSpec]:
    """Structure then aero: the structure's Q[i] from the aero unit's Q[i], the aero unit's e[i], de[i] from
    the structure's (all matched by name from the model descriptions)."""
    structure, aero = UnitSpec.read("structure", unzipped["structure"]), UnitSpec.read("aero", unzipped["aero"])
    for unit, source in ((structure, aero), (aero, structure)):
        produced = {name: vr for vr, name in source.outputs}
        md = read_model_description(str(unit.folder / "modelDescription.xml"))
        unit.connected = [(v.valueReference, source.name, produced[v.name]) for v in md.modelVariables
                          if v.causality == "input"]
    n = sum(1 for _, name in structure.outputs if name.startswith("e["))
    assert (len(structure.connected), len(aero.connected)) == (n, 2 * n)
    return [structure, aero]


def time_grid(steps: int, step: float, stop: float) -> list[float]:
    """Communication points k * step for k < steps, then stop (s)."""
    return [k * step for k in range(steps)] + [stop]


# ---- the C host ---------------------------------------------------------------------------------------
def host_input(units: list[UnitSpec], steps: int, step: float, stop: float) -> str:
    """The C host's input file (its format: the header comment of tests/fmi/c_host/fmi2_host.c) for `units`."""
    lines = [f"steps {steps}", f"step {step!r}", f"stop {stop!r}"]
    for unit in units:
        lines += [f"unit {unit.name}", f"location {unit.folder}", f"identifier {unit.identifier}",
                  f"guid {unit.guid}", f"resources {(unit.folder / 'resources').as_uri()}"]
        lines += [f"output {vr} {name}" for vr, name in unit.outputs]
        lines += [f"input {vr} {source} {source_vr}" for vr, source, source_vr in unit.connected]
        lines += [f"fixed {vr} {value!r}" for vr, value in unit.fixed]
    return "\n".join(lines) + "\n"


def run_c_host(host: Path, units: list[UnitSpec], steps: int, step: float, stop: float, mode: list[str],
               folder: Path, env: dict[str, str] | None = None, root: Path | None = None) -> dict[str, np.ndarray]:
    """The C host on `units` in environment `env` (default: numeric_env()); {phase: rows (time, then every
    unit's outputs in order)}. With `root`, the host runs in the system whose root folder that is (chroot,
    an empty environment): `host` and the units' folders are paths in it, `folder` is under `root`."""
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "input.txt").write_text(host_input(units, steps, step, stop), encoding="utf-8")
    files = [folder / "input.txt", folder / "out.csv"]
    command = [str(host), *(str(f) for f in files), *mode]
    if root is not None:
        command = [shutil.which("chroot") or "/usr/sbin/chroot", str(root), "/usr/bin/env", "-i", str(host),
                   *("/" + str(f.relative_to(root)) for f in files), *mode]
    out = subprocess.run(command, cwd=folder, env=numeric_env() if env is None else env, capture_output=True,
                         text=True, timeout=900)
    assert out.returncode == 0, f"C host ({' '.join(mode)}) exited with {out.returncode}:\n{out.stderr[-4000:]}"
    with open(folder / "out.csv", newline="", encoding="utf-8") as f:
        reader = csv.reader(f)
        header = next(reader)
        rows: dict[str, list[list[float]]] = {}
        for row in reader:
            rows.setdefault(row[0], []).append([float(x) for x in row[1:]])
    expected = ["phase", "time"] + [f"{u.name}.{name}" for u in units for _, name in u.outputs]
    assert header == expected
    return {phase: np.array(r) for phase, r in rows.items()}


# ---- the reference: the same call sequence through fmpy ---------------------------------------------
class FmpyHost:
    """The C host's calls, in its order, through fmpy's FMU2Slave in this process; every logged message
    at fmi2Warning or worse fails the call."""

    def __init__(self, units: list[UnitSpec], steps: int, step: float, stop: float):
        self.units, self.times = units, time_grid(steps, step, stop)
        self.values = {u.name: {} for u in units}            # {unit: {vr: latest output}}
        self.log: list[tuple[int, str]] = []

        def logger(env, instance, status, category, message):
            self.log.append((int(status), (message or b"").decode("utf-8", "replace")))

        self.callbacks = fmi2CallbackFunctions()
        self.callbacks.logger = fmi2CallbackLoggerTYPE(logger)
        self.callbacks.allocateMemory = fmi2CallbackAllocateMemoryTYPE(calloc)
        self.callbacks.freeMemory = fmi2CallbackFreeMemoryTYPE(free)
        self.fmus: dict[str, FMU2Slave] = {}

    def _checked(self, fn, *args):
        mark = len(self.log)
        result = fn(*args)
        bad = [m for s, m in self.log[mark:] if s > 0]
        assert not bad, f"{fn.__name__} logged: {bad}"
        return result

    def _read(self, unit: UnitSpec) -> None:
        vrs = [vr for vr, _ in unit.outputs]
        self.values[unit.name] = dict(zip(vrs, self._checked(self.fmus[unit.name].getReal, vrs)))

    def _set(self, unit: UnitSpec, before: int | None) -> None:
        """Inputs from the sources' latest outputs (only from units earlier than `before`, if given) and the
        fixed ones."""
        names = [u.name for u in self.units]
        pairs = [(vr, self.values[src][src_vr]) for vr, src, src_vr in unit.connected
                 if before is None or names.index(src) < before] + list(unit.fixed)
        if pairs:
            self._checked(self.fmus[unit.name].setReal, [p[0] for p in pairs], [p[1] for p in pairs])

    def _row(self, k: int) -> list[float]:
        return [self.times[k]] + [self.values[u.name][vr] for u in self.units for vr, _ in u.outputs]

    def start(self) -> list[list[float]]:
        for unit in self.units:
            fmu = FMU2Slave(guid=unit.guid, unzipDirectory=str(unit.folder), modelIdentifier=unit.identifier,
                            instanceName=unit.name)
            self._checked(fmu.instantiate, False, self.callbacks, True)
            self.fmus[unit.name] = fmu
            self._checked(fmu.setupExperiment, None, 0.0, None)
            self._checked(fmu.enterInitializationMode)
            self._checked(fmu.exitInitializationMode)
        for i, unit in enumerate(self.units):
            self._set(unit, i)
            self._read(unit)
        return [self._row(0)]

    def steps(self, first: int, last: int) -> list[list[float]]:
        rows = []
        for k in range(first + 1, last + 1):
            t0, t1 = self.times[k - 1], self.times[k]
            for unit in self.units:
                self._set(unit, None)
                self._checked(self.fmus[unit.name].doStep, t0, t1 - t0, False)
                self._read(unit)
            rows.append(self._row(k))
        return rows

    def get_states(self) -> dict:
        return {u.name: self._checked(self.fmus[u.name].getFMUstate) for u in self.units}

    def set_states(self, states: dict, k: int) -> list[list[float]]:
        for unit in self.units:
            self._checked(self.fmus[unit.name].setFMUstate, states[unit.name])
        for unit in self.units:
            self._read(unit)
        return [self._row(k)]

    def finish(self) -> None:
        for unit in self.units:
            fmu = self.fmus.pop(unit.name)
            self._checked(fmu.terminate)
            fmu.freeInstance()
            # pythonfmu put the unit's resources/ first on sys.path: take it out again
            resources = os.path.normpath(unit.folder / "resources")
            sys.path[:] = [p for p in sys.path if os.path.normpath(p) != resources]


def fmpy_run(units, steps, step, stop) -> np.ndarray:
    """The C host's "run" sequence through fmpy: rows (time, then every unit's outputs in order)."""
    ref = FmpyHost(units, steps, step, stop)
    rows = ref.start() + ref.steps(0, steps)
    ref.finish()
    return np.array(rows)


# ---- the FMI Compliance Checker -------------------------------------------------------------------------
def check(checker: Path, fmu: Path, out_csv: Path | None, step: float, stop: float,
          env: dict | None = None) -> subprocess.CompletedProcess:
    """The checker on `fmu` as a system tool starts it: an empty environment (or `env`), warnings logged,
    co-simulated with communication step `step` to `stop` (s), the outputs written to `out_csv` if given."""
    output = ["-o", str(out_csv)] if out_csv is not None else []
    return subprocess.run([str(checker), "-k", "cs", "-h", repr(step), "-s", repr(stop), "-l", "3", *output, str(fmu)],
                          env=env or {}, capture_output=True, text=True, timeout=600)


def assert_clean(proc: subprocess.CompletedProcess) -> None:
    """The checker's run reported no warning, no error and nothing fatal."""
    text = proc.stdout + proc.stderr
    assert proc.returncode == 0, text
    assert re.search(r"Checker reported:\s+0 Warning\(s\)\s+0 Error\(s\)", text), text
    assert re.search(r"FMU reported:\s+0 warning\(s\) and error\(s\)", text), text
    assert "Fatal" not in text and "FATAL" not in text, text


def assert_replayed_by_fmpy(fmu: Path, out_csv: Path, rows: int) -> None:
    """The checker's output `out_csv` (`rows` communication points) equals, bit for bit, the same points
    replayed through fmpy in the same empty environment."""
    proc = subprocess.run([sys.executable, str(REPLAY), str(fmu), str(out_csv)],
                          env={}, capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert f"rows={rows}" in proc.stdout
    assert "max_abs_difference=0.0" in proc.stdout, proc.stdout


# ---- the workers of standalone FMUs, from the process table ------------------------------------------------
def processes(command_matches, zombies: bool = True) -> list[int]:
    """The pids of the processes whose command line (bytes, its arguments separated by NUL) `command_matches`
    accepts; zombies (ended, not yet reaped) too unless `zombies` is False."""
    found = []
    for entry in Path("/proc").iterdir():
        if not entry.name.isdigit():
            continue
        try:
            command = (entry / "cmdline").read_bytes()
            state = (entry / "stat").read_text().rsplit(")", 1)[1].split()[0]
        except (OSError, IndexError):
            continue
        if command_matches(command) and (zombies or state != "Z"):
            found.append(int(entry.name))
    return found


def all_gone(find, patience: float) -> bool:
    """Whether `find()` (a list of pids) comes out empty within `patience` s, the time the kernel may take to end
    the processes."""
    deadline = time.monotonic() + patience
    while find():
        if time.monotonic() > deadline:
            return False
        time.sleep(0.05)
    return True
