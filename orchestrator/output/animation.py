"""The animation of a run (``wingsim run --animate``): ``animation.gif``, the bodies' reference lines moving
through the run in a 3D view with equal scales, with the wing's panels (grey) and the shed wake's vortex rings
(coloured by circulation, m^2/s) where the scene has an aero unit; the time in the title.

The frames are ``ANIMATION_FRAMES`` instants evenly spread over the run, from the recorded geometry
(``orchestrator.output.geometry_history``); written with matplotlib's PillowWriter (pillow comes with matplotlib)
at ``FPS`` frames per second. The view's limits hold every frame, so the picture does not jump.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

from orchestrator.files import write_file
from orchestrator.output.geometry_history import Frame, geometry_history
from orchestrator.output.mechanism_view import equal_3d
from orchestrator.output.wake_view import quads

ANIMATION_FILE = "animation.gif"
ANIMATION_FRAMES = 60
FPS = 12
DPI = 90
FONT_SIZE = 10


def frame_points(frame: Frame) -> np.ndarray:
    """Every point a frame draws, (k, 3) m."""
    parts = [*frame.lines.values()]
    if frame.wing is not None:
        parts.append(frame.wing.reshape(-1, 3))
    if frame.wake is not None:
        parts.append(frame.wake.reshape(-1, 3))
    return np.concatenate(parts)


def draw_frame(ax, frame: Frame, points: np.ndarray, norm, title: str) -> None:
    """Draw one frame on a 3D axis (cleared first), limits from ``points`` (every frame's), wake colours by
    ``norm``."""
    from matplotlib import colormaps
    from mpl_toolkits.mplot3d.art3d import Poly3DCollection

    ax.cla()
    if frame.wake is not None and frame.wake.shape[1] > 1:
        gamma = np.asarray(frame.wake_gamma, dtype=float).ravel()
        ax.add_collection3d(Poly3DCollection(quads(frame.wake), facecolors=colormaps["RdBu_r"](norm(gamma)),
                                             edgecolors="none", alpha=0.8))
    if frame.wing is not None:
        ax.add_collection3d(Poly3DCollection(quads(frame.wing), facecolors="0.75", edgecolors="0.35",
                                             linewidths=0.3, alpha=0.9))
    colors = colormaps["tab10"]
    for k, (body, line) in enumerate(frame.lines.items()):
        ax.plot(*line.T, color=colors(k % 10), linewidth=2.0, label=body)
    equal_3d(ax, points)
    ax.tick_params(labelsize=FONT_SIZE - 2)
    ax.set_title(title, fontsize=FONT_SIZE)


def write_animation(result, out_dir, frames: int = ANIMATION_FRAMES, budget_s: float | None = None,
                    history: tuple[list[Frame], str] | None = None) -> Path | None:
    """Write ``animation.gif`` into ``out_dir`` for a run with recorded structure coordinates; returns its path,
    or None (and removes a stale file) when nothing was recorded.

    Args:
        result: the RunResult.
        out_dir: the run's output folder.
        frames: instants drawn, evenly spread over the run.
        budget_s: wall time (s) of the aero replay (``geometry_history``).
        history: the (frames, note) of ``geometry_history`` when already computed (``shared_histories``).
    """
    from matplotlib.animation import PillowWriter
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.colors import Normalize
    from matplotlib.figure import Figure

    path = Path(out_dir) / ANIMATION_FILE
    history, note = history if history is not None else geometry_history(result, frames, budget_s)
    if not history:
        path.unlink(missing_ok=True)
        return None
    if note:
        print(f"note: {ANIMATION_FILE}: {note}", file=sys.stderr)
    points = np.concatenate([frame_points(f) for f in history])
    gammas = [np.abs(f.wake_gamma).max() for f in history if f.wake_gamma is not None and f.wake_gamma.size]
    scale = max(gammas, default=0.0) or 1.0
    norm = Normalize(-scale, scale)
    fig = Figure(figsize=(6.4, 5.2))
    FigureCanvasAgg(fig)
    ax = fig.add_subplot(projection="3d")
    status = "" if result.status == "ok" else f", {result.status} at {result.simulated_time_s:.4g} s"
    name = result.scene["name"]

    def write(tmp: Path) -> None:
        writer = PillowWriter(fps=FPS)
        with writer.saving(fig, str(tmp), DPI):
            for frame in history:
                draw_frame(ax, frame, points, norm, f"{name}: t = {frame.time:.4g} s{status}")
                if len(frame.lines) > 1:
                    ax.legend(fontsize=FONT_SIZE - 2, loc="upper left")
                writer.grab_frame()

    write_file(path, write)
    return path
