"""Plausible ranges of scene values: a value outside is allowed (the schema decides what is refused) but far from
the physics the units model, so ``wingsim run`` and ``wingsim sweep`` print a note before they run.

PLAUSIBLE is the one table of these ranges. A range applies when its condition holds for the resolved scene
(flow values only matter to a scene with an aero unit).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

from fmu_common.choices import aero_model

SPEED_OF_SOUND = 340.3
"""m/s, in the ISA sea-level atmosphere (15 degC)."""
INCOMPRESSIBLE_MACH = 0.3
"""The Mach number up to which the incompressible flow of the UVLM and strip theory is a fair model."""


def _aero(scene: dict) -> bool:
    return aero_model(scene["aero"]["model"]).builds_unit


@dataclass(frozen=True)
class PlausibleRange:
    """`key` (dotted scene key, in `unit`) is plausible in [low, high] when `applies(scene)`; `why` says what the
    bounds stand for."""

    key: str
    low: float
    high: float
    unit: str
    why: str
    applies: Callable[[dict], bool] = _aero


PLAUSIBLE = (
    PlausibleRange("flow.speed", 0.0, INCOMPRESSIBLE_MACH * SPEED_OF_SOUND, "m/s",
                   f"Mach {INCOMPRESSIBLE_MACH:g} in sea-level air: above it the incompressible flow of the aero "
                   "unit (UVLM, strip theory) misses compressibility"),
    PlausibleRange("flow.density", 0.05, 1.5, "kg/m^3",
                   "air between about 20 km altitude and sea level on a cold day (1.225 kg/m^3 in the ISA "
                   "sea-level atmosphere); a liquid is far outside the aero unit's model"),
)


def _value(scene: dict, key: str):
    node = scene
    for part in key.split("."):
        node = node[part]
    return node


def plausibility_notes(scene: dict) -> list[str]:
    """One note per value of the resolved scene outside its PLAUSIBLE range (empty when all are inside)."""
    notes = []
    for rule in PLAUSIBLE:
        if not rule.applies(scene):
            continue
        value = _value(scene, rule.key)
        if not rule.low <= value <= rule.high:
            notes.append(f"{rule.key} = {value:g} {rule.unit} is outside the plausible range "
                         f"[{rule.low:g}, {rule.high:.4g}] {rule.unit} ({rule.why}); the run goes ahead")
    return notes
