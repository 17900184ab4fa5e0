"""What a unit imports when it runs: run as a script by `orchestrator.build.runtime` while a standalone FMU is built.

    python -I import_trace.py RESOURCES STEPS PACKAGES

imports the slave module named in RESOURCES/slavemodule.txt from RESOURCES (as pythonfmu does), instantiates
its slave class on that folder's scene, and drives it as a host would: experiment set up, initialization,
STEPS communication steps of the scene's `coupling.step`, every Real read and the inputs written, a state
saved, serialized, read back and restored, refused calls, termination. It then imports every standard library
module that the unit's own sources name in an import statement anywhere (inside functions too: a call the run
did not make may import it), and prints, as JSON, every loaded module that comes from a file: {module name:
file}. Itself it imports only `ast`, `json`, `os` and `sys`, so that the list is the unit's. PACKAGES (comma
separated) are the top-level packages of the unit's requirements: any other top-level module of site-packages is
refused as not installed (`OnlyRequired`), so that an optional import of a requirement (numpy.f2py's of
charset_normalizer) takes the path it takes where only the requirements are installed.
"""
import ast
import json
import os
import sys


class OnlyRequired:
    """A meta path finder that refuses, as not installed, every top-level module of site-packages that is not among
    `packages` (the requirements' top-level packages); the standard library and the unit's resources are untouched."""

    def __init__(self, packages):
        installed = set()
        for folder in (p for p in sys.path if os.path.basename(p) in ("site-packages", "dist-packages")):
            if os.path.isdir(folder):
                installed.update(entry.split(".")[0] for entry in os.listdir(folder))
        self.refused = installed - set(packages)

    def find_spec(self, name, path=None, target=None):
        if "." not in name and name in self.refused:
            raise ModuleNotFoundError(f"No module named {name!r} (not among the unit's requirements)", name=name)
        return None


def slave_class(module):
    """The one concrete pythonfmu slave class of the module, as pythonfmu's builder finds it."""
    from pythonfmu import Fmi2Slave
    classes = [c for c in vars(module).values() if isinstance(c, type) and issubclass(c, Fmi2Slave)
               and c is not Fmi2Slave and not getattr(c, "__abstractmethods__", None)]
    if len(classes) != 1:
        raise SystemExit(f"{module.__name__}: {len(classes)} concrete slave classes, expected one")
    return classes[0]


def exercise(slave, steps: int, step: float) -> None:
    """The calls a host makes, in order; refusals are logged by the slave, never raised."""
    real = sorted(vr for vr, v in slave.vars.items() if type(v).__name__ in ("Real", "UnitReal"))
    inputs = [vr for vr in real if slave.vars[vr].causality.name == "input"]
    slave.setup_experiment(0.0)
    slave.enter_initialization_mode()
    slave.exit_initialization_mode()
    t = 0.0
    for _ in range(steps):
        values = slave.get_real(real)
        slave.set_real(inputs, [values[real.index(vr)] * 0.0 for vr in inputs])
        slave.do_step(t, step)
        t += step
    state = slave._get_fmu_state()
    data = type(slave)._fmu_state_to_bytes(state)
    slave._set_fmu_state(type(slave)._fmu_state_from_bytes(data))
    slave.do_step(t + 1.0, step)                # refused: not the unit's time
    slave.get_string([max(real) + 1000])       # refused: no such variable
    slave.terminate()


def imported_modules(sources) -> set[str]:
    """Every module named in an import statement (anywhere: inside functions too) of the Python files `sources`."""
    names = set()
    for source in sources:
        with open(source, encoding="utf-8") as f:
            tree = ast.parse(f.read())
        for node in ast.walk(tree):
            if isinstance(node, ast.Import):
                names.update(alias.name for alias in node.names)
            elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
                names.add(node.module)
    return names


def unit_sources(resources: str) -> list[str]:
    """The unit's own Python files in an FMU's resources folder (pythonfmu's excepted)."""
    found = []
    for folder, subfolders, files in os.walk(resources):
        subfolders[:] = [d for d in subfolders if d not in ("pythonfmu", "__pycache__")]
        found += [os.path.join(folder, f) for f in files if f.endswith(".py")]
    return found


def main(resources: str, steps: int, packages: list[str]) -> None:
    sys.path.insert(0, resources)
    sys.meta_path.insert(0, OnlyRequired(packages))
    with open(f"{resources}/slavemodule.txt", encoding="utf-8") as f:
        name = f.read().strip()
    with open(f"{resources}/scene.json", encoding="utf-8") as f:
        step = float(json.load(f)["coupling"]["step"])
    module = __import__(name)
    slave = slave_class(module)(instance_name="trace", resources=resources, visible=False)
    exercise(slave, steps, step)
    for name in sorted(imported_modules(unit_sources(resources))):
        if name.split(".")[0] in sys.stdlib_module_names:
            __import__(name)
    files = {k: getattr(m, "__file__", None) for k, m in list(sys.modules.items())}
    print(json.dumps({k: f for k, f in files.items() if isinstance(f, str)}))


if __name__ == "__main__":
    main(sys.argv[1], int(sys.argv[2]), [p for p in sys.argv[3].split(",") if p])
