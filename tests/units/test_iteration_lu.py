"""The factorization of generalized-alpha's iteration matrix (structure_fmu/iteration_lu.py), the model's reduced
tangent T^T X T and the Newton iteration's stopping rule, each against a reference computed another way: numpy's
dense solve, the dense product with T, and the same run with every step iterated to the plain correction test."""
import numpy as np
import pytest
from repository import SCENES

from orchestrator.scene.load import load_scene
from structure_fmu import integrators
from structure_fmu.iteration_lu import IterationLU
from fmu_common.specs import StructureUnitSpec
from structure_fmu.solver import StructureSolver


def _kkt(S, G, scale):
    m = len(G)
    return np.block([[S, scale * G.T], [scale * G, np.zeros((m, m))]])


def test_banded_and_dense_solves_equal_numpy_on_a_shuffled_banded_system():
    rng = np.random.default_rng(3)
    n, m = 60, 10
    S = 10 * np.eye(n)
    for k in range(0, n - 5, 3):                      # overlapping 6 x 6 blocks: a chain of elements
        S[k:k + 6, k:k + 6] += rng.standard_normal((6, 6))
    G = np.zeros((m, n))
    for row in G:
        start = rng.integers(0, n - 3)
        row[start:start + 3] = rng.standard_normal(3)
    shuffle = rng.permutation(n)                      # the band is hidden: the ordering must find it
    S, G = S[np.ix_(shuffle, shuffle)], G[:, shuffle]
    A = _kkt(S, G, 3.0)
    b = rng.standard_normal(n + m)
    exact = np.linalg.solve(A, b)
    banded = IterationLU(n, m, A != 0)
    assert banded.banded and banded.lower < 20
    for lu in (banded, IterationLU(n, m, None)):
        x = lu.factor(S, G, 3.0).solve(b)
        assert np.abs(x - exact).max() <= 1e-12 * np.abs(exact).max()


def test_a_singular_matrix_is_refused():
    S, G = np.eye(4), np.zeros((1, 4))
    for pattern in (None, _kkt(S, np.ones((1, 4)), 1.0) != 0):
        with pytest.raises(np.linalg.LinAlgError, match="singular"):
            IterationLU(4, 1, pattern).factor(S, G, 1.0)


@pytest.mark.parametrize("scene, stop", [("spin_up", 0.05), ("rotating_beam", 0.005), ("deploy_flexible", 0.002),
                                         ("scissor_array", 0.002)])
def test_the_pattern_holds_every_entry_and_the_banded_solve_is_the_dense_one(scene, stop):
    """Along a short run (states with strain, rates and multipliers), every nonzero entry of the iteration
    matrix lies in the model's pattern, and the banded factorization solves as numpy's dense one."""
    solver = StructureSolver(StructureUnitSpec.from_scene(load_scene(SCENES / f"{scene}.toml", [f"time.stop={stop}"])))
    model, rng = solver.model, np.random.default_rng(0)
    lu = IterationLU(len(solver.state.q), model.constraint_count, model.iteration_pattern())
    assert lu.banded
    for _ in range(2):
        solver.advance(solver.time + stop / 2)
        state = solver.state
        S, E = model.iteration_matrix(state.t, state.q, state.dq, state.latched, state.multipliers, 3e5, 4e2)
        G = model.constraint_jacobian(state.q, E)
        A = _kkt(S, G, 3e5)
        outside = (A != 0) & ~model.iteration_pattern()
        assert not outside.any()
        b = rng.standard_normal(len(A))
        exact = np.linalg.solve(A, b)
        assert np.abs(lu.factor(S, G, 3e5).solve(b) - exact).max() <= 1e-9 * np.abs(exact).max()


@pytest.mark.parametrize("scene", ["spin_up", "deploy_flexible", "scissor_wing"])
def test_the_reduced_tangent_is_the_product_with_T(scene):
    """T^T X T by the coordinate map's gathers (summed where slots share a coordinate or a slider's direction
    combines them) against the dense product."""
    resolved = load_scene(SCENES / f"{scene}.toml", ["time.stop=0.001"])
    model = StructureSolver(StructureUnitSpec.from_scene(resolved)).model
    X = np.random.default_rng(1).standard_normal((model.n, model.n))
    exact = model.T.T @ X @ model.T
    assert np.abs(model.map.congruence(X) - exact).max() <= 1e-13 * np.abs(exact).max()


def test_ending_newton_on_the_estimated_error_keeps_the_solution_within_the_tolerance(monkeypatch):
    """The spin-up over 6 s with the contraction-rate estimate (most steps end after one correction) and
    with every step iterated until the plain correction test passes: the same to well inside the Newton
    tolerance, for fewer iterations."""
    def run():                                    # in communication steps, as the FMU steps it
        solver = StructureSolver(StructureUnitSpec.from_scene(load_scene(SCENES / "spin_up.toml", ["time.stop=6.0"])))
        for k in range(600):
            solver.advance(0.01 * (k + 1))
        return solver.e, solver.integrator.newton_iterations

    e, iterations = run()
    original = integrators.GeneralizedAlpha._newton

    def plain(self, *args):
        self._eta = np.inf                        # the first correction is never accepted on an estimate
        return original(self, *args)

    monkeypatch.setattr(integrators.GeneralizedAlpha, "_newton", plain)
    monkeypatch.setattr(StructureSolver, "steps_in_one_call", False)   # every step through `_newton`
    reference, plain_iterations = run()
    assert iterations < 0.8 * plain_iterations
    assert np.abs(e - reference).max() <= 1e-8 * np.abs(reference).max()
