"""A one-line progress bar on stderr: simulated time / stop time (s), wall time (s) and the estimated time left.

Redrawn at most every ``min_interval`` seconds of wall time, and only on an interactive terminal
(stderr is a TTY and ``CI`` is not ``true``); otherwise silent until the final line, which is
always written.

The time left is the remaining simulated time over the rate of stepping so far (simulated s per wall s,
measured from the first reported step, so that loading the units does not count). After WARM_UP_S seconds of
stepping, a run whose time left at that rate exceeds LONG_RUN_S gets one note (on any stream, TTY or not): the
estimate and how to shorten it.
"""

from __future__ import annotations

import os
import sys
import time as _time
from typing import Callable, TextIO

CLEAR_TO_END = "\x1b[K"
"""ANSI: erase the rest of the terminal line (a shorter line leaves no stale characters)."""
LONG_RUN_S = 300.0
"""A run whose estimated time left exceeds this (s) after the warm-up gets a note."""
WARM_UP_S = 3.0
"""Wall time (s) of stepping measured before the time left is judged."""
REDUCE = ("shorten time.stop, or lengthen coupling.step (fewer communication steps; check that the results "
          "still converge)")


def is_interactive(stream: TextIO) -> bool:
    """True when ``stream`` is a terminal and we are not running under CI."""
    if os.environ.get("CI", "").strip().lower() in ("true", "1", "yes"):
        return False
    isatty = getattr(stream, "isatty", None)
    return bool(isatty and isatty())


def duration(seconds: float) -> str:
    """`seconds` in words: ``42 s``, ``7.5 min``, ``2.1 h``."""
    if seconds < 60:
        return f"{seconds:.0f} s"
    return f"{seconds / 60:.1f} min" if seconds < 7200 else f"{seconds / 3600:.1f} h"


class Progress:
    """Progress of one run from t = 0 to ``stop`` (s)."""

    WIDTH = 30

    def __init__(self, stop: float, label: str = "", stream: TextIO | None = None,
                 min_interval: float = 0.1, live: bool | None = None, warm_up: float = WARM_UP_S,
                 long_run: float = LONG_RUN_S, interrupted: Callable[[], bool] | None = None):
        self.stop = float(stop)
        self.label = label
        self.stream = stream if stream is not None else sys.stderr
        self.min_interval = min_interval
        self.live = is_interactive(self.stream) if live is None else live
        self.warm_up, self.long_run = warm_up, long_run
        self.interrupted = interrupted   # True once a signal stopped the run: a failure is then the interruption
        self._start = _time.perf_counter()
        self._last_draw = -float("inf")
        self._first: tuple[float, float] | None = None   # (t, wall clock) of the first reported step
        self._judged = False

    def remaining(self, t: float, now: float | None = None) -> float | None:
        """Estimated wall time (s) left to reach ``stop`` from ``t`` at the rate since the first reported step;
        None before a rate is known."""
        if self._first is None:
            return None
        t0, wall0 = self._first
        now = _time.perf_counter() if now is None else now
        if t <= t0 or now <= wall0:
            return None
        return (self.stop - t) * (now - wall0) / (t - t0)

    def _line(self, t: float, eta: bool = True) -> str:
        fraction = min(max(t / self.stop, 0.0), 1.0) if self.stop > 0 else 1.0
        filled = int(round(fraction * self.WIDTH))
        bar = "#" * filled + "-" * (self.WIDTH - filled)
        wall = _time.perf_counter() - self._start
        prefix = f"{self.label}: " if self.label else ""
        left = self.remaining(t) if eta and t < self.stop else None
        left_text = f", about {duration(left)} left" if left is not None else ""
        return f"{prefix}[{bar}] t = {t:.4g} / {self.stop:.4g} s, wall {wall:.1f} s{left_text}"

    def update(self, t: float) -> None:
        """Report simulated time ``t`` (s); redraws only if enough wall time has passed; notes a long run once
        after the warm-up."""
        now = _time.perf_counter()
        if self._first is None:
            self._first = (t, now)
        elif not self._judged and now - self._first[1] >= self.warm_up:
            self._judged = True
            left = self.remaining(t, now)
            if left is not None and left > self.long_run:
                start, clear = ("\r", CLEAR_TO_END) if self.live else ("", "")
                self.stream.write(f"{start}note: this run will take about {duration(left)} more at the rate of its "
                                  f"first {self.warm_up:g} s of steps (to t = {self.stop:g} s); Ctrl-C stops it and "
                                  f"keeps the results so far; to make it faster, {REDUCE}{clear}\n")
                self.stream.flush()
        if not self.live:
            return
        if now - self._last_draw < self.min_interval:
            return
        self._last_draw = now
        self.stream.write(f"\r{self._line(t)}{CLEAR_TO_END}")
        self.stream.flush()

    def finish(self, t: float, status: str) -> None:
        """Write the final line (always, TTY or not) with the run's status ("interrupted" for a run that failed
        after `interrupted` turned true: an FMU reports the signal that reached it as a failure of its call)."""
        if status != "ok" and self.interrupted is not None and self.interrupted():
            status = "interrupted"
        start, clear = ("\r", CLEAR_TO_END) if self.live else ("", "")
        self.stream.write(f"{start}{self._line(t, eta=False)}: {status}{clear}\n")
        self.stream.flush()
