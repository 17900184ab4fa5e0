"""Bad input crossing the FMU boundary mid-run: the real structure FMU reports it, the master stops cleanly."""
import types

import numpy as np

from orchestrator import units as real_units
from orchestrator.build import build_fmus
from orchestrator.master import run_scene
from orchestrator.scene import load_scene


def nan_from_step(k_bad):
    """A units module whose structure unit receives a NaN generalized force from its k_bad-th step on."""
    def make_unit(**kwargs):
        unit = real_units.make_unit(**kwargs)
        send, calls = unit.set_inputs, [0]

        def set_inputs(Q):
            calls[0] += 1
            Q = np.array(Q, dtype=float)
            if calls[0] >= k_bad:
                Q[4] = np.nan
            send(Q)
        unit.set_inputs = set_inputs
        return unit
    return types.SimpleNamespace(make_unit=make_unit, UnitError=real_units.UnitError)


def test_nan_input_mid_run_stops_the_master_with_the_units_reason(tmp_path):
    scene = load_scene("scenes/deploy_rigid.toml", ["time.stop=0.05", "coupling.step=0.01"])
    build_fmus(scene, tmp_path)
    result = run_scene(scene, backend="fmu", fmu_dir=tmp_path, units=nan_from_step(3))
    assert result.status == "error"
    assert "Q[5]" in result.message and "NaN" in result.message
    # samples at 0, 0.01 and 0.02 s were written before the failing step from 0.02 s
    np.testing.assert_allclose(result.series.time, [0.0, 0.01, 0.02])
    assert np.all(np.isfinite(result.series.positions))
