"""Scene loading: --set overrides, defaults, and malformed scenes naming key, value and allowed."""

import copy
import json

import pytest

from orchestrator.scene.overrides import apply_overrides, parse_override, parse_value
from orchestrator.scene.load import MISSING, load_scene, read_scene_file, resolve_scene
from fmu_common.errors import SceneError
from fmu_common.scene_schema import TAPERED
from repository import SCENES

EXAMPLE = SCENES / "deploy_rigid.toml"


@pytest.fixture
def raw():
    return read_scene_file(EXAMPLE)


def resolved(raw, *overrides):
    return resolve_scene(apply_overrides(raw, overrides), default_name="deploy_rigid")


# --- overrides ------------------------------------------------------------------------------------

@pytest.mark.parametrize("text, value", [
    ("20", 20), ("1e-3", 1e-3), ("-9.81", -9.81), ("true", True), ("rigid", "rigid"),
    ('"two words"', "two words"), ("[0,0,-9.8]", [0, 0, -9.8]), ("uvlm-flat", "uvlm-flat"), ("", ""),
])
def test_override_values_are_toml_or_bare_strings(text, value):
    assert parse_value(text) == value
    assert type(parse_value(text)) is type(value)


def test_overrides_dotted_keys_with_types(raw):
    scene = resolved(raw, "flow.speed=20", "structure.fidelity=flexible", "structure.gravity=[0,0,-9.81]",
                     "time.stop=1e-2", "structure.elements_per_body=6")
    assert scene["flow"]["speed"] == 20.0 and isinstance(scene["flow"]["speed"], float)
    assert scene["structure"]["fidelity"] == "flexible"
    assert scene["structure"]["gravity"] == [0.0, 0.0, -9.81]
    assert scene["time"]["stop"] == 0.01
    assert scene["structure"]["elements_per_body"] == 6


def test_override_creates_missing_section(raw):
    del raw["flow"]
    assert resolved(raw, "aero.model=none", "flow.density=0.02")["flow"] == {"speed": 0.0, "density": 0.02,
                                                                              "direction": [1.0, 0.0, 0.0]}


def test_override_addresses_array_of_tables_by_name_or_index(raw):
    scene = resolved(raw, "structure.bodies.outer.damping=0.5", "structure.joints.fold.stiffness=0.03",
                     "structure.masses.0.mass=0.05", "probes.tip.span=0.1", "structure.bodies[0].damping=0.2")
    inner, outer = scene["structure"]["bodies"]
    assert outer["damping"] == 0.5 and inner["damping"] == 0.2
    assert scene["structure"]["joints"][1]["stiffness"] == 0.03
    assert scene["structure"]["masses"][0]["mass"] == 0.05
    assert scene["probes"][1]["span"] == 0.1


def test_overrides_leave_the_raw_scene_alone(raw):
    before = copy.deepcopy(raw)
    apply_overrides(raw, ["structure.bodies.outer.damping=0.5", "flow.speed=3"])
    assert raw == before


def test_override_of_unknown_table_name_lists_the_names(raw):
    with pytest.raises(SceneError) as err:
        apply_overrides(raw, ["structure.bodies.middle.damping=0.5"])
    assert err.value.key == "structure.bodies.middle.damping"
    assert "'inner', 'outer'" in str(err.value)


@pytest.mark.parametrize("item", ["flow.speed", "=3", "flow..speed=3", ".speed=2"])
def test_malformed_override_is_a_scene_error(item):
    with pytest.raises(SceneError) as err:
        parse_override(item)
    assert err.value.key == "--set" and "KEY=VALUE" in str(err.value)


def test_override_inside_a_value_is_refused(raw):
    with pytest.raises(SceneError) as err:
        apply_overrides(raw, ["time.stop.x=1"])
    assert err.value.key == "time.stop.x" and "not a table" in str(err.value)


# --- defaults -------------------------------------------------------------------------------------

SECTION = {"chord": 0.1, "torsional_rigidity": 1.0, "thickness": 0.01, "density": 1000.0, "youngs_modulus": 1e9}


def test_defaults_of_a_minimal_scene():
    scene = resolve_scene({"time": {"stop": 1.0}, "structure": {"bodies": [{"name": "b", "length": 1.0,
                                                                             "section": SECTION}]}},
                          default_name="minimal")
    assert scene["name"] == "minimal" and scene["description"] == ""
    assert scene["coupling"] == {"step": 1e-3, "algorithm": "gauss-seidel", "tolerance": 1e-6,
                                 "max_iterations": 50, "acceleration": "aitken", "relaxation": 0.5}
    assert scene["flow"] == {"speed": 0.0, "density": 1.2, "direction": [0.0, 1.0, 0.0]}   # the body's chord axis
    # the free wake's far field: the treecode at the opening docs/aero.md decides for (CL within 1e-5 of the exact sum)
    assert scene["aero"] == {"model": "none", "chordwise_panels": 2, "spanwise_panels": 7, "wake_length": 5.0,
                             "step": None, "wake_far_field": "treecode", "wake_opening": 0.3,
                             "span_correction": "helmbold"}
    body = scene["structure"].pop("bodies")
    assert scene["structure"] == {
        "fidelity": "flexible", "elements_per_body": 4, "integrator": "generalized-alpha", "step": 1e-4,
        "rho_inf": 0.8, "damping_model": "deformation", "gravity": [0.0, 0.0, 0.0], "joints": [],
        "scissors": [], "masses": [], "loads": []}
    assert body == [{"name": "b", "length": 1.0, "root": [0.0, 0.0, 0.0], "span_axis": [1.0, 0.0, 0.0],
                     "chord_axis": [0.0, 1.0, 0.0], "damping": 0.0, "elements": None, "angular_velocity": None,
                     "sweep_deg": None, "twist_deg": 0.0, "dihedral_deg": 0.0,
                     "section": {**SECTION, "axis_position": 0.5, "axial_stiffness": None,
                                 "bending_stiffness_flap": None, "bending_stiffness_chord": None,
                                 "mass_per_length": None, "poissons_ratio": 0.0, "rotary_inertia": 0.0,
                                 "airfoil": None, **{f"{name}_tip": None for name in TAPERED}}}]
    assert scene["probes"] == []
    assert scene["strain_gauges"] == []
    assert scene["record"] == {"probes": "acceleration", "monitors": "all"}     # everything timeseries.csv holds
    assert list(scene) == ["name", "description", "time", "coupling", "flow", "aero", "structure", "probes",
                           "strain_gauges", "record"]
    json.dumps(scene, allow_nan=False)


def test_resolved_example_keeps_its_values(raw):
    scene = resolved(raw)
    assert scene["name"] == "deploy_rigid"
    assert scene["structure"]["fidelity"] == "rigid" and scene["structure"]["integrator"] == "rk4"
    for given, body in zip(raw["structure"]["bodies"], scene["structure"]["bodies"]):
        assert {k: body[k] for k in given if k != "section"} == {k: v for k, v in given.items() if k != "section"}
        assert {k: body["section"][k] for k in given["section"]} == given["section"]
    assert scene["structure"]["bodies"][1]["root"] is None     # a hinge's child starts at its parent's tip
    assert scene["probes"] == [{"name": "bending_100mm", "body": "inner", "span": 0.1, "chord": 0.5},
                               {"name": "tip", "body": "outer", "span": 0.15, "chord": 0.5}]
    # the surface distance defaults to half the 2 mm plate thickness
    assert scene["strain_gauges"] == [{"name": "strain_20mm", "body": "inner", "span": 0.02,
                                       "surface_distance": 0.001,
                                       "curvature": "model"}]


def test_probe_chord_defaults_to_the_body_axis(raw):
    raw["structure"]["bodies"][1]["section"]["axis_position"] = 0.25
    del raw["probes"][1]["chord"]
    assert resolved(raw)["probes"][1]["chord"] == 0.25


# --- malformed scenes -----------------------------------------------------------------------------

MALFORMED = [
    # (overrides, key, value, text of what is allowed)
    (["structure.fidelity=wobbly"], "structure.fidelity", "wobbly", "one of 'prescribed', 'rigid', 'flexible'"),
    (["structure.integrator=euler"], "structure.integrator", "euler", "'rk4', 'generalized-alpha'"),
    (["flw.speed=3"], "flw", {"speed": 3}, "allowed at the top level: name, description, time"),
    (["flow.sped=3"], "flow.sped", 3, "allowed in [flow]: speed, density"),
    (["structure.stiffness=3"], "structure.stiffness", 3, "allowed in [structure]: fidelity"),
    (["time.stop=abc"], "time.stop", "abc", "a finite number > 0"),
    (["time.stop=true"], "time.stop", True, "a finite number > 0"),
    (["time.stop=inf"], "time.stop", float("inf"), "a finite number > 0"),
    (["coupling.step=-1e-3"], "coupling.step", -1e-3, "a finite number > 0"),
    (["structure.step=0"], "structure.step", 0, "a finite number > 0"),
    (["flow.speed=-1"], "flow.speed", -1, "a finite number >= 0"),
    (["structure.gravity=[0,-9.8]"], "structure.gravity", [0, -9.8], "an array of 3 finite numbers"),
    (["structure.elements_per_body=2.5"], "structure.elements_per_body", 2.5, "an integer in [1, 100]"),
    (["structure.elements_per_body=0"], "structure.elements_per_body", 0, "an integer in [1, 100]"),
    (["structure.rho_inf=1.5"], "structure.rho_inf", 1.5, "a number in [0, 1]"),
    (["coupling.algorithm=newton"], "coupling.algorithm", "newton", "'gauss-seidel', 'jacobi', 'implicit'"),
    (["aero.model=vortex"], "aero.model", "vortex", "one of 'none', 'strip', 'uvlm-flat'"),
    (["coupling.tolerance=0"], "coupling.tolerance", 0, "a finite number > 0"),
    (["coupling.max_iterations=0"], "coupling.max_iterations", 0, "an integer in [1, 1000]"),
    (["coupling.max_iterations=2.5"], "coupling.max_iterations", 2.5, "an integer in [1, 1000]"),
    (["coupling.acceleration=broyden"], "coupling.acceleration", "broyden", "'aitken', 'iqn-ils'"),
    (["coupling.relaxation=0"], "coupling.relaxation", 0, "a number in (0, 1]"),
    (["coupling.relaxation=1.5"], "coupling.relaxation", 1.5, "a number in (0, 1]"),
    (["flow.direction=[0,0,0]"], "flow.direction", [0, 0, 0], "a non-zero array of 3 finite numbers"),
    (["flow.direction=[1,0]"], "flow.direction", [1, 0], "array of 3 finite numbers"),
    (["aero.chordwise_panels=0"], "aero.chordwise_panels", 0, "an integer in [1, 100]"),
    (["aero.wake_length=0"], "aero.wake_length", 0, "a finite number > 0, or inf"),
    (["aero.wake_length=-inf"], "aero.wake_length", float("-inf"), "a finite number > 0, or inf"),
    (["structure.bodies=3"], "structure.bodies", 3, "an array of tables"),
    (["flow=3"], "flow", 3, "a table [flow] with keys speed, density"),
    (["name=a/b"], "name", "a/b", "letters, digits"),
    (["description=3"], "description", 3, "a string"),
    (["probes.tip.body=wing"], "probes.tip.body", "wing", "'inner', 'outer'"),
    (["probes.tip.span=0.2"], "probes.tip.span", 0.2, "a number in [0, 0.15]"),
    (["probes.tip.chord=2"], "probes.tip.chord", 2, "a number in [0, 1]"),
    (["probes.tip.side=2"], "probes.tip.side", 2, "allowed in [probes.tip]: name, body, span, chord"),
    (["probes.tip.name=x,y"], "probes.1.name", "x,y", "letters, digits"),
    (["strain_gauges.strain_20mm.body=wing"], "strain_gauges.strain_20mm.body", "wing", "'inner', 'outer'"),
    (["strain_gauges.strain_20mm.span=0.2"], "strain_gauges.strain_20mm.span", 0.2, "a number in [0, 0.15]"),
    (["strain_gauges.strain_20mm.surface_distance=-1"], "strain_gauges.strain_20mm.surface_distance", -1,
     "a finite number > 0"),
    (["strain_gauges.strain_20mm.name=tip_x"], "strain_gauges.tip_x.name", "tip_x",
     "not used by another strain gauge or column of timeseries.csv"),
    (["strain_gauges.strain_20mm.chord=0.5"], "strain_gauges.strain_20mm.chord", 0.5,
     "allowed in [strain_gauges.strain_20mm]: name, body, span, surface_distance, curvature"),
    (["flow.speed=1979-05-27"], "flow.speed", "1979-05-27", "not a date or time"),
]


@pytest.mark.parametrize("overrides, key, value, allowed", MALFORMED,
                         ids=[f"{m[1]}={m[2]}" for m in MALFORMED])
def test_malformed_scene_names_key_value_and_allowed(raw, overrides, key, value, allowed):
    with pytest.raises(SceneError) as err:
        resolved(raw, *overrides)
    assert (err.value.key, err.value.value) == (key, value)
    message = str(err.value)
    assert f"'{key}'" in message and repr(value) in message and allowed in message


def test_missing_required_key(raw):
    del raw["time"]["stop"]
    with pytest.raises(SceneError) as err:
        resolved(raw)
    assert (err.value.key, err.value.value) == ("time.stop", MISSING)
    assert "required" in str(err.value)


def test_strain_gauge_on_a_section_without_thickness_needs_its_surface_distance(raw):
    section = raw["structure"]["bodies"][0]["section"]
    for key in ("thickness", "density", "youngs_modulus"):
        del section[key]
    section.update(axial_stiffness=1e6, bending_stiffness_flap=0.1, bending_stiffness_chord=10.0,
                   mass_per_length=0.1)
    with pytest.raises(SceneError) as err:
        resolved(raw)
    assert err.value.key == "strain_gauges.strain_20mm.surface_distance" and "no section.thickness" in str(err.value)
    gauge = resolved(raw, "strain_gauges.strain_20mm.surface_distance=0.003")["strain_gauges"][0]
    assert gauge["surface_distance"] == 0.003


def test_duplicate_probe_names(raw):
    raw["probes"].append(dict(raw["probes"][1]))
    with pytest.raises(SceneError) as err:
        resolved(raw)
    assert err.value.key == "probes.2.name" and "not used by another probe" in str(err.value)


# --- files ----------------------------------------------------------------------------------------

def test_load_scene_fails_on_a_bad_scalar_before_the_physics(tmp_path):
    path = tmp_path / "bad.toml"
    path.write_text(EXAMPLE.read_text().replace('fidelity = "rigid"', 'fidelity = "wobbly"'))
    with pytest.raises(SceneError, match="structure.fidelity"):
        load_scene(path)


def test_unreadable_scene_files(tmp_path):
    with pytest.raises(SceneError, match="no such file"):
        load_scene(tmp_path / "missing.toml")
    (tmp_path / "broken.toml").write_text("[time\nstop = 1")
    with pytest.raises(SceneError, match="not valid TOML"):
        load_scene(tmp_path / "broken.toml")


# --- with the structural topology (structure_fmu.topology) ----------------------------------------

def test_load_example_scene_checks_the_physics(raw):
    scene = load_scene(EXAMPLE, ["structure.bodies.outer.damping=0.5"])
    assert scene == resolved(raw, "structure.bodies.outer.damping=0.5")


def test_bad_physics_fails_at_load(tmp_path):
    path = tmp_path / "bad_body.toml"
    path.write_text(EXAMPLE.read_text())
    with pytest.raises(SceneError) as err:
        load_scene(path, ["structure.bodies.outer.length=-0.15"])
    assert "length" in err.value.key and "-0.15" in str(err.value)


@pytest.mark.parametrize("stop", [200, 180, -180])
def test_a_stop_angle_the_fold_angle_never_reaches_fails_at_load(stop):
    """The fold angle lies in (-180, 180] deg and a latch across its wrap is not a crossing, so a stop
    outside (-180, 180) deg would never latch: refused, not a silent 'not deployed'."""
    with pytest.raises(SceneError) as err:
        load_scene(EXAMPLE, [f"structure.joints.fold.stop_angle_deg={stop}"])
    assert err.value.key == "structure.joints.fold.stop_angle_deg" and "(-180, 180) (deg)" in str(err.value)


# --- aero scenes: flow.direction and the [motion] / [wing] shorthands ------------------------------

def aero_raw(name):
    return read_scene_file(SCENES / f"{name}.toml")


def test_flow_direction_defaults_to_the_chord_axis_of_the_first_root_body(raw):
    del raw["flow"]["direction"]
    inner, outer = raw["structure"]["bodies"]
    inner["chord_axis"] = [0, 2, 0]                  # any length
    del outer["chord_axis"]                          # the joint gives its child its frame
    raw["structure"]["bodies"] = [outer, inner]      # the hinge's child first
    scene = resolved(raw, "aero.model=uvlm-flat")
    assert scene["flow"]["direction"] == [0.0, 2.0, 0.0]                  # chord_axis of body 'inner'
    assert scene["structure"]["bodies"][0]["chord_axis"] is None         # the topology derives it
    assert resolved(raw, "aero.model=strip", "flow.direction=[1,0,1]")["flow"]["direction"] == [1.0, 0.0, 1.0]


def test_motion_shorthand_gives_the_heave_law_of_otsuka_2019_sec_VI_D():
    scene = resolve_scene(aero_raw("heaving_wing"), "heaving_wing")
    # 2 k V / c = 2 * 0.25 * 1 / 1 = 0.5 rad/s; 0.1 chords of 1 m
    motion = scene["structure"]["motion"]
    assert (motion["frequency"], motion["heave_amplitude"], motion["pitch_amplitude_deg"]) == (0.5, 0.1, 0.0)
    assert scene["motion"] == {"reduced_frequency": 0.25, "amplitude": 0.1}
    assert resolve_scene(scene, "heaving_wing") == scene                    # resolving again changes nothing
    faster = resolve_scene(apply_overrides(aero_raw("heaving_wing"), ["flow.speed=2", "motion.amplitude=0.2"]), "x")
    assert (faster["structure"]["motion"]["frequency"], faster["structure"]["motion"]["heave_amplitude"]) == (1.0, 0.2)


@pytest.mark.parametrize("overrides, key", [
    (["structure.motion.frequency=0.7"], "structure.motion.frequency"),       # contradicts 2 k V / c
    (["flow.speed=0"], "flow.speed"),                                          # k is relative to V
    (["structure.fidelity=rigid"], "motion"),                                  # sets a prescribed motion
    (["motion.phase=3"], "motion.phase"),
])
def test_motion_shorthand_refuses_contradictions(overrides, key):
    with pytest.raises(SceneError) as err:
        resolve_scene(apply_overrides(aero_raw("heaving_wing"), overrides), "x")
    assert err.value.key == key


def test_wing_shorthand_sets_length_chord_and_angle():
    scene = resolve_scene(aero_raw("steady_wing"), "steady_wing")
    body = scene["structure"]["bodies"][0]
    assert body["length"] == 8.0 and scene["structure"]["motion"]["alpha_deg"] == 5.0
    assert resolve_scene(scene, "steady_wing") == scene
    scene = resolve_scene(apply_overrides(aero_raw("steady_wing"), ["wing.chord=0.5", "wing.alpha_deg=-2"]), "x")
    body = scene["structure"]["bodies"][0]
    assert (body["length"], body["section"]["chord"], scene["structure"]["motion"]["alpha_deg"]) == (4.0, 0.5, -2.0)


@pytest.mark.parametrize("overrides, key", [
    (["structure.bodies.wing.length=3"], "structure.bodies.0.length"),     # contradicts AR x chord
    (["wing.alpha_deg=90"], "wing.alpha_deg"),
    (["wing.aspect_ratio=0"], "wing.aspect_ratio"),
    (["structure.fidelity=rigid"], "wing.alpha_deg"),
])
def test_wing_shorthand_refuses_contradictions(overrides, key):
    with pytest.raises(SceneError) as err:
        resolve_scene(apply_overrides(aero_raw("steady_wing"), overrides), "x")
    assert err.value.key == key


def test_wing_shorthand_needs_one_body(raw):
    raw["wing"] = {"aspect_ratio": 4.0}
    with pytest.raises(SceneError) as err:
        resolved(raw)
    assert err.value.key == "wing" and "exactly one body" in str(err.value)
