"""Spin-up maneuver (Otsuka et al. 2019, Sec. VI.B, Eq. 27; Simo & Vu-Quoc's beam): element convergence and settling."""
import numpy as np
import pytest

from orchestrator.scene.load import load_scene
from structure_fmu.motion import SpinUp
from fmu_common.specs import StructureUnitSpec
from structure_fmu.solver import StructureSolver
from repository import SCENES


def transverse_tip_deflection(elements, stop=20.0, sample=0.01):
    """Tip distance from the rigidly rotating beam line (m), sampled every `sample` s.

    The rigid line is rotated about Y by theta(t) of Otsuka et al. 2019, Eq. (27), computed here from the law itself.
    """
    scene = load_scene(SCENES / "spin_up.toml", [f"structure.elements_per_body={elements}"])
    joint = scene["structure"]["joints"][0]
    law = SpinUp([0, 1, 0], [0, 0, 0], joint["omega"], joint["ramp_time"])
    length = scene["structure"]["bodies"][0]["length"]
    solver = StructureSolver(StructureUnitSpec.from_scene(scene))
    times, deflection = [], []
    for k in range(1, int(round(stop / sample)) + 1):
        solver.advance(k * sample)
        theta = law.angle(solver.time)[0]
        transverse = np.array([np.sin(theta), 0.0, np.cos(theta)])   # R_y(theta) e_z
        tip = solver.topology.point_position(solver.e, "beam", length, 0.5)
        times.append(solver.time)
        deflection.append(tip @ transverse)
    return np.array(times), np.array(deflection)


@pytest.mark.slow
def test_spin_up_converges_with_elements_and_settles():
    t, coarse = transverse_tip_deflection(9)
    _, fine = transverse_tip_deflection(18)
    peak = np.max(np.abs(fine))
    assert peak > 0.1                                        # a real transient (m)
    assert np.max(np.abs(coarse - fine)) < 0.02 * peak       # 9 and 18 elements agree within 2% of the peak
    after = np.abs(fine[t > 17.0])                           # 2 s after the spin-up ends at T_s = 15 s
    assert np.max(after) < 0.05 * peak                       # settles to a small steady value
    print(f"peak {peak:.4f} m, 9-vs-18 max difference {np.max(np.abs(coarse - fine)):.2e} m, "
          f"max after 17 s {np.max(after):.2e} m")
