"""Numerical stability at the extremes: stiffness x 1e3 and x 1e-3, steps at and beyond the explicit limit."""
import json

import numpy as np
import pytest

from orchestrator.cli import main
from orchestrator.output.results import read_timeseries
from orchestrator.scene.load import load_scene
from structure_fmu.modes import natural_frequencies
from fmu_common.specs import StructureUnitSpec
from structure_fmu.solver import StructureSolver
from repository import SCENES

CANTILEVER = SCENES / "cantilever_static.toml"
STIFFNESS_KEYS = ("axial_stiffness", "bending_stiffness_flap", "bending_stiffness_chord", "torsional_rigidity")


def scaled(factor):
    """--set overrides multiplying every stiffness of the cantilever beam (E and G) by `factor`."""
    section = load_scene(CANTILEVER)["structure"]["bodies"][0]["section"]
    return [f"structure.bodies.beam.section.{k}={float(section[k] * factor)!r}" for k in STIFFNESS_KEYS]


def rk4_step_limit(overrides):
    """Largest stable RK4 step 2 sqrt(2) / omega_max (RK4 on the imaginary axis), from the linear modes."""
    solver = StructureSolver(StructureUnitSpec.from_scene(load_scene(CANTILEVER, overrides)))
    omega_max = natural_frequencies(solver, count=None).max()
    return float(2 * np.sqrt(2) / omega_max)


def run(tmp_path, overrides):
    args = ["run", str(CANTILEVER), "--backend", "direct", "--out", str(tmp_path)]
    for item in overrides:
        args += ["--set", item]
    code = main(args)
    summary = json.loads((tmp_path / "summary.json").read_text())
    return code, summary, read_timeseries(tmp_path / "timeseries.csv")[0]


@pytest.mark.parametrize("factor", [1e3, 1.0, 1e-3])
def test_rk4_below_its_limit_is_stable_and_beyond_it_diverges_cleanly(tmp_path, factor):
    stiff = scaled(factor)
    limit = rk4_step_limit(stiff)
    common = stiff + ["structure.integrator=rk4", f"time.stop={400 * limit!r}", f"coupling.step={40 * limit!r}"]
    code, summary, _ = run(tmp_path / "below", common + [f"structure.step={0.9 * limit!r}"])
    assert (code, summary["status"]) == (0, "ok")
    code, summary, rows = run(tmp_path / "beyond", common + [f"structure.step={1.5 * limit!r}"])
    assert (code, summary["status"]) == (1, "diverged")
    assert "diverged at t =" in summary["message"] and "structure.step" in summary["message"]
    # the results up to the failure are kept, and say when it failed
    assert len(rows) >= 1 and float(rows["time"][-1]) <= summary["simulated_time_s"] + 1e-12
    assert summary["simulated_time_s"] < 400 * limit


@pytest.mark.parametrize("factor", [1e3, 1e-3])
def test_generalized_alpha_is_stable_far_beyond_the_explicit_limit(tmp_path, factor):
    """The same quasi-static problem at both stiffness extremes: times scale with 1 / sqrt(factor)."""
    stiff = scaled(factor)
    limit = rk4_step_limit(stiff)
    ramp = float(0.4 / np.sqrt(factor))
    step = float(min(1e3 * limit, ramp / 100))
    assert step > 50 * limit      # far beyond what RK4 survives (1.5 x limit diverges above)
    code, summary, _ = run(tmp_path, stiff + [f"structure.step={step!r}", f"time.stop={1.25 * ramp!r}",
                                              f"coupling.step={ramp / 8!r}", f"structure.loads.0.ramp_time={ramp!r}",
                                              f"structure.loads.0.force=[0.0, 0.0, {-1000.0 * factor!r}]"])
    assert (code, summary["status"]) == (0, "ok")
    # the load scales with the stiffness, so the deflection is the same small static one
    body = summary["scene"]["structure"]["bodies"][0]
    expected = -1000.0 * body["length"] ** 3 / (3 * body["section"]["bending_stiffness_flap"] / factor)
    tip = summary["probes"]["tip"]
    assert tip["final"][2] - tip["initial"][2] == pytest.approx(expected, rel=0.02)
    assert summary["max_constraint_residual"] < 1e-8
