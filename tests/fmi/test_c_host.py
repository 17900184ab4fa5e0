"""The FMUs of deploy_rigid in a plain C FMI 2.0 co-simulation host (tests/c_host/fmi2_host.c), as another
FMI tool runs them: compiled here against fmpy's FMI 2.0 headers, linked with -ldl only (no libpython),
started without an environment (as `env -i`; see NUMERIC_PREFIXES), every status checked.

The reference for every scenario is the same call sequence through fmpy's FMU2Slave in this process:
the same Python arithmetic runs behind both hosts, so the numbers must be equal bit for bit. The coupled
run is also compared with wingsim's own master (orchestrator.master, fmu backend), which couples the units
in the same Gauss-Seidel order.
"""
from __future__ import annotations

import csv
import importlib.util
import os
import shlex
import shutil
import subprocess
import sys
import zipfile
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pytest

fmpy = pytest.importorskip("fmpy")
from fmpy import read_model_description  # noqa: E402
from fmpy.fmi1 import calloc, free  # noqa: E402
from fmpy.fmi2 import (FMU2Slave, fmi2CallbackAllocateMemoryTYPE, fmi2CallbackFreeMemoryTYPE,  # noqa: E402
                       fmi2CallbackFunctions, fmi2CallbackLoggerTYPE)

from orchestrator.build import build_fmus  # noqa: E402
from orchestrator.master import run_scene  # noqa: E402
from orchestrator.scene import load_scene  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
SCENE = ROOT / "scenes" / "deploy_rigid.toml"
HOST_SOURCE = Path(__file__).resolve().parent / "c_host" / "fmi2_host.c"
# The host runs with no environment (as `env -i`) but for the variables that select numpy's and OpenBLAS's
# kernels and threads in this process: under another kernel the same arithmetic rounds differently, and
# the comparisons with this process are bit for bit. test_runs_with_an_empty_environment drops those too.
NUMERIC_PREFIXES = ("OPENBLAS_", "GOTO_", "OMP_", "MKL_", "NPY_")

# The structure alone: a constant generalized force (N) on the position coordinates of the outer body's free
# end (e[28..30]: along the hinge axis, which the hinge holds, across the wing and along the span)
GIVEN_Q = {28: 0.02, 29: -0.01, 30: 0.005}
ALONE_STEPS = 100
STATE_AT, STATE_STEPS = 120, 20          # state round trips: save at step K, run M steps, restore, run them again
REINSTANTIATE_STEPS = 50                 # free and instantiate again: steps per round


# ---- building the host and the FMUs -----------------------------------------------------------------
def c_compiler() -> list[str] | None:
    """$CC (split like a shell word list), else cc, as `wingsim build` finds it; None if not on PATH."""
    cc = shlex.split(os.environ.get("CC") or "cc")
    return cc if cc and shutil.which(cc[0]) else None


def numeric_env() -> dict[str, str]:
    """The variables of this process that select numeric kernels and threads (NUMERIC_PREFIXES)."""
    return {k: v for k, v in os.environ.items() if k.startswith(NUMERIC_PREFIXES)}


@pytest.fixture(scope="module")
def host(tmp_path_factory) -> Path:
    """The C host, compiled into a temporary folder."""
    cc = c_compiler()
    if cc is None:
        pytest.skip("no C compiler ($CC, else cc) on PATH: the C FMI host cannot be built")
    headers = Path(importlib.util.find_spec("fmpy").origin).parent / "c-code"
    assert (headers / "fmi2Functions.h").is_file(), f"fmpy ships no FMI 2.0 headers in {headers}"
    exe = tmp_path_factory.mktemp("c_host") / "fmi2_host"
    build = subprocess.run([*cc, "-std=c99", "-O2", "-Wall", "-Wextra", "-I", str(headers), str(HOST_SOURCE),
                            "-o", str(exe), "-ldl"], capture_output=True, text=True, timeout=120)
    assert build.returncode == 0, f"compiling the C host failed:\n{build.stdout}{build.stderr}"
    return exe


@pytest.fixture(scope="module")
def scene() -> dict:
    return load_scene(SCENE)


@pytest.fixture(scope="module")
def fmus(scene, tmp_path_factory) -> dict[str, Path]:
    """{kind: the FMU file} built from deploy_rigid."""
    out = tmp_path_factory.mktemp("fmus")
    return {path.stem: path for path in build_fmus(scene, out)}


@pytest.fixture(scope="module")
def unzipped(fmus, tmp_path_factory) -> dict[str, Path]:
    """{kind: the FMU unzipped}, for both hosts."""
    root = tmp_path_factory.mktemp("unzipped")
    for kind, fmu in fmus.items():
        with zipfile.ZipFile(fmu) as z:
            z.extractall(root / kind)
    return {kind: root / kind for kind in fmus}


# ---- what both hosts are given ----------------------------------------------------------------------
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


def structure_alone(unzipped, q: dict[int, float]) -> list[UnitSpec]:
    """The structure unit with every Q[i] fixed: q[i] (N or N m) where given, else 0."""
    unit = UnitSpec.read("structure", unzipped["structure"])
    vr = unit.variables()
    n = sum(1 for name in vr if name.startswith("Q["))
    unit.fixed = [(vr[f"Q[{i}]"], float(q.get(i, 0.0))) for i in range(1, n + 1)]
    return [unit]


def time_grid(steps: int, step: float, stop: float) -> list[float]:
    """Communication points k * step for k < steps, then stop (s)."""
    return [k * step for k in range(steps)] + [stop]


# ---- the C host ---------------------------------------------------------------------------------------
def run_c_host(host: Path, units: list[UnitSpec], steps: int, step: float, stop: float, mode: list[str],
               folder: Path, env: dict[str, str] | None = None) -> dict[str, np.ndarray]:
    """The C host on `units` in environment `env` (default: numeric_env()); {phase: rows (time, then every
    unit's outputs in order)}."""
    lines = [f"steps {steps}", f"step {step!r}", f"stop {stop!r}"]
    for unit in units:
        lines += [f"unit {unit.name}", f"location {unit.folder}", f"identifier {unit.identifier}",
                  f"guid {unit.guid}", f"resources {(unit.folder / 'resources').as_uri()}"]
        lines += [f"output {vr} {name}" for vr, name in unit.outputs]
        lines += [f"input {vr} {source} {source_vr}" for vr, source, source_vr in unit.connected]
        lines += [f"fixed {vr} {value!r}" for vr, value in unit.fixed]
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "input.txt").write_text("\n".join(lines) + "\n", encoding="utf-8")
    out = subprocess.run([str(host), str(folder / "input.txt"), str(folder / "out.csv"), *mode], cwd=folder,
                         env=numeric_env() if env is None else env, capture_output=True, text=True, timeout=300)
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
    ref = FmpyHost(units, steps, step, stop)
    rows = ref.start() + ref.steps(0, steps)
    ref.finish()
    return np.array(rows)


def fmpy_state_round_trip(units, steps, step, stop, k, m) -> dict[str, np.ndarray]:
    """The C host's "state K M" sequence through fmpy."""
    ref = FmpyHost(units, steps, step, stop)
    out = {"run": ref.start() + ref.steps(0, k)}
    states = ref.get_states()
    data = {name: ref._checked(ref.fmus[name].serializeFMUstate, s) for name, s in states.items()}
    out["continued"] = ref.steps(k, k + m)
    out["restored"] = ref.set_states(states, k) + ref.steps(k, k + m)
    for name, s in states.items():
        ref._checked(ref.fmus[name].freeFMUstate, s)
    states = {name: ref._checked(ref.fmus[name].deSerializeFMUstate, b) for name, b in data.items()}
    out["deserialized"] = ref.set_states(states, k) + ref.steps(k, k + m)
    for name, s in states.items():
        ref._checked(ref.fmus[name].freeFMUstate, s)
    ref.finish()
    return {phase: np.array(rows) for phase, rows in out.items()}


def column(units: list[UnitSpec], unit: str, name: str) -> int:
    """Index of `unit`.`name` in a row (time first)."""
    names = [f"{u.name}.{n}" for u in units for _, n in u.outputs]
    return 1 + names.index(f"{unit}.{name}")


# ---- the scenarios ------------------------------------------------------------------------------------
def test_structure_alone_with_a_given_force(host, unzipped, scene, tmp_path):
    h = scene["coupling"]["step"]
    units = structure_alone(unzipped, GIVEN_Q)
    stop = ALONE_STEPS * h
    c = run_c_host(host, units, ALONE_STEPS, h, stop, ["run"], tmp_path / "alone")
    assert list(c) == ["run"]
    reference = fmpy_run(units, ALONE_STEPS, h, stop)
    assert c["run"].shape == (ALONE_STEPS + 1, 1 + len(units[0].outputs))
    np.testing.assert_array_equal(c["run"], reference)
    # the force reached the unit: without it the free end is elsewhere after the same steps
    unforced = fmpy_run(structure_alone(unzipped, {}), ALONE_STEPS, h, stop)
    tip = [column(units, "structure", f"e[{i}]") for i in (29, 30)]
    assert np.all(np.abs(c["run"][-1, tip] - unforced[-1, tip]) > 1e-6)
    assert np.all(np.isfinite(c["run"]))


def test_coupled_gauss_seidel_matches_fmpy_and_the_master(host, unzipped, fmus, scene, tmp_path):
    h, stop = scene["coupling"]["step"], scene["time"]["stop"]
    steps = round(stop / h)
    assert steps == 300
    units = coupled_units(unzipped)
    c = run_c_host(host, units, steps, h, stop, ["run"], tmp_path / "coupled")["run"]
    assert c.shape[0] == steps + 1
    np.testing.assert_array_equal(c, fmpy_run(units, steps, h, stop))

    # wingsim's master couples the same way (structure with the aero Q of t, aero with the new e, de)
    result = run_scene(scene, "fmu", fmus["structure"].parent)
    assert result.status == "ok", result.message
    np.testing.assert_array_equal(result.series.column("time"), c[:, 0])
    compared = []
    for name in result.series.columns:
        for unit in ("structure", "aero"):
            try:
                index = column(units, unit, name)
            except ValueError:
                continue
            np.testing.assert_array_equal(result.series.column(name), c[:, index], err_msg=f"{unit}.{name}")
            compared.append(name)
    assert {"fold_angle_fold", "energy", "CL", "lift"} <= set(compared)
    # the e, de the master handed the aero unit at every step are the structure outputs the C host read
    n = len(result.aero_inputs.e[0])
    e = [column(units, "structure", f"e[{i}]") for i in range(1, n + 1)]
    de = [column(units, "structure", f"de[{i}]") for i in range(1, n + 1)]
    np.testing.assert_array_equal(np.array(result.aero_inputs.e), c[1:, e])
    np.testing.assert_array_equal(np.array(result.aero_inputs.de), c[1:, de])
    # the wing deployed and latched within the run (fold angle from 170 degrees to the stop at 0)
    fold = c[:, column(units, "structure", "fold_angle_fold")]
    assert fold[0] == pytest.approx(170.0) and abs(fold[-1]) < 5.0
    assert c[-1, column(units, "structure", "latch_time_fold")] > 0.0


def test_state_get_set_and_serialize_round_trips(host, unzipped, scene, tmp_path):
    h, stop = scene["coupling"]["step"], scene["time"]["stop"]
    steps = round(stop / h)
    k, m = STATE_AT, STATE_STEPS
    units = coupled_units(unzipped)
    c = run_c_host(host, units, steps, h, stop, ["state", str(k), str(m)], tmp_path / "state")
    assert list(c) == ["run", "continued", "restored", "deserialized"]
    assert c["continued"].shape[0] == m
    # restored from the state and from its bytes: the outputs at t_K and the same M steps, bit for bit
    for phase in ("restored", "deserialized"):
        np.testing.assert_array_equal(c[phase][0], c["run"][k], err_msg=phase)
        np.testing.assert_array_equal(c[phase][1:], c["continued"], err_msg=phase)
    reference = fmpy_state_round_trip(units, steps, h, stop, k, m)
    for phase, rows in reference.items():
        np.testing.assert_array_equal(c[phase], rows, err_msg=phase)
    # the saved point is mid-deployment: the M steps after it move the wing
    fold = column(units, "structure", "fold_angle_fold")
    assert abs(c["continued"][-1, fold] - c["run"][k, fold]) > 1.0


def test_free_and_instantiate_again_in_one_process(host, unzipped, scene, tmp_path):
    h = scene["coupling"]["step"]
    steps = REINSTANTIATE_STEPS
    units = coupled_units(unzipped)
    c = run_c_host(host, units, steps, h, steps * h, ["reinstantiate", "2"], tmp_path / "again")
    assert list(c) == ["round1", "round2"]
    reference = fmpy_run(units, steps, h, steps * h)
    np.testing.assert_array_equal(c["round1"], reference)
    np.testing.assert_array_equal(c["round2"], reference)


def test_runs_with_an_empty_environment(host, unzipped, scene, tmp_path):
    h, stop = scene["coupling"]["step"], scene["time"]["stop"]
    steps = round(stop / h)
    units = coupled_units(unzipped)
    c = run_c_host(host, units, steps, h, stop, ["reinstantiate", "2"], tmp_path / "empty", env={})
    np.testing.assert_array_equal(c["round2"], c["round1"])
    reference = fmpy_run(units, steps, h, stop)
    if not numeric_env():
        np.testing.assert_array_equal(c["round1"], reference)
    else:  # kernels chosen by the CPU, not by this process's variables: the same numbers up to rounding
        np.testing.assert_allclose(c["round1"], reference, rtol=1e-11, atol=1e-12)
