"""What the master and its two ports (``fmu_port``, ``direct_port``) agree on: the unit kinds, the errors and
log entries a port reports, and the calls a port answers (``Port``).

A port is one unit instance behind plain calls: value references by name, batched readers and writers over
value-reference arrays, the FMI phases, states. ``orchestrator.run.units.Unit`` turns a port into the
e / de / Q interface the coupling schemes use.
"""
from __future__ import annotations

import re
from dataclasses import dataclass
from typing import Callable, NamedTuple, Protocol

import numpy as np

from aero_fmu.interface import AERO
from fmu_common.fmi_slave import DIVERGED_CATEGORY
from fmu_common.interface import INPUT, OUTPUT, Interface
from structure_fmu.interface import STRUCTURE


class UnitError(RuntimeError):
    """A unit call failed. The message carries the unit's own logged reason.

    `diverged` is True when the unit reported a diverging state (summary status "diverged"): it logged the
    failure in the category `DIVERGED_CATEGORY`, whatever the message says.
    """

    def __init__(self, message: str, diverged: bool = False):
        super().__init__(message)
        self.diverged = diverged


class LogEntry(NamedTuple):
    """One message a unit logged: its fmi2Status (0 OK .. 4 Fatal), category and text ('%' undoubled)."""

    status: int
    category: str
    text: str


def reported_divergence(entries) -> bool:
    """True when one of the log entries is the unit's divergence signal (its category, not its text)."""
    return any(entry.category == DIVERGED_CATEGORY for entry in entries)


@dataclass(frozen=True)
class UnitKind:
    """What distinguishes the unit kinds; everything else is one code path."""

    fmu_file: str
    slave: tuple[str, str]            # (module, class) of the slave, for the direct backend
    interface: Interface              # the unit's table: its blocks and the outputs monitors() reads, all required
    scene_sections: tuple[str, ...]   # scene sections an FMU must have been built from (else stale); the aero
                                      # unit sees the structure only through its topology, which the master
                                      # compares by topology_hash when the units connect

    @property
    def inputs(self) -> tuple[str, ...]:
        """The input blocks, each [1..n], in the table's order (structure: Q; aero: e, de)."""
        return tuple(b.name for b in self.interface.blocks if b.causality == INPUT)

    @property
    def outputs(self) -> tuple[str, ...]:
        """The output blocks, each [1..n], in the table's order (structure: e, de; aero: Q)."""
        return tuple(b.name for b in self.interface.blocks if b.causality == OUTPUT)


KINDS = {
    "structure": UnitKind("structure.fmu", ("structure_fmu.structure_slave", "StructureSlave"), STRUCTURE,
                          ("structure", "probes", "strain_gauges")),
    "aero": UnitKind("aero.fmu", ("aero_fmu.aero_slave", "AeroSlave"), AERO, ("aero", "flow")),
}
FMU_FILES = {kind: spec.fmu_file for kind, spec in KINDS.items()}
ERROR_STATUS = 3  # fmi2Error: a call that logged a message at this status (or worse) failed
_BLOCKS = sorted({b.name for spec in KINDS.values() for b in spec.interface.blocks})
INDEXED = re.compile(rf"^({'|'.join(map(re.escape, _BLOCKS))})\[(\d+)\]$")
"""The name of a block entry, `e[3]`: (block, index)."""


def warnings_and_errors(entries: list[LogEntry]) -> str:
    """The texts of the warnings and errors among `entries`, joined by '; '."""
    return "; ".join(entry.text for entry in entries if entry.status >= 1)


class Port(Protocol):
    """The calls a unit's backend answers; every failure raises `UnitError` naming the unit's logged reason."""

    backend: str          # "fmu" | "direct"
    label: str            # the instance as messages name it
    log: list[LogEntry]   # every message the unit logged

    def value_references(self) -> dict[str, int]:
        """{variable name: value reference} of every variable."""

    def reader(self, vrs: list[int]) -> Callable[[], np.ndarray]:
        """A function returning the Real values of `vrs` as a fresh array."""

    def writer(self, vrs: list[int]) -> Callable[[np.ndarray], None]:
        """A function setting the Real values of `vrs`."""

    def get_string(self, vr: int) -> str: ...

    def setup(self) -> None:
        """fmi2SetupExperiment (start time 0) and fmi2EnterInitializationMode."""

    def initialize(self) -> None:
        """fmi2ExitInitializationMode."""

    def do_step(self, t: float, h: float) -> None: ...

    def get_state(self): ...

    def set_state(self, state) -> None: ...

    def serialize_state(self, state) -> bytes: ...

    def deserialize_state(self, data: bytes): ...

    def close(self) -> None:
        """Terminate and free the instance; idempotent, never raises."""
