"""``--set KEY=VALUE`` overrides of a raw scene (before defaults and validation).

The value is parsed as a TOML value (``20``, ``1e-3``, ``true``, ``[0, 0, -9.81]``, ``"text"``) and
falls back to the bare string (``rigid``). The key is dotted; inside an array of tables a part names
the table by its ``name`` (``structure.bodies.outer.damping``) or by a 0-based index
(``structure.joints.1.stiffness``, also written ``structure.joints[1].stiffness``).
"""

from __future__ import annotations

import copy
import re
import tomllib
from typing import Any, Iterable

from fmu_common.errors import SceneError

INDEX_PATTERN = re.compile(r"\[(\d+)\]")


def parse_value(raw: str) -> Any:
    """A ``--set`` value: parsed as a TOML value (20, 1e-3, true, [0, 0, -9.8], "x"), else the bare string."""
    try:
        return tomllib.loads(f"v = {raw}")["v"]
    except tomllib.TOMLDecodeError:
        return raw


def parse_override(item: str) -> tuple[str, Any]:
    """Split ``KEY=VALUE`` into the dotted key and the parsed value."""
    key, sep, raw = item.partition("=")
    key = INDEX_PATTERN.sub(r".\1", key.strip())  # structure.bodies[1].length == structure.bodies.1.length
    if not sep or not key or not all(part.strip() for part in key.split(".")):
        raise SceneError("--set", item, "KEY=VALUE with a dotted scene key, e.g. --set flow.speed=20")
    return key, parse_value(raw.strip())


def _find_item(items: list, part: str, parent: str, key: str, value: Any) -> int:
    """Index of the table named ``part`` in an array of tables (or ``part`` as a 0-based index)."""
    for i, item in enumerate(items):
        if isinstance(item, dict) and item.get("name") == part:
            return i
    if part.isdigit() and int(part) < len(items):
        return int(part)
    names = [item["name"] for item in items if isinstance(item, dict) and isinstance(item.get("name"), str)]
    listed = ", ".join(repr(n) for n in names) or "none has a name"
    raise SceneError(key, value, f"no table named {part!r} in '{parent}' (names: {listed}; "
                                 f"or a 0-based index below {len(items)})")


def set_dotted(scene: dict, key: str, value: Any) -> None:
    """Set ``scene[a][b]...= value`` for the dotted ``key``, in place.

    Missing tables are created. Inside an array of tables a part addresses the table whose
    ``name`` equals it (``structure.bodies.outer.damping``), or else a 0-based index
    (``structure.joints.1.stiffness``; ``parse_override`` also accepts ``structure.joints[1].stiffness``).
    """
    parts = key.split(".")
    node: Any = scene
    for depth, part in enumerate(parts):
        parent = ".".join(parts[:depth]) or "<top level>"
        last = depth == len(parts) - 1
        if isinstance(node, list):
            index = _find_item(node, part, parent, key, value)
            if last:
                node[index] = value
                return
            node = node[index]
        elif isinstance(node, dict):
            if last:
                node[part] = value
                return
            node = node.setdefault(part, {})
        else:
            raise SceneError(key, value, f"'{parent}' is a value ({node!r}), not a table: no key inside it")
    # unreachable: the loop returns at the last part


def apply_overrides(raw: dict, overrides: Iterable[str]) -> dict:
    """A copy of the raw scene with each ``KEY=VALUE`` override applied, in order."""
    scene = copy.deepcopy(raw)
    for item in overrides:
        set_dotted(scene, *parse_override(item))
    return scene
