"""The scene's named choices (structure.fidelity, aero.model, structure.integrator): their names, the schema's
options, and what the shared code and the master ask of each.

Both units and the master read these traits instead of comparing names: the topology both units build asks
whether a fidelity's bodies deform (structure.elements_per_body elements each, Otsuka et al. 2019, Sec. IV),
the scissor chains whether its pins may hold any node, the size bounds whether an aero model has chordwise
panels or sheds a wake. How a unit realizes a choice is its own registry's: the structural models in
`structure_fmu.fidelities`, the time integrators in `structure_fmu.integrators`, the aero models in
`aero_fmu.models`, each keyed by these names (tests check that they agree).
"""
from __future__ import annotations

from dataclasses import dataclass

from .errors import SceneError


@dataclass(frozen=True)
class Fidelity:
    """A structural fidelity: `moved_by_law`, every body moves rigidly by structure.motion and no structural
    solver runs (prescribed); `deformable`, its bodies have structure.elements_per_body elements, free nodes
    and damping of deformation (the others one element per body, whose |r_x| stays 1: Otsuka et al. 2019,
    Eq. 17); `nodes_anywhere`, its pins and sliders may hold any node (scissor chains need it; else a pin
    holds a root to the ground); `shear_deformable`, its elements strain in shear and across the chord (Peng et
    al. 2019): a node's r_y is free (no unit-length and orthogonality rows, Otsuka et al. 2019, Eq. 6) and its
    sections are plates (the continuum is integrated over the plate's chord and thickness)."""

    name: str
    moved_by_law: bool
    deformable: bool
    nodes_anywhere: bool
    shear_deformable: bool = False


@dataclass(frozen=True)
class AeroModel:
    """An aero model: `builds_unit`, an aero unit is built (not for none); `chordwise`, M vortex rings along
    the chord (strip theory: one strip per spanwise panel); `sheds_wake`, a ring wake row is shed at each step
    (its rows are capped, their memory counted)."""

    name: str
    builds_unit: bool
    chordwise: bool
    sheds_wake: bool


FIDELITIES = {f.name: f for f in (
    Fidelity("prescribed", moved_by_law=True, deformable=False, nodes_anywhere=False),
    Fidelity("rigid", moved_by_law=False, deformable=False, nodes_anywhere=True),
    Fidelity("flexible", moved_by_law=False, deformable=True, nodes_anywhere=True),
    Fidelity("shear-deformable", moved_by_law=False, deformable=True, nodes_anywhere=True, shear_deformable=True),
    Fidelity("strain-based", moved_by_law=False, deformable=True, nodes_anywhere=False),
)}
"""structure.fidelity: name -> Fidelity, in the order docs/scenes.md lists them."""

AERO_MODELS = {m.name: m for m in (
    AeroModel("none", builds_unit=False, chordwise=False, sheds_wake=False),
    AeroModel("strip", builds_unit=True, chordwise=False, sheds_wake=False),
    AeroModel("uvlm-flat", builds_unit=True, chordwise=True, sheds_wake=False),
    AeroModel("uvlm-prescribed", builds_unit=True, chordwise=True, sheds_wake=True),
    AeroModel("uvlm-free", builds_unit=True, chordwise=True, sheds_wake=True),
)}
"""aero.model: name -> AeroModel."""

INTEGRATORS = ("rk4", "generalized-alpha")
"""structure.integrator: the names of `structure_fmu.integrators.INTEGRATORS`."""


def fidelity(name: str) -> Fidelity:
    """The Fidelity of structure.fidelity `name`; SceneError naming the key for an unknown one.

    Args:
        name: the fidelity's name, e.g. "rigid".
    """
    if name not in FIDELITIES:
        raise SceneError("structure.fidelity", name, f"one of {', '.join(map(repr, FIDELITIES))}")
    return FIDELITIES[name]


def aero_model(name: str) -> AeroModel:
    """The AeroModel of aero.model `name`; SceneError naming the key for an unknown one.

    Args:
        name: the aero model's name, e.g. "uvlm-free".
    """
    if name not in AERO_MODELS:
        raise SceneError("aero.model", name, f"one of {', '.join(map(repr, AERO_MODELS))}")
    return AERO_MODELS[name]


def fidelity_names(which) -> str:
    """'rigid or flexible': the names of the fidelities f for which `which(f)` holds, for messages.

    Args:
        which: a predicate on a Fidelity.
    """
    return " or ".join(f.name for f in FIDELITIES.values() if which(f))
