"""Run an SSP package written by `wingsim export` in OpenModelica's OMSimulator through its Python API, as its
user would (not a test module; the command line is run by the tests directly).

    PYTHONPATH=<omsimulator>/lib python tests/fmi/omsimulator_run.py PACKAGE.ssp STOP RESULT.csv [PARAMETER ...]

Instantiates the package (``OMSimulator.SSP(PACKAGE).instantiate()``), writes every variable at every step to
RESULT.csv, simulates to STOP (s: OMSimulator does not take the SSD's stop time) and prints
``<element>.<PARAMETER>=<value>`` for each named parameter as OMSimulator holds it at the end (the element
``structure_unit`` or ``aero_unit`` that declares it, read back through ``getValue``).

Run as a separate process: a crash of the tool (as with a parameter name it misreads) must not take the test
session with it. Exit code 1 with the error on a failure.
"""
import sys
import zipfile
import xml.etree.ElementTree as ET

SSD = {"ssd": "http://ssp-standard.org/SSP1/SystemStructureDescription"}


def parameters_of(ssp: str) -> tuple[str, dict[str, str]]:
    """(the SSD system's name, {parameter connector name: element name})."""
    with zipfile.ZipFile(ssp) as z:
        system = ET.fromstring(z.read("SystemStructure.ssd")).find("ssd:System", SSD)
    owners = {}
    for component in system.findall("ssd:Elements/ssd:Component", SSD):
        for connector in component.findall("ssd:Connectors/ssd:Connector[@kind='parameter']", SSD):
            owners[connector.get("name")] = component.get("name")
    return system.get("name"), owners


def main(ssp: str, stop: float, result: str, names: list[str]) -> None:
    from OMSimulator import SSP, CRef

    system, owners = parameters_of(ssp)
    model = SSP(ssp).instantiate()
    model.setResultFile(result)
    model.setStopTime(stop)
    model.initialize()
    model.simulate()
    for name in names:
        print(f"{owners[name]}.{name}={float(model.getValue(CRef(system, owners[name], name)))!r}")
    model.terminate()
    model.delete()


if __name__ == "__main__":
    main(sys.argv[1], float(sys.argv[2]), sys.argv[3], sys.argv[4:])
