"""Every module of the four packages imports on its own, as the API reference's builder (pdoc,
docs/api_reference.py) imports it: the packages walked with pkgutil.walk_packages, each module imported with
importlib, in a fresh Python that has imported nothing of ours. A module that does not import, raises a warning
from its own code while it imports, or is never reached by the walk (a folder without ``__init__.py``) fails,
named; pdoc need not be installed. Nothing is left out but what EXCLUDED names, each checked another way.
"""
import json
import subprocess
import sys

import pytest

from repository import ROOT
from subprocesses import wingsim

PACKAGES = ("fmu_common", "structure_fmu", "aero_fmu", "orchestrator", "wingsim")
EXCLUDED = {
    "orchestrator.__main__": "runs the command line when imported (`python -m orchestrator`); pdoc skips it too",
}

# In the child: walk the packages and import every module, warnings recorded throughout (the walk imports the
# packages themselves); prints {"walked": [modules], "errors": {module: traceback}, "warned": {module: [warnings
# raised from its file]}} as JSON.
_WALK_AND_IMPORT = r"""
import importlib, json, os, pkgutil, sys, traceback, warnings
root, packages, excluded = sys.argv[1], sys.argv[2].split(","), set(sys.argv[3].split(","))
sys.path.insert(0, root)
walked, errors, warned = [], {}, {}

def walk_error(name):
    errors[name] = traceback.format_exc()

def module_of(filename):
    parts = os.path.relpath(os.path.abspath(filename), root).removesuffix(".py").split(os.sep)
    if parts[0] not in packages:
        return None
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)

with warnings.catch_warnings(record=True) as caught:
    warnings.simplefilter("always")
    for package in packages:
        walked.append(package)
        try:
            module = importlib.import_module(package)
        except BaseException:
            errors[package] = traceback.format_exc()
            continue
        walked += [m.name for m in pkgutil.walk_packages(module.__path__, package + ".", onerror=walk_error)]
    for name in walked:
        if name not in excluded and name not in errors:
            try:
                importlib.import_module(name)
            except BaseException:
                errors[name] = traceback.format_exc()
for w in caught:
    if (name := module_of(w.filename)) is not None:
        warned.setdefault(name, []).append(f"line {w.lineno}: {w.category.__name__}: {w.message}")
print(json.dumps({"walked": walked, "errors": errors, "warned": warned}))
"""


def _on_disk() -> list[str]:
    """The modules of the packages, from their *.py files."""
    names = []
    for package in PACKAGES:
        for path in sorted((ROOT / package).rglob("*.py")):
            parts = path.relative_to(ROOT).with_suffix("").parts
            if "__pycache__" not in parts:
                names.append(".".join(parts[:-1] if parts[-1] == "__init__" else parts))
    return names


MODULES = _on_disk()
_report = {}


def _imported() -> dict:
    """The child's report, made once for the whole module (a second or two)."""
    if not _report:
        proc = subprocess.run([sys.executable, "-c", _WALK_AND_IMPORT, str(ROOT), ",".join(PACKAGES),
                               ",".join(EXCLUDED)], capture_output=True, text=True, timeout=300)
        assert proc.returncode == 0, proc.stderr
        _report.update(json.loads(proc.stdout.splitlines()[-1]))
    return _report


def test_every_module_on_disk_is_found():
    # the list below is not vacuous: the units' slaves, the master's stages and the build's scripts are in it
    assert {"structure_fmu.structure_slave", "aero_fmu.aero_slave", "orchestrator.build.import_trace",
            "orchestrator.export.container", "orchestrator.cli"} <= set(MODULES)
    assert set(EXCLUDED) <= set(MODULES), "an exclusion names no module"


@pytest.mark.parametrize("module", [m for m in MODULES if m not in EXCLUDED])
def test_the_module_imports(module):
    report = _imported()
    assert module in report["walked"], f"{module}: pkgutil.walk_packages does not reach it (is every folder " \
                                       f"above it a package, with __init__.py?); pdoc would leave it out"
    assert module not in report["errors"], f"{module} does not import:\n{report['errors'][module]}"
    assert module not in report["warned"], f"{module} warns when imported:\n" + "\n".join(report["warned"][module])


def test_the_walk_finds_nothing_that_is_not_on_disk():
    assert sorted(set(_imported()["walked"]) - set(MODULES)) == []


def test_main_runs_the_command_line(tmp_path):
    # orchestrator.__main__ is excluded above: importing it runs `wingsim`; here it runs as it is meant to
    proc = wingsim("--help", cwd=tmp_path)
    assert proc.returncode == 0 and "usage: " in proc.stdout, proc.stderr
