"""``wingsim clean``: remove what wingsim wrote into the current folder: built FMUs (``fmus/``), results
(``results/``) and exported packages (``export/``), all of them or one scene's.

Only entries inside those folders are removed, each checked to resolve inside its folder: a symbolic link is
removed as a link, never followed. A folder a running wingsim process holds (its run or build lock,
``orchestrator.files.folder_lock``) is left alone and named. A scene's entries are ``<root>/<scene>/`` and, under
``fmus/`` and ``export/``, its variants ``<root>/<scene>-<12 hex digits>/`` and standalone folders
``<root>/<scene>[-<12 hex digits>]-standalone/`` (``orchestrator.cli.fmu_dir``, ``export_dir``).
"""
from __future__ import annotations

import re
import shutil
from dataclasses import dataclass, field
from pathlib import Path

from orchestrator.build.fmus import BUILD_LOCK
from orchestrator.files import LOCK_FILE, held

LOCKS = (LOCK_FILE, BUILD_LOCK)


@dataclass
class Cleaning:
    """What `clean` removed (or would remove) and what it left because a process holds it."""

    removed: list[Path] = field(default_factory=list)
    busy: list[Path] = field(default_factory=list)


def targets(root: Path, scene_name: str | None) -> list[Path]:
    """The entries of `root` that belong to `scene_name` (all entries of `root` for None), sorted."""
    root = Path(root)
    if not root.is_dir():
        return []
    entries = sorted(root.iterdir())
    if scene_name is None:
        return entries
    variant = re.compile(re.escape(scene_name) + r"(-[0-9a-f]{12})?(-standalone)?")
    return [e for e in entries if variant.fullmatch(e.name)]


def _inside(path: Path, root: Path) -> bool:
    """True when `path` (not followed if it is a link) lies inside `root`."""
    parent = path.parent.resolve()
    return parent == root.resolve() or root.resolve() in parent.parents


def in_use(folder: Path) -> bool:
    """True when a live process holds a run or build lock anywhere in `folder` (``orchestrator.files.held``)."""
    if folder.is_symlink() or not folder.is_dir():
        return False
    return any(held(lock) for name in LOCKS for lock in folder.rglob(name))


def clean(roots: list[Path], scene_name: str | None = None, dry_run: bool = False) -> Cleaning:
    """Remove the entries of `roots` (folders such as ``fmus``, ``results``) that belong to `scene_name` (all
    for None), but those a process holds; with `dry_run` only list them. Returns what was (or would be)
    removed and what was left."""
    done = Cleaning()
    for root in roots:
        for entry in targets(root, scene_name):
            if not _inside(entry, Path(root)):
                continue
            if in_use(entry):
                done.busy.append(entry)
                continue
            if not dry_run:
                if entry.is_symlink() or not entry.is_dir():
                    entry.unlink()
                else:
                    shutil.rmtree(entry)
            done.removed.append(entry)
    return done
