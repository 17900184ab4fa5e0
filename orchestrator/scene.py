"""Scene files: load a TOML scene, apply ``--set`` overrides, fill defaults, validate.

The format is docs/scenes.md. The resolved scene is a plain, JSON-serialisable dict with every
top-level section present and every default filled in; it is what the units are built from and
what ``summary.json`` records. SI units throughout (s, m, kg, N, m/s, kg/m^3).

This module checks the top level and the scalar keys (time, coupling, flow, aero, probes, strain gauges
and the scalar ``structure`` keys). The physics tables (bodies, joints, masses, loads) are checked by
``structure_fmu.topology.StructureTopology.from_scene``, and an aero scene by ``aero_fmu.solver.AeroSolver``,
which ``load_scene`` calls last, so that every bad scene fails before anything runs with a
``SceneError`` naming the key, the value and what is allowed.

Two top-level tables are shorthands that the loader translates (after ``--set``, so that overriding
one of their keys or ``flow.speed`` takes effect), keeping them in the resolved scene as given:

- ``[motion]`` (a heaving wing, 000 Sec. VI.D): ``reduced_frequency`` k and ``amplitude`` (in chords c
  of the first body) become ``structure.motion.frequency`` = 2 k V / c (rad/s, V = ``flow.speed``)
  and ``structure.motion.heave_amplitude`` = amplitude * c (m);
- ``[wing]`` (a one-body wing): ``chord`` (m) becomes the body's ``section.chord``, ``aspect_ratio``
  its ``length`` = aspect_ratio * chord, ``alpha_deg`` the constant pitch ``structure.motion.alpha_deg``.

Both need ``structure.fidelity = "prescribed"`` where they set the motion. A translated key that the
scene also gives directly must agree with it (else SceneError): nothing is silently overridden.
"""

from __future__ import annotations

import copy
import datetime
import math
import re
import tomllib
from pathlib import Path
from typing import Any, Callable, Iterable

from orchestrator.acceleration import ACCELERATIONS
from orchestrator.overrides import apply_overrides
from orchestrator.timeseries import AERO_COLUMNS, COUPLING_COLUMNS, MONITOR_COLUMNS
from fmu_common.errors import SceneError, reject_unknown_keys

Checker = Callable[[str, Any], Any]
"""(dotted key, value) -> normalised value; raises SceneError."""

REQUIRED = object()
"""Default marker for keys a scene must give."""

MISSING = "<missing>"
"""The value reported in a SceneError for a required key that is absent."""

NAME_PATTERN = re.compile(r"[A-Za-z0-9][A-Za-z0-9_.-]*")
NAME_ALLOWED = "a non-empty name of letters, digits, '_', '-', '.' starting with a letter or digit"

AERO_MODELS = ("none", "strip", "uvlm-flat", "uvlm-prescribed", "uvlm-free")


class SceneFileError(SceneError):
    """The scene file cannot be read or is not valid TOML."""

    def __init__(self, path: Path, reason: str):
        self.key, self.value, self.allowed = "<file>", str(path), reason
        ValueError.__init__(self, f"cannot read scene file '{path}': {reason}")


# --- value checkers -------------------------------------------------------------------------------

def _is_number(value: Any) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value)


def _number(allowed: str, accept: Callable[[float], bool]) -> Checker:
    def check(key: str, value: Any) -> float:
        if not _is_number(value) or not accept(value):
            raise SceneError(key, value, allowed)
        return float(value)
    return check


def positive(unit: str) -> Checker:
    return _number(f"a finite number > 0 ({unit})", lambda x: x > 0)


def positive_or_inf(unit: str) -> Checker:
    """A number > 0, or inf (TOML `inf`)."""
    finite = _number(f"a finite number > 0, or inf ({unit})", lambda x: x > 0)

    def check(key: str, value: Any) -> float:
        return value if isinstance(value, float) and value == math.inf else finite(key, value)
    return check


def non_negative(unit: str) -> Checker:
    return _number(f"a finite number >= 0 ({unit})", lambda x: x >= 0)


def between(low: float, high: float, unit: str = "-") -> Checker:
    return _number(f"a number in [{low:g}, {high:g}] ({unit})", lambda x: low <= x <= high)


def integer_at_least(low: int) -> Checker:
    def check(key: str, value: Any) -> int:
        if isinstance(value, bool) or not isinstance(value, int) or value < low:
            raise SceneError(key, value, f"an integer >= {low}")
        return value
    return check


def choice(*options: str) -> Checker:
    allowed = "one of " + ", ".join(repr(o) for o in options)

    def check(key: str, value: Any) -> str:
        if not isinstance(value, str) or value not in options:
            raise SceneError(key, value, allowed)
        return value
    return check


def vector3(unit: str) -> Checker:
    def check(key: str, value: Any) -> list[float]:
        if not isinstance(value, list) or len(value) != 3 or not all(map(_is_number, value)):
            raise SceneError(key, value, f"an array of 3 finite numbers ({unit}), e.g. [0, 0, -9.81]")
        return [float(v) for v in value]
    return check


def optional(check: Checker) -> Checker:
    """``check``, or None when the key is absent."""
    def checked(key: str, value: Any) -> Any:
        return None if value is None else check(key, value)
    return checked


def optional_direction(what: str) -> Checker:
    vector = vector3(f"{what}, any length but not zero")

    def check(key: str, value: Any) -> list[float] | None:
        if value is None:
            return None
        v = vector(key, value)
        if not any(v):
            raise SceneError(key, value, f"a non-zero array of 3 finite numbers ({what})")
        return v
    return check


def text(key: str, value: Any) -> str:
    if not isinstance(value, str):
        raise SceneError(key, value, "a string")
    return value


def _is_name(value: Any) -> bool:
    return isinstance(value, str) and NAME_PATTERN.fullmatch(value) is not None


def name(key: str, value: Any) -> str:
    if not _is_name(value):
        raise SceneError(key, value, NAME_ALLOWED)
    return value


def table_list(what: str) -> Checker:
    def check(key: str, value: Any) -> list[dict]:
        if not isinstance(value, list) or not all(isinstance(v, dict) for v in value):
            raise SceneError(key, value, f"an array of tables [[{key}]], one per {what}")
        return value
    return check


def optional_table(what: str) -> Checker:
    def check(key: str, value: Any) -> dict | None:
        if value is not None and not isinstance(value, dict):
            raise SceneError(key, value, f"a table [{key}] with {what}")
        return value
    return check


# --- the schema (docs/scenes.md) ------------------------------------------------------------------

SECTIONS: dict[str, dict[str, tuple[Any, Checker]]] = {
    "time": {
        "stop": (REQUIRED, positive("end time, s")),
    },
    "coupling": {
        "step": (1e-3, positive("communication step, s")),
        "algorithm": ("gauss-seidel", choice("gauss-seidel", "jacobi", "implicit")),
        # implicit coupling only (orchestrator.master):
        "tolerance": (1e-6, positive("relative interface residual ||Q_new - Q_used|| / ||Q_new||, -")),
        "max_iterations": (50, integer_at_least(1)),
        "acceleration": ("aitken", choice(*ACCELERATIONS)),
        "relaxation": (0.5, _number("a number in (0, 1] (initial relaxation factor, -)", lambda x: 0 < x <= 1)),
    },
    "flow": {
        "speed": (0.0, non_negative("free-stream speed, m/s")),
        "density": (1.2, non_negative("air density, kg/m^3")),
        "direction": (None, optional_direction("free-stream direction")),
    },
    "aero": {
        "model": ("none", choice(*AERO_MODELS)),
        "chordwise_panels": (2, integer_at_least(1)),
        "spanwise_panels": (7, integer_at_least(1)),
        "wake_length": (5.0, positive_or_inf("wake length, chords; inf: semi-infinite flat wake, no truncation "
                                             "of a shed wake")),
        "step": (None, optional(positive("internal aero step, s; absent: one per communication step"))),
        "span_correction": ("helmbold", choice("helmbold", "none")),   # strip theory only (aero_fmu/strip.py)
    },
    "structure": {
        "fidelity": ("flexible", choice("prescribed", "rigid", "flexible")),
        "elements_per_body": (4, integer_at_least(1)),
        "integrator": ("generalized-alpha", choice("rk4", "generalized-alpha")),
        "step": (1e-4, positive("internal time step, s")),
        "rho_inf": (0.8, between(0.0, 1.0, "spectral radius at infinity")),
        "damping_model": ("deformation", choice("deformation", "mass-proportional")),
        "gravity": ([0.0, 0.0, 0.0], vector3("m/s^2")),
        "bodies": ([], table_list("body")),
        "joints": ([], table_list("joint")),
        "masses": ([], table_list("lumped mass")),
        "loads": ([], table_list("load")),
        "motion": (None, optional_table("the prescribed heave/pitch law")),
    },
}

SHORTHANDS: dict[str, dict[str, tuple[Any, Checker]]] = {
    "motion": {
        "reduced_frequency": (REQUIRED, non_negative("reduced frequency k = omega c / (2 V), -")),
        "amplitude": (REQUIRED, non_negative("heave amplitude, chords")),
    },
    "wing": {
        "chord": (None, optional(positive("chord, m"))),
        "aspect_ratio": (None, optional(positive("aspect ratio span / chord, -"))),
        "alpha_deg": (None, optional(_number("a finite angle of attack in degrees, in (-90, 90)",
                                             lambda x: -90 < x < 90))),
    },
}
"""Top-level tables translated into structure keys (see the module docstring)."""

TOP_LEVEL = ("name", "description", *SECTIONS, "probes", "strain_gauges", "load", *SHORTHANDS)
PROBE_KEYS = ("name", "body", "span", "chord")
STRAIN_GAUGE_KEYS = ("name", "body", "span", "surface_distance")
DEFAULT_AXIS_POSITION = 0.5
"""Reference line position, fraction of chord from the leading edge, when a body does not say."""


# --- reading --------------------------------------------------------------------------------------

def read_scene_file(path: str | Path) -> dict:
    """The raw TOML table of a scene file; raises SceneFileError when unreadable or not TOML."""
    path = Path(path)
    try:
        with path.open("rb") as f:
            return tomllib.load(f)
    except FileNotFoundError:
        raise SceneFileError(path, "no such file") from None
    except IsADirectoryError:
        raise SceneFileError(path, "it is a directory, not a .toml file") from None
    except OSError as err:
        raise SceneFileError(path, err.strerror or str(err)) from None
    except tomllib.TOMLDecodeError as err:
        raise SceneFileError(path, f"not valid TOML: {err}") from None


# --- defaults and validation ----------------------------------------------------------------------

def _resolve_section(scene: dict, section: str, rules: dict[str, tuple[Any, Checker]]) -> dict:
    table = scene.get(section, {})
    if not isinstance(table, dict):
        raise SceneError(section, table, f"a table [{section}] with keys {', '.join(rules)}")
    reject_unknown_keys(table, section, rules)
    resolved = {}
    for key, (default, check) in rules.items():
        dotted = f"{section}.{key}"
        if key not in table and default is REQUIRED:
            raise SceneError(dotted, MISSING, "required; " + _allowed_text(check, dotted))
        resolved[key] = check(dotted, copy.deepcopy(table.get(key, default)))
    return resolved


def _allowed_text(check: Checker, key: str) -> str:
    """What ``check`` accepts, as the text of the SceneError it raises for an impossible value."""
    try:
        check(key, object())
    except SceneError as err:
        return err.allowed
    return "a value"


def _default_flow_direction(scene: dict) -> None:
    """Aero scenes record the free-stream direction: given, or the chord axis of the first body."""
    flow = scene["flow"]
    if flow["direction"] is None:
        if scene["aero"]["model"] == "none":
            del flow["direction"]
            return
        bodies = scene["structure"]["bodies"]
        chord_axis = bodies[0].get("chord_axis", [0.0, 1.0, 0.0]) if bodies else [0.0, 1.0, 0.0]
        flow["direction"] = optional_direction("chord axis of the first body, the default flow.direction")(
            "structure.bodies.0.chord_axis", copy.deepcopy(chord_axis))


def _agree(key: str, given: Any, derived: float, source: str) -> float:
    """``derived`` if ``given`` is absent or equal to it (relative 1e-12), else a SceneError."""
    if given is not None and not (_is_number(given) and math.isclose(given, derived, rel_tol=1e-12)):
        raise SceneError(key, given, f"{derived:.12g} as {source} sets it, or leave the key out")
    return float(derived)


def _motion_table(scene: dict, key: str) -> dict:
    """The ``structure.motion`` table of a prescribed-fidelity scene, created if absent."""
    structure = scene["structure"]
    if structure["fidelity"] != "prescribed":
        raise SceneError(key, structure["fidelity"], "structure.fidelity = 'prescribed' (the shorthand "
                                                     "sets a prescribed motion)")
    if structure.get("motion") is None:
        structure["motion"] = {}
    return structure["motion"]


def _first_body(scene: dict, key: str, only: bool) -> dict:
    bodies = scene["structure"]["bodies"]
    if not bodies or (only and len(bodies) != 1) or not isinstance(bodies[0], dict):
        raise SceneError(key, f"{len(bodies)} bodies", "a scene with exactly one body in structure.bodies"
                         if only else "a scene with a body in structure.bodies")
    return bodies[0]


def _body_chord(body: dict) -> float:
    section = body.get("section")
    chord = section.get("chord", MISSING) if isinstance(section, dict) else MISSING
    return positive("chord, m")("structure.bodies.0.section.chord", chord)


def _apply_shorthands(raw: dict, scene: dict) -> None:
    """Resolve the [wing] and [motion] tables and translate them into structure keys, in place."""
    for table, rules in SHORTHANDS.items():
        if table in raw:
            resolved = _resolve_section(raw, table, rules)
            scene[table] = {k: v for k, v in resolved.items() if v is not None}
    wing = scene.get("wing")
    if wing:
        body = _first_body(scene, "wing", only=True)
        if "chord" in wing:
            section = body.setdefault("section", {})
            if not isinstance(section, dict):
                raise SceneError("structure.bodies.0.section", section, "a table with the chord")
            section["chord"] = _agree("structure.bodies.0.section.chord", section.get("chord"), wing["chord"],
                                      "wing.chord")
        if "aspect_ratio" in wing:
            chord = _body_chord(body)
            body["length"] = _agree("structure.bodies.0.length", body.get("length"), wing["aspect_ratio"] * chord,
                                    f"wing.aspect_ratio x chord ({wing['aspect_ratio']:g} x {chord:g} m)")
        if "alpha_deg" in wing:
            motion = _motion_table(scene, "wing.alpha_deg")
            motion["alpha_deg"] = _agree("structure.motion.alpha_deg", motion.get("alpha_deg"), wing["alpha_deg"],
                                         "wing.alpha_deg")
    heave = scene.get("motion")
    if heave is not None:
        chord = _body_chord(_first_body(scene, "motion", only=False))
        speed = scene["flow"]["speed"]
        if speed <= 0 and heave["reduced_frequency"] > 0:
            raise SceneError("flow.speed", speed, "a speed > 0 (m/s): motion.reduced_frequency is relative to it")
        motion = _motion_table(scene, "motion")
        source = f"motion.reduced_frequency = {heave['reduced_frequency']:g} (2 k V / c)"
        motion["frequency"] = _agree("structure.motion.frequency", motion.get("frequency"),
                                     2.0 * heave["reduced_frequency"] * speed / chord, source)
        motion["heave_amplitude"] = _agree("structure.motion.heave_amplitude", motion.get("heave_amplitude"),
                                           heave["amplitude"] * chord,
                                           f"motion.amplitude = {heave['amplitude']:g} chords")


def _body_point(prefix: str, table: dict, bodies: list[dict]) -> tuple[str, dict, float]:
    """(body name, its section table ({} if absent or malformed), span in m) of a probe or strain gauge
    table, checked."""
    by_name = {b["name"]: b for b in bodies if isinstance(b.get("name"), str)}
    body_name = table.get("body", MISSING)
    if not isinstance(body_name, str) or body_name not in by_name:
        listed = ", ".join(repr(n) for n in by_name) or "the scene has no named bodies"
        raise SceneError(f"{prefix}.body", body_name, f"the name of a body in structure.bodies: {listed}")
    body = by_name[body_name]
    span = non_negative("m from the body root")(f"{prefix}.span", table.get("span", MISSING))
    length = body.get("length")
    if _is_number(length) and 0 < length < span / (1 + 1e-12):  # a bad length is Topology's to report
        raise SceneError(f"{prefix}.span", span, f"a number in [0, {length:g}] "
                                                 f"(m from the root of body '{body_name}', {length:g} m long)")
    section = body.get("section") if isinstance(body.get("section"), dict) else {}
    return body_name, section, span


def _named_tables(kind: str, key: str, tables: Any, allowed: tuple[str, ...], taken: set[str]):
    """(prefix, name, table) of each table of the array ``key``, with unknown keys refused and names unique
    among themselves and not in ``taken`` (the other column names)."""
    table_list(kind)(key, tables)
    seen = set()
    for index, table in enumerate(tables):
        prefix = f"{key}.{table['name'] if _is_name(table.get('name')) else index}"
        reject_unknown_keys(table, prefix, allowed)
        table_name = name(f"{prefix}.name", table.get("name", MISSING))
        if table_name in seen or table_name in taken:
            raise SceneError(f"{prefix}.name", table_name, f"a {kind} name not used by another {kind} "
                                                           "or column of timeseries.csv")
        seen.add(table_name)
        yield prefix, table_name, table


def _resolve_probes(probes: Any, bodies: list[dict]) -> list[dict]:
    resolved = []
    for prefix, probe_name, probe in _named_tables("probe", "probes", probes, PROBE_KEYS, set()):
        body_name, section, span = _body_point(prefix, probe, bodies)
        axis = section.get("axis_position", DEFAULT_AXIS_POSITION)
        chord_default = axis if _is_number(axis) else DEFAULT_AXIS_POSITION
        chord = between(0.0, 1.0, "fraction of chord from the leading edge")(
            f"{prefix}.chord", probe.get("chord", chord_default))
        resolved.append({"name": probe_name, "body": body_name, "span": span, "chord": chord})
    return resolved


def _resolve_strain_gauges(gauges: Any, bodies: list[dict], taken: set[str]) -> list[dict]:
    """Each gauge with ``surface_distance`` (m) filled with half its body's plate thickness."""
    resolved = []
    for prefix, gauge_name, gauge in _named_tables("strain gauge", "strain_gauges", gauges, STRAIN_GAUGE_KEYS,
                                                   taken):
        body_name, section, span = _body_point(prefix, gauge, bodies)
        thickness = section.get("thickness")
        half = 0.5 * thickness if _is_number(thickness) and thickness > 0 else MISSING
        if "surface_distance" not in gauge and half is MISSING:
            raise SceneError(f"{prefix}.surface_distance", MISSING,
                             f"required: body '{body_name}' has no section.thickness (a distance > 0 from the "
                             "reference line to the gauged surface, m)")
        distance = positive("distance from the reference line to the gauged surface, m")(
            f"{prefix}.surface_distance", gauge.get("surface_distance", half))
        resolved.append({"name": gauge_name, "body": body_name, "span": span, "surface_distance": distance})
    return resolved


def _column_names(scene: dict) -> set[str]:
    """The timeseries.csv columns the scene's probes, hinges and monitors take (strain gauges excepted)."""
    probes = {f"{p['name']}_{axis}" for p in scene["probes"] for axis in "xyz"}
    hinges = {f"fold_angle_{j.get('name')}" for j in hinge_joints(scene)}
    return {"time", *probes, *hinges, *MONITOR_COLUMNS, *AERO_COLUMNS, *COUPLING_COLUMNS}


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
    """Fill defaults into a raw scene and check everything but the physics tables.

    Returns a new dict: ``name``, ``description``, the sections time, coupling, flow, aero,
    structure (numbers as float, counts as int), ``probes`` (each with ``chord`` filled from
    its body's ``section.axis_position``) and ``strain_gauges`` (each with ``surface_distance`` filled
    with half its body's ``section.thickness``). Raises SceneError at the first bad key.
    """
    if not isinstance(raw, dict):
        raise SceneError("<top level>", raw, "a TOML table")
    reject_unknown_keys(raw, "", TOP_LEVEL)
    _reject_dates(raw, "")
    scene: dict[str, Any] = {
        "name": name("name", raw.get("name", default_name)),
        "description": text("description", raw.get("description", "")),
    }
    for section, rules in SECTIONS.items():
        scene[section] = _resolve_section(raw, section, rules)
    if scene["structure"]["motion"] is None:
        del scene["structure"]["motion"]
    if "load" in raw:   # a load case by its non-dimensional parameter; checked by Topology
        scene["load"] = optional_table("parameter, direction, body, span, law, ramp_time")("load", copy.deepcopy(raw["load"]))
    _apply_shorthands(raw, scene)
    _default_flow_direction(scene)
    scene["probes"] = _resolve_probes(copy.deepcopy(raw.get("probes", [])), scene["structure"]["bodies"])
    scene["strain_gauges"] = _resolve_strain_gauges(copy.deepcopy(raw.get("strain_gauges", [])),
                                                    scene["structure"]["bodies"], _column_names(scene))
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
    """SceneError unless the units can be built from the resolved scene: the structural topology and,
    for an aero scene, the aero solver."""
    from structure_fmu.topology import StructureTopology  # lazy: the physics packages are only needed here

    StructureTopology.from_scene(scene)
    _check_sensor_outputs(scene)
    if scene["aero"]["model"] != "none":
        from aero_fmu.solver import AeroSolver

        AeroSolver(scene)


def _check_sensor_outputs(scene: dict) -> None:
    """SceneError naming the probe or strain gauge one of whose outputs of the structure unit (``<probe>_x``
    .. ``<probe>_vz``, ``<gauge>``) takes the name of another of its variables or of a timeseries.csv column.
    Run after the topology check: the parameter names come from the bodies and joints."""
    from structure_fmu.sensors import probe_output_names
    from structure_fmu.solver import StructureSolver

    hinges = [j["name"] for j in hinge_joints(scene)]
    owner = {name: "an output of the structure unit" for name in ("topology_hash", *MONITOR_COLUMNS)}
    owner.update({f"{kind}_{h}": f"an output of hinge {h}" for h in hinges for kind in ("fold_angle", "latch_time")})
    owner.update({name: "a parameter of the structure unit" for name in StructureSolver.tunable_parameters(scene)})
    owner.update({name: "a column of timeseries.csv" for name in ("time", *AERO_COLUMNS, *COUPLING_COLUMNS)})
    sensors = [("probes", "probe", p["name"], sum(probe_output_names(p["name"]), [])) for p in scene["probes"]]
    sensors += [("strain_gauges", "strain gauge", g["name"], [g["name"]]) for g in scene["strain_gauges"]]
    for key, kind, sensor, outputs in sensors:
        for output in outputs:
            if output in owner:
                raise SceneError(f"{key}.{sensor}.name", sensor, f"a {kind} name whose output {output!r} is not "
                                 f"already {owner[output]}")
            owner[output] = f"an output of {kind} {sensor}"


def hinge_joints(scene: dict) -> list[dict]:
    """The scene's hinge joint tables, in order (each has ``name``; ``stop_angle_deg`` if latched)."""
    return [j for j in scene["structure"]["joints"] if j.get("type") == "hinge"]
