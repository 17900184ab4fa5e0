"""docs/fmu.md's variable tables, generated from the units' interface tables (structure_fmu.interface,
aero_fmu.interface), the ones the slaves register their variables from.

    python -m orchestrator.build.interface_docs            # rewrites the tables in docs/fmu.md
    python -m orchestrator.build.interface_docs --check    # exit 1 if docs/fmu.md's tables differ from the generated

Only the text between the markers ``<!-- begin: <unit> variables ... -->`` and ``<!-- end: <unit> variables -->``
is generated; the rest of docs/fmu.md is written by hand in the file itself (docs/scenes.md, all reference, comes
from a template instead). Each table lists the rows of one unit in value-reference order, with the first and last
value reference of each row as a sum of the counts before it (n coordinates, H hinges, ...), and the tunable
parameters as `tunable_parameters` names them for an example scene (`EXAMPLE`).
"""

from __future__ import annotations

import argparse
import re
import sys
from pathlib import Path

from fmu_common.interface import COORDINATE_UNITS, DISCRETE, INPUT, QUANTITIES, Block, Interface, Output, fmi_name
from orchestrator.scene.docs import write_or_check
from orchestrator.scene.load import load_scene

ROOT = Path(__file__).resolve().parents[2]
OUTPUT = ROOT / "docs" / "fmu.md"
EXAMPLE = ROOT / "scenes" / "deploy_rigid.toml"
"""The scene whose tunable parameters the tables name."""
HEADER = ("| value references | name | causality | unit | meaning |", "|---|---|---|---|---|")
COORDINATES = "n: 9 x the number of nodes (per node r, r_x, r_y in the global frame, Otsuka et al. 2019, Eq. 3)"


def _cell(text: str) -> str:
    return text.replace("|", "\\|")


class Count:
    """A number of value references as a sum of symbols: {"n": 3, "H": 2, "": 4} is 3n+2H+4."""

    def __init__(self, terms: dict[str, int] | None = None):
        self.terms = dict(terms or {})

    def __add__(self, other: "Count") -> "Count":
        terms = dict(self.terms)
        for symbol, k in other.terms.items():
            terms[symbol] = terms.get(symbol, 0) + k
        return Count({s: k for s, k in terms.items() if k})

    def __str__(self) -> str:
        symbols = [f"{'' if k == 1 else k}{s}" for s, k in self.terms.items() if s]
        text = "+".join(symbols)
        constant = self.terms.get("", 0)
        if constant:
            text += f"{constant:+d}" if text else str(constant)
        return text or "0"

    def single(self) -> bool:
        return self.terms == {"": 1}


def _references(first: Count, count: Count) -> str:
    return str(first) if count.single() else f"{first} .. {first + count + Count({'': -1})}"


def _coordinate_units(quantity: str) -> str:
    """'m (r), 1 (r_x, r_y)': the units of a block's entries, per vector of a node."""
    column = QUANTITIES.index(quantity)
    return _grouped([(vec, units[column]) for vec, units in COORDINATE_UNITS.items()], code=False)


def _grouped(pairs: list[tuple[str, str]], code: bool = True) -> str:
    """'m (`_point_mismatch`), 1 (`_axis_product`, `_axis_error`)' from (what, unit) pairs."""
    units: dict[str, list[str]] = {}
    for what, unit in pairs:
        units.setdefault(unit, []).append(f"`{what}`" if code else what)
    return ", ".join(f"{unit} ({', '.join(whats)})" for unit, whats in units.items())


def _block_row(block: Block) -> tuple[str, str, str, str]:
    causality = block.causality if block.causality != INPUT else f"input (start: {block.start_doc})"
    return f"`{block.name}[1..n]`", causality, _coordinate_units(block.quantity), block.doc


def _output_row(output: Output) -> tuple[str, str, str, str]:
    unit = output.unit if isinstance(output.unit, str) else _grouped([(end, u) for end, u in output.unit.items()])
    causality = "output, discrete" if output.variability == DISCRETE else "output"
    return ", ".join(f"`{n}`" for n in output.names), causality, unit, output.doc or output.description


def _parameters_row(table: Interface, example: dict, slave_class) -> tuple[str, str, str, str]:
    spec = slave_class.spec_class.from_scene(example)
    parameters = slave_class.solver_class.tunable_parameters(spec)
    named = ", ".join(f"`{fmi_name(name)}` ({unit})" for name, (_, unit, _) in parameters.items())
    return ("the tunable parameters", "parameter, fixed", "as each declares",
            f"{table.parameters.doc}; for {EXAMPLE.relative_to(ROOT)}: {named}")


def variables_table(table: Interface, slave_class, example: dict | None = None) -> str:
    """The generated text of `table`'s variables: what the symbols count, then one row per row of the table,
    the tunable parameters those the slave's solver declares for `example` (default EXAMPLE)."""
    example = load_scene(EXAMPLE) if example is None else example
    symbols = {"n": COORDINATES}
    rows, first = [], Count()
    for block in table.blocks:
        rows.append((_references(first, Count({"n": 1})), *_block_row(block)))
        first += Count({"n": 1})
    for output in table.outputs:
        if output.items is None:
            count = Count({"": 1})
        else:
            count = Count({output.items.symbol: len(output.names)})
            symbols[output.items.symbol] = (f"{output.items.symbol}: {output.items.doc}; `{output.items.placeholder}` "
                                            "in a name stands for each one's name")
        rows.append((_references(first, count), *_output_row(output)))
        first += count
    symbols["K"] = "K: the tunable parameters"
    rows.append((_references(first, Count({"K": 1})), *_parameters_row(table, example, slave_class)))
    first += Count({"K": 1})
    rows.append((str(first), "`topology_hash`", "output, constant (String)", "-",
                 f"hash of the structural topology; must equal the {table.partner}'s"))
    table_rows = ("| " + " | ".join(_cell(cell) for cell in row) + " |" for row in rows)
    lines = ["Value references are contiguous from 0 in the order of the rows, so a host can get and set each block "
             "in one call; the rows count", "", *(f"- {text}" for text in symbols.values()), "", *HEADER, *table_rows]
    return "\n".join(lines) + "\n"


def _units():
    """(name in the markers, interface table, slave class) of each unit: the slave classes the FMUs carry."""
    from aero_fmu.aero_slave import AeroSlave
    from structure_fmu.structure_slave import StructureSlave

    return [("structure", StructureSlave.interface, StructureSlave), ("aero", AeroSlave.interface, AeroSlave)]


def _markers(name: str) -> tuple[str, str]:
    return (f"<!-- begin: {name} variables, generated from {name}_fmu/interface.py by "
            "python -m orchestrator.build.interface_docs -->", f"<!-- end: {name} variables -->")


def generate(text: str) -> str:
    """`text` (docs/fmu.md) with the text between each unit's markers generated anew."""
    example = load_scene(EXAMPLE)
    for name, table, slave_class in _units():
        begin, end = _markers(name)
        found = list(re.finditer(re.escape(begin) + r"\n.*?" + re.escape(end), text, re.DOTALL))
        if len(found) != 1:
            raise ValueError(f"{OUTPUT} needs the markers {begin!r} and {end!r} once, around the {name} table")
        generated = f"{begin}\n{variables_table(table, slave_class, example)}{end}"
        text = text[:found[0].start()] + generated + text[found[0].end():]
    return text


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--check", action="store_true", help="compare with docs/fmu.md instead of writing it")
    args = parser.parse_args(argv)
    return write_or_check(OUTPUT, generate(OUTPUT.read_text(encoding="utf-8")), args.check,
                          "the units' interface tables", "orchestrator.build.interface_docs")


if __name__ == "__main__":
    sys.exit(main())
