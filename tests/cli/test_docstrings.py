"""Every public function, class and method of structure_fmu, aero_fmu and fmu_common has a docstring in the
skeleton of docs/architecture.md ("Docstrings"): a one-line summary, optional prose, then Google-style
sections, `Args:` with one entry per parameter (shape, unit, frame) and `Returns:`.

The checker parses the sources with `ast` (nothing is imported) and names file:line and the object for:
- a public module-level function or class, or a public method of a public class, without a docstring, except a
  method that overrides a documented method of a base class (or a Protocol it inherits) of the same packages:
  pdoc shows the base's docstring for it;
- an `Args:` section naming a parameter that is not in the signature, or omitting one of it (self, cls, *args
  and **kwargs aside), or with an entry that is not `name: description`. A class documents the parameters of
  its `__init__` in its own docstring unless `__init__` has one;
- a function (or a class through its `__init__`) with parameters besides self and cls whose docstring has no
  `Args:` section.
"""
from __future__ import annotations

import ast
import inspect
import re
from dataclasses import dataclass, field

import pytest

from repository import ROOT

PACKAGES = ("structure_fmu", "aero_fmu", "fmu_common", "wingsim")

_ENTRY = re.compile(r"^\*{0,2}(?P<name>\w+)\s*(\([^)]*\))?\s*:")
_IGNORED = {"self", "cls"}


@dataclass
class _Class:
    """A class of the packages as the checker sees it: its bases' names and its methods with a docstring."""

    bases: list[str]
    documented: set[str] = field(default_factory=set)


def args_section(doc: str) -> list[tuple[str, int]] | None:
    """The parameter names of the docstring's `Args:` section with their line in the docstring, a name `?` for
    an entry that is not `name: description`; None when there is no such section.

    Args:
        doc: a docstring, cleaned (inspect.cleandoc).
    """
    lines = doc.splitlines()
    starts = [number for number, line in enumerate(lines) if line.strip() == "Args:"]
    if not starts:
        return None
    start = starts[0]
    base = len(lines[start]) - len(lines[start].lstrip())
    entries, entry_indent = [], None
    for number, line in enumerate(lines[start + 1:], start + 1):
        if not line.strip():
            continue
        indent = len(line) - len(line.lstrip())
        if indent <= base:
            break
        if entry_indent is None:
            entry_indent = indent
        if indent <= entry_indent:
            match = _ENTRY.match(line.strip())
            entries.append((match["name"] if match else "?", number))
    return entries


def _parameters(node: ast.FunctionDef | ast.AsyncFunctionDef) -> list[str]:
    arguments = node.args
    names = [a.arg for a in arguments.posonlyargs + arguments.args + arguments.kwonlyargs]
    return [n for n in names if n not in _IGNORED]


def _variadic(node: ast.FunctionDef | ast.AsyncFunctionDef) -> set[str]:
    """The names of *args and **kwargs, which `Args:` may document but need not."""
    return {a.arg for a in (node.args.vararg, node.args.kwarg) if a is not None}


def _decorators(node) -> set[str]:
    names = set()
    for decorator in node.decorator_list:
        target = decorator.func if isinstance(decorator, ast.Call) else decorator
        names.add(ast.unparse(target))
    return names


def _base_names(node: ast.ClassDef) -> list[str]:
    names = []
    for base in node.bases:
        target = base.value if isinstance(base, ast.Subscript) else base
        if isinstance(target, ast.Name):
            names.append(target.id)
        elif isinstance(target, ast.Attribute):
            names.append(target.attr)
    return names


def class_index(sources: dict[str, str]) -> dict[str, list[_Class]]:
    """{class name: every class of that name in `sources`} with its bases and documented methods.

    Args:
        sources: {file name: Python source}.
    """
    index: dict[str, list[_Class]] = {}
    for source in sources.values():
        for node in ast.walk(ast.parse(source)):
            if isinstance(node, ast.ClassDef):
                documented = {item.name for item in node.body
                              if isinstance(item, (ast.FunctionDef, ast.AsyncFunctionDef)) and ast.get_docstring(item)}
                index.setdefault(node.name, []).append(_Class(_base_names(node), documented))
    return index


def _inherits_doc(bases: list[str], method: str, index: dict[str, list[_Class]], seen: set[str]) -> bool:
    for name in bases:
        if name in seen:
            continue
        seen.add(name)
        for found in index.get(name, []):
            if method in found.documented or _inherits_doc(found.bases, method, index, seen):
                return True
    return False


def check_source(source: str, filename: str, index: dict[str, list[_Class]], require_args: bool = True) -> list[str]:
    """The faults of one module's source, each "file:line object: what is wrong".

    Args:
        source: the module's Python source.
        filename: its path as the faults name it.
        index: the classes of the packages (class_index), for the docstrings a method inherits.
        require_args: whether a function with parameters needs an `Args:` section (the last rule above).
    """
    faults = []

    def fault(node, name, text):
        faults.append(f"{filename}:{node.lineno} {name}: {text}")

    def check_args(node, name, doc, function, required):
        parameters = [] if function is None else _parameters(function)
        variadic = set() if function is None else _variadic(function)
        entries = args_section(doc) if doc else None
        if entries is None:
            if required and parameters:
                fault(node, name, f"no Args: section for {', '.join(parameters)}")
            return
        named = []
        for entry, _ in entries:
            if entry == "?":
                fault(node, name, "an Args: entry that is not `name: description`")
            elif entry in _IGNORED or entry in variadic:
                continue
            elif entry not in parameters:
                fault(node, name, f"Args: names {entry!r}, not a parameter")
            named.append(entry)
        for parameter in parameters:
            if parameter not in named:
                fault(node, name, f"Args: omits parameter {parameter!r}")

    def visit_function(node, name, class_bases):
        decorators = _decorators(node)
        if "overload" in decorators or "typing.overload" in decorators:
            return
        if any(d.endswith((".setter", ".deleter")) for d in decorators):
            return
        doc = ast.get_docstring(node)
        if not doc:
            if class_bases is not None and _inherits_doc(class_bases, node.name, index, set()):
                return
            fault(node, name, "no docstring")
            return
        is_property = bool(decorators & {"property", "functools.cached_property", "cached_property"})
        check_args(node, name, doc, None if is_property else node, require_args)

    def visit_class(node, name):
        doc = ast.get_docstring(node)
        if not doc:
            fault(node, name, "no docstring")
        bases = _base_names(node)
        for item in node.body:
            if isinstance(item, (ast.FunctionDef, ast.AsyncFunctionDef)):
                if item.name == "__init__":
                    if not ast.get_docstring(item):
                        check_args(node, name, doc, item, require_args)
                    else:
                        check_args(item, f"{name}.__init__", ast.get_docstring(item), item, require_args)
                elif not item.name.startswith("_"):
                    visit_function(item, f"{name}.{item.name}", bases)
            elif isinstance(item, ast.ClassDef) and not item.name.startswith("_"):
                visit_class(item, f"{name}.{item.name}")

    for node in ast.parse(source).body:
        if node_name := getattr(node, "name", ""):
            if node_name.startswith("_"):
                continue
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                visit_function(node, node_name, None)
            elif isinstance(node, ast.ClassDef):
                visit_class(node, node_name)
    return faults


def _sources() -> dict[str, str]:
    return {path.relative_to(ROOT).as_posix(): path.read_text(encoding="utf-8")
            for package in PACKAGES for path in sorted((ROOT / package).rglob("*.py"))}


def test_docstrings_follow_the_skeleton():
    sources = _sources()
    index = class_index(sources)
    faults = [f for name, source in sources.items() for f in check_source(source, name, index)]
    assert not faults, f"{len(faults)} docstring faults:\n" + "\n".join(faults)


_EXAMPLE = '''
class Base:
    """A base."""

    def step(self, h):
        """One step.

        Args:
            h: step, s.
        """


class Child(Base):
    """A child."""

    def step(self, h):
        return h

    def other(self):
        return 0


def undocumented(x):
    return x


def wrong_name(x, *args, **kwargs):
    """Wrong name.

    Args:
        y: not a parameter.
    """


def omitted(x, z):
    """Omits z.

    Args:
        x: (n,) a vector, m, global frame; one that continues
            on a second line: z
    """


def without_args(x):
    """No Args section."""


def no_parameters():
    """Nothing to document."""


def _private(x):
    return x


class Made:
    """Documents its __init__'s parameters.

    Args:
        a: one.
        b: not a parameter.
    """

    def __init__(self, a):
        self.a = a
'''


@pytest.mark.parametrize("require_args", [False, True])
def test_the_checker_finds_each_fault(require_args):
    faults = check_source(_EXAMPLE, "example.py", class_index({"example.py": _EXAMPLE}), require_args)
    text = "\n".join(faults)
    assert "Child.step" not in text                 # inherits Base.step's docstring
    assert re.search(r"example.py:\d+ Child.other: no docstring", text)
    assert re.search(r"example.py:\d+ undocumented: no docstring", text)
    assert re.search(r"example.py:\d+ wrong_name: Args: names 'y', not a parameter", text)
    assert re.search(r"example.py:\d+ wrong_name: Args: omits parameter 'x'", text)
    assert re.search(r"example.py:\d+ omitted: Args: omits parameter 'z'", text)
    assert "no_parameters" not in text and "_private" not in text
    assert re.search(r"example.py:\d+ Made: Args: names 'b', not a parameter", text)
    assert bool(re.search(r"example.py:\d+ without_args: no Args: section for x", text)) == require_args
    assert len(faults) == 6 + require_args, text


def test_args_section_reads_entries():
    doc = inspect.cleandoc('''Summary.

        Args:
            e: (n,) ANCF nodal coordinates, m (r) and 1 (r_x, r_y), global frame
            *args (float): more
            broken entry
        Returns:
            (n,) something''')
    assert [name for name, _ in args_section(doc)] == ["e", "args", "?"]
