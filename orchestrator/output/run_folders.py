"""Where ``wingsim run`` writes without ``--out``, so that no variant overwrites another's results, and the runs
found there (``wingsim results``).

- The scene as its file writes it: ``results/<scene>/``.
- A ``--set`` variant: ``results/<scene>/<label>/``, the label its overrides as given, joined by ``,``, e.g.
  ``results/deploy_flexible/structure.fidelity=rigid,flow.speed=10/`` (``variant_label``). The order is the
  order on the command line (a later ``--set`` of the same key wins, so order can matter). Characters that are
  not safe in a file name on Linux, macOS and Windows (anything but letters, digits and ``. _ - + = , [ ] ( )``)
  become ``_``; a label that had to be changed so, or that is longer than MAX_LABEL characters (cut to fit), ends
  in ``~`` and the first 8 hex digits of the SHA-256 of the overrides as given, so that two variants never share a
  folder. The overrides themselves are in the folder's ``run.json`` and the resolved scene in its
  ``summary.json``.

A run folder is any folder under the results root with a ``run.json`` (``orchestrator.output.run_record``): the
variants, the scene's own folder and the runs of a sweep (``<sweep>/runs/<run>/``).
"""
from __future__ import annotations

import hashlib
import json
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Sequence

from orchestrator.files import LOCK_FILE, held
from orchestrator.output.run_record import RUN_RECORD, complete_record

MAX_LABEL = 96
"""Characters of a variant folder's name at most (Windows' 260-character paths leave room for the rest)."""
DIGEST_CHARS = 8
_UNSAFE = re.compile(r"[^A-Za-z0-9._\-+=,\[\]()]")
SUMMARY = "summary.json"


def variant_label(overrides: Sequence[str]) -> str:
    """The folder name of a ``--set`` variant (module docstring): the overrides joined by ``,``, unsafe characters
    replaced by ``_``, cut to MAX_LABEL characters with a digest of the overrides when either changed them."""
    given = ",".join(overrides)
    label = _UNSAFE.sub("_", given)
    label = "_" + label[1:] if label[:1] in (".", "-") else label   # no hidden folder, no option look-alike
    if label == given and len(label) <= MAX_LABEL:
        return label
    digest = hashlib.sha256("\n".join(overrides).encode()).hexdigest()[:DIGEST_CHARS]
    return f"{label[:MAX_LABEL - DIGEST_CHARS - 1].rstrip('. ')}~{digest}"


def run_folder(root: Path, scene_name: str, overrides: Sequence[str]) -> Path:
    """``root/<scene>/`` for the scene as its file writes it, ``root/<scene>/<variant_label>/`` for a variant."""
    folder = Path(root) / scene_name
    return folder / variant_label(overrides) if overrides else folder


@dataclass(frozen=True)
class RunEntry:
    """One run folder as ``wingsim results`` lists it."""

    folder: Path
    overrides: tuple[str, ...]
    status: str             # the summary's status; "running" while a process holds the folder, "incomplete"
                            # for a run that did not finish (killed) or whose files changed since
    summary: dict           # summary.json ({} if missing or unreadable)

    def figures(self) -> dict[str, float | None]:
        """The key figures of the summary that apply to the run: simulated and wall time (s), deployment time
        (s) for a scene with latching hinges, final lift coefficient for an aero scene, energy drift (-)."""
        s = self.summary
        out = {"t_sim_s": s.get("simulated_time_s"), "wall_s": s.get("wall_time_s")}
        if s.get("deployment_time_s") is not None:
            out["deployment_s"] = s["deployment_time_s"]
        if isinstance(s.get("aero"), dict):
            out["CL_final"] = s["aero"].get("CL_final")
        if s.get("energy_drift") is not None:
            out["energy_drift"] = s["energy_drift"]
        return out


def _read_json(path: Path) -> dict:
    try:
        value = json.loads(path.read_text())
    except (OSError, ValueError):
        return {}
    return value if isinstance(value, dict) else {}


def find_runs(root: Path, scene_name: str | None = None) -> list[RunEntry]:
    """Every run folder under `root` (or under ``root/<scene_name>/``), sorted by path."""
    base = Path(root) / scene_name if scene_name else Path(root)
    entries = []
    for record_path in sorted(base.rglob(RUN_RECORD)) if base.is_dir() else []:
        folder = record_path.parent
        record = _read_json(record_path)
        summary = _read_json(folder / SUMMARY)
        if complete_record(folder) is not None:
            status = summary.get("status", "?")
        else:   # not finished: still running, or killed (or its files changed since)
            status = "running" if held(folder / LOCK_FILE) else "incomplete"
        entries.append(RunEntry(folder, tuple(record.get("overrides", ())), status, summary))
    return entries


def describe_runs(entries: Sequence[RunEntry], root: Path) -> list[str]:
    """One line per run: folder (relative to `root`), status, key figures, overrides."""
    lines = []
    for entry in entries:
        figures = ", ".join(f"{k} {v:.6g}" for k, v in entry.figures().items() if isinstance(v, (int, float)))
        overrides = " ".join(f"--set {o}" for o in entry.overrides) or "(scene as written)"
        lines.append(f"{entry.folder.relative_to(root)}: {entry.status}" + (f"; {figures}" if figures else "")
                     + f"; {overrides}")
    return lines
