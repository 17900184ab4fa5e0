"""Natural frequencies of the structure linearized about its current configuration, in any fidelity.

Small motions obey M dq'' + K_t dq = 0 on the tangent space of the constraints, G_q dq = 0, with M the
model's mass matrix on its coordinates q and K_t its tangent stiffness there: generalized-alpha's iteration
matrix without the mass and damping terms (ANCF: T^T (K_E + sum lambda_i H_i) T; strain-based: the constant K
plus B^T K_E B and the joint parameters' constraint term). Writing dq = N z with N an orthonormal basis of the
null space of G_q gives the reduced generalized eigenproblem (N^T K_t N) z = omega^2 (N^T M N) z.
"""
import numpy as np
from scipy.linalg import eigh, null_space


def natural_modes(solver):
    """The natural modes of `solver`'s structure at its current state: every mode of the tangent space.

    Args:
        solver: a StructureSolver.

    Returns:
        (omega (k,) rad/s ascending, shapes (n_q, k)): the shapes on its coordinates q, mass-normalized
        (shapes^T M shapes = I).
    """
    model, state = solver.model, solver.state
    q, still = state.q, np.zeros_like(state.q)
    K, E = model.iteration_matrix(state.t, q, still, state.latched, state.multipliers, 0.0, 0.0)
    N = null_space(model.constraint_jacobian(q, E)) if model.constraint_count else np.eye(len(q))
    stiffness, mass = N.T @ K @ N, N.T @ model.mass_matrix(q, state.t) @ N
    eigenvalues, z = eigh(0.5 * (stiffness + stiffness.T), mass)
    return np.sqrt(np.clip(eigenvalues, 0.0, None)), N @ z


def natural_frequencies(solver, count=6):
    """The `count` lowest natural frequencies (rad/s) of `solver`'s structure at its current state.

    Args:
        solver: a StructureSolver.
        count: how many; None: all of them.
    """
    omega, _ = natural_modes(solver)
    return omega if count is None else omega[:count]
