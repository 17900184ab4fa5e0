"""The vocabulary of a unit's FMI interface, which each unit declares once, as one table (`Interface`:
structure_fmu/interface.py, aero_fmu/interface.py), and `layout`, which lays a table out into variables. No
physics: every number comes from the unit's solver, through the functions the table's rows name.

A table holds, in value-reference order:
  * `Block`s, the coupling blocks e, de, Q: `name[1..n]`, one Real per ANCF coordinate of the topology;
  * `Output`s, scalar Real outputs: one variable (`energy`), or one per item of the unit, named by a pattern
    (`fold_angle_<hinge>`, `<probe>_x`), each with the function that reads its values from the solver;
  * the tunable parameters, as the solver's `tunable_parameters(spec)` declares them (`Parameters`);
  * `topology_hash`, the String both units compare before they are connected.

`layout(table, solver, spec)` gives every variable its value reference, contiguous from 0 in that order (the
Reals are the slave's value buffer, so a host gets and sets a block in one call; the String comes last), and
its start value: the solver's output at construction, an input's start, a parameter's default. The slaves
register and publish from it (fmu_common.fmi_slave), the master reads the monitors by the tables' names
(orchestrator.run.units), and docs/fmu.md's variable tables are generated from the tables
(orchestrator.build.interface_docs).
"""
from __future__ import annotations

import re
from dataclasses import dataclass
from typing import Any, Callable, Mapping, Sequence

import numpy as np

INPUT, OUTPUT, PARAMETER = "input", "output", "parameter"
"""FMI 2.0 causalities of our variables."""
CONTINUOUS, DISCRETE, FIXED, CONSTANT = "continuous", "discrete", "fixed", "constant"
"""FMI 2.0 variabilities of our variables."""
EXACT, CALCULATED = "exact", "calculated"
"""FMI 2.0 initial of outputs and parameters (an input has none: its start is what the host may override): exact,
the start value is the value after initialization; calculated, the value after initialization depends on the
parameters a host sets before it (no start value; listed as an InitialUnknown depending on the parameters)."""

QUANTITIES = ("coordinate", "rate", "force")
"""What a block holds per coordinate: the coordinate e, its rate de, or the work-conjugate force Q."""
COORDINATE_UNITS = {"r": ("m", "m/s", "N"), "r_x": ("1", "1/s", "N.m"), "r_y": ("1", "1/s", "N.m")}
"""Per vector of a node: units of e, de and the work-conjugate generalized force Q (Otsuka et al. 2019, Eq. 12),
in the order of QUANTITIES."""
_COMPONENTS = [(vec, axis) for vec in ("r", "r_x", "r_y") for axis in "xyz"]
_BNAME = re.compile(r"[A-Za-z_][A-Za-z0-9_]*(\[[0-9]+\])?")   # an identifier, or an array element 'gravity[3]'
_PLACEHOLDER = re.compile(r"<[^<>]+>")


def fmi_name(name: str) -> str:
    """FMI structured name for a dotted name.

    Parts that are neither identifiers nor array elements (`direction[1]`) are quoted ('outer wing').

    Args:
        name: the dotted name.
    """
    return ".".join(p if _BNAME.fullmatch(p) else "'" + p.replace("'", "_") + "'" for p in name.split("."))


def coordinate_description(topology, k: int) -> tuple[str, str, str]:
    """What the 0-based coordinate k is (per node r, r_x, r_y in the global frame).

    Otsuka et al. 2019, Eq. 3

    Args:
        topology: the unit's topology.
        k: index into E.

    Returns:
        (node name, component label like 'r_x[z]', vector 'r' | 'r_x' | 'r_y').
    """
    vec, axis = _COMPONENTS[k % 9]
    return topology.node_names[k // 9], f"{vec}[{axis}]", vec


class Reading:
    """The solver's outputs at one of its states (after construction, a step, a restored state, new parameters).

    Each query a row reads (a function solver -> value, e.g. one calling `solver.kinetic_energy()`) is made once,
    however many rows read it, and only when one of them is read (fmu_common.fmi_slave computes outputs when read).

    Args:
        solver: the unit's solver.
        start_time: the FMI start time, s: the origin of the unit's times (solver time + start).
    """

    __slots__ = ("solver", "start_time", "_done")

    def __init__(self, solver, start_time: float = 0.0):
        self.solver, self.start_time, self._done = solver, float(start_time), {}

    def once(self, query: Callable[[Any], Any]) -> Any:
        """query(solver), computed at the first call of this reading.

        Args:
            query: a function solver -> value.
        """
        try:
            return self._done[query]
        except KeyError:
            value = self._done[query] = query(self.solver)
            return value


@dataclass(frozen=True)
class Block:
    """A coupling block `name[1..n]`: one Real per ANCF coordinate of the topology (n = Topology.n_coordinates,
    9 per node: r, r_x, r_y in the global frame), in the topology's node order. Units per coordinate from
    COORDINATE_UNITS: e in m (r) and 1 (r_x, r_y), de in m/s and 1/s, Q in N and N.m."""

    name: str                  # "e", "de", "Q"
    causality: str             # INPUT or OUTPUT
    quantity: str              # one of QUANTITIES
    what: str                  # entry k describes itself as "<what> <node> <component>": "rate of node"
    doc: str                   # docs/fmu.md: what the block is, and from which equation
    value: Callable[[Reading, tuple], np.ndarray] | None = None   # an output's (n,) values: value(reading, ())
    start: Callable[[Any], np.ndarray] | None = None       # an input's (n,) start values from the solver; None: 0
    start_doc: str = "0"       # docs/fmu.md: what the start values are

    def __post_init__(self):
        if self.causality not in (INPUT, OUTPUT) or self.quantity not in QUANTITIES:
            raise ValueError(f"block {self.name}: causality {self.causality!r}, quantity {self.quantity!r}")
        if (self.value is None) == (self.causality == OUTPUT) or (self.start is not None and self.causality != INPUT):
            raise ValueError(f"block {self.name}: an output block needs a value and no start, an input no value")

    def names(self, n: int) -> list[str]:
        """`name[1]` .. `name[n]`.

        Args:
            n: the block's length.
        """
        return [f"{self.name}[{k}]" for k in range(1, n + 1)]


@dataclass(frozen=True)
class Items:
    """What a per-item output row is laid out over: the unit's hinges, probes, ... in the unit's order, their
    names replacing `placeholder` in the row's name patterns."""

    placeholder: str                        # "<hinge>"
    symbol: str                             # their number, in docs/fmu.md: "H"
    doc: str                                # docs/fmu.md: what they are
    of: Callable[[Any], Sequence[str]]      # solver -> their names, in the unit's order


@dataclass(frozen=True)
class Output:
    """A row of scalar Real outputs: one variable, or, with `items`, one per item for each name pattern
    (`names`, each holding the items' placeholder), laid out item by item.

    `unit` and `description` are one for every variable (the placeholder replaced by the item), or a mapping
    from the end of a variable's name to its unit or description (`{"_point_mismatch": "m", ...}`), where the
    row's variables differ. `describe` (solver -> {name: description}) takes the descriptions from the solver
    instead (`description` then ""), where they name more than the item (a probe's body and place).
    `value(reading, items)` gives the row's values, one per variable in layout order (a float for one
    variable)."""

    names: tuple[str, ...] | str
    unit: str | Mapping[str, str]
    description: str | Mapping[str, str]
    value: Callable[[Reading, tuple[str, ...]], Any]
    items: Items | None = None
    variability: str = CONTINUOUS
    key: str = ""              # the name the master files the row's values under (Unit.monitors()); default: the name
    doc: str = ""              # docs/fmu.md: what the outputs are, from which equation; default: the description
    describe: Callable[[Any], Mapping[str, str]] | None = None
    pending: float | None = None   # the value that means "none yet", which the master leaves out (per item)
    monitor: bool = False      # a column of wingsim's timeseries.csv (orchestrator.scene.columns)
    initial: str = EXACT       # CALCULATED where the value at initialization depends on the parameters

    def __post_init__(self):
        names = (self.names,) if isinstance(self.names, str) else tuple(self.names)
        object.__setattr__(self, "names", names)
        label = ", ".join(names)
        placeholders = {p for name in names for p in _PLACEHOLDER.findall(name)}
        if self.items is None:
            if placeholders or len(names) != 1:
                raise ValueError(f"output {label}: a row without items is one variable with a plain name")
            object.__setattr__(self, "key", self.key or names[0])
        elif placeholders != {self.items.placeholder} or any(self.items.placeholder not in n for n in names):
            raise ValueError(f"output {label}: every name needs the placeholder {self.items.placeholder}, and no other")
        elif not self.key:
            raise ValueError(f"output {label}: a per-item row needs the key the master files it under")
        if self.variability not in (CONTINUOUS, DISCRETE):
            raise ValueError(f"output {label}: variability {self.variability!r} (continuous or discrete)")
        if self.initial not in (EXACT, CALCULATED):
            raise ValueError(f"output {label}: initial {self.initial!r} (exact or calculated)")
        if self.monitor and self.items is not None:
            raise ValueError(f"output {label}: a monitor (a column of timeseries.csv) is one variable")
        if self.pending is not None and len(names) != 1:
            raise ValueError(f"output {label}: only a row of one name per item can mark values as pending")
        if not self.description and self.describe is None:
            raise ValueError(f"output {label}: a row needs a description, or `describe` to take them from the solver")
        if not self.doc and not (isinstance(self.description, str) and self.description):
            raise ValueError(f"output {label}: a row without one description of all its variables needs a doc")

    def names_of(self, item: str | None = None) -> tuple[str, ...]:
        """The FMI names of an item's variables (of the one variable, for a row without items).

        Args:
            item: the item; None for a row without items.
        """
        if self.items is None:
            return tuple(fmi_name(n) for n in self.names)
        return tuple(fmi_name(n.replace(self.items.placeholder, item)) for n in self.names)

    def _per_name(self, field_name: str, mapping: Mapping[str, str], name: str) -> str:
        found = [text for end, text in mapping.items() if name.endswith(end)]
        if len(found) != 1:
            raise ValueError(f"output {', '.join(self.names)}: the variable {name} ends with "
                             f"{'none' if not found else 'more than one'} of the {field_name} keys {list(mapping)}")
        return found[0]

    def unit_of(self, name: str) -> str:
        """The unit of the variable `name`.

        Args:
            name: the variable's name as the solver names it, before fmi_name.
        """
        return self.unit if isinstance(self.unit, str) else self._per_name("unit", self.unit, name)

    def description_of(self, name: str, item: str | None) -> str:
        """The description of the variable `name` of `item`, from the row (not from `describe`).

        Args:
            name: the variable's name as the solver names it.
            item: its item; None for a row without items.
        """
        if not isinstance(self.description, str):
            return self._per_name("description", self.description, name)
        return self.description if item is None else self.description.replace(self.items.placeholder, item)


@dataclass(frozen=True)
class Parameters:
    """The tunable parameters: every scalar `solver.tunable_parameters(spec)` declares (name -> (default, unit,
    description)), in its order, causality parameter, variability fixed: a host may set them before
    initialization, and the unit builds its solver with them."""

    doc: str                   # docs/fmu.md: what they are


@dataclass(frozen=True)
class Interface:
    """One unit's FMI interface: its blocks, outputs and parameters in value-reference order, then
    `topology_hash`."""

    unit: str                  # "structure unit", as messages name it
    blocks: tuple[Block, ...]
    outputs: tuple[Output, ...]
    parameters: Parameters
    partner: str               # the unit whose topology_hash must equal this one's: "aero unit"

    def __post_init__(self):
        names = [b.name for b in self.blocks] + [n for o in self.outputs for n in o.names]
        if len(set(names)) != len(names):
            raise ValueError(f"{self.unit}: a name is declared twice in {names}")

    def extended(self, *outputs: Output) -> "Interface":
        """The same table with `outputs` added after its outputs."""
        return Interface(self.unit, self.blocks, self.outputs + tuple(outputs), self.parameters, self.partner)


@dataclass(frozen=True)
class Variable:
    """One FMI variable as a unit declares it. Start values are the values the unit holds after construction (the
    model description gives none for an initial "calculated" output)."""

    name: str
    value_reference: int
    causality: str
    variability: str
    initial: str | None
    start: float | str
    unit: str | None           # None for the String
    description: str
    type: str = "Real"


@dataclass(frozen=True)
class Laid:
    """A row laid out: its value references (`where`, a slice of the value buffer) and its items."""

    row: Block | Output | Parameters
    where: slice
    items: tuple[str, ...] = ()

    @property
    def is_output(self) -> bool:
        """True for an output block or output row: one the slave publishes."""
        return isinstance(self.row, Output) or (isinstance(self.row, Block) and self.row.causality == OUTPUT)

    def read(self, reading: Reading):
        """The values of an output block or row from `reading`, one per variable in layout order.

        Args:
            reading: the Reading.

        Returns:
            a list, or a float for a row of one variable.
        """
        return self.row.value(reading, self.items)


@dataclass(frozen=True)
class Layout:
    """A table laid out for one solver: every variable (Reals from value reference 0, the String last), each
    row with its value references, and the tunable parameters (name -> (default, unit, description))."""

    variables: tuple[Variable, ...]
    rows: tuple[Laid, ...]
    tunables: dict

    @property
    def reals(self) -> tuple[Variable, ...]:
        """The Real variables, in value-reference order."""
        return tuple(v for v in self.variables if v.type == "Real")

    def where(self, row_type: type) -> slice:
        """The value references of the (one) row of `row_type`: the parameters' slice.

        Args:
            row_type: the row's class, e.g. Parameters.
        """
        (found,) = [laid.where for laid in self.rows if isinstance(laid.row, row_type)]
        return found


def layout(table: Interface, solver, spec) -> Layout:
    """The variables of `table` for `solver`, with contiguous value references from 0 in the table's order.

    Their start values are the solver's outputs now (a `Reading` at start time 0), the inputs' starts, the
    parameters' defaults. Raises ValueError naming the row whose values do not match its variables.

    Args:
        table: the unit's Interface.
        solver: the unit's solver, built from `spec`.
        spec: the unit's spec (fmu_common.specs).
    """
    topology = solver.topology
    n = int(topology.n_coordinates)
    reading = Reading(solver)
    variables: list[Variable] = []
    rows: list[Laid] = []

    def add(name, causality, variability, initial, start, unit, description):
        variables.append(Variable(name, len(variables), causality, variability, initial, start, unit, description))

    for block in table.blocks:
        laid = Laid(block, slice(len(variables), len(variables) + n))
        if block.causality == OUTPUT:
            values = np.asarray(laid.read(reading), dtype=float)
        else:
            values = np.zeros(n) if block.start is None else np.asarray(block.start(solver), dtype=float)
        if values.shape != (n,):
            raise ValueError(f"{table.unit}: block {block.name} has {values.size} values for its {n} coordinates")
        column = QUANTITIES.index(block.quantity)
        for k, (name, value) in enumerate(zip(block.names(n), values.tolist())):
            node, component, vec = coordinate_description(topology, k)
            add(name, block.causality, CONTINUOUS, EXACT if block.causality == OUTPUT else None, value,
                COORDINATE_UNITS[vec][column], f"{block.what} {node} {component}")
        rows.append(laid)

    for output in table.outputs:
        items = tuple(output.items.of(solver)) if output.items is not None else ()
        raw = ([(None, output.names[0])] if output.items is None else
               [(item, n.replace(output.items.placeholder, item)) for item in items for n in output.names])
        laid = Laid(output, slice(len(variables), len(variables) + len(raw)), items)
        values = np.asarray(laid.read(reading), dtype=float).reshape(-1)
        if values.size != len(raw):
            raise ValueError(f"{table.unit}: output {', '.join(output.names)} has {values.size} values for its "
                             f"{len(raw)} variables")
        described = output.describe(solver) if output.describe is not None else None
        for (item, name), value in zip(raw, values.tolist()):
            if described is not None and name not in described:
                raise ValueError(f"{table.unit}: the solver describes no output {name} (row {', '.join(output.names)})")
            text = described[name] if described is not None else output.description_of(name, item)
            add(fmi_name(name), OUTPUT, output.variability, output.initial, value, output.unit_of(name), text)
        rows.append(laid)

    first = len(variables)
    tunables = dict(solver.tunable_parameters(spec))
    for name, (default, unit, text) in tunables.items():
        add(fmi_name(name), PARAMETER, FIXED, EXACT, float(default), unit, text)
    rows.append(Laid(table.parameters, slice(first, len(variables))))

    variables.append(Variable("topology_hash", len(variables), OUTPUT, CONSTANT, EXACT, str(topology.topology_hash),
                              None, f"hash of the structural topology; must match the {table.partner}'s", "String"))
    seen = [v.name for v in variables]
    if len(set(seen)) != len(seen):
        twice = sorted({name for name in seen if seen.count(name) > 1})
        raise ValueError(f"{table.unit}: variables named twice: {', '.join(twice)}")
    return Layout(tuple(variables), tuple(rows), tunables)
