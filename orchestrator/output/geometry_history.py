"""The geometry of a run at chosen instants, for the animation (``orchestrator.output.animation``) and the
ParaView files (``orchestrator.output.vtk``): the structure's nodes, elements and reference lines from the
exchanged coordinates E the master recorded (``RunResult.structure_coordinates``), and, for a scene with an
aero unit, the vortex lattice's wing panels and shed wake from a replay of the aero unit with its recorded
inputs (``orchestrator.output.wake_view.replay``: bit for bit the unit's wake with explicit coupling).

Frames are the recorded structure samples nearest to ``frames`` instants evenly spread from t = 0 to the last
recorded time (``mechanism_view.instant_indices``). The lattice of a frame is the aero unit's after the
communication step ending at the frame's time (none at t = 0, before the first step). The replay stops after its
wall-time budget (``wake_view``: ``WINGSIM_WAKE_BUDGET_S``, default 60 s; 0: no lattice); later frames then have
the structure only, and the note says so.
"""

from __future__ import annotations

import os
from dataclasses import dataclass

import numpy as np

from orchestrator.output.mechanism_view import instant_indices, reference_lines


@dataclass
class Frame:
    """The geometry at one instant (m, global frame).

    time: s. nodes: (nodes, 3) the nodes' positions r. elements: (elements, 2) node indices of each element.
    element_body: (elements,) the index of each element's body in ``bodies``. bodies: the body names.
    lines: {body: (points, 3)} the bodies' reference lines (cubic Hermite, Otsuka et al. 2019, Eq. 2 at y = 0).
    wing: (B, M + 1, N + 1, 3) the lattice's panel corners, leading to trailing edge, or None.
    wake: (B, R + 1, N + 1, 3) the shed wake's ring corners, or None. wake_gamma: (B, R, N) their circulations,
    m^2/s, or None."""

    time: float
    nodes: np.ndarray
    elements: np.ndarray
    element_body: np.ndarray
    bodies: list[str]
    lines: dict[str, np.ndarray]
    wing: np.ndarray | None = None
    wake: np.ndarray | None = None
    wake_gamma: np.ndarray | None = None


def structure_layout(topology) -> tuple[np.ndarray, np.ndarray, list[str]]:
    """(elements (E, 2) node indices, element_body (E,) body index, body names) of a
    ``fmu_common.topology.Topology``."""
    bodies = list(topology.bodies)
    elements = np.asarray(topology.element_nodes, dtype=int).reshape(-1, 2)
    element_body = np.zeros(len(elements), dtype=int)
    for b, body in enumerate(topology.bodies.values()):
        element_body[list(body.elements)] = b
    return elements, element_body, bodies


def aero_step_at(inputs, time: float) -> int | None:
    """The index of the recorded aero step that ends at ``time`` (s; its t + h nearest), None before the first."""
    ends = np.asarray(inputs.t, dtype=float) + np.asarray(inputs.h, dtype=float)
    if len(ends) == 0 or time < ends[0] - 1e-12 * max(1.0, abs(time)):
        return None
    return int(np.argmin(np.abs(ends - time)))


def geometry_history(result, frames: int, budget_s: float | None = None) -> tuple[list[Frame], str]:
    """The frames of a recorded run (module docstring) and a note ("" when every frame is whole).

    Args:
        result: a RunResult with ``structure_coordinates`` (and ``aero_inputs`` for an aero scene).
        frames: how many instants, evenly spread from t = 0 to the last recorded time.
        budget_s: wall time (s) the aero replay may take; None: ``WINGSIM_WAKE_BUDGET_S`` or 60 s.
    """
    return geometry_histories(result, [frames], budget_s)[0]


def geometry_histories(result, counts: list[int], budget_s: float | None = None) -> list[tuple[list[Frame], str]]:
    """``geometry_history`` for several frame counts (the animation's and the VTK files' of one run) from one
    replay of the aero unit, up to the latest step any of them draws.

    Args:
        result: a RunResult with ``structure_coordinates`` (and ``aero_inputs`` for an aero scene).
        counts: for each history, how many instants.
        budget_s: wall time (s) the aero replay may take; None: ``WINGSIM_WAKE_BUDGET_S`` or 60 s.

    Returns:
        [(frames, note)] in the order of ``counts``.
    """
    from fmu_common.topology import Topology
    from fmu_common.wing_spec import StructureSpec
    from orchestrator.output.wake_view import BUDGET_ENV, REPLAY_BUDGET_S, replay

    record = result.structure_coordinates
    if record is None or len(record) == 0:
        return [([], "nothing recorded") for _ in counts]
    topology = Topology.from_spec(StructureSpec.from_scene(result.scene))
    elements, element_body, bodies = structure_layout(topology)
    histories = []
    for frames in counts:
        history = []
        for i in instant_indices(record.t, frames):
            e = np.asarray(record.e[i], dtype=float)
            history.append(Frame(record.t[i], e.reshape(-1, 9)[:, :3].copy(), elements, element_body, bodies,
                                 reference_lines(topology, e)))
        histories.append(history)
    inputs = getattr(result, "aero_inputs", None)
    if budget_s is None:
        budget_s = float(os.environ.get(BUDGET_ENV, REPLAY_BUDGET_S))
    if inputs is None or len(inputs) == 0:
        return [(history, "") for history in histories]
    if budget_s <= 0:
        return [(history, f"no lattice: {BUDGET_ENV} = 0 switches the aero replay off") for history in histories]
    frames_all = [frame for history in histories for frame in history]
    steps = [aero_step_at(inputs, frame.time) for frame in frames_all]
    wanted = sorted({s for s in steps if s is not None})
    snapshots, _, stopped = replay(result.scene, inputs, wanted, budget_s)
    by_step = dict(zip(wanted, snapshots))
    for frame, step in zip(frames_all, steps):
        snapshot = by_step.get(step)
        if snapshot is not None and abs(snapshot.time - frame.time) <= 1e-9 * max(1.0, abs(frame.time)):
            frame.wing, frame.wake, frame.wake_gamma = (snapshot.wing, snapshot.vortex["wake"],
                                                         snapshot.vortex["wake_gamma"])
    note = ""
    if stopped:
        note = (f"the aero replay reached its budget of {budget_s:g} s of wall time at t = {snapshots[-1].time:.4g} "
                f"s: later frames show the structure only ({BUDGET_ENV} sets the budget)")
    elif not inputs.complete:
        note = "the lattice only for the recorded part of the run (the master stopped recording the aero inputs)"
    return [(history, note) for history in histories]


def shared_histories(result, counts: list[int]):
    """A function ``frames -> (frames, note)`` for the frame counts in ``counts``, computing them all with one
    replay (``geometry_histories``) when first called: what the animation and the VTK files of one run share.

    Args:
        result: a RunResult.
        counts: the frame counts that will be asked for.
    """
    computed: dict[int, tuple[list[Frame], str]] = {}

    def history(frames: int) -> tuple[list[Frame], str]:
        if not computed:
            computed.update(zip(counts, geometry_histories(result, counts)))
        return computed[frames]

    return history
