"""One case of the peer benchmark (benchmarks/peers.py): the same physics run by wingsim and by a peer code, each
timed, each compared with a refined reference.

A peer module (peer_pterasoftware.py, peer_exudyn.py) lists its cases as `PeerCase`s. `ours` and `peer` each run
the case once from scratch in the calling process and return a `Measurement`: the wall and CPU time (s) of the
part that is compared (`timed`: the stepping, without imports, set-up or a JIT compilation that a warm-up run
pays) and the values the accuracy is judged on. `reference` returns those values from a refined run (computed
once per benchmark run); `errors(values, reference)` gives {name: error} for the table.
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Callable


@dataclass
class Measurement:
    """wall_s, cpu_s: the timed part (s); values: the numbers the accuracy is judged on (units in the case's doc);
    per_step: optional wall times (s) of each step, for ratios over part of a run."""

    wall_s: float
    cpu_s: float
    values: dict = field(default_factory=dict)
    per_step: list = field(default_factory=list)


@dataclass(frozen=True)
class PeerCase:
    """name: the case (a row of the table); peer: the peer code and version; what: how the two are made to do
    the same (lattice, step, tolerance); ours, peer: run once, return a Measurement; reference: the refined
    values; errors: {name: error} of a run's values against the reference; target: the product's target for the
    CPU-time ratio wingsim / peer (None: none set)."""

    name: str
    peer: str
    what: str
    ours: Callable[[], Measurement]
    peer_run: Callable[[], Measurement]
    reference: Callable[[], dict]
    errors: Callable[[dict, dict], dict]
    target: float | None = None


class Timer:
    """Wall and CPU time of a block: `with Timer() as t: ...`, then t.wall_s and t.cpu_s."""

    def __enter__(self):
        self._wall, self._cpu = time.perf_counter(), time.process_time()
        return self

    def __exit__(self, *exc):
        self.wall_s = time.perf_counter() - self._wall
        self.cpu_s = time.process_time() - self._cpu
        return False
