"""The energy monitor's external work (StructureSolver.monitors()["external_work"]): the work of the point loads
and Q since t = 0. A constant point force F does the work F . (displacement of its point), exactly; without
damping the energy changes by that work (energy balance), in the ANCF and the strain-based fidelity."""
import numpy as np
import pytest

from orchestrator.scene.load import read_scene_file, resolve_scene
from repository import SCENES
from structure_fmu.solver import StructureSolver
from fmu_common.specs import StructureUnitSpec

FORCE = np.array([0.0, 0.0, -1000.0])       # N, the scene's tip force


def undamped_cantilever(fidelity):
    """cantilever_static with its tip force applied at once and no damping; generalized-alpha without numerical
    dissipation (rho_inf = 1), 1 ms steps: the first bending period is 71 ms."""
    raw = read_scene_file(SCENES / "cantilever_static.toml")
    raw["structure"].update(fidelity=fidelity, rho_inf=1.0)
    raw["structure"]["bodies"][0]["damping"] = 0.0
    raw["structure"]["loads"] = [{"body": "beam", "span": 2.0, "force": FORCE.tolist()}]
    return resolve_scene(raw, "cantilever")


@pytest.mark.parametrize("fidelity", ["flexible", "strain-based"])
def test_work_of_a_constant_force_and_the_energy_balance(fidelity):
    solver = StructureSolver(StructureUnitSpec.from_scene(undamped_cantilever(fidelity)))
    tip0 = solver.sensors.positions(solver.e)[0]
    start = solver.monitors()["energy"]
    for t in (0.05, 0.1, 0.2):
        solver.advance(t)
        monitors = solver.monitors()
        work = monitors["external_work"]
        exact = FORCE @ (solver.sensors.positions(solver.e)[0] - tip0)
        # the trapezoidal power integral telescopes to F . displacement where the integrator's displacement is
        # the trapezoidal integral of its velocity (rho_inf = 1), up to the strain-based map's curvature
        assert work == pytest.approx(exact, rel=1e-6)
        assert monitors["energy"] - start == pytest.approx(work, rel=1e-4)   # kinetic + strain = work


def test_energy_drift_of_a_driven_conservative_run_is_its_numerical_drift():
    """The undamped cantilever driven by its constant 1000 N tip force, run 0.2 s (rho_inf = 1): the energy it
    gains is the work of the force, F . (tip displacement), so summary.json's energy_drift, (E_final - E_0 -
    W_external) / scale, is the integrator's drift, near 0; without W_external it would be the work itself, of
    the order of the peak kinetic energy."""
    from orchestrator.output.results import summarize
    from orchestrator.run.master import run_scene

    scene = undamped_cantilever("flexible")
    scene["time"]["stop"], scene["coupling"]["step"] = 0.2, 0.01
    result = run_scene(scene, backend="direct")
    assert result.status == "ok", result.message
    series = result.series
    tip = series.positions[:, 0]
    work = FORCE @ (tip[-1] - tip[0])                       # J, analytic work of a constant force
    assert series.external_work[-1] - series.external_work[0] == pytest.approx(work, rel=1e-6)
    gained = (series.energy[-1] - series.energy[0]) / max(abs(series.energy[0]), np.nanmax(series.kinetic_energy))
    assert abs(gained) > 0.1                                # what the drift was before the work was counted
    assert abs(summarize(result)["energy_drift"]) < 1e-4
