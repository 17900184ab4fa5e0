"""The structural fidelities as the structure unit realizes them: the registry from a fidelity
(`fmu_common.choices.Fidelity`, read from structure.fidelity) to the model class that assembles it, and the
contract every such model keeps (`StructuralModel`), which the integrators and `StructureSolver` call.

  prescribed     StructureModel: every body follows structure.motion, nothing is integrated
  rigid          StructureModel: one ANCF element per body, |r_x| = 1 (Otsuka et al. 2019, Eq. 17)
  flexible       StructureModel: N ANCF elements per body with their elastic force (Otsuka et al. 2019, Eqs. 7-11)
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

    @property
    def constraint_count(self) -> int: ...

    def initial_coordinates(self) -> np.ndarray: ...

    def coordinates(self, q, dq, t) -> tuple:
        """(E, dE/dt, p'' or None) at q, q', t."""

    def mass_matrix(self, q, t) -> np.ndarray: ...

    def solve_mass(self, q, t, b) -> np.ndarray: ...

    def force_q(self, q, dq, t, Q, latched) -> tuple:
        """(the reduced force (n_q,), E, dE, p'') for the generalized force Q (n,) on E."""

    def external_force_E(self, t, Q) -> np.ndarray: ...

    def constraint_residual(self, q, E) -> np.ndarray: ...

    def constraint_violation(self, q, E) -> float: ...

    def constraint_jacobian(self, q, E) -> np.ndarray: ...

    def constraint_rate(self, q, dq, E, dE) -> np.ndarray: ...

    def constraint_gamma(self, q, dq, E, dE, ddp) -> np.ndarray: ...

    def iteration_matrix(self, t, q, dq, latched, lam, beta_p, gamma_p) -> tuple: ...

    def iteration_pattern(self) -> np.ndarray: ...

    def acceleration_E(self, q, dq, ddq, t) -> np.ndarray: ...

    def velocity_map(self, q, t) -> np.ndarray: ...

    def rates_of(self, q, dE, t) -> np.ndarray: ...

    def fold_angles(self, q, E) -> dict: ...

    def potential_energy(self, q, E, latched, angles) -> float: ...


MODELS: dict[str, type] = {"prescribed": StructureModel, "rigid": StructureModel, "flexible": StructureModel,
                           "strain-based": StrainBasedModel}
"""structure.fidelity -> the model class (a StructuralModel) built from the topology and the parameters."""


def model_class(fidelity: Fidelity) -> type:
    """The model class of `fidelity` (the one choice made by its name)."""
    return MODELS[fidelity.name]

