"""`wingsim validate [FMU ...]`: check built FMUs as another FMI 2.0 tool would.

For each FMU: fmpy's model-description validation; the declared variables against the layout the unit's
code registers (names, value references, causality, variability, type, unit: `orchestrator.run.layout`), so a
model description edited after the build fails; then a short simulation through fmpy (the same path as
`wingsim run --backend fmu`): instantiate with the scene embedded in the FMU, 10 communication steps with
neutral inputs (structure: Q = 0; aero: the scene's initial coordinates at rest), every status checked and
every output finite. Without arguments, every FMU under fmus/.

Compliance and physics are reported apart: an FMU fails (exit 1) when it breaks the standard or its own
declarations (the model description, the layout, a call that fails without the unit reporting a divergence);
a compliant FMU whose short simulation diverges (the unit reports it, typed: ``UnitError.diverged``) or gives
non-finite outputs is reported as compliant with that physics finding stated apart (the scene it embeds may
diverge under neutral inputs; ``wingsim run`` is the place to study it).
"""
from __future__ import annotations

import shutil
import tempfile
from dataclasses import dataclass, field
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


@dataclass
class Findings:
    """What `validate` found in one FMU: `compliance` problems (the FMU breaks the FMI standard or its own
    declarations: it fails) and `physics` (its short simulation diverged or gave non-finite outputs through
    compliant calls: stated apart, the FMU is compliant)."""

    compliance: list[str] = field(default_factory=list)
    physics: list[str] = field(default_factory=list)


def _simulate(path: Path, kind: str) -> Findings:
    """The findings of a short simulation of the FMU at `path`: a call that fails other than by the unit's
    reported divergence is a compliance problem; a reported divergence or a non-finite output is physics."""
    from orchestrator.build.fmus import embedded_scene
    from orchestrator.run.port import FMU_FILES, UnitError
    from orchestrator.run.units import make_unit
    from fmu_common.wing_spec import StructureSpec
    from fmu_common.topology import Topology

    scene = embedded_scene(path)
    step = scene["coupling"]["step"]
    found = Findings()
    with tempfile.TemporaryDirectory(prefix="wingsim_validate_") as folder:
        shutil.copy(path, Path(folder) / FMU_FILES[kind])   # the units find an FMU by its kind's file name
        copy = str(Path(folder) / FMU_FILES[kind])

        def named(err: Exception) -> str:
            return str(err).replace(copy, str(path))    # the FMU the user gave, not its temporary copy
        try:
            unit = make_unit(kind, scene, "fmu", folder, check_layout=False)   # validate checked it already
        except UnitError as err:
            found.compliance.append(f"instantiation failed: {named(err)}")
            return found
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
                    found.physics.append(f"non-finite outputs after step {k + 1} (t = {(k + 1) * step:g} s)")
                    break
        except UnitError as err:
            if getattr(err, "diverged", False) is True:   # the unit reported it, typed (never from its text)
                found.physics.append(f"diverged in step {k + 1} (t = {k * step:g} s): {named(err)}")
            else:
                found.compliance.append(f"simulation failed: {named(err)}")
        finally:
            unit.terminate()
    return found


def validate(path: Path) -> Findings:
    """All findings of one FMU file: model description, declared variables, then a short simulation."""
    from fmpy.validation import validate_fmu

    if path.is_dir():
        return Findings([f"a folder, not an FMU file: {path}"])
    if not path.is_file():
        return Findings([f"no such file: {path}"])
    try:
        problems = [f"model description: {p}" for p in validate_fmu(str(path))]
        if problems:
            return Findings(problems)
        kind = _kind(path)
        mismatched = _layout(path, kind)
        return Findings(mismatched) if mismatched else _simulate(path, kind)
    except Exception as err:  # noqa: BLE001 - a broken file is a finding, not a crash
        return Findings([f"{type(err).__name__}: {err}"])


def main(paths: list[Path]) -> int:
    """Validate the FMUs at `paths` (default: fmus/**/*.fmu); 0 if all are compliant (physics findings are
    stated apart and do not fail), 1 otherwise."""
    paths = paths or sorted(Path("fmus").glob("**/*.fmu"))
    if not paths:
        print("error: no FMUs given and none under fmus/ (build one with 'wingsim build SCENE')")
        return 1
    failed = 0
    for path in paths:
        found = validate(Path(path))
        if found.compliance:
            verdict = "FAILED"
        elif found.physics:
            verdict = "compliant (model description valid); physics: its short simulation did not run cleanly"
        else:
            verdict = f"ok (model description valid, {STEPS} steps simulated)"
        print(f"{path}: {verdict}")
        for problem in found.compliance:
            print(f"  - {problem}")
        for note in found.physics:
            print(f"  - physics: {note}")
        failed += bool(found.compliance)
    return 1 if failed else 0
