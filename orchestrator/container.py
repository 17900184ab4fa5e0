"""The coupled system as one FMU (``wing.fmu``), for tools that want a single block.

`write_container(system, path)` builds an FMI 2.0 co-simulation FMU with fmpy's container FMU
(``fmpy.container_fmu``): fmpy's prebuilt ``container_fmu`` binary, kept for the platforms the units have
a binary for, loads the scene's FMUs from its own ``resources/`` and couples them inside. Its model
description is ours:

- the outputs: every Real output of each unit that is not a coupling variable (fold angles, latch times,
  probes, strain gauges, energies of the structure; CL, lift, ... of the aero unit), under the unit's
  own name, with its unit and description;
- the parameters: every parameter of each unit, under the unit's own name, start value as built;
- ``time`` (value reference 0, which the container answers itself).

Names are the units' own (the structure and aero units declare no public name twice; a clash is an
error). The coupling variables (``e``, ``de``, ``Q``) are connected inside and not exposed; a
structure-only scene holds the structure's Q at 0, as ``wingsim run`` does.

How the container steps (fmpy's container, read from its source and checked in the tests): at
``fmi2ExitInitializationMode`` it copies every connection once (the structure's initial e, de to the
aero unit, the aero unit's initial Q, zero, to the structure); each ``fmi2DoStep(t, h)`` takes h /
``coupling.step`` internal steps, in each of which every unit steps from the same inputs and the
connections are copied afterwards: Jacobi coupling, as ``coupling.algorithm = "jacobi"`` of ``wingsim
run``. h must be a multiple of ``coupling.step``; the container cannot roll back (no
``canGetAndSetFMUstate``). fmpy 0.3.32's binary aborts the host process when a unit inside fails to
instantiate (a panic where its source has ``todo!()``): the units' own refusals (a moved build environment, a
GUID that does not match) then end the host instead of returning NULL (docs/fmu.md).
"""
from __future__ import annotations

import os
import tempfile
import uuid
import zipfile
from pathlib import Path

from orchestrator.system import COUPLING, IncompatibleFMUs, System

CONTAINER_FILE = "wing.fmu"


def _container_description(system: System, public: list, parameters: list):
    """fmpy ModelDescription of the container: time first, then the outputs, then the parameters."""
    from fmpy.model_description import (CoSimulation, DefaultExperiment, ModelDescription, ModelVariable,
                                        Unknown)

    def copy(v, **changes):
        fields = dict(name=v.name, type="Real", description=v.description, causality=v.causality,
                      variability=v.variability, initial=v.initial, unit=v.unit, start=v.start)
        fields.update(changes)
        return ModelVariable(**fields)

    time = ModelVariable(name="time", type="Real", causality="independent", variability="continuous",
                         description="simulation time (s)")
    # outputs are computed by the units: no start value in the container (the container would otherwise set
    # it on the unit's output at instantiation, which FMI forbids), so initial="calculated"
    outputs = [copy(v, initial="calculated", start=None) for _, v in public]
    params = [copy(v, initial="exact") for _, v in parameters]
    guids = "|".join(c.model_description.guid for c in system.components)
    units = " and ".join(c.name for c in system.components)
    coupling = (f", coupled inside (Jacobi, step {system.step:g} s)" if system.connections else "")
    description = ModelDescription(
        fmiVersion="2.0", modelName=system.name, instantiationToken=str(uuid.uuid5(uuid.NAMESPACE_URL,
                                                                                   f"wingsim:{guids}")),
        description=f"{system.description or system.name}: the {units} units of wingsim in one FMU{coupling}",
        generationTool="wingsim (fmpy container_fmu)",
        defaultExperiment=DefaultExperiment(startTime=repr(system.start_time), stopTime=repr(system.stop_time),
                                            stepSize=repr(system.step)),
        # any step h that is a multiple of coupling.step (the container refuses others, naming the rule)
        coSimulation=CoSimulation(fixedInternalStepSize=system.step, canHandleVariableCommunicationStepSize=True,
                                  needsExecutionTool=any(c.model_description.coSimulation.needsExecutionTool
                                                         for c in system.components)),
        unitDefinitions=system.unit_definitions,
        modelVariables=[time] + outputs + params)
    description.outputs = [Unknown(variable=v) for v in outputs]
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


def _connectors(component, links) -> list:
    """The variables of `component` named by `links`, typed "Float64": fmpy 0.3.32's ``write_configuration``
    writes a connection's type as the variable declares it, and its container binary rejects the FMI 2 name
    "Real" ("unknown variant `Real`"); "Float64" is the same type under the name it accepts (it converts
    the types of the exposed variables so, but not those of connections)."""
    from fmpy.model_description import ModelVariable

    declared = {v.name: v for v in component.model_description.modelVariables}
    return [ModelVariable(name=c.variable, valueReference=declared[c.variable].valueReference, type="Float64")
            for c in links]


def _platforms(component) -> set[str]:
    """The FMI platform folders (``linux64``, ``win64``, ...) in which the component's FMU has its binary."""
    identifier = component.model_description.coSimulation.modelIdentifier
    with zipfile.ZipFile(component.fmu) as z:
        return {Path(name).parent.name for name in z.namelist()
                if name.startswith("binaries/") and Path(name).stem == identifier}


def _keep_only(archive: Path, platforms: set[str]) -> None:
    """Rewrite the zip `archive` with the container's binaries for `platforms` only (the platforms where every
    unit has its binary: fmpy ships its container binary for four) and without the empty ``Container.zip``
    that fmpy leaves in it (it zips the folder into a file inside that folder)."""
    def kept(name: str) -> bool:
        parts = name.split("/")
        return name != "Container.zip" and not (parts[0] == "binaries" and len(parts) > 1 and parts[1]
                                                and parts[1] not in platforms)

    stripped = archive.with_name(archive.name + ".stripped")
    with zipfile.ZipFile(archive) as source, zipfile.ZipFile(stripped, "w", zipfile.ZIP_DEFLATED) as target:
        for info in source.infolist():
            if kept(info.filename):
                target.writestr(info, source.read(info))
    os.replace(stripped, archive)


def write_container(system: System, path: Path) -> Path:
    """Write the container FMU of `system` to `path` (written whole or not at all); returns `path`."""
    from fmpy.container_fmu.cli import create_container_fmu
    from fmpy.container_fmu.config import Component, Configuration, Connection

    public, parameters = _public_variables(system)
    description, outputs, params = _container_description(system, public, parameters)
    components = {c.name: Component(name=c.name, filename=c.fmu, modelDescription=c.model_description)
                  for c in system.components}
    connections = []
    for block in ("e", "de", "Q"):   # one connection per block: the container copies it with one get/set
        links = [c for c in system.connections if COUPLING.match(c.variable).group(1) == block]
        if links:
            start, end = system.component(links[0].start), system.component(links[0].end)
            connections.append(Connection(components[start.name], _connectors(start, links),
                                          components[end.name], _connectors(end, links)))
    mappings = {container_var: [(components[c.name], v)]
                for container_var, (c, v) in zip(outputs + params, public + parameters)}
    configuration = Configuration(parallelDoStep=False, modelDescription=description,
                                  components=list(components.values()), connections=connections,
                                  variableMappings=mappings)
    path = Path(path)
    partial = path.with_name(f".{path.name}.partial")
    try:
        with tempfile.TemporaryDirectory(prefix="wingsim_container_") as folder:
            unzipdir = Path(folder) / "container"
            unzipdir.mkdir()   # fmpy removes and recreates it
            create_container_fmu(configuration, unzipdir, partial)
        _keep_only(partial, set.intersection(*(_platforms(c) for c in system.components)))
        os.replace(partial, path)
    finally:
        partial.unlink(missing_ok=True)
    return path
