"""The coupled system as one FMU (``wing.fmu``), for tools that want a single block.

`write_container(system, path)` writes an FMI 2.0 co-simulation FMU whose binary is ours: ``container.c``
beside this file, compiled with the system C compiler (``native_binary.c_compiler``) against the FMI 2.0
headers fmpy ships, for ``linux64`` only. The FMU holds:

- ``modelDescription.xml``, ours:
  - the outputs: every Real output of each unit that is not a coupling variable (fold angles, latch times,
    probes, strain gauges, energies of the structure; CL, lift, ... of the aero unit), under the unit's
    own name, with its unit and description;
  - the parameters: every parameter of each unit, under the unit's own name, start value the scene's
    (set on the unit at instantiation: the units may have been built with other values of these tunable keys);
  - ``time`` (value reference 0, which the container answers itself);
- ``resources/<unit>/``: each unit FMU unpacked whole (its binaries, its resources, its model
  description), the permissions of its files kept;
- ``resources/container.txt``: what the binary reads at fmi2Instantiate (the format is in container.c):
  the units, the coupling connections as blocks of value references, the exposed variables and the
  internal step ``coupling.step``;
- ``binaries/linux64/wing.so``, compiled from container.c.

Names are the units' own (the structure and aero units declare no public name twice; a clash is an
error). The coupling variables (``e``, ``de``, ``Q``) are connected inside and not exposed; a
structure-only scene holds the structure's Q at 0, as ``wingsim run`` does.

How the container steps (container.c): at ``fmi2ExitInitializationMode`` it copies every connection once
(the structure's initial e, de to the aero unit, the aero unit's initial Q, zero, to the structure); each
``fmi2DoStep(t, H)``, for any finite H > 0, takes internal steps of ``coupling.step`` from t, the last one
shortened to end at t + H, and in each of them every unit steps from the same inputs and the connections
are copied afterwards: Jacobi coupling, as ``coupling.algorithm = "jacobi"`` of ``wingsim run``. It cannot
roll back (no ``canGetAndSetFMUstate``). A unit's failure returns fmi2Error (fmi2Fatal if the unit's was
fatal) with the unit's message, prefixed with its name, in the host's log.
"""
from __future__ import annotations

import tempfile
import uuid
import zipfile
from pathlib import Path
from time import localtime

from orchestrator.build import native_binary
from orchestrator.export.system import COUPLING, IncompatibleFMUs, System
from orchestrator.files import write_file

CONTAINER_FILE = "wing.fmu"
MODEL_IDENTIFIER = "wing"
SOURCE = Path(__file__).with_name("container.c")
CONFIGURATION = "resources/container.txt"   # the name container.c reads
PLATFORM_DIR = native_binary.PLATFORM_DIR   # the only platform container.c is compiled for


class ContainerUnavailable(RuntimeError):
    """The container's binary cannot be built here (no C compiler, no FMI headers); the message says what is
    missing."""


def _container_description(system: System, public: list, parameters: list):
    """fmpy ModelDescription of the container: time first (value reference 0), then the outputs, then the
    parameters, value references counting up."""
    from fmpy.model_description import (CoSimulation, DefaultExperiment, ModelDescription, ModelVariable,
                                        Unknown)

    def copy(v, **changes):
        fields = dict(name=v.name, type="Real", description=v.description, causality=v.causality,
                      variability=v.variability, initial=v.initial, unit=v.unit, start=v.start)
        fields.update(changes)
        return ModelVariable(**fields)

    time = ModelVariable(name="time", type="Real", causality="independent", variability="continuous",
                         description="simulation time (s)")
    # outputs are computed by the units: no start value in the container, so initial="calculated"
    outputs = [copy(v, initial="calculated", start=None) for _, v in public]
    params = [copy(v, initial="exact", start=repr(c.value(v))) for c, v in parameters]
    for vr, variable in enumerate([time] + outputs + params):
        variable.valueReference = vr
    guids = "|".join(c.model_description.guid for c in system.components)
    units = " and ".join(c.name for c in system.components)
    unit_names = " + ".join(c.model_description.modelName for c in system.components)   # what each unit says it is
    coupling = (f", coupled inside (Jacobi, internal step {system.step:g} s, any communication step)"
                if system.connections else f" (internal step {system.step:g} s, any communication step)")
    description = ModelDescription(
        fmiVersion="2.0", modelName=f"{system.name}: {unit_names}",
        instantiationToken=str(uuid.uuid5(uuid.NAMESPACE_URL,
                                                                                   f"wingsim:{guids}")),
        description=f"{system.description or system.name}: the {units} units of wingsim in one FMU{coupling}",
        generationTool="wingsim (orchestrator/export/container.c)",
        defaultExperiment=DefaultExperiment(startTime=repr(system.start_time), stopTime=repr(system.stop_time),
                                            stepSize=repr(system.step)),
        coSimulation=CoSimulation(modelIdentifier=MODEL_IDENTIFIER, canHandleVariableCommunicationStepSize=True,
                                  needsExecutionTool=any(c.model_description.coSimulation.needsExecutionTool
                                                         for c in system.components)),
        unitDefinitions=system.unit_definitions,
        modelVariables=[time] + outputs + params)
    # outputs change only in fmi2DoStep (it has no inputs); at initialization they are calculated from the
    # parameters, which the InitialUnknowns' default dependencies (every parameter) say
    description.outputs = [Unknown(variable=v, dependencies=[]) for v in outputs]
    description.initialUnknowns = [Unknown(variable=v) for v in outputs]
    return description, outputs, params


def _public_variables(system: System) -> tuple[list, list]:
    """([(component, output)], [(component, parameter)]) the container exposes, names unique."""
    public = [(c, v) for c in system.components for v in c.public_outputs]
    parameters = [(c, v) for c in system.components for v in c.parameters]
    seen: dict[str, str] = {}
    for component, v in public + parameters:
        if v.name in seen:
            raise IncompatibleFMUs(f"both the {seen[v.name]} and the {component.name} unit declare {v.name!r}: "
                                   "the container FMU cannot expose both under one name")
        seen[v.name] = component.name
    return public, parameters


def _configuration(system: System, description, exposed: list) -> str:
    """The text of resources/container.txt (format: container.c's header comment). `exposed` pairs each
    container variable (outputs, then parameters) with its (component, unit variable)."""
    lines = ["# wing.fmu: what its binary (orchestrator/export/container.c) couples", "wingsim-container 1",
             f"guid {description.guid}", f"step {system.step!r}"]
    for c in system.components:
        lines.append(f"unit {c.name} {c.model_description.coSimulation.modelIdentifier} {c.model_description.guid}")
    for block in ("e", "de", "Q"):   # one block per variable name: one get and one set per exchange
        links = [c for c in system.connections if COUPLING.match(c.variable).group(1) == block]
        if links:
            start, end = system.component(links[0].start), system.component(links[0].end)
            refs = [str(_value_reference(start, c.variable)) for c in links]
            refs += [str(_value_reference(end, c.variable)) for c in links]
            lines.append(f"connection {start.name} {end.name} {len(links)} {' '.join(refs)}")
    for container_var, (component, v) in exposed:
        lines.append(f"variable {container_var.valueReference} {v.causality} {component.name} {v.valueReference} "
                     f"{v.name}")
        if v.causality == "parameter":   # the scene's value, which the unit may not have been built with
            lines.append(f"start {container_var.valueReference} {component.value(v)!r}")
    return "\n".join(lines) + "\n"


def _value_reference(component, name: str) -> int:
    return next(v.valueReference for v in component.model_description.modelVariables if v.name == name)


def _compile(folder: Path) -> Path:
    """Compile container.c into `folder`; ContainerUnavailable when the compiler or the FMI headers are
    missing, RuntimeError when the compiler fails."""
    try:
        # the FMI function table and URI headers it shares with the shim live beside the shim's source
        command = native_binary.c_compiler() + ["-I", str(native_binary.fmi_headers()),
                                                "-I", str(native_binary.SHIM_SOURCE.parent)]
    except native_binary.ShimUnavailable as missing:
        raise ContainerUnavailable(f"its binary is compiled from orchestrator/export/{SOURCE.name}, which needs a C "
                                   f"compiler and fmpy's FMI 2.0 headers: {missing}") from None
    binary = folder / f"{MODEL_IDENTIFIER}.so"
    native_binary.run_compiler(command + ["-std=c99", "-shared", "-fPIC", "-O2", "-pthread", "-Wall", "-Wextra",
                                          "-o", str(binary), str(SOURCE), "-ldl"])
    return binary


def _entry(name: str, mode: int) -> zipfile.ZipInfo:
    """A zip entry of the container's own, with its permissions (the units' entries keep theirs)."""
    info = zipfile.ZipInfo(name, date_time=localtime()[:6])
    info.compress_type = zipfile.ZIP_DEFLATED
    info.external_attr = mode << 16
    return info


def _copy_unit(target: zipfile.ZipFile, component) -> None:
    """The unit FMU's every file under resources/<unit>/, permissions (external_attr) as in the unit FMU."""
    with zipfile.ZipFile(component.fmu) as source:
        for info in source.infolist():
            if info.is_dir():
                continue
            entry = zipfile.ZipInfo(f"resources/{component.name}/{info.filename}", date_time=info.date_time)
            entry.external_attr, entry.create_system = info.external_attr, info.create_system
            entry.compress_type = zipfile.ZIP_DEFLATED
            target.writestr(entry, source.read(info))


def write_container(system: System, path: Path) -> Path:
    """Write the container FMU of `system` to `path` (written whole or not at all); returns `path`.
    ContainerUnavailable, before anything is written, when the binary cannot be built here."""
    from fmpy.model_description import write_model_description

    public, parameters = _public_variables(system)
    description, outputs, params = _container_description(system, public, parameters)
    configuration = _configuration(system, description, list(zip(outputs + params, public + parameters)))
    path = Path(path)
    with tempfile.TemporaryDirectory(prefix="wingsim_container_") as folder:
        binary = _compile(Path(folder))
        write_model_description(description, Path(folder) / "modelDescription.xml")

        def write(partial: Path) -> None:   # a temporary name beside `path`, renamed when whole
            with zipfile.ZipFile(partial, "w", zipfile.ZIP_DEFLATED) as fmu:
                fmu.writestr(_entry("modelDescription.xml", 0o644),
                             (Path(folder) / "modelDescription.xml").read_bytes())
                fmu.writestr(_entry(f"{PLATFORM_DIR}/{MODEL_IDENTIFIER}.so", 0o755), binary.read_bytes())
                fmu.writestr(_entry(CONFIGURATION, 0o644), configuration)
                for component in system.components:
                    _copy_unit(fmu, component)

        write_file(path, write)
    return path
