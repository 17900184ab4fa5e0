"""Scene files: read a TOML scene, apply ``--set`` overrides and the [wing]/[motion] shorthands, resolve it
against the schema and check that the units can be built from it.

Every key is declared once, in ``fmu_common.scene_schema`` (docs/scenes.md is generated from it); its
``resolve_scene`` fills every default and checks types, ranges, unknown keys and size bounds. What this
module adds: the file, the overrides, the shorthands, the probes' and strain gauges' places on their bodies
and names against the columns of timeseries.csv, and ``check_physics``, which builds the structural
topology (and the aero solver of an aero scene), so that a scene that loads can run and every bad scene
fails before anything runs with a ``SceneError`` naming the key, the value and what is allowed.

Two top-level tables are shorthands that the loader translates (after ``--set``, so that overriding one of
their keys or ``flow.speed`` takes effect), keeping them in the resolved scene as given:

- ``[motion]`` (a heaving wing, Otsuka et al. 2019, Sec. VI.D): ``reduced_frequency`` k and ``amplitude``
  (in chords c of the first body) become ``structure.motion.frequency`` = 2 k V / c (rad/s, V =
  ``flow.speed``) and ``structure.motion.heave_amplitude`` = amplitude * c (m);
- ``[wing]`` (a one-body wing): ``chord`` (m) becomes the body's ``section.chord``, ``aspect_ratio`` its
  ``length`` = aspect_ratio * chord, ``alpha_deg`` the constant pitch ``structure.motion.alpha_deg``.

Both need ``structure.fidelity = "prescribed"`` where they set the motion. A translated key that the
scene also gives directly must agree with it (else SceneError): nothing is silently overridden.
"""

from __future__ import annotations

import copy
import datetime
import math
import tomllib
from pathlib import Path
from typing import Any, Iterable

from fmu_common.choices import FIDELITIES, fidelity_names
from fmu_common.errors import SceneError
from fmu_common.scene_schema import PARENT_JOINTS, SCENE
from fmu_common.scene_schema import resolve_scene as resolve_schema
from fmu_common.schema import MISSING, is_number
from orchestrator.scene.overrides import apply_overrides
from orchestrator.scene.shipped import locate, missing_hint
from orchestrator.scene.columns import AERO_COLUMNS, COUPLING_COLUMNS, MONITOR_COLUMNS, hinge_moment_column
from structure_fmu.joint_monitors import monitor_names

__all__ = ["MISSING", "SceneFileError", "read_scene_file", "resolve_scene", "load_scene", "check_physics",
           "hinge_joints"]


class SceneFileError(SceneError):
    """The scene file cannot be read or is not valid TOML."""

    def __init__(self, path: Path, reason: str):
        self.key, self.value, self.allowed = "<file>", str(path), reason
        ValueError.__init__(self, f"cannot read scene file '{path}': {reason}")


def read_scene_file(path: str | Path) -> dict:
    """The raw TOML table of a scene file, or of the shipped scene `path` names (``orchestrator.scene.shipped``:
    a file that exists wins); raises SceneFileError when unreadable or not TOML."""
    given, path = path, locate(path)
    try:
        with path.open("rb") as f:
            return tomllib.load(f)
    except FileNotFoundError:
        raise SceneFileError(path, missing_hint(given)) from None
    except IsADirectoryError:
        raise SceneFileError(path, "it is a directory, not a .toml file") from None
    except OSError as err:
        raise SceneFileError(path, err.strerror or str(err)) from None
    except tomllib.TOMLDecodeError as err:
        raise SceneFileError(path, f"not valid TOML: {err}") from None


# --- the [wing] and [motion] shorthands -----------------------------------------------------------

def _declared(raw: dict, dotted: str) -> Any:
    """The value of the scalar key ``dotted`` of the raw scene, checked against its declaration, or its
    default; SceneError if a table on the way is not a table."""
    spec, node, parts = SCENE, raw, dotted.split(".")
    for depth, part in enumerate(parts):
        if not isinstance(node, dict):
            key = ".".join(parts[:depth])
            raise SceneError(key, node, f"a table [{key}]")
        spec, node = spec.keys[part], node.get(part)
    return spec.resolve(dotted, node)


def _agree(key: str, given: Any, derived: float, source: str) -> float:
    """``derived`` if ``given`` is absent or equal to it (relative 1e-12), else a SceneError."""
    if given is not None and not (is_number(given) and math.isclose(given, derived, rel_tol=1e-12)):
        raise SceneError(key, given, f"{derived:.12g} as {source} sets it, or leave the key out")
    return float(derived)


def _motion_table(raw: dict, key: str) -> dict:
    """The raw ``structure.motion`` table of a prescribed-fidelity scene, created if absent."""
    fidelity = _declared(raw, "structure.fidelity")
    known = FIDELITIES.get(fidelity) if isinstance(fidelity, str) else None    # not resolved yet: any value
    if known is None or not known.moved_by_law:
        raise SceneError(key, fidelity, f"structure.fidelity = '{fidelity_names(lambda f: f.moved_by_law)}' (the "
                                        "shorthand sets a prescribed motion)")
    motion = raw["structure"].setdefault("motion", {})
    if not isinstance(motion, dict):
        raise SceneError("structure.motion", motion, "a table [structure.motion]")
    return motion


def _first_body(raw: dict, key: str, only: bool) -> dict:
    structure = raw.get("structure")
    bodies = structure.get("bodies") if isinstance(structure, dict) else None
    if not isinstance(bodies, list) or not bodies or (only and len(bodies) != 1) or not isinstance(bodies[0], dict):
        count = len(bodies) if isinstance(bodies, list) else 0
        raise SceneError(key, f"{count} bodies", "a scene with exactly one body in structure.bodies"
                         if only else "a scene with a body in structure.bodies")
    return bodies[0]


def _body_chord(body: dict) -> float:
    section = body.get("section")
    chord = section.get("chord") if isinstance(section, dict) else None
    return SCENE.keys["structure"].keys["bodies"].item.keys["section"].keys["chord"].resolve(
        "structure.bodies.0.section.chord", chord)


def _apply_shorthands(raw: dict) -> None:
    """Translate the [wing] and [motion] tables of the raw scene into structure keys, in place."""
    wing = SCENE.keys["wing"].resolve("wing", raw["wing"]) if raw.get("wing") is not None else None
    heave = SCENE.keys["motion"].resolve("motion", raw["motion"]) if raw.get("motion") is not None else None
    if wing is not None:
        body = _first_body(raw, "wing", only=True)
        if wing["chord"] is not None:
            section = body.setdefault("section", {})
            if not isinstance(section, dict):
                raise SceneError("structure.bodies.0.section", section, "a table with the chord")
            section["chord"] = _agree("structure.bodies.0.section.chord", section.get("chord"), wing["chord"],
                                      "wing.chord")
        if wing["aspect_ratio"] is not None:
            chord = _body_chord(body)
            body["length"] = _agree("structure.bodies.0.length", body.get("length"), wing["aspect_ratio"] * chord,
                                    f"wing.aspect_ratio x chord ({wing['aspect_ratio']:g} x {chord:g} m)")
        if wing["alpha_deg"] is not None:
            motion = _motion_table(raw, "wing.alpha_deg")
            motion["alpha_deg"] = _agree("structure.motion.alpha_deg", motion.get("alpha_deg"), wing["alpha_deg"],
                                         "wing.alpha_deg")
    if heave is not None:
        chord = _body_chord(_first_body(raw, "motion", only=False))
        speed = _declared(raw, "flow.speed")
        if speed <= 0 and heave["reduced_frequency"] > 0:
            raise SceneError("flow.speed", speed, "a speed > 0 (m/s): motion.reduced_frequency is relative to it")
        motion = _motion_table(raw, "motion")
        source = f"motion.reduced_frequency = {heave['reduced_frequency']:g} (2 k V / c)"
        motion["frequency"] = _agree("structure.motion.frequency", motion.get("frequency"),
                                     2.0 * heave["reduced_frequency"] * speed / chord, source)
        motion["heave_amplitude"] = _agree("structure.motion.heave_amplitude", motion.get("heave_amplitude"),
                                           heave["amplitude"] * chord,
                                           f"motion.amplitude = {heave['amplitude']:g} chords")


# --- probes and strain gauges on their bodies -----------------------------------------------------

def _check_spans(scene: dict) -> None:
    """SceneError for a probe or strain gauge beyond its body's tip."""
    lengths = {b["name"]: b["length"] for b in scene["structure"]["bodies"]}
    for key in ("probes", "strain_gauges"):
        for item in scene[key]:
            length = lengths[item["body"]]
            if item["span"] > length * (1 + 1e-12):
                raise SceneError(f"{key}.{item['name']}.span", item["span"],
                                 f"a number in [0, {length:g}] (m from the root of body '{item['body']}', "
                                 f"{length:g} m long)")


def _check_gauge_names(scene: dict) -> None:
    """A strain gauge is a column of timeseries.csv: its name must not be another column's."""
    probes = {f"{p['name']}_{axis}" for p in scene["probes"] for axis in "xyz"}
    hinges = {f"fold_angle_{j['name']}" for j in hinge_joints(scene)}
    hinges |= {hinge_moment_column(j["name"]) for j in hinge_joints(scene)}
    taken = {"time", *probes, *hinges, *MONITOR_COLUMNS, *AERO_COLUMNS, *COUPLING_COLUMNS}
    for gauge in scene["strain_gauges"]:
        if gauge["name"] in taken:
            raise SceneError(f"strain_gauges.{gauge['name']}.name", gauge["name"],
                             "a strain gauge name not used by another strain gauge or column of timeseries.csv")


def _reject_dates(value: Any, key: str) -> None:
    """TOML dates and times are not scene values (and would not survive summary.json)."""
    if isinstance(value, (datetime.date, datetime.time)):
        raise SceneError(key, value.isoformat(), "a number, string, boolean, array or table (not a date or time)")
    if isinstance(value, dict):
        for k, v in value.items():
            _reject_dates(v, f"{key}.{k}" if key else k)
    elif isinstance(value, list):
        for i, v in enumerate(value):
            label = v["name"] if isinstance(v, dict) and isinstance(v.get("name"), str) else str(i)
            _reject_dates(v, f"{key}.{label}")


def resolve_scene(raw: dict, default_name: str) -> dict:
    """The resolved scene of a raw one (overrides applied): shorthands translated, every key checked and
    every default filled (``fmu_common.scene_schema``), probes and strain gauges on their bodies. Raises
    SceneError at the first bad key; does not build the units (``check_physics``)."""
    if not isinstance(raw, dict):
        raise SceneError("<top level>", raw, "a TOML table")
    _reject_dates(raw, "")
    raw = copy.deepcopy(raw)
    _apply_shorthands(raw)
    scene = resolve_schema(raw, default_name)
    _check_spans(scene)
    _check_gauge_names(scene)
    return scene


def load_scene(path: str | Path, overrides: Iterable[str] = ()) -> dict:
    """Read, override, resolve and fully check a scene file; returns the resolved scene.

    ``overrides`` are ``KEY=VALUE`` strings as given to ``--set``. The physics tables are
    checked by building the structural topology (and the aero solver of an aero scene), so a scene that
    loads can run.
    """
    raw = apply_overrides(read_scene_file(path), overrides)
    scene = resolve_scene(raw, default_name=Path(path).stem)
    check_physics(scene)
    return scene


def check_physics(scene: dict) -> None:
    """SceneError unless the units can be built from the resolved scene: the structural topology, which the
    aero unit builds too (`StructureTopology` extends it), and the names of the structure unit's outputs. No
    solver is built: what an aero solver checks beyond the topology (its model and flow) the schema has
    checked."""
    from fmu_common.specs import StructureUnitSpec  # lazy: the physics packages are only needed here
    from structure_fmu.topology import StructureTopology

    spec = StructureUnitSpec.from_scene(scene)
    StructureTopology.from_spec(spec.structure)
    _check_sensor_outputs(scene, spec)


def _check_sensor_outputs(scene: dict, spec) -> None:
    """SceneError naming the probe or strain gauge one of whose outputs of the structure unit (``<probe>_x``
    .. ``<probe>_vz``, ``<gauge>``) takes the name of another of its variables or of a timeseries.csv column.
    Run after the topology check: the parameter names come from the bodies and joints (`spec`, the structure
    unit's `fmu_common.specs.StructureUnitSpec`)."""
    from structure_fmu.sensors import probe_output_names
    from structure_fmu.solver import StructureSolver

    hinges = [j["name"] for j in hinge_joints(scene)]
    owner = {name: "an output of the structure unit" for name in ("topology_hash", *MONITOR_COLUMNS)}
    owner.update({f"{kind}_{h}": f"an output of hinge {h}" for h in hinges for kind in ("fold_angle", "latch_time")})
    owner.update({name: "a parameter of the structure unit" for name in StructureSolver.tunable_parameters(spec)})
    owner.update({name: "a column of timeseries.csv" for name in ("time", *AERO_COLUMNS, *COUPLING_COLUMNS)})
    owner.update({hinge_moment_column(h): f"a column of timeseries.csv (hinge {h})" for h in hinges})
    sensors = [("probes", "probe", p["name"], sum(probe_output_names(p["name"]), [])) for p in scene["probes"]]
    sensors += [("strain_gauges", "strain gauge", g["name"], [g["name"]]) for g in scene["strain_gauges"]]
    for key, kind, sensor, outputs in sensors:
        for output in outputs:
            if output in owner:
                raise SceneError(f"{key}.{sensor}.name", sensor, f"a {kind} name whose output {output!r} is not "
                                 f"already {owner[output]}")
            owner[output] = f"an output of {kind} {sensor}"


def joint_monitor_names(scene: dict) -> list[str]:
    """The structure unit's joint monitor outputs (`structure_fmu.joint_monitors`) of the scene's joints with a
    parent body, in the scene's order."""
    return [name for j in scene["structure"]["joints"] if j["type"] in PARENT_JOINTS and j["parent"] is not None
            for name in monitor_names(j["name"], j["type"])]


def hinge_joints(scene: dict) -> list[dict]:
    """The scene's hinge joint tables, in order (each has ``name``; ``stop_angle_deg`` if latched)."""
    return [j for j in scene["structure"]["joints"] if j.get("type") == "revolute"]
