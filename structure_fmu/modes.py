"""Natural frequencies of the structure linearized about its initial configuration.

Small motions obey M_q dq'' + K_q dq = 0 on the tangent space of the constraints, G_q dq = 0, with
K_q = T^T (K_E + sum lambda_i H_i) T (K_E the elastic tangent stiffness, lambda = 0 at an unloaded
initial state). Writing dq = N z with N an orthonormal basis of the null space of G_q gives the reduced
generalized eigenproblem (N^T K N) z = omega^2 (N^T M N) z.
"""
import numpy as np
from scipy.linalg import eigh, null_space


def natural_frequencies(solver, count=6):
    """The `count` lowest natural frequencies (rad/s) of `solver`'s structure at its current state
    (all of them if count is None)."""
    model = solver.model
    state = solver.state
    E, dE, _ = model.coordinates(state.q, np.zeros_like(state.q), state.t)
    K, _ = model.tangent_E(E, np.zeros_like(dE), state.latched)
    if model.constraints.count:
        K = K + model.constraints.hessian_sum(state.multipliers)
        N = null_space(model.constraints.jacobian(E))
    else:
        N = np.eye(len(state.q))
    T = model.T @ N
    stiffness, mass = T.T @ K @ T, N.T @ model.mass_q @ N
    eigenvalues = eigh(0.5 * (stiffness + stiffness.T), mass, eigvals_only=True)
    return np.sqrt(np.clip(eigenvalues if count is None else eigenvalues[:count], 0.0, None))
