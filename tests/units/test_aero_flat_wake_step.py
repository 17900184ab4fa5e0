"""The flat-wake UVLM step in one compiled call (aero_fmu/flat_wake_step.c) against its numpy reference (the lattice's
matrices, factorization.BoundSystem, vlm.pressure_jump_forces, loads.resultants; $WINGSIM_KERNELS=numpy): the same
circulations, panel forces, Q and resultants to 1e-12 relative, step after step (the circulation history of
dGamma/dt, a repeated step), on a rectangular wing, a folding two-body wing and a tapered, swept, twisted, cambered
wing folded about a skewed hinge; the same reuse of the factorization; the same refusals of degenerate lattices."""
import numpy as np
import pytest

from aero_fmu import flat_wake_step
from aero_fmu.factorization import BoundSystem
from aero_fmu.flat_wake_step import FlatWakeStep
from aero_fmu.solver import AeroSolver
from fmu_common.errors import SolverDiverged
from fmu_common.specs import AeroUnitSpec, StructureUnitSpec
from flat_wing import wing_scene
from orchestrator.scene.load import load_scene
from planform_wing import folded_wing_scene
from repository import ROOT
from structure_fmu.solver import StructureSolver

TOLERANCE = 1e-12


@pytest.fixture(params=["kernel LU", "LAPACK LU"])
def factorization(request, monkeypatch):
    """The compiled step factorizes in the kernel (small lattices) or with LAPACK (COMPILED_LU_PANELS = 0)."""
    if request.param == "LAPACK LU":
        monkeypatch.setattr(flat_wake_step, "COMPILED_LU_PANELS", 0)
    return request.param


def both_paths(scene, kernels):
    """(reference AeroSolver on the numpy path, AeroSolver on the compiled step) of one scene."""
    kernels("numpy")
    reference = AeroSolver(AeroUnitSpec.from_scene(scene))
    kernels("compiled")
    compiled = AeroSolver(AeroUnitSpec.from_scene(scene))
    assert isinstance(reference.model.system, BoundSystem)
    assert isinstance(compiled.model.system, FlatWakeStep), "the compiled step did not load"
    return reference, compiled


def relative_error(a, b):
    """max |a - b| / max |b|."""
    a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    return float(np.abs(a - b).max() / np.abs(b).max())


def assert_same_step(reference, compiled):
    """Circulations, panel forces and their points, ring corners (against their largest entries), Q, and the
    resultants to TOLERANCE. Q = S_a^T f and the resultants are sums of the panel forces that cancel in part, so
    each is measured against the sum of the magnitudes it adds, the scale of its round-off: Q against |S_a|^T |f|,
    the forces against the sum of |f|, the moments against the sum of |x| |f|."""
    r, c = reference.state, compiled.state
    for name, a, b in (("gamma", c.gamma, r.gamma), ("forces", c.loads.forces, r.loads.forces),
                       ("points", c.loads.points, r.loads.points), ("corners", c.corners, r.corners)):
        assert relative_error(a, b) <= TOLERANCE, name
    forces, points = r.loads.forces, r.loads.points
    magnitudes = np.abs(reference.lattice.application_matrix).T @ np.abs(forces)        # (n_slots, 3)
    assert np.abs(c.loads.Q - r.loads.Q).max() <= TOLERANCE * magnitudes.max(), "Q"
    force_scale = np.linalg.norm(forces, axis=1).sum()
    moment_scale = (np.linalg.norm(points, axis=1) * np.linalg.norm(forces, axis=1)).sum()
    q_area = reference.outputs()["lift"] / reference.outputs()["CL"] if reference.outputs()["CL"] else None
    for name, value in reference.outputs().items():
        scale = moment_scale if name.startswith("moment") else force_scale
        if name in ("CL", "CD"):
            scale = force_scale / q_area
        assert abs(compiled.outputs()[name] - value) <= TOLERANCE * scale, name
    assert compiled.outputs()["wake_panels"] == reference.outputs()["wake_panels"]


def prescribed_run(scene, kernels, steps=8, dt=0.05):
    """(reference, compiled, structure) after `steps` steps of the scene's prescribed motion, each step checked
    equal on both paths."""
    reference, compiled = both_paths(scene, kernels)
    structure = StructureSolver(StructureUnitSpec.from_scene(scene))
    for k in range(1, steps + 1):
        structure.advance(dt * k)
        for aero in (reference, compiled):
            aero.advance(dt * k, structure.e, structure.de)
        assert_same_step(reference, compiled)
    return reference, compiled, structure


def deformed(E0, k):
    """E0 moved and deformed a little differently at each k: every lattice point and tangent moves, not rigidly."""
    index = np.arange(E0.size)
    return E0 + 2e-5 * k * np.sin(index + 0.7 * k), 0.05 * np.cos(index - 0.3 * k)


@pytest.mark.parametrize("wake_length", [np.inf, 20.0])
def test_rectangular_wing_in_heave_and_pitch_equals_the_reference(kernels, wake_length):
    """A rectangular wing (span 4 c, 3 x 4 panels) heaving and pitching (prescribed), its horseshoes semi-infinite
    or 20 chords long: eight steps (dGamma/dt first then second order, the wake's legs turning against the wing, so
    the matrices are rebuilt) and a repeated last step with other coordinates, equal on both paths."""
    scene = wing_scene("uvlm-flat", {"heave_amplitude": 0.1, "pitch_amplitude_deg": 4.0, "frequency": 2.0},
                       span=4.0, M=3, N=4, wake_length=wake_length)
    reference, compiled, structure = prescribed_run(scene, kernels)
    assert np.abs(reference.state.loads.forces).max() > 0.01      # a wing that lifts
    for aero in (reference, compiled):
        aero.advance(0.4, structure.e + 1e-3, structure.de)          # the last step again, other inputs
    assert_same_step(reference, compiled)
    assert compiled.model.system.builds == reference.model.system.builds == 9


def test_heaving_wing_reuses_its_factorization_as_the_reference_does(kernels):
    """A wing that only heaves moves rigidly with its horseshoes: both paths factorize once in eight steps (the
    compiled step's distance test, then the Kabsch fit), with the same loads."""
    scene = wing_scene("uvlm-flat", {"heave_amplitude": 0.1, "frequency": 2.0}, span=4.0, M=3, N=4)
    reference, compiled, _ = prescribed_run(scene, kernels)
    assert compiled.model.system.builds == reference.model.system.builds == 1


@pytest.mark.parametrize("scene_name", ["deploy_rigid", "deploy_flexible"])
def test_folding_wing_deforming_step_after_step_equals_the_reference(kernels, scene_name):
    """The shipped deployments' lattices (two bodies, 2 x 7 panels each, horseshoes 5 chords long), their nodes
    and slopes moved differently at every step (no rigid motion: a build per step), and three steps at rest
    (the factorization reused): equal on both paths."""
    scene = load_scene(ROOT / "scenes" / f"{scene_name}.toml")
    reference, compiled = both_paths(scene, kernels)
    E0 = reference.topology.initial_coordinates()
    for k in range(1, 7):
        e, de = deformed(E0, k)
        for aero in (reference, compiled):
            aero.advance(1e-3 * k, e, de)
        assert_same_step(reference, compiled)
    for k in range(7, 10):
        for aero in (reference, compiled):
            aero.advance(1e-3 * k, e, de)
        assert_same_step(reference, compiled)
    assert compiled.model.system.builds == reference.model.system.builds == 6


@pytest.mark.parametrize("wake_length", [np.inf, 3.0])
def test_folded_tapered_swept_cambered_wing_equals_the_reference(kernels, wake_length, factorization):
    """The tapered, swept, twisted, cambered wing folded about a skewed hinge (the mean surface's offsets, the
    edge form of the pressure jump on non-rectangular panels), deformed differently at each of six steps, then
    turned rigidly about an axis (the stream does not turn with it: rebuilt): equal on both paths, with either
    factorization."""
    scene = folded_wing_scene("uvlm-flat", wake_length)
    reference, compiled = both_paths(scene, kernels)
    assert compiled.model.system.lapack_lu == (factorization == "LAPACK LU")
    E0 = StructureSolver(StructureUnitSpec.from_scene(scene)).e
    for k in range(1, 7):
        e, de = deformed(E0, k)
        for aero in (reference, compiled):
            aero.advance(0.01 * k, e, de)
        assert_same_step(reference, compiled)
    angle = np.radians(3.0)
    turn = np.array([[1.0, 0.0, 0.0], [0.0, np.cos(angle), -np.sin(angle)], [0.0, np.sin(angle), np.cos(angle)]])
    turned = (e.reshape(-1, 3) @ turn.T).ravel()
    for aero in (reference, compiled):
        aero.advance(0.07, turned, de)
    assert_same_step(reference, compiled)
    assert compiled.model.system.builds == reference.model.system.builds == 7


def test_degenerate_lattices_are_refused_as_the_reference_refuses_them(kernels, factorization):
    """A body collapsed to zero chord (zero-area panels) and a tip body laid onto the inner body (coinciding
    collocation points: a singular influence matrix) raise SolverDiverged with the reference's reason on both
    paths, with either factorization; the state stays that of the last good step, and the next good step equals
    the reference."""
    scene = load_scene(ROOT / "scenes" / "deploy_rigid.toml")
    reference, compiled = both_paths(scene, kernels)
    assert compiled.model.system.lapack_lu == (factorization == "LAPACK LU")
    E0 = reference.topology.initial_coordinates()
    for aero in (reference, compiled):
        aero.advance(1e-3, E0, np.zeros_like(E0))
    flat = E0.reshape(-1, 3, 3).copy()
    flat[:, 2] = 0.0                                              # r_y = 0: no chord
    nodes = reference.topology.n_nodes
    stacked = E0.reshape(-1, 9).copy()
    stacked[nodes // 2:] = stacked[:nodes // 2]                   # the outer body's nodes on the inner body's
    for bad, reason in ((flat.ravel(), "has zero area"), (stacked.ravel(), "two collocation points coincide")):
        messages = []
        for aero in (reference, compiled):
            with pytest.raises(SolverDiverged) as refused:
                aero.advance(2e-3, bad, np.zeros_like(E0))
            messages.append(str(refused.value))
            assert aero.time == 1e-3
        assert reason in messages[1] and messages[0] == messages[1]
    e, de = deformed(E0, 2)
    for aero in (reference, compiled):
        aero.advance(2e-3, e, de)
    assert_same_step(reference, compiled)


def test_the_numpy_kernels_select_the_reference_path(kernels):
    """$WINGSIM_KERNELS=numpy builds the flat-wake UVLM on the numpy path (factorization.BoundSystem); the shed-wake
    models never take the compiled flat step."""
    scene = wing_scene("uvlm-flat", {"heave_amplitude": 0.1, "frequency": 2.0}, span=4.0, M=3, N=4)
    kernels("numpy")
    assert isinstance(AeroSolver(AeroUnitSpec.from_scene(scene)).model.system, BoundSystem)
    kernels("compiled")
    shed = wing_scene("uvlm-prescribed", {"heave_amplitude": 0.1, "frequency": 2.0}, span=4.0, M=3, N=4)
    assert isinstance(AeroSolver(AeroUnitSpec.from_scene(shed)).model.system, BoundSystem)
