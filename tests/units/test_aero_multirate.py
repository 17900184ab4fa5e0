"""Multi-rate aero unit (aero.step, aero_fmu/solver.py): k aero steps inside one communication step, the
inner ones on inputs e, de interpolated linearly between the previous and the new inputs.

Independent numbers: the wake gains one row per aero step (a count) and each prescribed row is V x
aero step long; the interpolated inputs are recomputed here as the midpoint of two structure samples;
Theodorsen's heave amplitude (tests/flat_wing.py) and an estimate of what the interpolation changes
(test_theodorsen_heave_multirate). The wing and the heave helpers are those of tests/flat_wing.py.
"""
import pickle

import numpy as np
import pytest

from aero_fmu.solver import AeroSolver
from fmu_common.specs import AeroUnitSpec, StructureUnitSpec
from orchestrator.scene.overrides import parse_value
from orchestrator.scene.load import load_scene, resolve_scene
from fmu_common.errors import SceneError
from structure_fmu.solver import StructureSolver
from flat_wing import assert_heave_matches, fitted_amplitude, heave_theory, wing_scene
from repository import SCENES

MODELS = ("strip", "uvlm-flat", "uvlm-prescribed", "uvlm-free")


def small_wing(model, step=None, wake_length=3.0, pitch_deg=3.0):
    """A 6 m x 1 m wing heaving 0.1 m and pitching pitch_deg at 0.7 rad/s in V = 1 m/s, M = 3, N = 4."""
    scene = wing_scene(model, {"heave_amplitude": 0.1, "pitch_amplitude_deg": pitch_deg, "frequency": 0.7},
                       span=6.0, M=3, N=4, wake_length=wake_length)
    if step is not None:
        scene["aero"]["step"] = step
    return scene


def structure_inputs(scene, times):
    """[(t, e, de)] of the prescribed structure at the given times (s)."""
    structure, out = StructureSolver(StructureUnitSpec.from_scene(scene)), []
    for t in times:
        structure.advance(t)
        out.append((t, structure.e, structure.de))
    return out


def driven(scene, inputs):
    """An AeroSolver of the scene advanced through inputs [(t, e, de)]."""
    aero = AeroSolver(AeroUnitSpec.from_scene(scene))
    for t, e, de in inputs:
        aero.advance(t, e, de)
    return aero


def assert_same_state(a, b):
    """Two AeroSolvers in bit-identical states (loads, circulations, wake)."""
    sa, sb = a.get_state(), b.get_state()
    assert sa.time == sb.time
    np.testing.assert_array_equal(a.Q, b.Q)
    assert a.outputs() == b.outputs()
    if hasattr(sa, "gamma"):
        np.testing.assert_array_equal(sa.gamma, sb.gamma)
        np.testing.assert_array_equal(sa.corners, sb.corners)
        assert (sa.wake is None) == (sb.wake is None)
        if sa.wake is not None:
            np.testing.assert_array_equal(sa.wake.corners, sb.wake.corners)
            np.testing.assert_array_equal(sa.wake.gamma, sb.wake.gamma)


# ---------------------------------------------------------------------------------------------- 1
@pytest.mark.parametrize("model", MODELS)
def test_without_aero_step_nothing_changes(model):
    """Key absent, None (as the resolved scene records it), equal to the communication step (times k x 0.1
    carry rounding: t_end - t is 0.1 +- 3e-17) or 100 times larger: one aero step per communication step,
    bit-identical states; and the same as calling the model itself once per communication step."""
    times = [0.1 * j for j in range(1, 9)]
    inputs = structure_inputs(small_wing(model), times)
    reference = driven(small_wing(model), inputs)
    model_state = reference.model.initial_state()
    for t, e, de in inputs:
        model_state = reference.model.advance(model_state, t, e, de, reference.U, reference.density,
                                              reference.direction)
    np.testing.assert_array_equal(model_state.loads.Q, reference.Q)
    assert model_state.loads.outputs == reference.outputs()
    for step in (None, 0.1, 10.0):
        scene = small_wing(model)
        scene["aero"]["step"] = step
        assert_same_state(driven(scene, inputs), reference)


# ---------------------------------------------------------------------------------------------- 2
@pytest.mark.parametrize("model", ["uvlm-prescribed", "uvlm-free"])
@pytest.mark.parametrize("k", [2, 3])
def test_shed_wake_gains_k_rows_per_communication_step(model, k):
    """Communication step H = 0.3 s, aero.step = H / k (0.15, 0.1: H / 3 is not exact in binary and the
    times 0.3 j carry rounding): the first aero step is the start (no wake), each later one sheds a row,
    so after n communication steps the wake has k n - 1 rows of N = 4 rings (wake 20 chords: never
    truncated). The prescribed wake's rows are V H / k = 0.3 / k m long (heave only: the trailing edge
    keeps its x)."""
    H, n, N = 0.3, 6, 4
    scene = small_wing(model, step=H / k, wake_length=20.0, pitch_deg=0.0)
    aero = driven(scene, structure_inputs(scene, [H * j for j in range(1, n + 1)]))
    assert aero.outputs()["wake_panels"] == (k * n - 1) * N
    if model == "uvlm-prescribed":
        rows = np.diff(aero.get_state().wake.corners[0, :, :, 0], axis=0)
        np.testing.assert_allclose(rows, H / k, rtol=1e-12)


@pytest.mark.parametrize("model", MODELS)
def test_inner_steps_use_linearly_interpolated_inputs(model):
    """aero.step = H / 2: the same states as a single-rate solver stepped every H / 2 with inputs built
    here: at the inner times the mean of the structure's e, de at the two neighbouring communication
    times, at the first communication step the new inputs held (no previous ones). Equal to rounding
    (1e-12 relative: e0 + (e - e0) / 2 is not (e0 + e) / 2 bit for bit)."""
    H, n = 0.2, 6
    samples = structure_inputs(small_wing(model), [H * j for j in range(1, n + 1)])
    multirate = driven(small_wing(model, step=H / 2), samples)
    fine = []
    for j, (t, e, de) in enumerate(samples):
        e0, de0 = (e, de) if j == 0 else samples[j - 1][1:]
        fine += [(t - H / 2, (e0 + e) / 2, (de0 + de) / 2), (t, e, de)]
    single = driven(small_wing(model), fine)
    scale = np.abs(single.Q).max()
    assert scale > 0
    np.testing.assert_allclose(multirate.Q, single.Q, rtol=0, atol=1e-12 * scale)
    assert multirate.outputs()["wake_panels"] == single.outputs()["wake_panels"]


# ---------------------------------------------------------------------------------------------- 3
def heave_run(M, H, step, k=0.25, periods=3):
    """Otsuka et al. 2019, Sec. VI.D heaving wing (heave_response of tests/units/test_aero_unsteady.py: V = 1 m/s,
    c = 1 m, span 1000 m, N = 5, h = 0.1 sin(2 k t), wake 20 chords) with communication step H and aero.step
    `step`; the fitted complex C_L amplitude over periods 1..3 of the samples at the communication times."""
    omega = 2 * k
    scene = wing_scene("uvlm-prescribed", {"heave_amplitude": 0.1, "frequency": omega}, M=M, N=5,
                       wake_length=20.0)
    scene["aero"]["step"] = step
    T = 2 * np.pi / omega
    inputs = structure_inputs(scene, H * np.arange(1, int(np.ceil(periods * T / H)) + 1))
    aero, CL = AeroSolver(AeroUnitSpec.from_scene(scene)), []
    for t, e, de in inputs:
        aero.advance(t, e, de)
        CL.append(aero.outputs()["CL"])
    return fitted_amplitude(np.array([t for t, _, _ in inputs]), np.array(CL), omega, T)


def interpolation_effect(k, M, h0_over_c, wagner_start=0.5):
    """Estimated |change of the C_L amplitude| / |Theodorsen's| when every other aero step (h = c/(MV))
    takes inputs interpolated over 2h. For a sinusoid the midpoint of the chord is the exact value times
    cos(omega h), omega h = 2k/M: the inner step's normal velocity is off by eps = 1 - cos(omega h)
    ((omega h)^2 / 2, the O(h^2) interpolation error), so its bound circulation by eps phi Gamma_qs,
    Gamma_qs = pi c w the quasi-steady one and phi = 1/2 the share a sudden change gets at once (Wagner's
    phi(0)). At the next (sampled) step the second-order backward difference weighs Gamma_{n-1} by -2/h,
    and Eq. (23) summed over the chord turns dGamma/dt into lift with the first moment (3/4 + 1/(4M)) c
    (aero_fmu/uvlm.py): Delta C_L = (3/4 + 1/(4M)) 2 (c/(hV)) eps phi C_L,qs with C_L,qs = 4 pi k h0/c, in
    phase with the heave rate like the dominant term, so it raises the amplitude. The difference of an
    O(h^2) input error over one step makes it O(h): about 3 k^2 phi / M of C_L,qs."""
    eps = 1 - np.cos(2 * k / M)
    change = (0.75 + 0.25 / M) * 2 * M * eps * wagner_start * 4 * np.pi * k * h0_over_c
    return change / abs(heave_theory(k, h0_over_c))


def test_theodorsen_heave_multirate():
    """k = 0.25, M = 10: communication step 2h = 0.2 s with aero.step = h = 0.1 s against the single-rate
    run at h (tests/units/test_aero_unsteady.py: +0.89%, 1.26 deg from Theodorsen) and Theodorsen. Measured:
    multi-rate +1.76%, +1.28 deg from Theodorsen; |z_multi - z_single| / |z_single| = 0.86%, the amplitude
    larger as estimated (interpolation_effect: 1.39%). First order in h as estimated: M = 20 (h = 0.05 s,
    2h = 0.1 s) gives 0.44% (estimate 0.69%). The single-rate run at 2h (what one aero step per
    communication step would give) is -6.6%, -3.3 deg off. Required: Theodorsen's 3% and 3 deg as the
    single-rate test; the difference below the estimate, amplitude larger."""
    M, h = 10, 0.1
    single, multi = heave_run(M, h, None), heave_run(M, 2 * h, h)
    assert_heave_matches(multi, heave_theory(0.25, 0.1), 0.03, 3.0)
    assert abs(multi - single) / abs(single) < interpolation_effect(0.25, M, 0.1)
    assert abs(multi) > abs(single)


# ---------------------------------------------------------------------------------------------- 4
def test_state_restores_the_previous_inputs_bit_for_bit():
    """uvlm-free with 3 aero steps per communication step: save at t = 0.6, advance to 0.8, then to 1.0
    (which replaces the previous inputs), restore, advance to 0.8 again: bit-identical to the first time.
    The restored state must carry the inputs at 0.6, the start of the interpolation; it also survives a
    pickle round trip (the FMU serializes its states so) and the caller's copy does not leak in."""
    scene = small_wing("uvlm-free", step=0.2 / 3)
    inputs = structure_inputs(scene, [0.2 * j for j in range(1, 6)])
    aero = driven(scene, inputs[:3])
    saved = aero.get_state()
    aero.advance(*inputs[3])
    first = AeroSolver(AeroUnitSpec.from_scene(scene))
    first.set_state(aero.get_state())
    aero.advance(*inputs[4])
    assert not np.array_equal(aero.Q, first.Q)
    for state in (saved, pickle.loads(pickle.dumps(saved))):
        aero.set_state(state)
        state.inputs[0][:] = np.nan                     # the caller's copy: must not leak in
        aero.advance(*inputs[3])
        assert_same_state(aero, first)
    restored = saved.copy()
    restored.inputs = None                              # without the previous inputs: another result
    aero.set_state(restored)
    aero.advance(*inputs[3])
    assert not np.array_equal(aero.Q, first.Q)


# ---------------------------------------------------------------------------------------------- 5
@pytest.mark.parametrize("value", ["0", "-1", "x", '"x"', "true", "nan"])
def test_bad_aero_step_is_refused_naming_the_key(value):
    """What a user sees: `--set aero.step=...` on the heaving-wing scene fails to load with a SceneError
    naming aero.step and what is allowed; so does resolving a scene given as a dict."""
    with pytest.raises(SceneError, match=r"aero\.step.*> 0") as err:
        load_scene(SCENES / "heaving_wing.toml", [f"aero.step={value}"])
    assert err.value.key == "aero.step"
    raw = {"time": {"stop": 1.0}, "aero": {"model": "uvlm-flat", "step": parse_value(value)}}
    with pytest.raises(SceneError, match=r"aero\.step"):
        resolve_scene(raw, default_name="bad")
    scene = small_wing("uvlm-flat")
    for bad in (0, -1.0, "x", True, float("nan"), float("inf")):
        scene["aero"]["step"] = bad
        with pytest.raises(SceneError, match=r"aero\.step.*> 0"):
            resolve_scene(scene, default_name="bad")


def test_good_aero_step_loads_and_defaults_to_absent():
    scene = load_scene(SCENES / "heaving_wing.toml", ["aero.step=0.05"])
    assert scene["aero"]["step"] == 0.05 and AeroSolver(AeroUnitSpec.from_scene(scene)).step == 0.05
    scene = load_scene(SCENES / "heaving_wing.toml")
    assert scene["aero"].get("step") is None and AeroSolver(AeroUnitSpec.from_scene(scene)).step is None
