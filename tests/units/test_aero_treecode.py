"""The free wake's far-field treecode (aero_fmu/treecode.py) against the exact cored Biot-Savart sum: the error
bound of the monopole-dipole expansion on random and wake-like segment sets, its order, the compiled kernel
against the numpy reference, threads against one thread, a free-wake run's CL against the exact sum's, and the
scene keys that select it."""
import numpy as np
import pytest

from aero_fmu import treecode
from aero_fmu import wake as wakes
from aero_fmu.biot_savart import induced_velocity
from aero_fmu.solver import AeroSolver
from flat_wing import wing_scene
from fmu_common.errors import SceneError
from fmu_common.specs import AeroUnitSpec, StructureUnitSpec
from orchestrator.scene.load import resolve_scene
from structure_fmu.solver import StructureSolver

RNG = np.random.default_rng(32)


def random_segments(S, spread=(4.0, 1.0, 0.3), length=0.05):
    """(starts, ends, gamma) of S short segments of random direction and circulation in a flattened cloud."""
    starts = RNG.normal(size=(S, 3)) * spread
    return starts, starts + RNG.normal(size=(S, 3)) * length, RNG.normal(size=S)


def sheet_wake(rows=120, span_rings=16):
    """A wavy shed wake of `rows` x `span_rings` rings, one chord per 4 rows, its circulation elliptic along the span
    and varying along the wake: (ShedWake, its live segments (starts, ends, gamma))."""
    x, y = np.arange(rows + 1) * 0.25, np.linspace(0.0, 8.0, span_rings + 1)
    X, Y = np.meshgrid(x, y, indexing="ij")
    corners = np.stack([X, Y, 0.2 * np.sin(0.7 * X) * np.cos(0.4 * Y)], axis=-1)[None]
    along = np.sqrt(1.0 - np.linspace(-0.95, 0.95, span_rings) ** 2)
    gamma = along[None, None, :] * (1.0 + 0.3 * np.cos(0.3 * np.arange(rows)))[None, :, None]
    wake = wakes.ShedWake(corners, gamma)
    return wake, wakes.live_segments(wake)


@pytest.mark.parametrize("kind", ["numpy", "compiled"])
@pytest.mark.parametrize("core", [0.0, 0.02])
def test_the_treecode_error_stays_within_its_truncation_bound_on_random_segments(kernels, kind, core):
    """|v_tree - v_exact| <= bound at every point (the expansion's remainder 3 rho^2 sum|alpha| / (4 pi (d - rho)^4)
    plus the core's delta sum|alpha| / (8 pi (d - rho)^3) per far cluster), v_exact the cored sum over every
    segment; the far field is used (bound > 0) and a smaller opening parameter is more accurate."""
    kernels(kind)
    starts, ends, gamma = random_segments(3000)
    points = RNG.normal(size=(400, 3)) * (4.0, 1.0, 0.3)
    exact = induced_velocity(points, starts, ends, gamma, core)
    tree = treecode.build(starts, ends, gamma)
    errors = {}
    for theta in (0.7, 0.5, 0.3):
        v, bound = treecode.velocity(points, tree, core, theta)
        error = np.linalg.norm(v - exact, axis=1)
        assert np.all(error <= bound)
        assert np.count_nonzero(bound) > 0.9 * len(points)
        errors[theta] = error.max()
    assert errors[0.3] < errors[0.5] < errors[0.7]


def test_the_treecode_error_stays_within_its_bound_on_a_wake_sheet_at_its_own_corners(kernels):
    """A shed wake's velocity at its own corners (the free wake's convection) with the convection core: within the
    bound at every corner, and below 1% of the largest velocity at the default opening parameter."""
    kernels("compiled")
    wake, (starts, ends, gamma) = sheet_wake()
    points, core = wake.corners.reshape(-1, 3), 0.05
    exact = induced_velocity(points, starts, ends, gamma, core)
    v, bound = treecode.velocity(points, treecode.build(starts, ends, gamma), core, 0.3)
    error = np.linalg.norm(v - exact, axis=1)
    assert np.all(error <= bound)
    assert error.max() < 1e-2 * np.linalg.norm(exact, axis=1).max()


def test_the_expansion_error_falls_as_the_fourth_power_of_the_distance():
    """Two segments of one leaf seen from d and 2 d along a direction off their axes: the monopole-dipole error
    (second-order Taylor remainder) falls as d^-4, 16 times per doubling, while the velocity falls as d^-2."""
    starts = np.array([[0.0, 0.0, 0.0], [0.1, 0.05, 0.0]])
    ends = np.array([[0.0, 0.2, 0.0], [0.1, 0.05, 0.15]])
    gamma = np.array([1.0, -0.6])
    tree = treecode.build(starts, ends, gamma)
    direction = np.array([[0.6, 0.48, 0.64]])
    errors = []
    for d in (4.0, 8.0, 16.0):
        v, _ = treecode.velocity(d * direction, tree, 0.0, 0.5)
        errors.append(np.linalg.norm(v - induced_velocity(d * direction, starts, ends, gamma)))
    ratios = np.array(errors[:-1]) / np.array(errors[1:])
    assert np.all(np.abs(ratios / 16.0 - 1.0) < 0.1), ratios


def test_a_small_opening_parameter_sums_every_segment_exactly(kernels):
    """With theta so small that no cluster is far, the treecode is the exact sum (to round-off) and its bound 0."""
    kernels("compiled")
    starts, ends, gamma = random_segments(500)
    points = RNG.normal(size=(50, 3))
    v, bound = treecode.velocity(points, treecode.build(starts, ends, gamma), 0.01, 1e-6)
    exact = induced_velocity(points, starts, ends, gamma, 0.01)
    assert np.abs(v - exact).max() <= 1e-12 * np.abs(exact).max()
    assert np.all(bound == 0.0)


def test_the_compiled_treecode_equals_the_numpy_reference(kernels):
    """Velocity and bound of the C kernel against its numpy reference, on a wake sheet: 1e-12 relative (of the
    largest value; only the order of the sums differs)."""
    wake, (starts, ends, gamma) = sheet_wake(rows=60)
    points, tree = wake.corners.reshape(-1, 3), treecode.build(starts, ends, gamma)
    results = {}
    for kind in ("numpy", "compiled"):
        kernels(kind)
        results[kind] = treecode.velocity(points, tree, 0.05, 0.4)
    for a, b in zip(results["compiled"], results["numpy"]):
        assert np.abs(a - b).max() <= 1e-12 * np.abs(b).max()


def test_threads_give_the_one_thread_result_bit_for_bit(kernels, monkeypatch):
    """The points split over threads: each point is evaluated on one thread in the same order, so 1, 2 and 3
    threads give the same bits."""
    kernels("compiled")
    starts, ends, gamma = random_segments(4000)
    points = RNG.normal(size=(2000, 3)) * (4.0, 1.0, 0.3)
    assert len(points) * len(starts) >= treecode.THREADED_PAIRS
    tree, results = treecode.build(starts, ends, gamma), []
    for threads in ("1", "2", "3"):
        monkeypatch.setenv("WINGSIM_THREADS", threads)
        results.append(treecode.velocity(points, tree, 0.01, 0.5))
    for v, bound in results[1:]:
        assert np.array_equal(v, results[0][0]) and np.array_equal(bound, results[0][1])


def test_a_thread_count_that_is_not_a_positive_integer_is_refused_naming_the_variable(kernels, monkeypatch):
    kernels("compiled")
    starts, ends, gamma = random_segments(2000)
    monkeypatch.setenv("WINGSIM_THREADS", "0")
    with pytest.raises(ValueError, match="WINGSIM_THREADS"):
        treecode.velocity(RNG.normal(size=(1000, 3)), treecode.build(starts, ends, gamma), 0.0, 0.5)


def test_an_opening_parameter_outside_zero_to_one_is_refused():
    starts, ends, gamma = random_segments(10)
    with pytest.raises(ValueError, match="theta"):
        treecode.velocity(np.zeros((1, 3)), treecode.build(starts, ends, gamma), 0.0, 1.0)


def free_wake_cl(far_field, steps, M=4, N=16):
    """C_L history of the AR-8 flat plate at 5 deg started impulsively with the free wake (the PteraSoftware peer
    case, benchmarks/peer_pterasoftware.py), dt = c / (M V), the whole wake kept."""
    body = {"name": "wing", "span_axis": [0, 1, 0], "chord_axis": [1, 0, 0],
            "section": {"thickness": 0.01, "density": 100.0, "youngs_modulus": 1e9, "torsional_rigidity": 1.0}}
    dt = 1.0 / (M * 10.0)
    scene = resolve_scene({"time": {"stop": steps * dt}, "coupling": {"step": dt},
                           "structure": {"fidelity": "prescribed", "bodies": [body]},
                           "wing": {"chord": 1.0, "aspect_ratio": 8.0, "alpha_deg": 5.0},
                           "flow": {"speed": 10.0, "density": 1.2},
                           "aero": {"model": "uvlm-free", "chordwise_panels": M, "spanwise_panels": N,
                                    "wake_length": float("inf"), "wake_far_field": far_field}}, "plate")
    structure, aero = StructureSolver(StructureUnitSpec.from_scene(scene)), AeroSolver(AeroUnitSpec.from_scene(scene))
    history = []
    for k in range(1, steps + 1):
        structure.advance(k * dt)
        aero.advance(k * dt, structure.e, structure.de)
        history.append(aero.outputs()["CL"])
    return np.array(history)


def test_a_free_wake_run_with_the_treecode_keeps_cl_within_a_thousandth_of_the_exact_sum(kernels):
    """The default (treecode, theta = 0.3) against every segment summed: C_L within 0.1% of the exact run's at
    every step of 60 (15 chords of travel, 61 x 17 wake corners)."""
    kernels("compiled")
    exact, tree = free_wake_cl("exact", 60), free_wake_cl("treecode", 60)
    assert 0.0 < np.abs(tree - exact).max() <= 1e-3 * np.abs(exact[-1])      # the far field was used


def test_the_far_field_scene_keys_are_validated_naming_the_key():
    base = wing_scene("uvlm-free", {"heave_amplitude": 0.1, "frequency": 0.5}, M=2, N=2)
    assert base["aero"]["wake_far_field"] == "treecode" and base["aero"]["wake_opening"] == 0.3
    body = {"name": "wing", "length": 4.0, "span_axis": [0, 1, 0], "chord_axis": [1, 0, 0],
            "section": {"chord": 1.0, "thickness": 0.01, "density": 100.0, "youngs_modulus": 1e9,
                        "torsional_rigidity": 1.0}}
    for key, value in (("wake_opening", 1.0), ("wake_opening", 0.0), ("wake_far_field", "fmm")):
        with pytest.raises(SceneError, match=rf"aero\.{key}"):
            resolve_scene({"time": {"stop": 1.0}, "structure": {"fidelity": "prescribed", "bodies": [body],
                                                                "motion": {"heave_amplitude": 0.1}},
                           "aero": {"model": "uvlm-free", key: value}, "flow": {"speed": 1.0}}, "wing")
