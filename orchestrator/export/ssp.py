"""The coupled system as a System Structure and Parameterization package (SSP 1.0, `.ssp`).

`write_ssp(system, path)` writes a zip holding ``SystemStructure.ssd`` and the FMUs as
``resources/<component>.fmu``. The SSD (`system_structure`) has:

- one Component per FMU, with a Connector for each connected input, each Real output and each
  parameter (name and unit as the FMU declares them);
- every coupling Connection of ``orchestrator.export.system`` (``e[k]``, ``de[k]``: structure -> aero;
  ``Q[k]``: aero -> structure);
- on each Component, a ParameterBinding with an inline ``ssv:ParameterSet`` holding its parameters at
  the scene's values (the FMUs are shared by the variants of a scene that differ in tunable keys only:
  each variant's package carries its own parameter set), names as in the FMU (libcosim applies them; fmpy's
  ``simulate_ssp`` applies only a parameter set passed to it, with names ``<component>.<parameter>``:
  `parameter_set_for_fmpy` builds that set);
- the Units of the FMUs' UnitDefinitions;
- a DefaultExperiment (startTime 0, stopTime ``time.stop``) whose annotation of type
  ``com.opensimulationplatform`` gives the communication step (``osp:FixedStepAlgorithm baseStepSize``,
  s): SSP 1.0 has no attribute for a step, and this annotation is the one libcosim reads;
- on the System, an annotation of type ``org.openmodelica`` with the same step for OMSimulator's fixed-step
  master (``oms:FixedStepMaster``, "oms-ma"): OMSimulator cannot give a root system a type without it.

SSP 1.0 gives a step to no tool, so each tool that needs one gets its own annotation; every tool ignores the
others'. Every namespace is declared on the root element with the prefixes ssd, ssc, ssv, osp and oms:
libcosim's parser matches elements by these literal prefixes.

The elements are named ``structure_unit`` and ``aero_unit`` (`element_name`), not after the units' kinds: the
parameters are named by their dotted scene keys (``structure.step``, ``structure.joints.fold.stiffness``), and
OMSimulator resolves a parameter ``structure.step`` bound on an element named ``structure`` as that element's
variable ``step``.
"""
from __future__ import annotations

import zipfile
import xml.etree.ElementTree as ET
from pathlib import Path

from orchestrator.export.system import System
from orchestrator.files import write_file

SSD_FILE = "SystemStructure.ssd"
SSP_VERSION = "1.0"
NAMESPACES = {
    "ssd": "http://ssp-standard.org/SSP1/SystemStructureDescription",
    "ssc": "http://ssp-standard.org/SSP1/SystemStructureCommon",
    "ssv": "http://ssp-standard.org/SSP1/SystemStructureParameterValues",
    "osp": "http://opensimulationplatform.com/SSP/OSPAnnotations",
    "oms": "https://raw.githubusercontent.com/OpenModelica/OMSimulator/master/schema/oms.xsd",
}
OSP_ANNOTATION = "com.opensimulationplatform"
OMS_ANNOTATION = "org.openmodelica"
OMS_TOLERANCE = "0.0001"   # OMSimulator's default; its fixed-step master without algebraic loops never uses it
BASE_UNIT_EXPONENTS = ("kg", "m", "s", "A", "K", "mol", "cd", "rad")


def _tag(qualified: str) -> str:
    prefix, name = qualified.split(":")
    return f"{{{NAMESPACES[prefix]}}}{name}"


def _sub(parent: ET.Element, qualified: str, **attributes) -> ET.Element:
    return ET.SubElement(parent, _tag(qualified), {k: v for k, v in attributes.items() if v is not None})


def _number(value) -> str:
    """A Real as XML text that reads back to the same double."""
    return repr(float(value))


def element_name(component: str) -> str:
    """The SSD element of a component ("structure" or "aero"): ``structure_unit``, ``aero_unit`` (module
    docstring: no parameter name starts with it)."""
    return f"{component}_unit"


def component_source(name: str) -> str:
    """Where a component's FMU lies in the package, relative to the SSD."""
    return f"resources/{element_name(name)}.fmu"


def system_structure(system: System) -> bytes:
    """The text of ``SystemStructure.ssd`` (UTF-8) for `system`."""
    for prefix, uri in NAMESPACES.items():
        ET.register_namespace(prefix, uri)
    root = ET.Element(_tag("ssd:SystemStructureDescription"), {"version": SSP_VERSION, "name": system.name,
                                                               "generationTool": "wingsim"})
    node = _sub(root, "ssd:System", name=system.name, description=system.description or None)
    elements = _sub(node, "ssd:Elements")
    connected_inputs = {(c.end, c.variable) for c in system.connections}
    for component in system.components:
        _component(elements, component, connected_inputs, system.name)
    if system.connections:
        connections = _sub(node, "ssd:Connections")
        for c in system.connections:
            _sub(connections, "ssd:Connection", startElement=element_name(c.start), startConnector=c.variable,
                 endElement=element_name(c.end), endConnector=c.variable)
    oms = _sub(_sub(_sub(_sub(node, "ssd:Annotations"), "ssc:Annotation", type=OMS_ANNOTATION), "oms:Annotations"),
               "oms:SimulationInformation")
    _sub(oms, "oms:FixedStepMaster", description="oms-ma", stepSize=_number(system.step),
         absoluteTolerance=OMS_TOLERANCE, relativeTolerance=OMS_TOLERANCE)
    _units(root, system.unit_definitions)
    experiment = _sub(root, "ssd:DefaultExperiment", startTime=_number(system.start_time),
                      stopTime=_number(system.stop_time))
    annotation = _sub(_sub(experiment, "ssd:Annotations"), "ssc:Annotation", type=OSP_ANNOTATION)
    _sub(_sub(annotation, "osp:Algorithm"), "osp:FixedStepAlgorithm", baseStepSize=_number(system.step))
    ET.indent(root)
    return ET.tostring(root, encoding="utf-8", xml_declaration=True)


def _component(elements: ET.Element, component, connected_inputs: set, system_name: str) -> None:
    """The Component element: its connectors and its parameter binding."""
    element = _sub(elements, "ssd:Component", name=element_name(component.name), type="application/x-fmu-sharedlibrary",
                   source=component_source(component.name), implementation="CoSimulation")
    connectors = _sub(element, "ssd:Connectors")
    # unconnected inputs are left out (SSP requires only connected ones): they keep their start values
    inputs = [v for v in component.variables("input") if (component.name, v.name) in connected_inputs]
    for kind, variables in (("input", inputs), ("output", component.variables("output")),
                            ("parameter", component.parameters)):
        for v in variables:
            connector = _sub(connectors, "ssd:Connector", name=v.name, kind=kind, description=v.description)
            _sub(connector, "ssc:Real", unit=v.unit)
    if component.parameters:
        binding = _sub(_sub(element, "ssd:ParameterBindings"), "ssd:ParameterBinding")
        parameter_set = _sub(_sub(binding, "ssd:ParameterValues"), "ssv:ParameterSet", version=SSP_VERSION,
                             name=f"{system_name} {element_name(component.name)}")
        parameters = _sub(parameter_set, "ssv:Parameters")
        for v in component.parameters:
            _sub(_sub(parameters, "ssv:Parameter", name=v.name), "ssv:Real", value=_number(component.value(v)))


def _units(root: ET.Element, units: list) -> None:
    """The Units element from fmpy ``Unit`` objects (exponents and factor/offset that differ from 0 and 1)."""
    if not units:
        return
    node = _sub(root, "ssd:Units")
    for unit in units:
        base = unit.baseUnit
        attributes = {k: str(getattr(base, k)) for k in BASE_UNIT_EXPONENTS if base and getattr(base, k)}
        if base and base.factor != 1.0:
            attributes["factor"] = _number(base.factor)
        if base and base.offset != 0.0:
            attributes["offset"] = _number(base.offset)
        _sub(_sub(node, "ssc:Unit", name=unit.name), "ssc:BaseUnit", **attributes)


def write_ssp(system: System, path: Path) -> Path:
    """Write the SSP package of `system` to `path` (written whole or not at all); returns `path`."""
    def write(partial: Path) -> None:   # a temporary name beside `path`, renamed when whole
        with zipfile.ZipFile(partial, "w", compression=zipfile.ZIP_DEFLATED) as z:
            z.writestr(SSD_FILE, system_structure(system))
            for component in system.components:   # FMUs are zips already: stored, not compressed again
                z.write(component.fmu, component_source(component.name), compress_type=zipfile.ZIP_STORED)

    return write_file(Path(path), write)


def parameter_set_for_fmpy(ssp: Path):
    """The parameter bindings of an SSP written by `write_ssp`, as the one ``fmpy.ssp.ssd.ParameterSet``
    that ``fmpy.ssp.simulation.simulate_ssp(..., parameter_set=...)`` applies (fmpy reads the bindings of
    the SSD but does not apply them itself; it expects names ``<component>.<parameter>``)."""
    from fmpy.ssp.ssd import Parameter, ParameterSet, find_components, read_ssd

    ssd = read_ssd(str(ssp))
    combined = ParameterSet(name=ssd.name)
    for component in find_components(ssd.system):
        for binding in component.parameterBindings:
            for parameter_set in binding.parameterValues:
                combined.parameters += [Parameter(name=f"{component.name}.{p.name}", type=p.type, value=p.value,
                                                  unit=p.unit) for p in parameter_set.parameters]
    return combined
