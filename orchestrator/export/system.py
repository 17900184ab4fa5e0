"""The coupled system as another tool sees it: the built FMUs, their connections and their public variables.

`coupled_system(scene, fmu_dir)` reads the model descriptions of the scene's FMUs (built by
``orchestrator.build.fmus`` into ``fmu_dir``) and returns a `System`: the components (``structure``, and ``aero``
for an aero scene or the aero unit FMU swapped in by ``wingsim export --aero``), every coupling connection
(``e[k]`` and ``de[k]`` from the structure's output to the aero unit's input, ``Q[k]`` from the aero unit's output
to the structure's input, k = 1..n, docs/architecture.md), each component's parameters with the scene's values (its
tunable keys, which may differ from the values the FMUs were built with: ``orchestrator.build.fmus.build_digest``),
the outputs a user reads (every Real output that is not a coupling variable: fold angles, latch times, probes, CL,
lift, ...), and the experiment (start 0, stop ``time.stop``, communication step ``coupling.step``, s). A
structure-only scene is the structure alone, its Q inputs held at their start value 0, as ``wingsim run`` holds
them.

``orchestrator.export.ssp`` writes this as an SSP package, ``orchestrator.export.container`` as one FMU.
"""
from __future__ import annotations

import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Sequence

from orchestrator.build.fmus import units_needed
from orchestrator.build.sources import UNITS

COUPLING = re.compile(r"^(e|de|Q)\[(\d+)\]$")
"""The names of the coupling variables: indexed blocks e, de (structure -> aero) and Q (aero -> structure)."""

FLOWS = (("e", "structure", "aero"), ("de", "structure", "aero"), ("Q", "aero", "structure"))
"""(block, from component, to component) of every coupling connection."""


class IncompatibleFMUs(RuntimeError):
    """The built FMUs cannot form the scene's coupled system; the message names the mismatch."""


@dataclass(frozen=True)
class Component:
    """One FMU of the system: ``name`` is its kind ("structure" or "aero"), ``fmu`` its file and
    ``model_description`` what fmpy reads from it."""

    name: str
    fmu: Path
    model_description: Any
    values: dict[str, float] = field(default_factory=dict)   # parameter name -> the scene's value

    def value(self, parameter) -> float:
        """The value of a parameter variable in the scene of the system: the scene's (its tunable key), else
        the FMU's start value."""
        return self.values.get(parameter.name, float(parameter.start))

    def variables(self, causality: str) -> list:
        """The Real variables of this causality, in the order the FMU declares them."""
        return [v for v in self.model_description.modelVariables if v.type == "Real" and v.causality == causality]

    @property
    def parameters(self) -> list:
        """The Real parameters (tunable scalars, docs/fmu.md), their start values as built (`value`: the
        scene's)."""
        return self.variables("parameter")

    @property
    def public_outputs(self) -> list:
        """The Real outputs that are not coupling variables: what a user plots."""
        return [v for v in self.variables("output") if not COUPLING.match(v.name)]

    def block(self, name: str, causality: str) -> list:
        """The variables ``name[1..n]`` of this causality, in index order; empty if there are none."""
        indexed = {}
        for v in self.variables(causality):
            match = COUPLING.match(v.name)
            if match and match.group(1) == name:
                indexed[int(match.group(2))] = v
        if indexed and sorted(indexed) != list(range(1, len(indexed) + 1)):
            raise IncompatibleFMUs(f"{self.fmu}: the {causality}s {name}[k] are not numbered 1..{len(indexed)}")
        return [indexed[k] for k in sorted(indexed)]

    def constant(self, name: str) -> str | None:
        """The start value of a variable (e.g. the String ``topology_hash``), None if it has none."""
        for v in self.model_description.modelVariables:
            if v.name == name:
                return v.start
        return None


@dataclass(frozen=True)
class Connection:
    """One coupling connection: ``start`` component's output ``variable`` to ``end`` component's input of
    the same name."""

    start: str
    end: str
    variable: str


@dataclass
class System:
    """The scene's coupled system (see the module docstring). Times in s."""

    name: str
    description: str
    components: list[Component]
    connections: list[Connection] = field(default_factory=list)
    start_time: float = 0.0
    stop_time: float = 1.0
    step: float = 1e-3

    def component(self, name: str) -> Component:
        return next(c for c in self.components if c.name == name)

    @property
    def unit_definitions(self) -> list:
        """The UnitDefinitions of all components, each name once (fmpy ``Unit`` objects)."""
        units: dict[str, Any] = {}
        for c in self.components:
            for unit in c.model_description.unitDefinitions:
                known = units.setdefault(unit.name, unit)
                if _base(known) != _base(unit):
                    raise IncompatibleFMUs(f"the unit {unit.name!r} is defined differently in the components' "
                                       f"model descriptions ({known.baseUnit} vs {unit.baseUnit})")
        return [units[name] for name in sorted(units)]


def _base(unit) -> tuple | None:
    base = unit.baseUnit
    return None if base is None else tuple(getattr(base, k) for k in ("kg", "m", "s", "A", "K", "mol", "cd", "rad",
                                                                        "factor", "offset"))


def coupled_system(scene: dict, fmu_dir: Path, aero: Path | None = None, variant: Sequence[str] = ()) -> System:
    """The `System` of the scene's FMUs in ``fmu_dir`` (built from ``scene``; see ``orchestrator.build.fmus``).

    Args:
        scene: the resolved scene (``--set`` overrides applied).
        fmu_dir: the folder of its FMUs.
        aero: an aero unit FMU to couple instead of ``fmu_dir``'s (``wingsim export --aero``), its parameters
            set to the scene's values; None: the scene's own (none for a structure-only scene).
        variant: the ``--set`` overrides the scene was resolved with, named in the description.

    Returns:
        The system, described by what its units say they are (their model names) and by the variant.

    Raises:
        IncompatibleFMUs: the FMUs cannot be connected (a different number of coupling variables, different
            structural topologies, ``topology_hash``) or an FMU lacks a parameter of the scene's tunable keys.
    """
    from fmpy import read_model_description

    from fmu_common.interface import fmi_name
    from orchestrator.run.units import scene_parameters

    paths = {kind: Path(fmu_dir) / UNITS[kind][0] for kind in units_needed(scene)}
    if aero is not None:
        paths["aero"] = Path(aero)
    components = []
    for kind, path in paths.items():
        values = {fmi_name(name): value for name, value in scene_parameters(kind, scene).items()}
        component = Component(kind, path, read_model_description(str(path)), values)
        missing = sorted(set(values) - {v.name for v in component.parameters})
        if missing:
            raise IncompatibleFMUs(f"{path} has no parameter {missing[0]} of the scene's tunable keys: rebuild it "
                                   "(wingsim build SCENE)")
        components.append(component)
    system = System(scene["name"], _description(scene, components, variant, aero), components, start_time=0.0,
                    stop_time=float(scene["time"]["stop"]), step=float(scene["coupling"]["step"]))
    if len(components) == 2:
        system.connections = _connections(*components)
    return system


def _description(scene: dict, components: list[Component], variant: Sequence[str], aero: Path | None) -> str:
    """What the system is: the scene's own description for the scene as its file writes it with its own units;
    for a variant, the overrides and the swapped aero FMU instead (the file's text may name another model or
    speed); then each unit's model name (its fidelity, model and lattice)."""
    changes = list(variant) + ([f"aero unit {aero.name} from {aero.parent}"] if aero is not None else [])
    head = f"{scene['name']} with {', '.join(changes)}" if changes else scene["description"] or scene["name"]
    units = "; ".join(f"{c.name}: {c.model_description.modelName}" for c in components)
    return f"{head} ({units})"


def _connections(structure: Component, aero: Component) -> list[Connection]:
    hashes = structure.constant("topology_hash"), aero.constant("topology_hash")
    if hashes[0] != hashes[1]:
        raise IncompatibleFMUs(f"{structure.fmu} and {aero.fmu} carry different structural topologies (topology_hash "
                               f"{hashes[0]} vs {hashes[1]}): build the aero unit for this structure, from the same "
                               "scene (wingsim build SCENE [--set aero.model=...] --unit aero)")
    by_name = {c.name: c for c in (structure, aero)}
    connections = []
    n = len(structure.block("e", "output"))
    for block, start, end in FLOWS:
        outputs, inputs = by_name[start].block(block, "output"), by_name[end].block(block, "input")
        if len(outputs) != n or len(inputs) != n:
            raise IncompatibleFMUs(f"{block}[k]: {start} has {len(outputs)} outputs and {end} {len(inputs)} inputs, "
                               f"but the structure has n = {n} coordinates: rebuild both FMUs from one scene")
        connections += [Connection(start, end, v.name) for v in outputs]
    # the order a host exchanges them in does not matter: every exchange happens between steps
    return connections
