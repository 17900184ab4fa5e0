"""A scene for scripts and notebooks: a TOML scene file (or a shipped scene by name) with its overrides, loaded,
resolved and checked as ``wingsim run`` loads it (``orchestrator.scene.load.load_scene``).

Overrides are the ``--set`` of the command line given as Python values: ``scene.set("flow.speed", 10)`` is
``--set flow.speed=10``; each is checked when it is set (``SceneError`` naming the key, nothing changed).
"""

from __future__ import annotations

import copy
import json
import math
from pathlib import Path
from typing import Any, Iterable, Mapping

from fmu_common.errors import SceneError
from orchestrator.scene import shipped
from orchestrator.scene.load import load_scene as _load_resolved

def shipped_scenes() -> list[str]:
    """The names of the scenes that come with wingsim (installed with the package, ``wingsim scenes`` lists them
    with their headlines: ``orchestrator.scene.shipped``), sorted."""
    return list(shipped.shipped_scenes())


def scene_path(path_or_name: str | Path) -> Path:
    """The file of a scene: ``path_or_name`` itself when it is a file, else the shipped scene of that name
    (``"deploy_rigid"`` or ``"deploy_rigid.toml"``), as ``wingsim run SCENE`` finds it (``orchestrator.scene.shipped``).

    Args:
        path_or_name: a scene file's path, or the name of a shipped scene.

    Returns:
        The scene file's path. SceneError naming the argument when it is neither.
    """
    path = shipped.locate(path_or_name)
    if path.is_file():
        return path
    raise SceneError("scene", str(path_or_name), "a scene file, or the name of a shipped scene: "
                                                 + ", ".join(shipped_scenes()))


def override_text(key: str, value: Any) -> str:
    """The ``--set`` item ``KEY=VALUE`` of a Python value (a number, bool, string or list of them), written as the
    TOML value ``orchestrator.scene.overrides.parse_value`` reads back.

    Args:
        key: a dotted scene key, e.g. ``"flow.speed"``.
        value: its value.
    """
    return f"{key}={_toml(key, value)}"


def _toml(key: str, value: Any) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, int):
        return str(value)
    if isinstance(value, float):
        if not math.isfinite(value):
            raise SceneError(key, value, "a finite number")
        return repr(value)
    if isinstance(value, str):
        return json.dumps(value)      # a TOML basic string: quotes and backslashes escaped alike
    if isinstance(value, (list, tuple)):
        return "[" + ", ".join(_toml(key, v) for v in value) + "]"
    if hasattr(value, "tolist"):      # a numpy scalar or array
        return _toml(key, value.tolist())
    raise SceneError(key, value, "a number, a bool, a string or a list of them")


class Scene:
    """A scene file with overrides, resolved and checked.

    Attributes:
        path: the scene file.
        overrides: the ``KEY=VALUE`` items applied to it, in order (as ``--set`` gives them).
        resolved: the resolved scene (every key, every default filled), a dict.

    Args:
        path: the scene file.
        overrides: ``KEY=VALUE`` items, as ``--set`` gives them.
    """

    def __init__(self, path: str | Path, overrides: Iterable[str] = ()):
        self.path = Path(path)
        self.overrides = list(overrides)
        self.resolved = _load_resolved(self.path, self.overrides)

    @property
    def name(self) -> str:
        """The scene's name (``name``, default the file's stem)."""
        return self.resolved["name"]

    def get(self, key: str) -> Any:
        """The resolved value of a dotted key, e.g. ``scene.get("flow.speed")`` (m/s); a table as a dict.

        Args:
            key: a dotted scene key; an item of an array of tables by its name or index
                (``structure.bodies.wing.length``, ``structure.bodies.0.length``).
        """
        value: Any = self.resolved
        for part in key.split("."):
            if isinstance(value, list):
                named = [item for item in value if isinstance(item, dict) and item.get("name") == part]
                if named:
                    value = named[0]
                elif part.isdigit() and int(part) < len(value):
                    value = value[int(part)]
                else:
                    raise SceneError(key, None, f"a key of the scene: no item {part!r}")
            elif isinstance(value, dict) and part in value:
                value = value[part]
            else:
                raise SceneError(key, None, f"a key of the scene: no {part!r} there")
        return copy.deepcopy(value)

    def set(self, key: str, value: Any) -> "Scene":
        """Override a dotted key (``--set key=value``) and check the scene again; returns the scene itself.

        Args:
            key: a dotted scene key, e.g. ``"flow.speed"``.
            value: its new value (number, bool, string or list), in the key's unit (docs/scenes.md).

        Returns:
            This scene. SceneError naming the key (the scene unchanged) when the value is refused.
        """
        overrides = [*self.overrides, override_text(key, value)]
        self.resolved = _load_resolved(self.path, overrides)
        self.overrides = overrides
        return self

    def with_overrides(self, overrides: Mapping[str, Any] | None = None) -> "Scene":
        """A new scene: this one with more overrides (``{dotted key: value}``), checked.

        Args:
            overrides: {dotted key: value}; None or empty: a copy.
        """
        return Scene(self.path, [*self.overrides, *(override_text(k, v) for k, v in (overrides or {}).items())])

    def __repr__(self) -> str:
        sets = "".join(f" --set {item}" for item in self.overrides)
        return f"<Scene {self.name}: {self.path}{sets}>"


def load_scene(path_or_name: str | Path | Scene, overrides: Mapping[str, Any] | None = None) -> Scene:
    """Load a scene file, or a shipped scene by name (``wingsim.load_scene("deploy_rigid")``), with overrides.

    Args:
        path_or_name: a scene file, the name of a shipped scene (``shipped_scenes()``), or a Scene (copied).
        overrides: {dotted key: value} applied in order, as ``--set`` items.

    Returns:
        The Scene. SceneError naming the key or the file when it is refused.
    """
    if isinstance(path_or_name, Scene):
        return path_or_name.with_overrides(overrides)
    return Scene(scene_path(path_or_name), [override_text(k, v) for k, v in (overrides or {}).items()])
