"""The free wake's velocities through the compiled and numpy Biot-Savart kernels: the convection velocity of the
wake's corners (bound rings and wake summed over their unique segments in one call) against every ring summed
leg by leg, and a whole free-wake run equal with both kernels."""
import numpy as np
import pytest

from aero_fmu.biot_savart import segment_velocity
from fmu_common.specs import AeroUnitSpec, StructureUnitSpec
from aero_fmu.solver import AeroSolver
from flat_wing import wing_scene
from structure_fmu.solver import StructureSolver

MOTION = {"heave_amplitude": 0.1, "pitch_amplitude_deg": 5.0, "frequency": 0.7}


def free_wake_run(steps, M=3, N=6, far_field="exact"):
    """(AeroSolver after `steps` steps of dt = c / (M V), C_L history) of a pitching and heaving wing of span 4 c
    with the free wake, convected by `far_field` (aero.wake_far_field)."""
    scene = wing_scene("uvlm-free", MOTION, span=4.0, M=M, N=N)
    scene["aero"]["wake_far_field"] = far_field
    structure, aero = StructureSolver(StructureUnitSpec.from_scene(scene)), AeroSolver(AeroUnitSpec.from_scene(scene))
    dt, history = 1.0 / M, []
    for k in range(1, steps + 1):
        structure.advance(k * dt)
        aero.advance(k * dt, structure.e, structure.de)
        history.append(aero.outputs()["CL"])
    return aero, np.array(history)


def ring_by_ring_velocity(points, aero, core):
    """Velocity (P, 3) m/s at points induced by the bound and wake rings, each ring its own four legs with its own
    circulation (no segment shared between rings), by the plain (P, S, 3) tensor of `segment_velocity`."""
    state, lattice = aero.state, aero.lattice
    c = state.wake.corners                                                       # (B, R + 1, N + 1, 3)
    wake_rings = np.stack([c[:, :-1, :-1], c[:, 1:, :-1], c[:, 1:, 1:], c[:, :-1, 1:]], axis=-2).reshape(-1, 4, 3)
    rings = np.concatenate([state.corners[lattice.rings], wake_rings])           # corners in circulation order
    gamma = np.concatenate([state.gamma, state.wake.gamma.ravel()])
    tensor = segment_velocity(points, rings.reshape(-1, 3), np.roll(rings, -1, axis=1).reshape(-1, 3), core)
    return np.einsum("psc,s->pc", tensor, np.repeat(gamma, 4))


@pytest.mark.parametrize("kind", ["numpy", "compiled"])
def test_free_wake_convection_velocity_is_the_sum_over_every_ring(kernels, kind):
    """The corners of a rolled-up free wake move with U + w, w induced by the bound rings and the wake with the
    convection core: equal to every ring summed leg by leg (1e-12 of the largest w), on both kernels."""
    kernels(kind)
    aero, _ = free_wake_run(12)
    model, state = aero.model, aero.state
    points = state.wake.corners.reshape(-1, 3)
    w = (model._displacement(state, aero.U, 1.0) - aero.U).reshape(-1, 3)
    expected = ring_by_ring_velocity(points, aero, model.convection_core)
    assert np.abs(expected).max() > 0.01                                          # a wake that induces something
    assert np.abs(w - expected).max() <= 1e-12 * np.abs(expected).max()


@pytest.mark.parametrize("far_field", ["exact", "treecode"])
def test_a_free_wake_run_is_the_same_on_both_kernels(kernels, far_field):
    """A free-wake run with every Biot-Savart sum on the compiled kernels equals the numpy reference: with the exact
    sums, C_L history, circulations and wake corners to 1e-12 relative (of their largest values). With the treecode
    a cluster whose opening test falls on its boundary to round-off (rho = theta d, as on the regular rows of a
    young wake) is opened on one path and not on the other, so the two runs agree to the far-field error, not to
    round-off: each keeps C_L within a thousandth of the exact sum's (test_aero_treecode.py), so within two
    thousandths of each other."""
    runs = {}
    for kind in ("numpy", "compiled"):
        kernels(kind)
        runs[kind] = free_wake_run(20, far_field=far_field)
    (reference, cl_reference), (compiled, cl_compiled) = runs["numpy"], runs["compiled"]
    if far_field == "treecode":
        assert np.abs(cl_compiled - cl_reference).max() <= 2e-3 * np.abs(cl_reference).max()
    else:
        for a, b in ((cl_compiled, cl_reference), (compiled.state.gamma, reference.state.gamma),
                     (compiled.state.wake.gamma, reference.state.wake.gamma),
                     (compiled.state.wake.corners, reference.state.wake.corners)):
            assert np.abs(a - b).max() <= 1e-12 * np.abs(b).max()
    assert reference.state.wake.n_rows == 19                                     # the first step starts the motion
