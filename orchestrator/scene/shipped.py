"""The scenes shipped with wingsim (the repository's ``scenes/``, installed as the package ``orchestrator.scenes``):
found by name from any folder, listed with their headlines, copied to be edited.

A scene argument (``wingsim run SCENE``) is a path when that file exists; otherwise a bare name (no folder, with
or without ``.toml``) is a shipped scene of that name. A file in the current folder therefore wins over a shipped
scene of the same name.
"""
from __future__ import annotations

import importlib.resources
import re
from pathlib import Path

from fmu_common.errors import SceneError
from orchestrator.files import write_file

PACKAGE = "orchestrator.scenes"
SUFFIX = ".toml"
_NAME_LINE = re.compile(r'^name\s*=\s*"[^"]*"\s*$', re.MULTILINE)
_SCENE_NAME = re.compile(r"^[A-Za-z0-9_][A-Za-z0-9_.-]*$")


def shipped_scenes() -> dict[str, Path]:
    """{name: path} of every shipped scene file, sorted by name."""
    folder = Path(str(importlib.resources.files(PACKAGE)))
    return {p.stem: p for p in sorted(folder.glob(f"*{SUFFIX}"))}


def headline(path: Path) -> str:
    """The first line of a scene file's header comment, without the ``#`` (empty if it has none)."""
    for line in Path(path).read_text(encoding="utf-8").splitlines():
        if line.strip():
            return line.strip().lstrip("#").strip() if line.lstrip().startswith("#") else ""
    return ""


def _bare_name(scene: str | Path) -> str | None:
    """`scene` as a shipped scene's name (``deploy_rigid`` or ``deploy_rigid.toml``), None if it has a folder."""
    text = str(scene)
    if "/" in text or "\\" in text:
        return None
    return text[: -len(SUFFIX)] if text.endswith(SUFFIX) else text


def locate(scene: str | Path) -> Path:
    """The scene file `scene` names: the path itself when it exists (or names no shipped scene), else the shipped
    scene of that name. A path that does not exist is returned as it is (reading it names the missing file)."""
    path = Path(scene)
    if path.exists():
        return path
    name = _bare_name(scene)
    return shipped_scenes().get(name, path) if name else path


def missing_hint(scene: str | Path) -> str:
    """Why `scene` was not found, naming the shipped scenes when it looks like a name."""
    if _bare_name(scene) is None:
        return "no such file"
    return f"no such file, and no shipped scene of that name (wingsim scenes lists them: {', '.join(shipped_scenes())})"


def init_scene(name: str, source: str | Path, folder: Path = Path(".")) -> Path:
    """Copy the scene `source` (a shipped name or a file) to ``folder/<name>.toml`` with its ``name = ...`` line set
    to `name`; returns the new file. SceneError (naming NAME or --from) for a bad name, a missing source or a file
    that exists already: nothing is overwritten."""
    name = name[: -len(SUFFIX)] if name.endswith(SUFFIX) else name
    if not _SCENE_NAME.match(name):
        raise SceneError("NAME", name, "a file name of letters, digits, '_', '-' and '.', e.g. my_wing")
    path = locate(source)
    if not path.is_file():
        raise SceneError("--from", str(source), f"a scene file or a shipped scene ({missing_hint(source)})")
    target = Path(folder) / f"{name}{SUFFIX}"
    if target.exists():
        raise SceneError("NAME", name, f"a name whose file does not exist yet ({target} exists: nothing is "
                                       "overwritten)")
    text = path.read_text(encoding="utf-8")
    renamed, count = _NAME_LINE.subn(f'name = "{name}"', text, count=1)
    if count == 0:   # a scene without a name line is named after its file: the copy's name is its own
        renamed = text
    return write_file(target, lambda tmp: tmp.write_text(renamed, encoding="utf-8"))
