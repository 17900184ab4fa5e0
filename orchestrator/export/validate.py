"""`wingsim validate [FMU ...]`: check built FMUs as another FMI 2.0 tool would.

For each FMU: fmpy's model-description validation; the declared variables against the layout the unit's
code registers (names, value references, causality, variability, type, unit: `orchestrator.run.layout`), so a
model description edited after the build fails; then a short simulation through fmpy (the same path as
`wingsim run --backend fmu`): instantiate with the scene embedded in the FMU, 10 communication steps with
neutral inputs (structure: Q = 0; aero: the scene's initial coordinates at rest), every status checked and
every output finite. Without arguments, every FMU under fmus/.
"""
from __future__ import annotations

import shutil
import tempfile
from pathlib import Path

import numpy as np

STEPS = 10


def _kind(path: Path) -> str:
    from fmpy import read_model_description

    identifier = read_model_description(str(path)).coSimulation.modelIdentifier
    if identifier not in ("structure", "aero"):
        raise ValueError(f"model identifier {identifier!r} is not a wingsim unit (structure or aero)")
    return identifier


def _layout(path: Path, kind: str) -> list[str]:
    """Variables the FMU at `path` declares otherwise than its unit's code registers them
    (`orchestrator.run.layout`); empty when they match."""
    import zipfile

    from fmpy import read_model_description

    from orchestrator.build.fmus import BUILD_INFO_RESOURCE
    from orchestrator.run.layout import check
    from fmu_common.fmi_slave import SCENE_RESOURCE

    with tempfile.TemporaryDirectory(prefix="wingsim_layout_") as folder, zipfile.ZipFile(path) as z:
        for name in (SCENE_RESOURCE, BUILD_INFO_RESOURCE):
            if f"resources/{name}" in z.namelist():
                z.extract(f"resources/{name}", folder)
        return check(read_model_description(str(path)), kind, Path(folder, "resources"))


def _simulate(path: Path, kind: str) -> list[str]:
    """Problems found in a short simulation of the FMU at `path` (empty when it runs cleanly)."""
    from orchestrator.build.fmus import embedded_scene
    from orchestrator.run.port import FMU_FILES, UnitError
    from orchestrator.run.units import make_unit
    from fmu_common.wing_spec import StructureSpec
    from fmu_common.topology import Topology

    scene = embedded_scene(path)
    step = scene["coupling"]["step"]
    with tempfile.TemporaryDirectory(prefix="wingsim_validate_") as folder:
        shutil.copy(path, Path(folder) / FMU_FILES[kind])   # the units find an FMU by its kind's file name
        copy = str(Path(folder) / FMU_FILES[kind])

        def named(err: Exception) -> str:
            return str(err).replace(copy, str(path))    # the FMU the user gave, not its temporary copy
        try:
            unit = make_unit(kind, scene, "fmu", folder, check_layout=False)   # validate checked it already
        except UnitError as err:
            return [f"instantiation failed: {named(err)}"]
        try:
            e0 = Topology.from_spec(StructureSpec.from_scene(scene)).initial_coordinates()
            for k in range(STEPS):
                if kind == "structure":
                    unit.set_inputs(np.zeros(unit.n))
                else:
                    unit.set_inputs(e0, np.zeros_like(e0))
                unit.do_step(k * step, step)
                outputs = np.concatenate([np.ravel(o) for o in unit.get_outputs()])
                if not np.all(np.isfinite(outputs)):
                    return [f"non-finite outputs after step {k + 1} (t = {(k + 1) * step:g} s)"]
        except UnitError as err:
            return [f"simulation failed: {named(err)}"]
        finally:
            unit.terminate()
    return []


def validate(path: Path) -> list[str]:
    """All problems of one FMU file: model description, then a short simulation."""
    from fmpy.validation import validate_fmu

    if path.is_dir():
        return [f"a folder, not an FMU file: {path}"]
    if not path.is_file():
        return [f"no such file: {path}"]
    try:
        problems = [f"model description: {p}" for p in validate_fmu(str(path))]
        if problems:
            return problems
        kind = _kind(path)
        return _layout(path, kind) or _simulate(path, kind)
    except Exception as err:  # noqa: BLE001 - a broken file is a finding, not a crash
        return [f"{type(err).__name__}: {err}"]


def main(paths: list[Path]) -> int:
    """Validate the FMUs at `paths` (default: fmus/**/*.fmu); 0 if all pass, 1 otherwise."""
    paths = paths or sorted(Path("fmus").glob("**/*.fmu"))
    if not paths:
        print("error: no FMUs given and none under fmus/ (build one with 'wingsim build SCENE')")
        return 1
    failed = 0
    for path in paths:
        problems = validate(Path(path))
        verdict = f"ok (model description valid, {STEPS} steps simulated)" if not problems else "FAILED"
        print(f"{path}: {verdict}")
        for problem in problems:
            print(f"  - {problem}")
        failed += bool(problems)
    return 1 if failed else 0
