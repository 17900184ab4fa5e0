"""The vocabulary the scene schema is written in: typed keys with unit, default, allowed values and a
one-line description; tables of keys; arrays of tables; tables whose keys depend on a selector (variants).

`Table.resolve(key, raw)` (and the same method of every declaration) checks a raw TOML value against its
declaration and returns it resolved: every default filled, numbers as float, counts as int, unknown keys
refused. A SceneError names the dotted key the user wrote, the value and what is allowed. Inside an array
of tables an item is named by its `name` when it has a valid one, else by its 0-based index
(`structure.bodies.outer.length`, `structure.masses.0.span`): the addresses `--set` accepts.

Defaults: `REQUIRED` (the scene must give the key), a value, or `Absent(text)`: the key resolves to None
when not given, and `text` says what that means or what fills it (e.g. a default that depends on another
table, filled by `fmu_common.scene_schema.resolve_scene`).

Tunable keys (`tunable=True`) change neither the size nor the layout of a unit: each is an FMI parameter of
the unit that owns its section, named by its dotted key (a vector's components `key[1]` .. `key[3]`), that a
host sets before initialization. `tunables(scene)` lists them with their values in a resolved scene, and
`without_tunables(scene)` is the scene with their values blanked: what an FMU's build depends on.
"""
from __future__ import annotations

import math
import re
from dataclasses import dataclass, field
from typing import Any, Callable

from .errors import SceneError, reject_unknown_keys

MISSING = "<missing>"
TUNABLE = "<tunable>"
"""What `without_tunables` puts in place of a tunable key's value."""
"""The value reported in a SceneError for a required key that is absent."""

NAME_PATTERN = re.compile(r"[A-Za-z0-9][A-Za-z0-9_.-]*")
NAME_ALLOWED = "a non-empty name of letters, digits, '_', '-', '.' starting with a letter or digit"


class _Required:
    def __repr__(self):
        return "REQUIRED"


REQUIRED = _Required()


@dataclass(frozen=True)
class Absent:
    """The default of a key that resolves to None when not given; `text` says what None means."""

    text: str


def is_number(value: Any) -> bool:
    """True for a finite int or float that is not a bool (an int beyond the float range is not finite).

    Args:
        value: any value.
    """
    if not isinstance(value, (int, float)) or isinstance(value, bool):
        return False
    try:
        return math.isfinite(value)
    except OverflowError:
        return False


def is_name(value: Any) -> bool:
    """True for a string that NAME_PATTERN matches whole.

    Args:
        value: any value.
    """
    return isinstance(value, str) and NAME_PATTERN.fullmatch(value) is not None


def item_label(index: int, item: Any) -> str:
    """How an item of an array of tables is named in a dotted key: its `name` if valid, else its index.

    Args:
        index: the item's 0-based index.
        item: the item as given.
    """
    name = item.get("name") if isinstance(item, dict) else None
    return name if is_name(name) else str(index)


def _fmt(x: float) -> str:
    return f"{x:g}"


# --- scalar keys ----------------------------------------------------------------------------------

@dataclass(frozen=True)
class Key:
    """A scalar key: unit, default, one-line description; `tunable`: an FMI parameter (module docstring)."""

    unit: str = "-"
    default: Any = REQUIRED
    doc: str = ""
    tunable: bool = field(default=False, kw_only=True)

    type_name = "value"

    def tunables(self, key: str, value: Any):
        """(dotted key, declaration, value) of the tunable keys in `value` resolved at `key`.

        Args:
            key: the dotted key.
            value: its resolved value.
        """
        if self.tunable and value is not None:
            yield key, self, value

    def blanked(self, value: Any) -> Any:
        """`value` with the values of its tunable keys replaced by TUNABLE.

        Args:
            value: the resolved value.
        """
        return TUNABLE if self.tunable else value

    def allowed(self) -> str:
        """What the key accepts, as an error message says it."""
        raise NotImplementedError

    def check(self, key: str, value: Any) -> Any:
        """The checked value; SceneError naming `key` for one the key does not accept.

        Args:
            key: the dotted key, for the error.
            value: the value given (not None).
        """
        raise NotImplementedError

    def resolve(self, key: str, value: Any) -> Any:
        """The resolved value of `key`; SceneError naming it for a value the key does not accept.

        Args:
            key: the dotted key.
            value: the value given; None: not given.
        """
        if value is None:
            if self.default is REQUIRED:
                raise SceneError(key, MISSING, "required; " + self.allowed())
            if isinstance(self.default, Absent):
                return None
            value = self.default
        return self.check(key, value)


@dataclass(frozen=True)
class Number(Key):
    """A real number in a range; finite unless `inf` (then +inf is allowed too). `why` says why a bound."""

    low: float | None = None
    high: float | None = None
    low_open: bool = False
    high_open: bool = False
    inf: bool = False
    why: str = ""

    type_name = "number"

    def _accepts(self, x: float) -> bool:
        return ((self.low is None or (x > self.low if self.low_open else x >= self.low))
                and (self.high is None or (x < self.high if self.high_open else x <= self.high)))

    def range_text(self) -> str:
        """The range accepted, e.g. "a number in [0, 1]"."""
        if self.low is not None and self.high is not None:
            return (f"a number in {'(' if self.low_open else '['}{_fmt(self.low)}, {_fmt(self.high)}"
                    f"{')' if self.high_open else ']'}")
        if self.low is not None:
            return f"a finite number {'>' if self.low_open else '>='} {_fmt(self.low)}"
        if self.high is not None:
            return f"a finite number {'<' if self.high_open else '<='} {_fmt(self.high)}"
        return "a finite number"

    def allowed(self) -> str:
        text = self.range_text() + (", or inf" if self.inf else "")
        return f"{text} ({self.unit}){': ' + self.why if self.why else ''}"

    def check(self, key: str, value: Any) -> float:
        if self.inf and isinstance(value, float) and value == math.inf:
            return value
        if not is_number(value) or not self._accepts(value):
            raise SceneError(key, value, self.allowed())
        return float(value)


@dataclass(frozen=True)
class Integer(Key):
    """An integer (not a bool, not a float) in [low, high]; `why` says why the upper bound."""

    low: int = 1
    high: int | None = None
    why: str = ""

    type_name = "integer"

    def allowed(self) -> str:
        if self.high is None:
            return f"an integer >= {self.low}"
        return f"an integer in [{self.low}, {self.high}]{': ' + self.why if self.why else ''}"

    def check(self, key: str, value: Any) -> int:
        if (isinstance(value, bool) or not isinstance(value, int) or value < self.low
                or (self.high is not None and value > self.high)):
            raise SceneError(key, value, self.allowed())
        return value


@dataclass(frozen=True)
class Choice(Key):
    """One of `options`, a string."""

    options: tuple[str, ...] = ()

    type_name = "string"

    def allowed(self) -> str:
        return "one of " + ", ".join(repr(o) for o in self.options)

    def check(self, key: str, value: Any) -> str:
        if not isinstance(value, str) or value not in self.options:
            raise SceneError(key, value, self.allowed())
        return value


@dataclass(frozen=True)
class Text(Key):
    """A string."""

    type_name = "string"

    def allowed(self) -> str:
        return "a string"

    def check(self, key: str, value: Any) -> str:
        if not isinstance(value, str):
            raise SceneError(key, value, self.allowed())
        return value


@dataclass(frozen=True)
class Name(Key):
    """A name: referenced by other tables, part of column, variable and --set names."""

    type_name = "string"

    def allowed(self) -> str:
        return NAME_ALLOWED

    def check(self, key: str, value: Any) -> str:
        if not is_name(value):
            raise SceneError(key, value, self.allowed())
        return value


@dataclass(frozen=True)
class Vector(Key):
    """Three finite numbers; `nonzero` for a direction (any length but not zero)."""

    nonzero: bool = False

    type_name = "array of 3 numbers"

    def allowed(self) -> str:
        if self.nonzero:
            return f"a non-zero array of 3 finite numbers ({self.unit}, any length)"
        return f"an array of 3 finite numbers ({self.unit}), e.g. [0, 0, -9.81]"

    def check(self, key: str, value: Any) -> list[float]:
        if not isinstance(value, list) or len(value) != 3 or not all(map(is_number, value)):
            raise SceneError(key, value, self.allowed())
        if self.nonzero and not any(value):
            raise SceneError(key, value, self.allowed())
        return [float(v) for v in value]


# --- tables ---------------------------------------------------------------------------------------

Rule = Callable[[str, dict], None]
"""(dotted key of a table, its resolved dict) -> None; raises SceneError: a rule between keys of one table."""


@dataclass(frozen=True)
class Table:
    """A table of keys (scalars, tables, arrays of tables). `optional`: may be left out, and is then absent
    from the resolved scene (not None). `rules` check relations between its resolved keys."""

    keys: dict[str, Any]
    doc: str = ""
    optional: bool = False
    rules: tuple[Rule, ...] = ()

    type_name = "table"

    def allowed(self) -> str:
        """What the table accepts, as an error message says it."""
        return f"a table with keys {', '.join(self.keys)}"

    def resolve(self, key: str, value: Any) -> dict:
        """The resolved table; a table not given is an empty one (its defaults; its required keys missing).

        Args:
            key: the table's dotted key ("" at the top level).
            value: the table given; None: not given.
        """
        value = {} if value is None else value
        if not isinstance(value, dict):
            where = f"a table [{key}]" if key else "a TOML table"
            raise SceneError(key or "<top level>", value, f"{where} with keys {', '.join(self.keys)}")
        reject_unknown_keys(value, key, self.keys)
        out = {}
        for name, spec in self.keys.items():
            dotted = f"{key}.{name}" if key else name
            given = value.get(name)
            if getattr(spec, "optional", False) and given is None:
                continue
            out[name] = spec.resolve(dotted, given)
        for rule in self.rules:
            rule(key, out)
        return out

    def tunables(self, key: str, value: dict):
        """(dotted key, declaration, value) of the tunable keys in the resolved table.

        Args:
            key: the table's dotted key ("" at the top level).
            value: the resolved table.
        """
        for name, spec in self.keys.items():
            if name in value:
                yield from spec.tunables(f"{key}.{name}" if key else name, value[name])

    def blanked(self, value: dict) -> dict:
        """`value` with the values of its tunable keys replaced by TUNABLE.

        Args:
            value: the resolved table.
        """
        return {name: self.keys[name].blanked(v) if name in self.keys else v for name, v in value.items()}


@dataclass(frozen=True)
class Variants:
    """A table whose keys depend on the value of its `selector` key: one Table per value."""

    selector: str
    tables: dict[str, Table]
    default: Any = REQUIRED
    doc: str = ""
    optional: bool = False

    type_name = "table"

    @property
    def selector_key(self) -> Choice:
        """The selector as a Choice among the variants."""
        return Choice(default=self.default, options=tuple(self.tables), doc=self.doc)

    def allowed(self) -> str:
        """What the table accepts, as an error message says it."""
        return f"a table whose {self.selector} is {self.selector_key.allowed()}"

    def resolve(self, key: str, value: Any) -> dict:
        """The resolved table of the variant its selector names; SceneError naming the key otherwise.

        Args:
            key: the table's dotted key.
            value: the table given.
        """
        if not isinstance(value, dict):
            raise SceneError(key, value, self.allowed())
        kind = self.selector_key.resolve(f"{key}.{self.selector}", value.get(self.selector))
        table = self.tables[kind]
        resolved = Table({self.selector: self.selector_key, **table.keys}, rules=table.rules).resolve(key, value)
        return resolved

    def tunables(self, key: str, value: dict):
        """(dotted key, declaration, value) of the tunable keys in the resolved table.

        Args:
            key: the table's dotted key.
            value: the resolved table.
        """
        yield from self.tables[value[self.selector]].tunables(key, value)

    def blanked(self, value: dict | None) -> dict | None:
        """`value` with the values of its tunable keys replaced by TUNABLE (None stays None).

        Args:
            value: the resolved table, or None.
        """
        return None if value is None else self.tables[value[self.selector]].blanked(value)


@dataclass(frozen=True)
class Tables:
    """An array of tables [[key]], each a Table or Variants; `unique` names: no two items share a `name`.
    `min_items`: at least that many."""

    item: Any
    what: str
    doc: str = ""
    default: Any = field(default_factory=list)
    min_items: int = 0

    type_name = "array of tables"

    def allowed(self) -> str:
        """What the array accepts, as an error message says it."""
        least = f" (at least {self.min_items})" if self.min_items else ""
        return f"an array of tables, one per {self.what}{least}"

    def resolve(self, key: str, value: Any) -> list[dict]:
        """The resolved items; SceneError naming the key for a wrong array, item or repeated name.

        Args:
            key: the array's dotted key.
            value: the array given (None: the default).
        """
        if value is None:
            if self.default is REQUIRED:
                raise SceneError(key, MISSING, "required; " + self.allowed())
            value = list(self.default)
        if not isinstance(value, list) or not all(isinstance(v, dict) for v in value):
            raise SceneError(key, value, f"an array of tables [[{key}]], one per {self.what}")
        if len(value) < self.min_items:
            raise SceneError(key, value, self.allowed())
        out, seen = [], set()
        for index, item in enumerate(value):
            resolved = self.item.resolve(f"{key}.{item_label(index, item)}", item)
            name = resolved.get("name")
            if name is not None:
                if name in seen:
                    raise SceneError(f"{key}.{index}.name", name,
                                     f"a {self.what} name not used by another {self.what}")
                seen.add(name)
            out.append(resolved)
        return out

    def tunables(self, key: str, value: list):
        """(dotted key, declaration, value) of the tunable keys in the resolved items.

        Args:
            key: the array's dotted key.
            value: the resolved items.
        """
        for index, item in enumerate(value):
            yield from self.item.tunables(f"{key}.{item_label(index, item)}", item)

    def blanked(self, value: list) -> list:
        """`value` with the values of its items' tunable keys replaced by TUNABLE.

        Args:
            value: the resolved items.
        """
        return [self.item.blanked(item) for item in value]
