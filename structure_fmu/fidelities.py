"""The structural fidelities as the structure unit realizes them: the registry from a fidelity
(`fmu_common.choices.Fidelity`, read from structure.fidelity) to the model class that assembles it, and the
contract every such model keeps (`StructuralModel`), which the integrators and `StructureSolver` call.

  prescribed     StructureModel: every body follows structure.motion, nothing is integrated
  rigid          StructureModel: one ANCF element per body, |r_x| = 1 (Otsuka et al. 2019, Eq. 17)
  flexible       StructureModel: N ANCF elements per body with their elastic force (Otsuka et al. 2019, Eqs. 7-11)
  shear-deformable  StructureModel: N shear-deformable ANCF elements per body (Peng et al. 2019, Eqs. 1-10),
                 no internal constraints
  strain-based   StrainBasedModel: constant strains per element and joint parameters (Otsuka et al. 2022, Eq. 9)

What both units ask of a fidelity (its bodies' element count, whether pins may hold any node, whether a law
moves it) is its `Fidelity` traits; the topology reads those, the model class here is the only choice made by
name.
"""
from __future__ import annotations

from typing import Protocol

import numpy as np

from fmu_common.choices import Fidelity

from .model import StructureModel
from .strain_model import StrainBasedModel


class StructuralModel(Protocol):
    """M(q) q'' + Phi_q^T lambda = F(q, q', t), Phi(q, t) = 0 on the generalized coordinates q (n_q,), with the
    exchanged coordinates E = E(q, t) (n,): what the integrators (structure_fmu.integrators), the solver and
    the modes (structure_fmu.modes) ask of a model. SI units; E in the global frame."""

    hinges: list
    mass_E: np.ndarray                 # (n, n) the constant mass matrix on E (Otsuka et al. 2019, Eq. 5)
    newton_weights: np.ndarray | None  # (n_q,) factors on q in generalized-alpha's convergence test (None: 1)

    @property
    def constraint_count(self) -> int:
        """Constraint rows the integrators solve, m (the independent ones)."""

    def initial_coordinates(self) -> np.ndarray:
        """q at t = 0.

        Returns:
            (n_q,) generalized coordinates, SI units.
        """

    def coordinates(self, q, dq, t) -> tuple:
        """The exchanged coordinates and rates at a state, and the prescribed acceleration.

        Args:
            q: (n_q,) generalized coordinates.
            dq: (n_q,) their rates q', per s.
            t: time, s.

        Returns:
            (E (n,), dE/dt (n,), p'' (3 n_prescribed,) or None when nothing prescribed moves), global frame.
        """

    def mass_matrix(self, q, t) -> np.ndarray:
        """M_q, the mass matrix on q.

        Args:
            q: (n_q,) generalized coordinates.
            t: time, s.

        Returns:
            (n_q, n_q) SI.
        """

    def mass_product(self, q, t, x) -> np.ndarray:
        """M_q x, without forming M_q where it depends on q (generalized-alpha's residual).

        Args:
            q: (n_q,) generalized coordinates.
            t: time, s.
            x: (n_q,) accelerations.

        Returns:
            (n_q,) SI.
        """

    def solve_mass(self, q, t, b) -> np.ndarray:
        """M_q^-1 b.

        Args:
            q: (n_q,) generalized coordinates.
            t: time, s.
            b: (n_q,) or (n_q, k) right-hand sides.

        Returns:
            the shape of b.
        """

    def force_q(self, q, dq, t, Q, latched) -> tuple:
        """The reduced generalized force on q and the exchanged coordinates it was computed at.

        Args:
            q: (n_q,) generalized coordinates.
            dq: (n_q,) their rates, per s.
            t: time, s.
            Q: (n,) generalized external force on E, N and N m, global frame.
            latched: {hinge: latched} of the state (State.latched).

        Returns:
            (the reduced force (n_q,), E (n,), dE (n,), p'' or None).
        """

    def external_force_E(self, t, Q) -> np.ndarray:
        """The external generalized force on E: the point loads and Q.

        Args:
            t: time, s.
            Q: (n,) generalized external force on E, N and N m, global frame.

        Returns:
            (n,) N and N m, global frame.
        """

    def constraint_residual(self, q, E) -> np.ndarray:
        """Phi, the constraint rows the integrators solve.

        Args:
            q: (n_q,) generalized coordinates.
            E: (n,) the exchanged coordinates at q, global frame.

        Returns:
            (m,) one value per row, in the row's unit.
        """

    def constraint_violation(self, q, E) -> float:
        """Largest |Phi| of every row, redundant ones included (the monitor).

        Args:
            q: (n_q,) generalized coordinates.
            E: (n,) the exchanged coordinates at q, global frame.
        """

    def constraint_jacobian(self, q, E) -> np.ndarray:
        """Phi_q, the constraint Jacobian.

        Args:
            q: (n_q,) generalized coordinates.
            E: (n,) the exchanged coordinates at q, global frame.

        Returns:
            (m, n_q).
        """

    def constraint_rate(self, q, dq, E, dE) -> np.ndarray:
        """dPhi/dt.

        Args:
            q: (n_q,) generalized coordinates.
            dq: (n_q,) their rates, per s.
            E: (n,) the exchanged coordinates at q, global frame.
            dE: (n,) their rates, per s.

        Returns:
            (m,) per s.
        """

    def constraint_gamma(self, q, dq, E, dE, ddp) -> np.ndarray:
        """-(d2Phi/dt2 - Phi_q q''): the right-hand side of the acceleration-level constraints.

        Args:
            q: (n_q,) generalized coordinates.
            dq: (n_q,) their rates, per s.
            E: (n,) the exchanged coordinates at q, global frame.
            dE: (n,) their rates, per s.
            ddp: (3 n_prescribed,) the prescribed acceleration p'', or None.

        Returns:
            (m,) per s^2.
        """

    def iteration_matrix(self, t, q, dq, latched, lam, beta_p, gamma_p) -> tuple:
        """Generalized-alpha's iteration matrix without the constraint rows.

        Peng et al. 2019, Fig. 3

        Args:
            t: time, s.
            q: (n_q,) generalized coordinates.
            dq: (n_q,) their rates, per s.
            latched: {hinge: latched} of the state.
            lam: (m,) the constraint multipliers.
            beta_p: beta', 1/s^2, the factor on the mass matrix.
            gamma_p: gamma', 1/s, the factor on the damping.

        Returns:
            (S (n_q, n_q), E (n,)).
        """

    def iteration_pattern(self) -> np.ndarray:
        """The entries of the iteration matrix [[S, G^T], [G, 0]] that can be nonzero.

        Returns:
            (n_q + m, n_q + m) bool.
        """

    def acceleration_E(self, q, dq, ddq, t) -> np.ndarray:
        """d2E/dt2 for the generalized accelerations q''.

        Args:
            q: (n_q,) generalized coordinates.
            dq: (n_q,) their rates, per s.
            ddq: (n_q,) their accelerations, per s^2.
            t: time, s.

        Returns:
            (n,) per s^2, global frame.
        """

    def velocity_map(self, q, t) -> np.ndarray:
        """dE/dq.

        Args:
            q: (n_q,) generalized coordinates.
            t: time, s.

        Returns:
            (n, n_q).
        """

    def rates_of(self, q, dE, t) -> np.ndarray:
        """The q' whose exchanged rates come closest to dE (least squares).

        Args:
            q: (n_q,) generalized coordinates.
            dE: (n,) wanted rates of E, per s, global frame.
            t: time, s.

        Returns:
            (n_q,) per s.
        """

    def fold_angles(self, q, E) -> dict:
        """The fold angle of each revolute hinge.

        Args:
            q: (n_q,) generalized coordinates.
            E: (n,) the exchanged coordinates at q, global frame.

        Returns:
            {hinge: fold angle, rad}.
        """

    def element_curvatures(self, q) -> np.ndarray | None:
        """Each element's own flap curvature (n_elements,) 1/m, where the model's elements carry one of their own
        (the strain gauges reading the model's curvature take it); None where it is the cubic field of the nodal
        vectors, which the gauges read from E.

        Args:
            q: (n_q,) generalized coordinates.
        """

    def potential_energy(self, q, E, latched, angles) -> float:
        """Elastic, gravity and actuator spring potential, J.

        Args:
            q: (n_q,) generalized coordinates.
            E: (n,) the exchanged coordinates at q, global frame.
            latched: {hinge: latched} of the state.
            angles: {hinge: fold angle, rad} at E.
        """


MODELS: dict[str, type] = {"prescribed": StructureModel, "rigid": StructureModel, "flexible": StructureModel,
                           "shear-deformable": StructureModel, "strain-based": StrainBasedModel}
"""structure.fidelity -> the model class (a StructuralModel) built from the topology and the parameters."""


def model_class(fidelity: Fidelity) -> type:
    """The model class of `fidelity` (the one choice made by its name).

    Args:
        fidelity: the structure's fidelity (fmu_common.choices.Fidelity).
    """
    return MODELS[fidelity.name]

