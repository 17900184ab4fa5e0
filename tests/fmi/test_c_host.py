"""The FMUs of deploy_rigid in a plain C FMI 2.0 co-simulation host (tests/fmi/c_host/fmi2_host.c), as another
FMI tool runs them: compiled here against fmpy's FMI 2.0 headers, linked with -ldl only (no libpython),
started without an environment (as `env -i`; see tests/fmi_hosts.py, NUMERIC_PREFIXES), every status checked.

The reference for every scenario is the same call sequence through fmpy's FMU2Slave in this process:
the same Python arithmetic runs behind both hosts, so the numbers must be equal bit for bit. The coupled
run is also compared with wingsim's own master (orchestrator.run.master, fmu backend), which couples the units
in the same Gauss-Seidel order.
"""
from __future__ import annotations

import csv
import os
import subprocess
import sys
import zipfile
from pathlib import Path

import numpy as np
import pytest

from fmi_hosts import FmpyHost, UnitSpec, coupled_units, fmpy_run, host_input, numeric_env, run_c_host
from orchestrator.run.master import run_scene
from orchestrator.scene.load import load_scene
from repository import ROOT, SCENES
from subprocesses import CODE_ROOT

SCENE = SCENES / "deploy_rigid.toml"

# The structure alone: a constant generalized force (N) on the position coordinates of the outer body's free
# end (e[28..30]: along the hinge axis, which the hinge holds, across the wing and along the span)
GIVEN_Q = {28: 0.02, 29: -0.01, 30: 0.005}
ALONE_STEPS = 100
STATE_AT, STATE_STEPS = 120, 20          # state round trips: save at step K, run M steps, restore, run them again
REINSTANTIATE_STEPS = 50                 # free and instantiate again: steps per round


@pytest.fixture(scope="module")
def scene() -> dict:
    return load_scene(SCENE)


@pytest.fixture(scope="module")
def fmus(built_fmus) -> dict[str, Path]:
    """{kind: the FMU file} built from deploy_rigid."""
    folder = built_fmus("deploy_rigid")
    return {kind: folder / f"{kind}.fmu" for kind in ("structure", "aero")}


@pytest.fixture(scope="module")
def unzipped(fmus, tmp_path_factory) -> dict[str, Path]:
    """{kind: the FMU unzipped}, for both hosts."""
    root = tmp_path_factory.mktemp("unzipped")
    for kind, fmu in fmus.items():
        with zipfile.ZipFile(fmu) as z:
            z.extractall(root / kind)
    return {kind: root / kind for kind in fmus}


def structure_alone(unzipped, q: dict[int, float]) -> list[UnitSpec]:
    """The structure unit with every Q[i] fixed: q[i] (N or N m) where given, else 0."""
    unit = UnitSpec.read("structure", unzipped["structure"])
    vr = unit.variables()
    n = sum(1 for name in vr if name.startswith("Q["))
    unit.fixed = [(vr[f"Q[{i}]"], float(q.get(i, 0.0))) for i in range(1, n + 1)]
    return [unit]


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
def test_structure_alone_with_a_given_force(c_host, unzipped, scene, tmp_path):
    h = scene["coupling"]["step"]
    units = structure_alone(unzipped, GIVEN_Q)
    stop = ALONE_STEPS * h
    c = run_c_host(c_host, units, ALONE_STEPS, h, stop, ["run"], tmp_path / "alone")
    assert list(c) == ["run"]
    reference = fmpy_run(units, ALONE_STEPS, h, stop)
    assert c["run"].shape == (ALONE_STEPS + 1, 1 + len(units[0].outputs))
    np.testing.assert_array_equal(c["run"], reference)
    # the force reached the unit: without it the free end is elsewhere after the same steps
    unforced = fmpy_run(structure_alone(unzipped, {}), ALONE_STEPS, h, stop)
    tip = [column(units, "structure", f"e[{i}]") for i in (29, 30)]
    assert np.all(np.abs(c["run"][-1, tip] - unforced[-1, tip]) > 1e-6)
    assert np.all(np.isfinite(c["run"]))


def test_coupled_gauss_seidel_matches_fmpy_and_the_master(c_host, unzipped, fmus, scene, tmp_path):
    h, stop = scene["coupling"]["step"], scene["time"]["stop"]
    steps = round(stop / h)
    assert steps == 300
    units = coupled_units(unzipped)
    c = run_c_host(c_host, units, steps, h, stop, ["run"], tmp_path / "coupled")["run"]
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


def test_state_get_set_and_serialize_round_trips(c_host, unzipped, scene, tmp_path):
    h, stop = scene["coupling"]["step"], scene["time"]["stop"]
    steps = round(stop / h)
    k, m = STATE_AT, STATE_STEPS
    units = coupled_units(unzipped)
    c = run_c_host(c_host, units, steps, h, stop, ["state", str(k), str(m)], tmp_path / "state")
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


def test_free_and_instantiate_again_in_one_process(c_host, unzipped, scene, tmp_path):
    h = scene["coupling"]["step"]
    steps = REINSTANTIATE_STEPS
    units = coupled_units(unzipped)
    c = run_c_host(c_host, units, steps, h, steps * h, ["reinstantiate", "2"], tmp_path / "again")
    assert list(c) == ["round1", "round2"]
    reference = fmpy_run(units, steps, h, steps * h)
    np.testing.assert_array_equal(c["round1"], reference)
    np.testing.assert_array_equal(c["round2"], reference)


def test_runs_with_an_empty_environment(c_host, unzipped, scene, tmp_path):
    h, stop = scene["coupling"]["step"], scene["time"]["stop"]
    steps = round(stop / h)
    units = coupled_units(unzipped)
    c = run_c_host(c_host, units, steps, h, stop, ["reinstantiate", "2"], tmp_path / "empty", env={})
    np.testing.assert_array_equal(c["round2"], c["round1"])
    reference = fmpy_run(units, steps, h, stop)
    if not numeric_env():
        np.testing.assert_array_equal(c["round1"], reference)
    else:  # kernels chosen by the CPU, not by this process's variables: the same numbers up to rounding
        # the probe accelerations come from solves with the mass matrix (condition number 1e7-1e8, model.py):
        # there the kernels' rounding grows to kappa x eps ~ 1e-8 relative; the state and every other output
        # keep the rounding of their kernels
        accelerations = [name for _, name in units[0].outputs if name.endswith(("_ax", "_ay", "_az"))]
        solved = [column(units, "structure", name) for name in accelerations]
        rest = [k for k in range(reference.shape[1]) if k not in solved]
        np.testing.assert_allclose(c["round1"][:, rest], reference[:, rest], rtol=1e-11, atol=1e-12)
        np.testing.assert_allclose(c["round1"][:, solved], reference[:, solved], rtol=1e-8, atol=1e-9)


def test_host_input_writes_the_input_of_the_coupled_run(fmus, unzipped, scene, tmp_path):
    """tests/fmi/c_host/host_input.py (the docs' way to the host's input file) writes the input the coupled test
    above runs the host on (the host's rows equal fmpy's and the master's there), but for the unzipped folders."""
    proc = subprocess.run([sys.executable, str(ROOT / "tests" / "fmi" / "c_host" / "host_input.py"),
                           str(fmus["structure"].parent), str(tmp_path)], capture_output=True, text=True,
                          env={**os.environ, "PYTHONPATH": str(CODE_ROOT)}, timeout=300)
    assert proc.returncode == 0, proc.stderr
    h, stop = scene["coupling"]["step"], scene["time"]["stop"]
    expected = host_input(coupled_units(unzipped), round(stop / h), h, stop)
    for kind, folder in unzipped.items():
        expected = expected.replace(str(folder), str(tmp_path.resolve() / kind))
        expected = expected.replace(folder.as_uri(), (tmp_path.resolve() / kind).as_uri())
    assert proc.stdout == expected


@pytest.mark.slow
def test_the_c_host_example_of_the_docs_runs_as_written(c_compiler, scene, tmp_path):
    """docs/fmu.md, "A plain C host": its commands, run in an empty folder with the repository's paths and
    virtual environment put in, build the FMUs, write the input file, compile and run the host; the host's rows
    equal wingsim's own run of the same FMUs (to 1e-12: `env -i` may select other BLAS kernels)."""
    text = (ROOT / "docs" / "fmu.md").read_text().split("### A plain C host", 1)[1]
    block = text.split("```sh\n", 1)[1].split("```", 1)[0]
    script = (block.replace(".venv/bin/", f"{Path(sys.executable).parent}/")
              .replace("scenes/", f"{ROOT}/scenes/").replace("tests/", f"{ROOT}/tests/")
              .replace("cc -std", f"{' '.join(c_compiler)} -std"))
    assert "host_input.py fmus/deploy_rigid unzipped > input.txt" in block
    proc = subprocess.run(["bash", "-euo", "pipefail", "-c", script], cwd=tmp_path, capture_output=True, text=True,
                          env={**os.environ, "PYTHONPATH": str(CODE_ROOT)}, timeout=900)
    assert proc.returncode == 0, proc.stderr[-4000:]
    with open(tmp_path / "out.csv", newline="") as f:
        header = next(csv.reader(f))
    c = np.loadtxt(tmp_path / "out.csv", delimiter=",", skiprows=1, usecols=range(1, len(header)))
    result = run_scene(scene, "fmu", tmp_path / "fmus" / "deploy_rigid")
    assert result.status == "ok" and c.shape[0] == len(result.series) == 301
    np.testing.assert_array_equal(c[:, 0], result.series.column("time"))
    for name in ("fold_angle_fold", "energy"):
        np.testing.assert_allclose(c[:, header.index(f"structure.{name}") - 1], result.series.column(name),
                                   rtol=1e-12, atol=1e-12)
    for name in ("CL", "lift"):
        np.testing.assert_allclose(c[:, header.index(f"aero.{name}") - 1], result.series.column(name),
                                   rtol=1e-12, atol=1e-12)
