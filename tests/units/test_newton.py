"""Generalized-alpha's Newton iteration (structure_fmu/integrators.py) converges where its iteration matrix
is not the tangent at the solution.

The case: deploy_flexible with one spanwise aero panel per body, coupled in-process (Gauss-Seidel, as the
master does) up to t = 0.1708 s, just after the latch (0.1688 s). There the step's predictor is far from the
solution, a matrix factorized at the predictor contracts Newton's corrections only by about 0.4-0.6 per
iteration, and a matrix refreshed only once per step runs out of iterations ("Newton did not converge in 30
iterations"). The reference is the root of the same step equations (Peng et al. 2019, Eqs. 23-24 with the
index-3 constraints) found by scipy's hybrid Powell method from the same predictor: the step must agree with it.
"""

import numpy as np
from scipy.optimize import root

from aero_fmu.solver import AeroSolver
from fmu_common.specs import AeroUnitSpec, StructureUnitSpec
from orchestrator.scene.load import load_scene
from structure_fmu.solver import StructureSolver
from repository import SCENES

SCENE = SCENES / "deploy_flexible.toml"


def coupled_until(scene, stop):
    """Structure and aero solvers stepped in-process with Gauss-Seidel coupling to `stop` (s): (structure,
    the aero generalized force Q held over the next step)."""
    structure, aero = StructureSolver(StructureUnitSpec.from_scene(scene)), AeroSolver(AeroUnitSpec.from_scene(scene))
    h = scene["coupling"]["step"]
    aero.advance(0.0, structure.e, structure.de)
    for k in range(round(stop / h)):
        structure.advance((k + 1) * h, aero.Q)
        aero.advance((k + 1) * h, structure.e, structure.de)
    return structure, aero.Q


def step_equations(model, integrator, state, h, Q):
    """(residual function of x = [q_{n+1}, lambda_{n+1}], its starting point): Peng et al. 2019, Eqs. (23)-(24) make
    q'_{n+1} and q''_{n+1} affine in q_{n+1} about the displacement predictor."""
    ga = integrator
    beta_p = (1 - ga.alpha_m) / (h * h * ga.beta * (1 - ga.alpha_f))
    gamma_p = ga.gamma / (h * ga.beta)
    q0, dq0, ddq0, _ = ga._predictor(state, h, "displacement")
    n, t = len(q0), state.t + h

    def residual(x):
        q, lam = x[:n], x[n:]
        dq, ddq = dq0 + gamma_p * (q - q0), ddq0 + beta_p * (q - q0)
        F, E, _, _ = model.force_q(q, dq, t, Q, state.latched)
        dynamics = model.mass_q @ ddq - F + model.constraints.jacobian(E).T @ lam
        return np.concatenate([dynamics / beta_p, model.constraints.residual(E)])

    return residual, np.concatenate([q0, state.multipliers])


def test_generalized_alpha_step_after_the_latch_converges_to_the_root_of_its_equations():
    scene = load_scene(SCENE, overrides=["aero.spanwise_panels=1"])
    structure, Q = coupled_until(scene, 0.170)
    assert structure.state.latched.get("fold"), "the case is meant to start just after the latch"
    model, integrator = structure.model, structure.integrator
    taken = []                                           # (state, h, new state) of each internal step

    def recorded_step(model, state, h, Q):
        start = state.copy()
        new = type(integrator).step(integrator, model, state, h, Q)
        taken.append((start, h, new))
        return new

    integrator.step = recorded_step
    structure.steps_in_one_call = False          # each step through `step`, recorded (the call takes the same steps)
    structure.advance(0.171, Q)                          # 0.1700 -> 0.1710 s, as the coupled run steps it
    assert len(taken) == 5
    for state, h, new in taken:
        residual, start = step_equations(model, integrator, state, h, Q)
        reference = root(residual, start, method="hybr", options={"xtol": 1e-13})
        assert reference.success, reference.message
        n = len(state.q)
        assert np.abs(new.q - reference.x[:n]).max() <= 1e-8 * np.abs(reference.x[:n]).max()
