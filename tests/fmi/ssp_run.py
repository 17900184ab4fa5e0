"""Run an SSP package written by `wingsim export` in another tool, as its user would (not a test module).

    python tests/fmi/ssp_run.py libcosim PACKAGE.ssp [PARAMETER ...]
    python tests/fmi/ssp_run.py fmpy PACKAGE.ssp

The stop time and the communication step are read from the package's SystemStructure.ssd
(DefaultExperiment stopTime; the step of its com.opensimulationplatform annotation):

- libcosim (libcosimpy's SSP loader, ``CosimExecution.from_ssp_file`` without a step: libcosim takes the
  algorithm and its step from the annotation itself) steps to the stop time;
- fmpy (``fmpy.ssp.simulation.simulate_ssp``, which reads no experiment from the SSD) is given them, with
  the package's parameter bindings as its parameter set (fmpy does not apply the SSD's bindings itself).

Prints ``deployment_time_s=<value>`` (the structure's output ``latch_time_fold`` at the end), with libcosim
``time_s=<value>`` (the time reached), with fmpy ``steps=<count>`` (the steps taken); with libcosim also
``<PARAMETER>=<value>`` for each named parameter of the structure or aero component as libcosim holds it at
the end, and ``<element>.<output>=<value>`` for every Real output of every component at the end. Exit code 1 with
the error on a failure.
Run as a separate process: libcosim may crash at interpreter exit after a failure (docs/fmu.md, libcosim), so the
script leaves by os._exit once its answer is printed.
"""
import os
import sys
import zipfile
import xml.etree.ElementTree as ET

SSD = {"ssd": "http://ssp-standard.org/SSP1/SystemStructureDescription",
       "ssc": "http://ssp-standard.org/SSP1/SystemStructureCommon",
       "osp": "http://opensimulationplatform.com/SSP/OSPAnnotations"}


def experiment(ssp: str) -> tuple[float, float]:
    """(stop time, communication step) in s, from the package's SystemStructure.ssd."""
    with zipfile.ZipFile(ssp) as z:
        root = ET.fromstring(z.read("SystemStructure.ssd"))
    default = root.find("ssd:DefaultExperiment", SSD)
    step = default.find("ssd:Annotations/ssc:Annotation/osp:Algorithm/osp:FixedStepAlgorithm", SSD)
    return float(default.get("stopTime")), float(step.get("baseStepSize"))


def run_libcosim(ssp: str, stop: float, step: float, parameters: list[str]) -> None:
    from libcosimpy.CosimEnums import CosimVariableCausality, CosimVariableType
    from libcosimpy.CosimExecution import CosimExecution
    from libcosimpy.CosimLogging import CosimLogLevel, log_output_level
    from libcosimpy.CosimObserver import CosimObserver

    log_output_level(CosimLogLevel.ERROR)
    execution = CosimExecution.from_ssp_file(ssp)
    index = {info.name.decode(): info.index for info in execution.slave_infos()}
    refs = {(unit, v.name.decode()): (i, v.reference) for unit, i in index.items()
            for v in execution.slave_variables(i)}
    observer = CosimObserver.create_last_value()
    execution.add_observer(observer)
    for k in range(int(round(stop / step))):
        if not execution.step(1):
            raise SystemExit(f"libcosim step failed at t = {k * step:g} s")
    reached = execution.status().current_time * 1e-9
    print(f"time_s={reached!r}")
    for unit, i in index.items():
        for v in execution.slave_variables(i):
            if (CosimVariableCausality(v.causality), CosimVariableType(v.type)) == (CosimVariableCausality.OUTPUT,
                                                                                 CosimVariableType.REAL):
                print(f"{unit}.{v.name.decode()}={float(observer.last_real_values(i, [v.reference])[0])!r}")
    if ("structure_unit", "latch_time_fold") in refs:
        structure, latch = refs[("structure_unit", "latch_time_fold")]
        print(f"deployment_time_s={float(observer.last_real_values(structure, [latch])[0])!r}")
    for name in parameters:
        unit, vr = next(refs[(u, name)] for u in ("structure_unit", "aero_unit") if (u, name) in refs)
        print(f"{name}={float(observer.last_real_values(unit, [vr])[0])!r}")
    del execution


def run_fmpy(ssp: str, stop: float, step: float) -> None:
    from fmpy.ssp.simulation import simulate_ssp

    from orchestrator.export.ssp import parameter_set_for_fmpy

    result = simulate_ssp(ssp, stop_time=stop, step_size=step, parameter_set=parameter_set_for_fmpy(ssp))
    print(f"steps={len(result)}")   # one row per step: the time it started from, the outputs it ended with
    print(f"deployment_time_s={float(result['structure_unit.latch_time_fold'][-1])!r}")


if __name__ == "__main__":
    tool, package = sys.argv[1], sys.argv[2]
    stop_time, step_size = experiment(package)
    if tool == "libcosim":
        run_libcosim(package, stop_time, step_size, sys.argv[3:])
    elif tool == "fmpy":
        run_fmpy(package, stop_time, step_size)
    else:
        raise SystemExit(f"unknown tool {tool!r}: libcosim or fmpy")
    sys.stdout.flush()
    os._exit(0)
