"""Size bounds of a scene: what keeps a run within seconds-to-hours and a few GiB, checked at load.

Bounds on one key (elements per body, panels per body, coupling iterations) are declared with the key
(`fmu_common.scene_schema`); `check_sizes` checks the bounds that combine keys: internal steps per
communication step, communication steps per run, bound panels of the whole wing, and a rough estimate of
the memory the run holds. Each refusal names the key, the bound and why. The bounds are generous for real
use (the shipped scenes and the benchmark grids stay well below them); what they refuse is a typo
(`structure.step = 1e-300`, `time.stop = 1e9`) that would otherwise hang or end in MemoryError far from its
cause.
"""
from __future__ import annotations

import math

from .choices import aero_model, fidelity
from .errors import SceneError

MAX_ELEMENTS_PER_BODY = 100
MAX_CHORDWISE_PANELS = 100
MAX_SPANWISE_PANELS = 1000
MAX_PANELS = 4096
MAX_COUPLING_ITERATIONS = 1000
MAX_STEPS_PER_COMMUNICATION = 100_000
MAX_COMMUNICATION_STEPS = 10_000_000
MAX_MEMORY_BYTES = 4 * 2**30
MAX_WAKE_ROWS = 1000
"""Rows of a shed wake (uvlm-prescribed, uvlm-free): a cap, not a refusal; older rows are dropped."""

DENSE_STRUCTURE = "the structure's matrices are dense in its 9 (elements + 1) coordinates per body"
DENSE_AERO = "the aero unit's influence matrices are dense in the bound panels"

BOUNDS = (
    ("structure.elements_per_body", f"<= {MAX_ELEMENTS_PER_BODY}",
     f"{DENSE_STRUCTURE}: memory grows as their square, each factorization as their cube (the shipped scenes "
     "use at most 15)"),
    ("aero.chordwise_panels", f"<= {MAX_CHORDWISE_PANELS}", DENSE_AERO),
    ("aero.spanwise_panels", f"<= {MAX_SPANWISE_PANELS}", DENSE_AERO),
    ("bodies x chordwise x spanwise panels (strips for strip theory)", f"<= {MAX_PANELS}",
     f"{DENSE_AERO}: about 12 x 8 bytes per panel pair (1.5 GiB at {MAX_PANELS} panels) and O(panels^3) per "
     "factorization (the shipped scenes and benchmarks use at most a few hundred)"),
    ("coupling.max_iterations", f"<= {MAX_COUPLING_ITERATIONS}",
     "each implicit iteration repeats the step of both units: a step that needs more is better refined (a "
     "shorter coupling.step) than iterated"),
    ("coupling.step / structure.step, coupling.step / aero.step", f"<= {MAX_STEPS_PER_COMMUNICATION:,}",
     "a unit takes its internal steps inside one communication step without returning to the host, which "
     "meanwhile can neither report progress nor stop it"),
    ("time.stop / coupling.step", f"<= {MAX_COMMUNICATION_STEPS:,}", "every communication step is a row of "
     "timeseries.csv"),
    ("estimated memory of the run", f"<= {MAX_MEMORY_BYTES / 2**30:g} GiB",
     "so that a sweep's worker processes run side by side within a workstation's memory (the estimate: "
     "`fmu_common.scene_bounds.memory_estimate`)"),
    ("rows of a shed wake", f"capped at {MAX_WAKE_ROWS}", "older rows are dropped (not a refusal): it bounds "
     "the cost of a wake at a flow speed near zero, or of wake_length = inf"),
)
"""(what, bound, why) of each size bound, for docs/scenes.md."""

AERO_INPUT_RECORD_VALUES = 20_000_000
"""The master records the aero unit's inputs (e, de of each step, for the wake pictures) up to this many
numbers (8 bytes each), then stops recording."""

ROW_BYTES = 120
"""Memory of one recorded sample beyond its 8-byte numbers (a numpy row and its list entry)."""


def _ratio_check(key: str, value: float, numerator: float, numerator_key: str, limit: int, what: str) -> None:
    """SceneError unless numerator / value <= limit."""
    if numerator / value > limit * (1 + 1e-9):
        raise SceneError(key, value, f"a value >= {numerator_key} / {limit:g} = {numerator / limit:.3g} s: at most "
                                     f"{limit:,} {what} ({numerator_key} / {key} = {numerator / value:.3g})")


def wing_panels(scene: dict) -> int:
    """Bound panels of the whole wing: bodies x chordwise x spanwise (strips for strip theory); 0 without aero.

    Args:
        scene: the resolved scene.
    """
    aero, bodies = scene["aero"], len(scene["structure"]["bodies"])
    model = aero_model(aero["model"])
    if not model.builds_unit:
        return 0
    chordwise = aero["chordwise_panels"] if model.chordwise else 1
    return bodies * chordwise * aero["spanwise_panels"]


def body_elements(structure: dict, body: dict) -> int:
    """Elements of a body: its own `elements` if given, else elements_per_body for a deformable fidelity.

    One for a rigid or prescribed body (Otsuka et al. 2019, Sec. IV; `fmu_common.choices.Fidelity`).

    Args:
        structure: the resolved `structure` table.
        body: one of its resolved bodies.
    """
    if body.get("elements") is not None:
        return body["elements"]
    return structure["elements_per_body"] if fidelity(structure["fidelity"]).deformable else 1


def structure_coordinates(scene: dict) -> int:
    """Exchanged coordinates: 9 per node, elements + 1 nodes per body.

    Args:
        scene: the resolved scene.
    """
    structure = scene["structure"]
    return 9 * sum(body_elements(structure, body) + 1 for body in structure["bodies"])


def communication_steps(scene: dict) -> int:
    """Samples of the run: one per communication step and the one at t = 0.

    Args:
        scene: the resolved scene.
    """
    return int(scene["time"]["stop"] / scene["coupling"]["step"]) + 1


def memory_estimate(scene: dict) -> dict[str, tuple[str, float]]:
    """Rough memory (bytes) a run holds, by part: {part: (the key that sizes it, bytes)}.

    time series: one row per communication step of 8-byte numbers (time, 9 per probe, one per hinge, strain
    gauge, monitor and aero column) plus ROW_BYTES; structure: about 14 dense matrices of the coordinates'
    size (maps, mass, tangent and constraint matrices, the LU and their temporaries); aero: about 12 dense
    matrices of the bound panels' size (influence, their contractions, the LU, temporaries); aero input
    record: e and de of each aero step, at most AERO_INPUT_RECORD_VALUES numbers; structure coordinate record:
    E of each communication step (a numpy row and its time, a float in a list: ROW_BYTES + 32 bytes beyond
    its numbers), thinned to about AERO_INPUT_RECORD_VALUES numbers (``orchestrator.run.master.StructureCoordinates``);
    shed wake: 4 numbers per corner (position, circulation) of at most MAX_WAKE_ROWS rows, in about 8 copies
    (states saved for implicit coupling, the velocities of a free wake). The factors were measured on the
    shipped scenes refined (structure: 50 and 100 elements per body; aero: 1024 and 2048 panels).

    Args:
        scene: the resolved scene.
    """
    steps = communication_steps(scene)
    hinges = sum(1 for j in scene["structure"]["joints"] if j["type"] == "revolute")
    columns = 1 + 9 * len(scene["probes"]) + hinges + len(scene["strain_gauges"]) + 3 + 4
    n = structure_coordinates(scene)
    kept = min(steps, math.ceil(steps / math.ceil(steps * n / AERO_INPUT_RECORD_VALUES)) + 1)
    parts = {"time series": ("time.stop", steps * (8.0 * columns + ROW_BYTES)),
             "structure matrices": ("structure.elements_per_body", 14 * 8.0 * n * n),
             "structure coordinate record": ("time.stop", kept * (8.0 * n + ROW_BYTES + 32))}
    panels = wing_panels(scene)
    if panels:
        aero = scene["aero"]
        parts["aero influence matrices"] = ("aero.spanwise_panels", 12 * 8.0 * panels * panels)
        aero_steps = steps * aero_steps_per_communication(scene)
        parts["aero input record"] = ("time.stop", 8.0 * min(2.0 * n * aero_steps, AERO_INPUT_RECORD_VALUES))
        if aero_model(aero["model"]).sheds_wake:
            rows = min(aero_steps, MAX_WAKE_ROWS) + 1
            corners = len(scene["structure"]["bodies"]) * rows * (aero["spanwise_panels"] + 1)
            parts["shed wake"] = ("aero.spanwise_panels", 8 * 4 * 8.0 * corners)
    return parts


_STEP_SLACK = 1e-9      # relative: an interval within rounding of aero.step (or of k aero.steps) is not split


def substep_count(interval: float, step) -> int:
    """Number k of equal aero steps over a communication interval: ceil(interval / step).

    With a 1e-9 relative slack so that rounding never adds a step.

    Args:
        interval: the communication interval, s.
        step: the internal aero step, s; None: 1 step.
    """
    if step is None or not interval > step * (1 + _STEP_SLACK):
        return 1
    return math.ceil(interval / step - _STEP_SLACK)


def aero_steps_per_communication(scene: dict) -> int:
    """Aero steps in one communication step (`substep_count` of coupling.step).

    Args:
        scene: the resolved scene.
    """
    return substep_count(scene["coupling"]["step"], scene["aero"]["step"])


def check_sizes(scene: dict) -> None:
    """SceneError naming the key when the resolved scene exceeds a size bound (module docstring).

    Args:
        scene: the resolved scene.
    """
    coupling = scene["coupling"]
    _ratio_check("structure.step", scene["structure"]["step"], coupling["step"], "coupling.step",
                 MAX_STEPS_PER_COMMUNICATION, "internal structure steps per communication step")
    if scene["aero"]["step"] is not None and aero_model(scene["aero"]["model"]).builds_unit:
        _ratio_check("aero.step", scene["aero"]["step"], coupling["step"], "coupling.step",
                     MAX_STEPS_PER_COMMUNICATION, "internal aero steps per communication step")
    steps = scene["time"]["stop"] / coupling["step"]
    if steps > MAX_COMMUNICATION_STEPS:
        raise SceneError("time.stop", scene["time"]["stop"],
                         f"at most {MAX_COMMUNICATION_STEPS:,} communication steps, each a row of timeseries.csv: "
                         f"time.stop / coupling.step = {steps:.3g}; shorten time.stop or lengthen coupling.step")
    panels = wing_panels(scene)
    if panels > MAX_PANELS:
        raise SceneError("aero.spanwise_panels", scene["aero"]["spanwise_panels"],
                         f"at most {MAX_PANELS} bound panels on the whole wing (bodies x chordwise x spanwise = "
                         f"{panels}): {DENSE_AERO}, their memory grows as its square and a factorization as "
                         "its cube")
    parts = memory_estimate(scene)
    total = sum(size for _, size in parts.values())
    if total > MAX_MEMORY_BYTES:
        part, (key, _) = max(parts.items(), key=lambda item: item[1][1])
        listed = ", ".join(f"{name} {size / 2**30:.2g} GiB" for name, (_, size) in parts.items())
        value = scene
        for name in key.split("."):
            value = value[name]
        raise SceneError(key, value, f"a run of at most {MAX_MEMORY_BYTES / 2**30:g} GiB of estimated memory; "
                                     f"this one needs {total / 2**30:.3g} GiB, most of it the {part} ({listed})")
