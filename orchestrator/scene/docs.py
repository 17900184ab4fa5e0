"""docs/scenes.md, generated from the scene schema (fmu_common.scene_schema) and a hand-written template.

    python -m orchestrator.scene.docs            # writes docs/scenes.md
    python -m orchestrator.scene.docs --check    # exit 1 if docs/scenes.md differs from the generated text

The template (orchestrator/templates/scenes.md) holds the introduction and the explanations; its markers
``{{ reference }}``, ``{{ bounds }}`` and ``{{ plausible }}`` become the reference of every key (type, unit,
default, allowed, description; one table per scene table, one per variant of a table whose keys depend on a
selector), the size bounds (fmu_common.scene_bounds.BOUNDS) and the plausible ranges
(orchestrator.scene.plausibility.PLAUSIBLE).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any, Iterator

from fmu_common.scene_bounds import BOUNDS
from orchestrator.scene.plausibility import PLAUSIBLE
from fmu_common.scene_schema import SCENE
from fmu_common.schema import (REQUIRED, Absent, Choice, Integer, Key, Name, Number, Table, Tables, Text, Variants,
                               Vector)

ROOT = Path(__file__).resolve().parents[2]
TEMPLATE = Path(__file__).resolve().parent / "templates" / "scenes.md"
OUTPUT = ROOT / "docs" / "scenes.md"
HEADER = ("| key | type | unit | default | allowed | description |", "|---|---|---|---|---|---|")


def _cell(text: str) -> str:
    return text.replace("|", "\\|")


def _value(value: Any) -> str:
    if isinstance(value, float):
        return f"{value:g}"
    if isinstance(value, list):
        return "[" + ", ".join(_value(v) for v in value) + "]"
    if isinstance(value, str):
        return f'"{value}"'
    return str(value)


def default_text(spec: Key) -> str:
    if spec.default is REQUIRED:
        return "required"
    if isinstance(spec.default, Absent):
        return spec.default.text
    return f"`{_value(spec.default)}`"


def allowed_text(spec: Key) -> str:
    """What the key accepts, without its unit (a column of its own)."""
    if isinstance(spec, Number):
        return spec.range_text() + (", or `inf`" if spec.inf else "")
    if isinstance(spec, Choice):
        return " \\| ".join(f"`{o}`" for o in spec.options)
    if isinstance(spec, Integer):
        return spec.allowed().split(":")[0]
    if isinstance(spec, Name):
        return "a name: letters, digits, `_`, `-`, `.`"
    if isinstance(spec, Vector):
        return "3 finite numbers, not all zero" if spec.nonzero else "3 finite numbers"
    if isinstance(spec, Text):
        return "any string"
    return spec.allowed()


def _rows(table: Table, prefix: str = "") -> Iterator[str]:
    """Rows of the scalar keys of `table`, its nested plain tables flattened (`section.chord`)."""
    for name, spec in table.keys.items():
        if isinstance(spec, Key):
            unit = "" if spec.unit == "-" else spec.unit
            doc = spec.doc + (" (*tunable*)" if spec.tunable else "")
            yield (f"| `{prefix}{name}` | {spec.type_name} | {_cell(unit)} | {_cell(default_text(spec))} | "
                   f"{allowed_text(spec)} | {_cell(doc)} |")
        elif isinstance(spec, Table) and not spec.optional:
            yield from _rows(spec, f"{prefix}{name}.")


def _table_block(table: Table, flatten: bool) -> list[str]:
    if flatten:
        rows = list(_rows(table))
    else:
        rows = [row for name, spec in table.keys.items() if isinstance(spec, Key)
                for row in _rows(Table({name: spec}))]
    return [*HEADER, *rows] if rows else []


def _variants_block(variants: Variants) -> list[str]:
    default = "required" if variants.default is REQUIRED else f'default `"{variants.default}"`'
    lines = [f"`{variants.selector}` ({default}) selects the keys" + (f"; {variants.doc}." if variants.doc else ".")]
    for value, table in variants.tables.items():
        lines += ["", f'`{variants.selector} = "{value}"`' + (f": {table.doc}." if table.doc else ""), "",
                  *_table_block(table, flatten=True)]
    return lines


def _section(title: str, spec: Any) -> list[str]:
    doc = "" if isinstance(spec, Variants) else spec.doc     # a variant table's doc goes with its selector
    lines = [f"### {title}", ""] + ([doc + ".", ""] if doc else [])
    item = spec.item if isinstance(spec, Tables) else spec
    if isinstance(item, Variants):
        lines += _variants_block(item)
    else:
        lines += _table_block(item, flatten=isinstance(spec, Tables))
    return lines + [""]


def reference() -> str:
    """The reference of every key of SCENE, one section per table."""
    lines = ["### Top level", "", *_table_block(SCENE, flatten=False), ""]
    for name, spec in SCENE.keys.items():
        if isinstance(spec, Key):
            continue
        lines += _section(f"`[[{name}]]`" if isinstance(spec, Tables) else f"`[{name}]`", spec)
        if name == "structure":
            for sub, subspec in spec.keys.items():
                if not isinstance(subspec, Key):
                    dotted = f"structure.{sub}"
                    lines += _section(f"`[[{dotted}]]`" if isinstance(subspec, Tables) else f"`[{dotted}]`", subspec)
    return "\n".join(lines).rstrip() + "\n"


def bounds() -> str:
    rows = [f"| {_cell(what)} | {_cell(bound)} | {_cell(why)} |" for what, bound, why in BOUNDS]
    return "\n".join(["| what | bound | why |", "|---|---|---|", *rows]) + "\n"


def plausible() -> str:
    rows = [f"| `{r.key}` | {r.low:g} to {r.high:.4g} {r.unit} | {_cell(r.why)} |" for r in PLAUSIBLE]
    return "\n".join(["| key | plausible | why |", "|---|---|---|", *rows]) + "\n"


def generate() -> str:
    """The text of docs/scenes.md."""
    text = TEMPLATE.read_text(encoding="utf-8")
    return (text.replace("{{ reference }}\n", reference()).replace("{{ bounds }}\n", bounds())
            .replace("{{ plausible }}\n", plausible()))


def write_or_check(path: Path, text: str, check: bool, source: str, command: str) -> int:
    """Write the generated `text` to `path` (exit code 0), or with `check` compare it with the file: 1, saying that
    it differs from `source` and which `command` regenerates it, when it does."""
    if not check:
        path.write_text(text, encoding="utf-8")
        return 0
    if path.read_text(encoding="utf-8") != text:
        print(f"{path} differs from {source}: run python -m {command}", file=sys.stderr)
        return 1
    return 0


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--check", action="store_true", help="compare with docs/scenes.md instead of writing it")
    args = parser.parse_args(argv)
    return write_or_check(OUTPUT, generate(), args.check, "the schema", "orchestrator.scene.docs")


if __name__ == "__main__":
    sys.exit(main())
