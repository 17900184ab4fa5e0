"""The variables an FMU declares, checked against the layout its unit's code reports.

A model description is a file in a zip: editing it (two value references or two names swapped) would make
a host read the fold angle into the energy column. The layout the unit really has comes from the code:
the installed slave class (the one the direct backend instantiates, `orchestrator.run.port.KINDS`) is
instantiated with the FMU's own embedded scene, and its registered variables (pythonfmu `Fmi2Slave.vars`,
each as its `to_xml()` writes it) are compared with the model description fmpy reads: name, value
reference, causality, variability, type and unit of every variable.

The comparison is only meaningful when the FMU was built from the installed sources: the FMU's
`build_info.json` digest (`orchestrator.build.fmus`) says so. When it differs, a mismatch is reported as a stale
build to rebuild rather than as tampering.

Instantiating a slave costs a few milliseconds (the solver is built, no step is taken).
"""
from __future__ import annotations

import importlib
import json
from dataclasses import dataclass
from pathlib import Path

MAX_LISTED = 6
"""At most this many mismatches are named; the rest are counted."""


@dataclass(frozen=True)
class Variable:
    """One scalar variable as a model description declares it (FMI 2.0 defaults filled in)."""

    value_reference: int
    causality: str
    variability: str
    type: str
    unit: str | None

    def differences(self, other: "Variable") -> tuple[list[str], list[str]]:
        """(['valueReference 109', ...] of self, [the same fields of other]) for the fields that differ."""
        labels = {"value_reference": "valueReference", "causality": "causality", "variability": "variability",
                  "type": "type", "unit": "unit"}
        fields = [f for f in labels if getattr(self, f) != getattr(other, f)]
        return ([f"{labels[f]} {getattr(self, f)}" for f in fields], [f"{getattr(other, f)}" for f in fields])


def declared_layout(model_description) -> dict[str, Variable]:
    """{name: Variable} of an fmpy ModelDescription (`fmpy.read_model_description`)."""
    return {v.name: Variable(int(v.valueReference), v.causality or "local", v.variability or "continuous",
                             v.type, v.unit or None)
            for v in model_description.modelVariables}


def unit_layout(kind: str, resources: Path) -> dict[str, Variable]:
    """{name: Variable} the installed slave of `kind` registers when instantiated with `resources`
    (a folder holding the FMU's `scene.json`). Raises whatever the slave's construction raises."""
    from orchestrator.run.port import KINDS

    module, class_name = KINDS[kind].slave
    slave = getattr(importlib.import_module(module), class_name)(instance_name=f"{kind} layout",
                                                                 resources=str(resources))
    layout = {}
    for var in slave.vars.values():
        node = var.to_xml()
        typed = node[0]
        layout[node.get("name")] = Variable(int(node.get("valueReference")), node.get("causality", "local"),
                                            node.get("variability", "continuous"), typed.tag,
                                            typed.get("unit"))
    return layout


def mismatches(declared: dict[str, Variable], reported: dict[str, Variable], kind: str) -> list[str]:
    """One line per variable declared otherwise than the `kind` unit registers it, in value-reference order."""
    lines = []
    for name, var in declared.items():
        if name not in reported:
            lines.append((var.value_reference, f"modelDescription.xml declares {name} (valueReference "
                                               f"{var.value_reference}), which the {kind} unit does not have"))
        elif var != reported[name]:
            ours, theirs = var.differences(reported[name])
            lines.append((reported[name].value_reference, f"modelDescription.xml declares {name} with "
                          f"{' and '.join(ours)}, the {kind} unit registers it with {' and '.join(theirs)}"))
    lines += [(var.value_reference, f"the {kind} unit's {name} (valueReference {var.value_reference}) is not "
                                    "declared in modelDescription.xml")
              for name, var in reported.items() if name not in declared]
    return [text for _, text in sorted(lines, key=lambda item: item[0])]


def _shorten(lines: list[str]) -> list[str]:
    more = len(lines) - MAX_LISTED
    return lines[:MAX_LISTED] + ([f"... and {more} more variables declared otherwise"] if more > 0 else [])


def _built_from_installed_sources(kind: str, resources: Path) -> tuple[bool, str]:
    """(True, "") when the FMU's build_info.json names the installed sources, else (False, why not)."""
    from orchestrator.build.fmus import BUILD_INFO_RESOURCE
    from orchestrator.build.sources import source_digest

    try:
        info = json.loads((Path(resources) / BUILD_INFO_RESOURCE).read_text(encoding="utf-8"))
        built = info["sources_sha256"]
    except (OSError, ValueError, KeyError, TypeError) as exc:
        return False, f"its {BUILD_INFO_RESOURCE} is missing or unreadable ({type(exc).__name__}: {exc})"
    if built != source_digest(kind):
        return False, "it was built from other sources than the installed wingsim (build_info sources_sha256 differs)"
    return True, ""


def check(model_description, kind: str, resources: Path) -> list[str]:
    """Problems of an FMU of `kind` ("structure" | "aero") whose model description fmpy read and whose
    resources folder (extracted) is `resources`; empty when every declared variable matches the unit."""
    current, why_not = _built_from_installed_sources(kind, resources)
    rebuild = "rebuild it (wingsim build SCENE)"
    try:
        reported = unit_layout(kind, resources)
    except Exception as exc:  # noqa: BLE001 - a unit that cannot report its layout is a finding
        cause = f"{type(exc).__name__}: {exc}"
        if not current:
            return [f"the layout of its variables cannot be checked: {why_not}, and the installed {kind} unit "
                    f"cannot be instantiated with its scene ({cause}); {rebuild}"]
        return [f"the installed {kind} unit cannot be instantiated with the FMU's scene to check its layout: "
                f"{cause}"]
    found = mismatches(declared_layout(model_description), reported, kind)
    if not found:
        return []
    if not current:
        return [f"its variables differ from the installed {kind} unit's ({found[0]}"
                + (f"; {len(found) - 1} more" if len(found) > 1 else "") + f"), but {why_not}: {rebuild}"]
    return _shorten(found)
