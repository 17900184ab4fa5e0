"""Bad input crossing the FMU boundary mid-run: the real structure or aero FMU reports it, the master stops
cleanly with status "error", the unit's reason and the samples recorded before the failing step."""
import types

import numpy as np

from orchestrator.run import units as real_units
from orchestrator.run.master import run_scene
from orchestrator.scene.load import load_scene
from repository import SCENES


def nan_from_step(k_bad, kind="structure"):
    """A units module whose `kind` unit receives a NaN in its first input (structure: Q; aero: e) at its
    k_bad-th set_inputs call and after."""
    def make_unit(**kwargs):
        unit = real_units.make_unit(**kwargs)
        if kwargs["kind"] != kind:
            return unit
        send, calls = unit.set_inputs, [0]

        def set_inputs(first, *rest):
            calls[0] += 1
            first = np.array(first, dtype=float)
            if calls[0] >= k_bad:
                first[4] = np.nan
            send(first, *rest)
        unit.set_inputs = set_inputs
        return unit
    return types.SimpleNamespace(make_unit=make_unit, UnitError=real_units.UnitError)


def test_nan_input_mid_run_stops_the_master_with_the_units_reason(built_fmus):
    scene = load_scene(SCENES / "deploy_rigid.toml", ["time.stop=0.05", "coupling.step=0.01", "aero.model=none"])
    result = run_scene(scene, backend="fmu", fmu_dir=built_fmus("deploy_rigid"), units=nan_from_step(3))
    assert result.status == "error"
    assert "Q[5]" in result.message and "NaN" in result.message
    # samples at 0, 0.01 and 0.02 s were written before the failing step from 0.02 s
    np.testing.assert_allclose(result.series.time, [0.0, 0.01, 0.02])
    assert np.all(np.isfinite(result.series.positions))


def test_aero_unit_failing_mid_run_stops_the_master_with_its_reason(built_fmus):
    """The aero FMU is given a NaN coordinate at its 3rd input (t = 0.02 s with Gauss-Seidel, which hands
    it the structure's e at the end of each step); it refuses the step, and the run ends there."""
    scene = load_scene(SCENES / "deploy_rigid.toml", ["time.stop=0.05", "coupling.step=0.01"])
    result = run_scene(scene, backend="fmu", fmu_dir=built_fmus("deploy_rigid"), units=nan_from_step(3, kind="aero"))
    assert result.status == "error"
    assert "aero" in result.message and "e[5]" in result.message and "NaN" in result.message
    # the initial inputs (call 1) and the step to 0.01 s (call 2) are fine; the step from 0.01 s fails
    # after the structure stepped, so the samples at 0 and 0.01 s are kept
    np.testing.assert_allclose(result.series.time, [0.0, 0.01])
    assert np.all(np.isfinite(result.series.positions)) and np.all(np.isfinite(result.series.CL))
