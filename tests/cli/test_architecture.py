"""The package layout is the architecture: no import runs in a circle, the stages of the master import only
the stages before them, the product never imports the study toolkit, and the two units never import each
other or the master. Every import counts, also one inside a function (a lazy import is still a dependency).
"""
import ast
import re

import pytest

from repository import ROOT

PACKAGES = ("fmu_common", "structure_fmu", "aero_fmu", "orchestrator", "wingsim")
STAGES = ("scene", "build", "run", "output", "export", "sweep", "cli", "__main__")
"""The master's stages in order (orchestrator/__init__.py): each may import only itself and those before it."""


def _module_name(path) -> str:
    parts = list(path.relative_to(ROOT).with_suffix("").parts)
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def _imports() -> dict[str, set[str]]:
    """{module: the project's modules it imports}, from every import statement of its source."""
    files = {_module_name(p): p for package in PACKAGES for p in (ROOT / package).rglob("*.py")}
    graph = {}
    for name, path in files.items():
        package = name if path.name == "__init__.py" else name.rpartition(".")[0]
        found = set()
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, ast.Import):
                found.update(alias.name for alias in node.names)
            elif isinstance(node, ast.ImportFrom):
                base = node.module or ""
                if node.level:
                    base = ".".join(package.split(".")[:len(package.split(".")) - node.level + 1] + [base]).strip(".")
                found.add(base)
                found.update(f"{base}.{alias.name}" for alias in node.names)
        graph[name] = {m for m in found if m in files and m != name}
    return graph


def _cycle(graph: dict[str, set[str]]) -> list[str]:
    """One import circle as a list of modules (first == last), or [] when there is none."""
    state, stack = {}, []

    def visit(node):
        state[node] = "open"
        stack.append(node)
        for nxt in sorted(graph[node]):
            if state.get(nxt) == "open":
                return stack[stack.index(nxt):] + [nxt]
            if nxt not in state and (found := visit(nxt)):
                return found
        state[node] = "done"
        stack.pop()
        return []

    for node in sorted(graph):
        if node not in state and (found := visit(node)):
            return found
    return []


GRAPH = _imports()


def test_the_import_graph_is_read():
    # the graph is not vacuous: the run loop imports the coupling schemes, the units their solvers
    assert "orchestrator.run.coupling" in GRAPH["orchestrator.run.master"]
    assert "structure_fmu.solver" in GRAPH["structure_fmu.structure_slave"]


def test_no_import_circle():
    assert _cycle(GRAPH) == [], " -> ".join(_cycle(GRAPH))


def test_a_circle_is_found():
    assert _cycle({"a": {"b"}, "b": {"c"}, "c": {"a"}}) == ["a", "b", "c", "a"]


def _stage(module: str) -> str | None:
    parts = module.split(".")
    return parts[1] if parts[0] == "orchestrator" and len(parts) > 1 and parts[1] in (*STAGES, "studies") else None


@pytest.mark.parametrize("module", sorted(m for m in GRAPH if _stage(m) in STAGES))
def test_a_stage_imports_only_the_stages_before_it(module):
    own = STAGES.index(_stage(module))
    later = sorted(m for m in GRAPH[module] if _stage(m) is not None
                   and (_stage(m) == "studies" or STAGES.index(_stage(m)) > own))
    assert later == [], f"{module} imports {later}"


def test_the_units_import_neither_each_other_nor_the_master():
    for module, imported in GRAPH.items():
        top = module.split(".")[0]
        if top in ("structure_fmu", "aero_fmu", "fmu_common"):
            foreign = {m.split(".")[0] for m in imported} - {top, "fmu_common"}
            assert not foreign, f"{module} imports {sorted(foreign)}"


def test_the_package_maps_name_every_module():
    # each package's docstring lists its modules, so a newcomer finds every one from orchestrator/__init__.py
    for package in sorted(m for m in GRAPH if (ROOT / m.replace(".", "/") / "__init__.py").is_file()):
        if not package.startswith("orchestrator"):
            continue
        text = ast.get_docstring(ast.parse((ROOT / package.replace(".", "/") / "__init__.py").read_text()))
        children = sorted(m.rpartition(".")[2] for m in GRAPH if m.rpartition(".")[0] == package)
        missing = [c for c in children if f"``{c}``" not in text]
        assert not missing, f"{package}/__init__.py does not name {missing}"


# The units read the scene through typed specs (fmu_common.specs, fmu_common.wing_spec), converted once
# where a unit starts: a string key into a scene table, or a `scene` dict, is a read the specs should carry.
SPEC_READERS = [*sorted((ROOT / "structure_fmu").rglob("*.py")), *sorted((ROOT / "aero_fmu").rglob("*.py")),
                *(ROOT / "fmu_common" / name for name in ("topology.py", "fmi_slave.py", "interface.py"))]
SCENE_TABLES = ("structure", "aero", "flow", "time", "coupling", "bodies", "joints", "masses", "loads", "motion",
                "probes", "strain_gauges", "section", "type", "load", "scissors", "gravity", "fidelity")
SCENE_READS = [re.compile(r"\bscene\s*\["), re.compile(r"\bscene\.get\("), re.compile(r"\bscene\s*:\s*dict"),
               re.compile(r"\[\s*['\"](" + "|".join(SCENE_TABLES) + r")['\"]\s*\]"),
               re.compile(r"\b(spec|joint|body|table|structure|aero|flow|section|motion|probe|gauge|load|mass|chain)"
                          r"\s*\[\s*['\"]")]


def _scene_reads(text: str) -> list[tuple[int, str]]:
    """(line number, line) of each scene read in the source `text`."""
    found = []
    for number, line in enumerate(text.splitlines(), start=1):
        code = line.split("#")[0]
        if any(p.search(code) for p in SCENE_READS):
            found.append((number, line.strip()))
    return found


def test_the_units_read_specs_not_the_scene_dict():
    reads = [f"{path.relative_to(ROOT)}:{number}: {line}" for path in SPEC_READERS
             for number, line in _scene_reads(path.read_text(encoding="utf-8"))]
    assert not reads, "\n".join(reads)


def test_a_scene_read_is_found():
    for line in ('k = scene["structure"]["bodies"]', 'x = joint["stiffness"]', 'def f(scene: dict): pass',
                 'step = structure.get("motion")["frequency"] if x["fidelity"] else 0'):
        assert _scene_reads(line), line
    assert not _scene_reads('values["structure.step"]; parts["corner"]; spec.structure.step  # scene["x"]')


# Choices as named strategies: a fidelity, aero model or integrator is chosen by name only in its registry;
# everywhere else the code asks the chosen object (fmu_common.choices traits, the units' registries).
CHOICE_REGISTRIES = {"fmu_common/choices.py", "structure_fmu/fidelities.py", "structure_fmu/integrators.py",
                     "aero_fmu/models.py"}


def _choice_names():
    from fmu_common import choices
    return {*choices.FIDELITIES, *choices.AERO_MODELS, *choices.INTEGRATORS, "flat", "free"}   # + uvlm-<wake>


CHOICE_NAMES = _choice_names()
PLAIN_WORDS = {"prescribed", "none", "flat", "free"}
"""Choice names that are plain words elsewhere too (a pin's free axis, span_correction none): flagged only where
the compared expression names a fidelity, model, integrator or wake."""
CHOICE_SUBJECTS = re.compile(r"fidelity|model|integrator|wake", re.I)


def _choice_uses(source: str) -> list[tuple[int, str]]:
    """(line, what) of each name-based choice in `source`: a comparison with a choice name, a tuple, list or set
    grouping choice names, a dict keyed by them, a removeprefix of "uvlm-"."""
    found = []
    tree = ast.parse(source)
    for node in ast.walk(tree):
        if isinstance(node, ast.Compare):
            parts = [node.left, *node.comparators]
            names = [c.value for p in parts for c in ast.walk(p) if isinstance(c, ast.Constant)
                     and c.value in CHOICE_NAMES]
            subject = " ".join(ast.unparse(p) for p in parts if not isinstance(p, (ast.Constant, ast.Tuple)))
            if any(n not in PLAIN_WORDS or CHOICE_SUBJECTS.search(subject) for n in names):
                found.append((node.lineno, ast.unparse(node)))
        elif isinstance(node, (ast.Tuple, ast.List, ast.Set)):
            names = [e.value for e in node.elts
                     if isinstance(e, ast.Constant) and e.value in CHOICE_NAMES - PLAIN_WORDS]
            if len(names) >= 2:
                found.append((node.lineno, ast.unparse(node)))
        elif isinstance(node, ast.Dict):
            if any(isinstance(k, ast.Constant) and k.value in CHOICE_NAMES - PLAIN_WORDS for k in node.keys):
                found.append((node.lineno, ast.unparse(node)[:80]))
        elif (isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute) and node.func.attr == "removeprefix"
              and any(isinstance(a, ast.Constant) and str(a.value).startswith("uvlm") for a in node.args)):
            found.append((node.lineno, ast.unparse(node)))
    return found


def test_choices_are_compared_by_name_only_in_their_registries():
    uses = []
    for package in PACKAGES:
        for path in sorted((ROOT / package).rglob("*.py")):
            where = path.relative_to(ROOT).as_posix()
            if where not in CHOICE_REGISTRIES:
                uses += [f"{where}:{line}: {what}" for line, what in _choice_uses(path.read_text(encoding="utf-8"))]
    assert not uses, "\n".join(uses)


def test_a_choice_by_name_is_found():
    for code in ('x = fidelity == "rigid"', 'y = spec.aero.model != "none"', 'z = kind in ("flexible", "strain-based")',
                 'h = {"rk4": 1}', 'w = name.removeprefix("uvlm-")', 'v = structure["integrator"] == "rk4"',
                 'u = self.wake_model == "flat"'):
        assert _choice_uses(code), code
    assert not _choice_uses('a = joint.axis == "free"; b = span_correction == "none"; c = fidelity.deformable')


def test_the_registries_cover_every_choice_of_the_schema():
    from aero_fmu.models import MODELS
    from fmu_common.choices import AERO_MODELS, FIDELITIES, INTEGRATORS
    from fmu_common.scene_schema import SCENE
    from structure_fmu.fidelities import MODELS as STRUCTURAL_MODELS
    from structure_fmu.integrators import INTEGRATORS as INTEGRATOR_CLASSES

    structure, aero = SCENE.keys["structure"].keys, SCENE.keys["aero"].keys
    assert tuple(structure["fidelity"].options) == tuple(FIDELITIES) and set(STRUCTURAL_MODELS) == set(FIDELITIES)
    assert tuple(structure["integrator"].options) == INTEGRATORS and set(INTEGRATOR_CLASSES) == set(INTEGRATORS)
    assert tuple(aero["model"].options) == tuple(AERO_MODELS)
    assert set(MODELS) == {name for name, model in AERO_MODELS.items() if model.builds_unit}
