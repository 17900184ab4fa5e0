"""Interface acceleration for implicit coupling: the next interface force Q of a communication step from
the previous iterations (``orchestrator.run.coupling.Implicit``).

Each scheme has `start()` (a new communication step) and `update(x, x_tilde) -> x_next`, where x is the Q
used by the structure in this iteration and x_tilde the Q the aero unit returned for it.
"""
from __future__ import annotations

import numpy as np

RESIDUAL_FLOOR = 1e-12
"""Smallest ||Q_new|| (N and N m) the interface residual is relative to: a still interface (Q = 0) then
converges on the absolute residual instead of dividing by zero."""


class Aitken:
    """Aitken's dynamic relaxation (Irons and Tuck 1969; for FSI Kuettler and Wall 2008, Comput. Mech. 43,
    61-72). ``start()`` at each time step; ``update(x, x_tilde)`` returns the next input from the input x
    used and the output x_tilde = H(x) it gave. The first update of a step relaxes with ``omega0``."""

    name = "aitken"

    def __init__(self, omega0: float):
        self.omega0 = float(omega0)
        self.start()

    def start(self) -> None:
        self._r, self._omega = None, self.omega0

    def update(self, x: np.ndarray, x_tilde: np.ndarray) -> np.ndarray:
        r = x_tilde - x
        if self._r is not None:
            dr = r - self._r
            denom = float(dr @ dr)
            if denom > 0.0:
                self._omega = -self._omega * float(self._r @ dr) / denom
        self._r = r
        return x + self._omega * r


class IQNILS:
    """Interface quasi-Newton with an approximation of the inverse Jacobian from a least-squares model
    (IQN-ILS: Degroote, Bathe and Vierendeels 2009, Comput. Struct. 87, 793-801; as in preCICE: Bungartz et
    al. 2016, Comput. Fluids 141, and Mehl et al. 2016, Comput. Math. Appl. 71, with the QR filter of
    Haelterman et al. 2016, Comput. Struct. 171). Only this time step's
    iterations enter (no reuse of earlier steps). With the residual r_k = x_tilde_k - x_k, the columns
    V = [r_k - r_i] and W = [x_tilde_k - x_tilde_i] over the earlier iterations i of the step, the
    coefficients alpha = argmin ||V alpha + r_k|| (by QR; columns whose R diagonal falls below
    ``filter_eps`` times their norm are dropped, newest kept first), and x_(k+1) = x_tilde_k + W alpha.
    The first iteration of a step relaxes with ``omega0``: x_1 = x_0 + omega0 r_0."""

    name = "iqn-ils"

    def __init__(self, omega0: float, filter_eps: float = 1e-10):
        self.omega0, self.filter_eps = float(omega0), float(filter_eps)
        self.start()

    def start(self) -> None:
        self._r: list[np.ndarray] = []
        self._xt: list[np.ndarray] = []

    def update(self, x: np.ndarray, x_tilde: np.ndarray) -> np.ndarray:
        r = x_tilde - x
        self._r.append(r)
        self._xt.append(np.array(x_tilde, dtype=float))
        if len(self._r) == 1:
            return x + self.omega0 * r
        # newest difference first, so that the filter keeps the newest information
        V = np.column_stack([r - ri for ri in self._r[-2::-1]])
        W = np.column_stack([x_tilde - xi for xi in self._xt[-2::-1]])
        keep: list[int] = []
        for j in range(V.shape[1]):           # QR filter: drop a column (nearly) in the span of the kept
            Q, R = np.linalg.qr(V[:, keep + [j]])
            if abs(R[-1, -1]) > self.filter_eps * max(np.linalg.norm(V[:, j]), 1e-300):
                keep.append(j)
        if not keep:
            return x + self.omega0 * r
        Q, R = np.linalg.qr(V[:, keep])
        alpha = np.linalg.solve(R, -(Q.T @ r))
        return x_tilde + W[:, keep] @ alpha


ACCELERATIONS = {"aitken": Aitken, "iqn-ils": IQNILS}
"""Scene value of ``coupling.acceleration`` -> scheme."""


def make_acceleration(coupling: dict):
    """The implicit coupling's acceleration from the resolved scene's ``coupling`` table."""
    name = coupling["acceleration"]
    if name not in ACCELERATIONS:
        raise ValueError(f"coupling.acceleration = {name!r} is not implemented; use one of {', '.join(ACCELERATIONS)}")
    return ACCELERATIONS[name](coupling["relaxation"])


def interface_residual(q_new: np.ndarray, q_used: np.ndarray) -> float:
    """||q_new - q_used|| / max(||q_new||, RESIDUAL_FLOOR) (2-norms), the implicit coupling's criterion."""
    return float(np.linalg.norm(q_new - q_used) / max(float(np.linalg.norm(q_new)), RESIDUAL_FLOOR))
