"""SI units of FMI variables: pythonfmu's Real with a unit, and the model description's UnitDefinitions.

pythonfmu 0.7.0 has no unit attribute on variables: `UnitReal` adds one, and `unit_definitions` declares each
unit used by its base-unit exponents (kg, m, s, A, K, mol, cd, rad) and factor, as FMI 2.0 Sec. 2.2.2 asks.
"""
from __future__ import annotations

import math
import re
from typing import Iterable
from xml.etree.ElementTree import Element, SubElement

from pythonfmu import Real


class UnitReal(Real):
    """pythonfmu Real with a declared SI unit (pythonfmu 0.7.0 has no unit attribute).

    Args:
        name: the variable's name.
        unit: its unit in FMI notation; None: none.
        **kwargs: pythonfmu Real's.
    """

    def __init__(self, name: str, unit: str | None = None, **kwargs):
        super().__init__(name, **kwargs)
        self.unit = unit

    def to_xml(self):
        """pythonfmu's ScalarVariable element with the unit attribute on its Real."""
        node = super().to_xml()
        if self.unit:
            node.find("Real").set("unit", self.unit)
        return node


# Base-unit exponents (kg, m, s, A, K, mol, cd, rad) and factor of the symbols our units are made of.
_SYMBOLS = {
    "1": ({}, 1.0), "-": ({}, 1.0), "kg": ({"kg": 1}, 1.0), "m": ({"m": 1}, 1.0), "s": ({"s": 1}, 1.0),
    "rad": ({"rad": 1}, 1.0), "deg": ({"rad": 1}, math.pi / 180.0), "N": ({"kg": 1, "m": 1, "s": -2}, 1.0),
    "J": ({"kg": 1, "m": 2, "s": -2}, 1.0), "W": ({"kg": 1, "m": 2, "s": -3}, 1.0),
    "Pa": ({"kg": 1, "m": -1, "s": -2}, 1.0), "Hz": ({"s": -1}, 1.0), "K": ({"K": 1}, 1.0),
}


def fmi_unit(unit: str) -> str:
    """A scene schema's unit in the notation of our FMI variables.

    'N m/rad' -> 'N.m/rad', 'm/s^2' -> 'm/s2', '-' -> '1'.

    Args:
        unit: the schema's unit.
    """
    return "1" if unit == "-" else ".".join(unit.split()).replace("^", "")


def base_unit(unit: str) -> tuple[dict, float] | None:
    """Exponents and factor of a unit string like 'N.m/rad', 'N m s/rad', 'm/s2', 'm/s^2', '1/s'.

    Symbols are separated by spaces, '.' or '*', with at most one '/'.

    Args:
        unit: the unit string.

    Returns:
        ({base unit: exponent}, factor), or None if not understood.
    """
    parts = unit.split("/")
    if len(parts) > 2:
        return None
    exps: dict[str, int] = {}
    factor = 1.0
    for sign, part in zip((1, -1), parts):
        for token in part.replace("*", " ").replace(".", " ").split():
            m = re.fullmatch(r"([A-Za-z]+|1|-)\^?(-?\d+)?", token)
            if m is None or m.group(1) not in _SYMBOLS:
                return None
            p = sign * int(m.group(2) or 1)
            for k, v in _SYMBOLS[m.group(1)][0].items():
                exps[k] = exps.get(k, 0) + p * v
            factor *= _SYMBOLS[m.group(1)][1] ** p
    return {k: v for k, v in exps.items() if v}, factor


def unit_definitions(units: Iterable[str]) -> Element:
    """The <UnitDefinitions> element of `units` (each once, sorted).

    Each with its <BaseUnit> where `base_unit` understands it.

    Args:
        units: unit strings in FMI notation.
    """
    defs = Element("UnitDefinitions")
    for unit in sorted(set(units)):
        node = SubElement(defs, "Unit", name=unit)
        parsed = base_unit(unit)
        if parsed is not None:
            exps, factor = parsed
            attrib = {k: str(v) for k, v in exps.items()}
            if factor != 1.0:
                attrib["factor"] = repr(factor)
            SubElement(node, "BaseUnit", attrib)
    return defs
