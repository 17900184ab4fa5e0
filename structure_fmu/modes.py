"""Natural frequencies of the structure linearized about its initial configuration.

Small motions obey M_q dq'' + K_q dq = 0 on the tangent space of the constraints, G_q dq = 0, with
K_q = T^T (K_E + sum lambda_i H_i) T (K_E the elastic tangent stiffness, lambda = 0 at an unloaded
initial state). Writing dq = N z with N an orthonormal basis of the null space of G_q gives the reduced
generalized eigenproblem (N^T K N) z = omega^2 (N^T M N) z.
"""
import numpy as np
from scipy.linalg import eigh, null_space


def natural_modes(solver):
    """(omega (k,) rad/s ascending, shapes (n_q, k)) of `solver`'s structure at its current state: every
    mode of the tangent space, the shapes on the free coordinates q and mass-normalized
    (shapes^T M_q shapes = I)."""
    model = solver.model
    state = solver.state
    E, dE, _ = model.coordinates(state.q, np.zeros_like(state.q), state.t)
    K, _ = model.tangent_E(E, np.zeros_like(dE), state.latched)
    if model.constraints.count:
        K = K + model.constraints.hessian_sum(state.multipliers, E)
        N = null_space(model.constraints.jacobian(E))
    else:
        N = np.eye(len(state.q))
    T = model.T @ N
    stiffness, mass = T.T @ K @ T, N.T @ model.mass_q @ N
    eigenvalues, z = eigh(0.5 * (stiffness + stiffness.T), mass)
    return np.sqrt(np.clip(eigenvalues, 0.0, None)), N @ z


def natural_frequencies(solver, count=6):
    """The `count` lowest natural frequencies (rad/s) of `solver`'s structure at its current state
    (all of them if count is None)."""
    omega, _ = natural_modes(solver)
    return omega if count is None else omega[:count]
