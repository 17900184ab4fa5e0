"""A one-line progress bar on stderr: simulated time / stop time (s) and wall time (s).

Redrawn at most every ``min_interval`` seconds of wall time, and only on an interactive terminal
(stderr is a TTY and ``CI`` is not ``true``); otherwise silent until the final line, which is
always written.
"""

from __future__ import annotations

import os
import sys
import time as _time
from typing import TextIO

CLEAR_TO_END = "\x1b[K"
"""ANSI: erase the rest of the terminal line (a shorter line leaves no stale characters)."""


def is_interactive(stream: TextIO) -> bool:
    """True when ``stream`` is a terminal and we are not running under CI."""
    if os.environ.get("CI", "").strip().lower() in ("true", "1", "yes"):
        return False
    isatty = getattr(stream, "isatty", None)
    return bool(isatty and isatty())


class Progress:
    """Progress of one run from t = 0 to ``stop`` (s)."""

    WIDTH = 30

    def __init__(self, stop: float, label: str = "", stream: TextIO | None = None,
                 min_interval: float = 0.1, live: bool | None = None):
        self.stop = float(stop)
        self.label = label
        self.stream = stream if stream is not None else sys.stderr
        self.min_interval = min_interval
        self.live = is_interactive(self.stream) if live is None else live
        self._start = _time.perf_counter()
        self._last_draw = -float("inf")

    def _line(self, t: float) -> str:
        fraction = min(max(t / self.stop, 0.0), 1.0) if self.stop > 0 else 1.0
        filled = int(round(fraction * self.WIDTH))
        bar = "#" * filled + "-" * (self.WIDTH - filled)
        wall = _time.perf_counter() - self._start
        prefix = f"{self.label}: " if self.label else ""
        return f"{prefix}[{bar}] t = {t:.4g} / {self.stop:.4g} s, wall {wall:.1f} s"

    def update(self, t: float) -> None:
        """Report simulated time ``t`` (s); redraws only if enough wall time has passed."""
        if not self.live:
            return
        now = _time.perf_counter()
        if now - self._last_draw < self.min_interval:
            return
        self._last_draw = now
        self.stream.write(f"\r{self._line(t)}{CLEAR_TO_END}")
        self.stream.flush()

    def finish(self, t: float, status: str) -> None:
        """Write the final line (always, TTY or not) with the run's status."""
        start, clear = ("\r", CLEAR_TO_END) if self.live else ("", "")
        self.stream.write(f"{start}{self._line(t)}: {status}{clear}\n")
        self.stream.flush()
