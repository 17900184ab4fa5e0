"""One scene schema: every key declared once (fmu_common.scene_schema), resolved and checked once at load.

Bad input of every kind (misspelt keys in nested tables, non-finite numbers, wrong types, duplicate names,
sizes beyond the bounds) gives a SceneError naming the key as the scene writes it, quickly and before any
unit is built; the shipped scenes resolve to themselves with every default filled; docs/scenes.md is the
text generated from the schema."""
from __future__ import annotations

import copy
import json

import numpy as np
import pytest

from fmu_common.errors import SceneError
from fmu_common.wing_spec import StructureSpec
from fmu_common.topology import Topology
from fmu_common.scene_bounds import AERO_INPUT_RECORD_VALUES, MAX_MEMORY_BYTES, memory_estimate
from fmu_common.scene_schema import ACCELERATIONS, SCENE
from fmu_common.scene_schema import resolve_scene as resolve_schema
from fmu_common.schema import REQUIRED, Key, Table, Tables, Variants, item_label
from fmu_common.scissors import chain_tables
from orchestrator.cli import main
from orchestrator.scene.load import load_scene, read_scene_file, resolve_scene
from repository import SCENES

SHIPPED = sorted(SCENES.glob("*.toml"))


def refusal(scene: str, overrides: list[str]) -> SceneError:
    """The SceneError of loading scenes/<scene>.toml with `overrides`."""
    with pytest.raises(SceneError) as err:
        load_scene(SCENES / f"{scene}.toml", overrides)
    return err.value


# --- bad input names the key --------------------------------------------------------------------------

CAMPAIGN = [
    # (scene, overrides, the key named, text of what is allowed)
    ("deploy_rigid", ["structure.masses.0.spn=0.15"], "structure.masses.0.spn", "unknown key"),
    ("cantilever_static", ["structure.loads.0.ramp_tme=2"], "structure.loads.0.ramp_tme", "unknown key"),
    ("deploy_rigid", ["structure.bodies.0.sectoin.chord=1"], "structure.bodies.inner.sectoin", "unknown key"),
    ("deploy_rigid", ["structure.joints.fold.stifness=1"], "structure.joints.fold.stifness", "unknown key"),
    ("deploy_rigid", ["structure.motion.frequency=1"], "structure.motion", "only with structure.fidelity"),
    ("heaving_wing", ["structure.motion.phase=1"], "structure.motion.phase", "unknown key"),
    ("stability_wing", ["load.ramp_time=0.1"], "load.ramp_time", "unknown key"),   # constant law: no ramp
    ("deploy_rigid", ["structure.bodies.inner.section.youngs_modulus=inf"],
     "structure.bodies.inner.section.youngs_modulus", "a finite number > 0"),
    ("deploy_flexible", ["structure.bodies.inner.section.youngs_modulus=inf"],
     "structure.bodies.inner.section.youngs_modulus", "a finite number > 0"),
    ("deploy_flexible", ["structure.bodies.outer.section.density=inf"],
     "structure.bodies.outer.section.density", "a finite number > 0"),
    ("deploy_flexible", ["structure.bodies.inner.section.chord=inf"], "structure.bodies.inner.section.chord",
     "a finite number > 0"),
    ("cantilever_static", ["structure.bodies.beam.section.bending_stiffness_flap=nan"],
     "structure.bodies.beam.section.bending_stiffness_flap", "a finite number > 0"),
    ("deploy_flexible", ["structure.bodies.inner.section.youngs_modulus=1e308",
                         "structure.bodies.inner.section.chord=10"],
     "structure.bodies.inner.section", "axial_stiffness"),                   # E c h overflows to inf
    ("deploy_rigid", ["structure.gravity=[0,0,-inf]"], "structure.gravity", "finite"),
    ("deploy_rigid", ["structure.joints.fold.torque=inf"], "structure.joints.fold.torque", "a finite number"),
    ("deploy_rigid", ["structure.masses.0.mass=inf"], "structure.masses.0.mass", "a finite number > 0"),
    ("spin_up", ["structure.joints.0.omega=inf"], "structure.joints.0.omega", "a finite number"),
    ("deploy_rigid", ["structure.bodies.inner.section.thickness=0"], "structure.bodies.inner.section.thickness",
     "a finite number > 0"),
    ("deploy_rigid", ["structure.bodies.inner.section.thickness=-0.002"],
     "structure.bodies.inner.section.thickness", "a finite number > 0"),
    ("deploy_rigid", ["structure.bodies.inner.section.thickness=inf"], "structure.bodies.inner.section.thickness",
     "a finite number > 0"),
    ("deploy_rigid", ['structure.bodies.inner.section="aluminium"'], "structure.bodies.inner.section",
     "a table [structure.bodies.inner.section]"),
    ("deploy_rigid", ["structure.bodies.outer.name=inner"], "structure.bodies.1.name",
     "a body name not used by another body"),
    ("deploy_rigid", ['structure.joints.fold.stiffness="stiff"'], "structure.joints.fold.stiffness",
     "a finite number >= 0"),
    ("deploy_rigid", ["structure.joints.fold.initial_angle_deg=[170]"], "structure.joints.fold.initial_angle_deg",
     "a number in (-180, 180)"),
    ("deploy_rigid", ["structure.joints.0.body=3"], "structure.joints.0.body", "a non-empty name"),
    ("deploy_rigid", ["structure.joints.0.type=weld"], "structure.joints.0.type", "'clamp', 'pin', 'driven'"),
    ("deploy_rigid", ["structure.joints.0=3"], "structure.joints", "an array of tables"),
    ("deploy_rigid", ["structure.masses.0.mass=[1]"], "structure.masses.0.mass", "a finite number > 0"),
    ("deploy_rigid", ['structure.masses.0.span="tip"'], "structure.masses.0.span", "a finite number >= 0"),
    ("deploy_rigid", ["structure.masses.0.body=1"], "structure.masses.0.body", "a non-empty name"),
    ("deploy_rigid", ["structure.masses.0.body=wing"], "structure.masses.0.body", "one of the bodies"),
    ("deploy_rigid", ["structure.masses.0.span=0.01"], "structure.masses.0.span", "a node position"),
    ("cantilever_static", ["structure.loads.0.law=step"], "structure.loads.0.law", "'constant', 'cosine_ramp'"),
    ("cantilever_static", ["structure.loads.0.span=3"], "structure.loads.0.span", "0 <= span <= 2"),
    ("spin_up", ["structure.joints.0.law=sudden"], "structure.joints.0.law", "'spin_up'"),
    ("deploy_rigid", ["structure.bodies.outer.root=[0,0,1]"], "structure.bodies.outer.root", "not allowed"),
    ("deploy_rigid", ["structure.bodies.outer.chord_axis=[0,1,0]"], "structure.bodies.outer.chord_axis",
     "the chord axis the joint gives the child"),
    ("heaving_wing", ["structure.motion.alpha_deg=5"], "structure.motion.alpha_deg", "0 when heave_amplitude"),
    ("deploy_rigid", ["structure.joints.fold.name=outer"], "structure.joints.outer.name", "not a body's"),
    ("deploy_rigid", ["time.stop=1" + "0" * 400], "time.stop", "a finite number > 0"),    # beyond the floats
    ("steady_wing", ["structure.bodies.wing.section.youngs_modulus=1e9", "structure.bodies.wing.section.density=-1"],
     "structure.bodies.wing.section.density", "a finite number > 0"),
]


@pytest.mark.parametrize("scene, overrides, key, allowed", CAMPAIGN, ids=[f"{c[0]}:{c[1][-1]}" for c in CAMPAIGN])
def test_bad_scene_is_refused_naming_the_key(scene, overrides, key, allowed):
    err = refusal(scene, overrides)
    assert err.key == key, str(err)
    assert allowed in str(err) and f"'{key}'" in str(err)


def test_section_keys_a_plate_or_explicit():
    """A plate needs all three of thickness, density and Young's modulus; without one, every explicit
    property is required; a strain gauge on an explicit section needs its own surface distance."""
    err = refusal("deploy_rigid", ["structure.bodies.inner.section={chord=0.05, torsional_rigidity=3.5, "
                                   "thickness=0.002, density=2740.0}"])
    assert err.key == "structure.bodies.inner.section.youngs_modulus" and "required with" in str(err)
    err = refusal("deploy_rigid", ["structure.bodies.inner.section={chord=0.05, torsional_rigidity=3.5}"])
    assert err.key == "structure.bodies.inner.section.axial_stiffness" and "required unless" in str(err)


def test_wrong_types_anywhere_are_scene_errors_never_type_errors():
    """Every scalar key of a deploy scene, set to a value of each wrong kind: a SceneError naming that key."""
    raw = read_scene_file(SCENES / "deploy_rigid.toml")
    paths = list(_scalar_paths(raw))
    for path, value in paths:
        for wrong in ([1, 2], {"a": 1}, True, *([] if isinstance(value, str) else ["text"])):
            bad = copy.deepcopy(raw)
            _set(bad, path, wrong)
            with pytest.raises(SceneError) as err:
                resolve_scene(bad, "bad")
            assert err.value.key == _labelled(raw, path), (path, wrong)
    assert len(paths) > 40


def _scalar_paths(node, path=()):
    if isinstance(node, dict):
        for k, v in node.items():
            yield from _scalar_paths(v, (*path, k))
    elif isinstance(node, list) and node and isinstance(node[0], dict):
        for i, v in enumerate(node):
            yield from _scalar_paths(v, (*path, i))
    elif path and path[-1] not in ("name", "description"):
        yield path, node


def _set(node, path, value):
    for part in path[:-1]:
        node = node[part]
    node[path[-1]] = value


def _labelled(raw, path):
    """The dotted key of `path` as a SceneError names it (items of arrays by name or index)."""
    out, node = [], raw
    for part in path:
        out.append(item_label(part, node[part]) if isinstance(part, int) else part)
        node = node[part]
    return ".".join(out)


# --- size bounds ------------------------------------------------------------------------------------------

@pytest.mark.parametrize("overrides, key, bound", [
    (["structure.elements_per_body=1000000"], "structure.elements_per_body", "an integer in [1, 100]"),
    (["structure.step=1e-300"], "structure.step", "at most 100,000 internal structure steps"),
    (["aero.step=1e-300"], "aero.step", "at most 100,000 internal aero steps"),
    (["aero.spanwise_panels=100000"], "aero.spanwise_panels", "an integer in [1, 1000]"),
    (["aero.chordwise_panels=40", "aero.spanwise_panels=100"], "aero.spanwise_panels", "at most 4096 bound panels"),
    (["time.stop=1e9"], "time.stop", "at most 10,000,000 communication steps"),
    (["coupling.max_iterations=1000000"], "coupling.max_iterations", "an integer in [1, 1000]"),
])
def test_sizes_beyond_the_bounds_are_refused_at_once(overrides, key, bound):
    err = refusal("deploy_flexible", overrides)
    assert err.key == key and bound in str(err)


def test_estimated_memory_is_bounded():
    """Ten 100-element bodies: about 9000 coordinates, whose dense structure matrices (~9 GiB) exceed the bound."""
    raw = read_scene_file(SCENES / "stability_wing.toml")
    body = raw["structure"]["bodies"][0]
    raw["structure"]["bodies"] = [dict(body, name=f"b{i}") for i in range(10)]
    raw["structure"]["elements_per_body"] = 100
    del raw["load"], raw["probes"]
    with pytest.raises(SceneError) as err:
        resolve_scene(raw, "large")
    assert err.value.key == "structure.elements_per_body" and "GiB of estimated memory" in str(err.value)
    assert "structure matrices" in str(err.value)


@pytest.mark.parametrize("path", SHIPPED, ids=[p.stem for p in SHIPPED])
def test_shipped_scenes_are_well_within_the_bounds(path):
    scene = load_scene(path)
    total = sum(size for _, size in memory_estimate(scene).values())
    assert total < MAX_MEMORY_BYTES / 10


def test_time_series_estimate_matches_the_recorded_rows():
    """The time-series part of the estimate against the bytes the master's rows take (numpy rows in a list)."""
    import sys


    scene = load_scene(SCENES / "deploy_flexible.toml", ["time.stop=1.0"])
    estimate = memory_estimate(scene)["time series"][1]
    columns = 1 + 9 * 2 + 1 + 1 + 3 + 2      # time, 2 probes (position, velocity, acceleration), 1 hinge, 1 gauge,
                                             # monitors, CL, lift
    row = np.zeros(columns)
    measured = (sys.getsizeof(row) + 8) * 1001                 # the row and its list entry, 1001 samples
    assert measured <= estimate <= 1.2 * measured


def test_the_bounds_restate_the_units_own_limits():
    from orchestrator.run.acceleration import ACCELERATIONS as SCHEMES
    from orchestrator.run.coupling import AeroInputs

    assert AeroInputs.max_values == AERO_INPUT_RECORD_VALUES
    assert tuple(SCHEMES) == ACCELERATIONS


# --- the shipped scenes -------------------------------------------------------------------------------------

@pytest.mark.parametrize("path", SHIPPED, ids=[p.stem for p in SHIPPED])
def test_shipped_scene_resolves_complete_and_to_itself(path):
    """Every key the file gives keeps its value (the shorthands' keys as translated by docs/scenes.md),
    every other key with a declared default has it, resolving the resolved scene changes nothing, and it
    survives JSON (as in summary.json and the FMUs)."""
    raw = _translated(read_scene_file(path))
    scene = load_scene(path)
    _check_filled(SCENE, raw, scene, "")
    assert resolve_scene(scene, path.stem) == scene
    assert resolve_schema(json.loads(json.dumps(scene)), path.stem) == scene


def _translated(raw):
    """[wing] and [motion] as docs/scenes.md states them: length = aspect_ratio x chord, section.chord = chord,
    structure.motion.alpha_deg = alpha_deg; frequency = 2 k V / c, heave_amplitude = amplitude x c; a scissor
    chain's bodies, joints and probes appended (fmu_common.scissors.chain_tables)."""
    raw = copy.deepcopy(raw)
    resolved = SCENE.resolve("", raw)["structure"] if raw["structure"].get("scissors") else {"scissors": []}
    for chain in resolved["scissors"]:
        bodies, joints, probes = chain_tables(resolved, chain)
        raw["structure"].setdefault("bodies", []).extend(bodies)
        raw["structure"].setdefault("joints", []).extend(joints)
        raw.setdefault("probes", []).extend(probes)
    if "wing" not in raw and "motion" not in raw:
        return raw
    body = raw["structure"]["bodies"][0]
    wing, heave = raw.get("wing", {}), raw.get("motion")
    if "chord" in wing:
        body["section"]["chord"] = wing["chord"]
    if "aspect_ratio" in wing:
        body["length"] = wing["aspect_ratio"] * body["section"]["chord"]
    if "alpha_deg" in wing:
        raw["structure"].setdefault("motion", {})["alpha_deg"] = wing["alpha_deg"]
    if heave is not None:
        c, speed = body["section"]["chord"], raw["flow"]["speed"]
        raw["structure"].setdefault("motion", {}).update(frequency=2 * heave["reduced_frequency"] * speed / c,
                                                         heave_amplitude=heave["amplitude"] * c)
    return raw


ABSENT = object()


def _check_filled(spec, raw, resolved, key):
    """`resolved` against the declaration `spec` and the raw value (ABSENT: not given)."""
    if isinstance(spec, Variants):
        spec = Table({spec.selector: spec.selector_key, **spec.tables[resolved[spec.selector]].keys})
    if isinstance(spec, Table):
        raw = {} if raw is ABSENT else raw
        assert set(resolved) <= set(spec.keys), key
        for name, sub in spec.keys.items():
            if name not in resolved:
                assert getattr(sub, "optional", False) and name not in raw, f"{key}.{name}"
            else:
                _check_filled(sub, raw.get(name, ABSENT), resolved[name], f"{key}.{name}")
    elif isinstance(spec, Tables):
        raw = [] if raw is ABSENT else raw
        assert len(resolved) == len(raw), key
        for i, item in enumerate(resolved):
            _check_filled(spec.item, raw[i], item, f"{key}.{i}")
    elif raw is not ABSENT:
        assert resolved == raw, key                              # given: kept
    elif spec.default is not REQUIRED and not hasattr(spec.default, "text"):
        assert resolved == spec.default, key                     # a plain default: filled in


def test_a_jointed_child_takes_its_frame_from_its_parent():
    """A revolute joint's child gets its parent's chord axis, whatever that is (not a fixed default), turned by
    the joint's orientation: the resolved scene leaves it to the topology."""
    raw = read_scene_file(SCENES / "deploy_rigid.toml")
    del raw["structure"]["bodies"][1]["chord_axis"]
    outer = resolve_scene(raw, "x")["structure"]["bodies"][1]
    assert outer["chord_axis"] is None and outer["root"] is None and outer["span_axis"] is None
    chord = lambda scene: Topology.from_spec(StructureSpec.from_scene(scene)).bodies["outer"].chord_axis
    assert chord(resolve_scene(raw, "x")) == pytest.approx([1.0, 0.0, 0.0], abs=1e-15)
    raw["structure"]["bodies"][0]["chord_axis"] = [0.0, 1.0, 0.0]
    assert chord(resolve_scene(raw, "x")) == pytest.approx([0.0, 1.0, 0.0], abs=1e-15)
    # a quarter turn about the span first takes the chord to the normal; the fold then turns that about the
    # chord axis by theta_0: sin(theta_0) span + cos(theta_0) normal of the parent
    raw["structure"]["joints"][1]["orientation_deg"] = [90.0, 0.0, 0.0]
    scene = resolve_scene(raw, "x")
    inner = Topology.from_spec(StructureSpec.from_scene(scene)).bodies["inner"]
    theta = np.radians(scene["structure"]["joints"][1]["initial_angle_deg"])
    normal = np.cross(inner.span_axis, inner.chord_axis)
    assert chord(scene) == pytest.approx(np.sin(theta) * inner.span_axis + np.cos(theta) * normal, abs=1e-15)


def test_load_case_defaults_are_its_body_tip_and_axis():
    scene = load_scene(SCENES / "stability_wing.toml")
    assert (scene["load"]["body"], scene["load"]["span"], scene["load"]["chord"]) == ("wing", 0.15, 0.5)


# --- the command line ------------------------------------------------------------------------------------

@pytest.mark.parametrize("setting, key", [
    ("structure.masses.0.spn=0.15", "structure.masses.0.spn"),
    ("structure.step=1e-300", "structure.step"),
])
def test_run_exits_2_naming_the_key(setting, key, tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    code = main(["run", str(SCENES / "deploy_flexible.toml"), "--set", setting, "--out", str(tmp_path / "out")])
    assert code == 2 and f"'{key}'" in capsys.readouterr().err
    assert not (tmp_path / "fmus").exists() and not (tmp_path / "out").exists()    # refused before anything ran


def test_build_refuses_an_infinite_youngs_modulus(tmp_path, capsys, monkeypatch):
    """The flexible fidelity with E = inf: exit 2 naming the key, and no FMU (no start="nan" anywhere)."""
    monkeypatch.chdir(tmp_path)
    scene = tmp_path / "stiff.toml"
    scene.write_text((SCENES / "deploy_flexible.toml").read_text().replace("youngs_modulus = 2.83e9",
                                                                            "youngs_modulus = inf"))
    code = main(["build", str(scene), "--out", str(tmp_path / "fmus")])
    assert code == 2 and "'structure.bodies.inner.section.youngs_modulus' = inf" in capsys.readouterr().err
    assert not list(tmp_path.rglob("*.fmu"))


# --- docs/scenes.md --------------------------------------------------------------------------------------

def test_docs_scenes_md_is_generated_from_the_schema():
    from orchestrator.scene.docs import OUTPUT, generate

    text = generate()
    assert OUTPUT.read_text(encoding="utf-8") == text, "run python -m orchestrator.scene.docs"
    for name, spec in SCENE.keys["structure"].keys.items():
        if isinstance(spec, Key):
            assert f"| `{name}` |" in text
    assert "| `section.youngs_modulus` | number | Pa |" in text and '`type = "revolute"`' in text
