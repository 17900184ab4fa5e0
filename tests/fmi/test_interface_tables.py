"""Each unit's FMI interface, declared once as a table (structure_fmu/interface.py, aero_fmu/interface.py): the
variables a built FMU declares are the table's, laid out for its scene; the values the slave publishes and the
master reads are the solver's own (compared with the solver API called directly, or with an independent count);
docs/fmu.md's tables are generated from the tables; and an output added to a table is registered, published and
read by the master with no other change."""
import re
import zipfile
from dataclasses import replace
from xml.etree import ElementTree

import numpy as np
import pytest

from aero_fmu.interface import AERO
from aero_fmu.solver import AeroSolver
from fmu_common.interface import Block, Interface, Items, Output, Parameters, Reading, layout
from fmu_common.scene_schema import resolve_scene
from fmu_common.specs import AeroUnitSpec, StructureUnitSpec
from orchestrator.run.direct_port import DirectPort
from orchestrator.run.port import KINDS, UnitError
from orchestrator.run.units import Unit, make_unit, scene_items
from orchestrator.scene.columns import AERO_COLUMNS, MONITOR_COLUMNS
from orchestrator.scene.load import joint_monitor_names, load_scene
from repository import SCENES
from structure_fmu.interface import LATCH_PENDING, STRUCTURE
from structure_fmu.solver import StructureSolver
from structure_fmu.structure_slave import StructureSlave

SOLVERS = {"structure": StructureSolver, "aero": AeroSolver}
SPECS = {"structure": StructureUnitSpec, "aero": AeroUnitSpec}


def structure_layout(table, scene):
    """`table` laid out for the structure solver of `scene`."""
    spec = StructureUnitSpec.from_scene(scene)
    return layout(table, StructureSolver(spec), spec)


# --- the tables against the FMUs built from them ------------------------------------------------------------

def _declared(fmu):
    """Every ScalarVariable of the FMU's modelDescription.xml as written: (name, valueReference, causality,
    variability, initial or None, type, unit or None, description, start as text)."""
    with zipfile.ZipFile(fmu) as archive:
        root = ElementTree.fromstring(archive.read("modelDescription.xml"))
    return [(v.get("name"), int(v.get("valueReference")), v.get("causality"), v.get("variability"), v.get("initial"),
             v[0].tag, v[0].get("unit"), v.get("description"), v[0].get("start"))
            for v in root.iter("ScalarVariable")]


@pytest.mark.parametrize("name", ["deploy_rigid", "deploy_flexible"])
def test_a_built_fmu_declares_exactly_the_variables_of_its_table(name, built_fmus):
    scene = load_scene(SCENES / f"{name}.toml")
    folder = built_fmus(name)
    for kind in ("structure", "aero"):
        expected = layout(KINDS[kind].interface, SOLVERS[kind](spec := SPECS[kind].from_scene(scene)), spec).variables
        declared = _declared(folder / f"{kind}.fmu")
        assert [v[0] for v in declared] == [v.name for v in expected], kind
        for got, want in zip(declared, expected):
            assert got[:8] == (want.name, want.value_reference, want.causality, want.variability, want.initial,
                               want.type, want.unit, want.description)
            if want.initial == "calculated":   # FMI 2.0: no start value; its value comes with initialization
                assert got[8] is None, want.name
                continue
            start = got[8] if want.type == "String" else float(got[8])   # written with 16 significant digits
            assert start == (want.start if want.type == "String" else pytest.approx(want.start, rel=1e-15)), want.name
        assert [v[1] for v in declared] == list(range(len(declared)))   # contiguous from 0


@pytest.mark.parametrize("path", sorted(SCENES.glob("*.toml")), ids=lambda p: p.stem)
def test_an_output_declared_exact_keeps_its_start_value_whatever_parameters_a_host_sets(path):
    # FMI 2.0: initial="exact" says the value after initialization is the start value. A host may set every
    # parameter before initialization, when the unit builds its solver with them (fmi_slave.exit_initialization_mode):
    # so an output whose value at initialization changes with a parameter must be declared "calculated"
    scene = load_scene(path)
    kinds = ["structure"] + (["aero"] if scene["aero"]["model"] != "none" else [])
    for kind in kinds:
        spec = SPECS[kind].from_scene(scene)
        table = KINDS[kind].interface
        defaults = {name: v[0] for name, v in SOLVERS[kind].tunable_parameters(spec).items()}
        nominal = {v.name: v for v in layout(table, SOLVERS[kind](spec), spec).variables if v.causality == "output"}
        for name, default in defaults.items():
            # a different, admissible value: directions turned, everything else scaled up
            value = default + 0.3 if "direction" in name else 1.5 * default + 0.1
            solver = SOLVERS[kind](spec, parameters={**defaults, name: value})
            for v in layout(table, solver, spec).variables:
                if v.causality != "output" or v.type != "Real":
                    continue
                changed = not np.array_equal(v.start, nominal[v.name].start, equal_nan=True)
                assert not (changed and v.initial == "exact"), f"{kind} {v.name} changes with {name} at t = 0"


@pytest.mark.parametrize("model", ["uvlm-flat", "uvlm-prescribed", "strip"])
def test_the_aero_table_declares_every_output_the_solver_gives_and_no_other(model):
    scene = load_scene(SCENES / "deploy_rigid.toml", [f"aero.model={model}"])
    solver = AeroSolver(AeroUnitSpec.from_scene(scene))
    produced = solver.outputs()
    assert {n for row in AERO.outputs if row.items is None for n in row.names} == set(produced)
    per_hinge = [row for row in AERO.outputs if row.items is not None]
    assert [row.names for row in per_hinge] == [("hinge_moment_<hinge>",)]
    assert list(solver.hinge_moments()) == per_hinge[0].items.of(solver) == ["fold"]
    assert "CM" not in produced      # the aero slave once declared a unit for it: nothing produces it


def test_the_sensor_rows_carry_the_units_the_solver_declares():
    scene = load_scene(SCENES / "deploy_flexible.toml")
    solver_spec = StructureUnitSpec.from_scene(scene)
    solver = StructureSolver(solver_spec)
    units = {v.name: v.unit for v in layout(STRUCTURE, solver, solver_spec).variables}
    declared = solver.sensors.output_declarations()
    assert declared and {name: units[name] for name, _, _ in declared} == {n: u for n, u, _ in declared}


def test_the_master_and_the_unit_name_the_same_items_for_every_shipped_scene():
    for path in sorted(SCENES.glob("*.toml")):
        scene = load_scene(path)
        solver = StructureSolver(StructureUnitSpec.from_scene(scene))
        master = scene_items(scene)
        for row in STRUCTURE.outputs:
            if row.items is not None:
                assert sorted(master[row.items.placeholder]) == sorted(row.items.of(solver)), (path.name, row.key)


def test_the_timeseries_columns_are_the_tables_monitors():
    assert MONITOR_COLUMNS == ("energy", "kinetic_energy", "constraint_residual", "external_work")
    assert AERO_COLUMNS == ("CL", "lift")


# --- what the slave publishes and the master reads, against the solver API called directly -------------------

def _stepped(solver_class, scene, steps, h, *inputs):
    spec_class = SPECS[next(kind for kind, cls in SOLVERS.items() if cls is solver_class)]
    solver = solver_class(spec_class.from_scene(scene))
    for k in range(steps):
        solver.advance(k * h + h, *inputs)     # the end of step k as the unit computes it: t + h
    return solver


def test_the_structure_unit_reports_what_its_solver_computes():
    scene = load_scene(SCENES / "deploy_rigid.toml", ["aero.model=none"])    # it latches within time.stop
    h = scene["coupling"]["step"]
    steps = round(scene["time"]["stop"] / h)
    unit = make_unit("structure", scene, "direct", None)
    try:
        for k in range(steps):
            unit.set_inputs(np.zeros(unit.n))
            unit.do_step(k * h, h)
        e, de = unit.get_outputs()
        m = unit.monitors()
    finally:
        unit.terminate()
    solver = _stepped(StructureSolver, scene, steps, h)
    assert np.array_equal(e, solver.e) and np.array_equal(de, solver.de)
    reference = solver.monitors()
    for name in MONITOR_COLUMNS:
        assert m[name] == reference[name], name
    assert m["fold_angles_deg"] == solver.fold_angles_deg()
    assert m["latch_times"] == reference["latch_times"] and m["latch_times"]     # FMI start time 0
    assert m["joints"] == solver.joint_monitors() and m["joints"]
    positions = solver.sensors.positions(solver.e)
    for j, probe in enumerate(solver.sensors.probe_names):
        np.testing.assert_allclose(m["probe_positions"][probe], positions[j], rtol=0, atol=1e-15)
    np.testing.assert_allclose([m["strains"][g] for g in solver.sensors.gauge_names], solver.sensors.strains(solver.e),
                               rtol=1e-12, atol=1e-18)


def test_the_aero_unit_reports_what_its_solver_computes():
    scene = load_scene(SCENES / "heaving_wing.toml")
    h, steps = scene["coupling"]["step"], 3
    e0 = AeroSolver(AeroUnitSpec.from_scene(scene)).topology.initial_coordinates()
    de0 = np.zeros_like(e0)
    unit = make_unit("aero", scene, "direct", None)
    try:
        for k in range(steps):
            unit.set_inputs(e0, de0)
            unit.do_step(k * h, h)
        (Q,) = unit.get_outputs()
        m = unit.monitors()
    finally:
        unit.terminate()
    solver = _stepped(AeroSolver, scene, steps, h, e0, de0)
    assert np.array_equal(Q, solver.Q)
    assert m == {**{name: float(v) for name, v in solver.outputs().items()}, "hinge_moments": {}}   # no hinge
    assert m["wake_panels"] > 0      # a count the table publishes as Real


@pytest.mark.parametrize("model", ["uvlm-flat", "strip"])
def test_the_aero_unit_reports_the_hinge_moments_its_solver_computes(model):
    # deploy_rigid's fold hinge at 170 deg in a flow turned out of the chord: a non-zero moment about the hinge
    scene = load_scene(SCENES / "deploy_rigid.toml", [f"aero.model={model}", "flow.direction=[1.0, 0.1, 0.05]"])
    h, steps = scene["coupling"]["step"], 2
    e0 = AeroSolver(AeroUnitSpec.from_scene(scene)).topology.initial_coordinates()
    de0 = np.zeros_like(e0)
    unit = make_unit("aero", scene, "direct", None)
    try:
        assert unit.monitors()["hinge_moments"] == {"fold": 0.0}     # before the first step
        for k in range(steps):
            unit.set_inputs(e0, de0)
            unit.do_step(k * h, h)
        m = unit.monitors()
    finally:
        unit.terminate()
    solver = _stepped(AeroSolver, scene, steps, h, e0, de0)
    assert m["hinge_moments"] == solver.hinge_moments()
    assert abs(m["hinge_moments"]["fold"]) > 1e-4       # N m: the 0.15 x 0.05 m outer body at 10 m/s


def test_a_non_finite_input_is_named_by_its_node_and_component():
    scene = load_scene(SCENES / "heaving_wing.toml")
    e = AeroSolver(AeroUnitSpec.from_scene(scene)).topology.initial_coordinates()
    first_node = AeroSolver(AeroUnitSpec.from_scene(scene)).topology.node_names[0]
    e[4] = np.nan                         # coordinate 5 of a node: r_x, its y component (per node r, r_x, r_y)
    unit = make_unit("aero", scene, "direct", None)
    try:
        unit.set_inputs(e, np.zeros_like(e))
        with pytest.raises(UnitError, match=re.escape(f"input e[5] (node {first_node} r_x[y]) is NaN")):
            unit.do_step(0.0, scene["coupling"]["step"])
    finally:
        unit.terminate()


def test_a_latch_time_is_pending_until_the_hinge_latches_and_the_master_leaves_it_out():
    scene = load_scene(SCENES / "deploy_rigid.toml", ["aero.model=none"])
    latch = [v for v in structure_layout(STRUCTURE, scene).variables if v.name.startswith("latch_time_")]
    assert latch and {(v.start, v.variability) for v in latch} == {(LATCH_PENDING, "discrete")}
    unit = make_unit("structure", scene, "direct", None)
    try:
        assert unit.monitors()["latch_times"] == {}
    finally:
        unit.terminate()


def test_universal_and_revolute_joint_monitors_have_their_units_and_values():
    section = {"chord": 0.1, "axis_position": 0.3, "torsional_rigidity": 50.0, "axial_stiffness": 1e5,
               "bending_stiffness_flap": 20.0, "bending_stiffness_chord": 200.0, "mass_per_length": 1.0}
    bodies = [{"name": "A", "length": 1.0, "root": [0, 0, 0], "span_axis": [1, 0, 0], "chord_axis": [0, 1, 0],
               "section": section}, {"name": "B", "length": 0.8, "section": section},
              {"name": "C", "length": 0.5, "section": section}]
    joints = [{"type": "ball", "name": "root", "child": "A"},
              {"type": "universal", "name": "cross", "parent": "A", "child": "B", "parent_axis": [0, 1, 0],
               "child_axis": [0, 0, 1], "orientation_deg": [0, -90, 0]},
              {"type": "revolute", "name": "hinge", "parent": "B", "child": "C", "initial_angle_deg": 30}]
    scene = resolve_scene({"time": {"stop": 0.01}, "coupling": {"step": 1e-3}, "structure": {
        "fidelity": "rigid", "integrator": "rk4", "step": 1e-4, "gravity": [0.0, -9.8, 0.0], "bodies": bodies,
        "joints": joints}}, "joints")
    solver_spec = StructureUnitSpec.from_scene(scene)
    solver = StructureSolver(solver_spec)
    variables = {v.name: v for v in layout(STRUCTURE, solver, solver_spec).variables}
    assert [(variables[n].unit, variables[n].description) for n in solver.joint_monitor_names()] == [
        ("m", "distance between the parent's tip and the child's root"),
        ("1", "axis condition of the joint, 0 while it holds"),
        ("m", "distance between the parent's tip and the child's root"),
        ("1", "axis condition of the joint, 0 while it holds")]
    assert solver.joint_monitor_names() == joint_monitor_names(scene) == [
        "cross_point_mismatch", "cross_axis_product", "hinge_point_mismatch", "hinge_axis_error"]
    unit = make_unit("structure", scene, "direct", None)
    try:
        unit.set_inputs(np.zeros(unit.n))
        unit.do_step(0.0, 1e-3)
        joints = unit.monitors()["joints"]
    finally:
        unit.terminate()
    assert joints == _stepped(StructureSolver, scene, 1, 1e-3).joint_monitors()


# --- docs/fmu.md ----------------------------------------------------------------------------------------------

def test_docs_fmu_md_is_generated_from_the_interface_tables():
    from orchestrator.build.interface_docs import OUTPUT, generate

    text = OUTPUT.read_text(encoding="utf-8")
    assert generate(text) == text, "run python -m orchestrator.build.interface_docs"
    for row in STRUCTURE.outputs + AERO.outputs:
        assert all(f"`{name}`" in text for name in row.names), row.names
    assert "| 3n+H | `energy` | output | J |" in text and "| 3n | `CL` | output | 1 |" in text
    assert "`CM`" not in text


# --- adding an output: one row ---------------------------------------------------------------------------------

def _solver_time(reading, _):
    return reading.solver.time


SOLVER_TIME = Output("solver_time", "s", "time of the structure solver since the start", _solver_time)
EXTENDED = STRUCTURE.extended(SOLVER_TIME)


class ExtendedSlave(StructureSlave):
    interface = EXTENDED


def test_an_output_added_to_the_table_is_registered_published_and_read_by_the_master():
    scene = load_scene(SCENES / "deploy_rigid.toml", ["aero.model=none"])
    spec = replace(KINDS["structure"], slave=(__name__, "ExtendedSlave"), interface=EXTENDED)
    unit = Unit(DirectPort(scene, "extended", spec), scene, {}, "structure", spec)
    h, steps = scene["coupling"]["step"], 3
    try:
        slave = unit._port._slave
        registered = {v.name: v for v in slave.vars.values()}
        plain = structure_layout(STRUCTURE, scene)
        first_parameter = plain.where(Parameters).start
        var = registered["solver_time"]
        assert (var.value_reference, var.unit, var.causality.name) == (first_parameter, "s", "output")
        assert min(v.value_reference for v in registered.values() if v.causality.name == "parameter") == \
            first_parameter + 1
        assert unit.monitors()["solver_time"] == 0.0
        for k in range(steps):
            unit.set_inputs(np.zeros(unit.n))
            unit.do_step(k * h, h)
        read = unit.monitors()["solver_time"]
    finally:
        unit.terminate()
    assert read == _stepped(StructureSolver, scene, steps, h).time
    assert read == pytest.approx(steps * h, rel=1e-12)


def test_an_output_added_to_the_table_is_in_the_generated_docs():
    from orchestrator.build.interface_docs import variables_table

    text = variables_table(EXTENDED, StructureSlave)
    assert "| `solver_time` | output | s | time of the structure solver since the start |" in text
    assert text.index("`external_work`") < text.index("`solver_time`") < text.index("| the tunable parameters |")


# --- the vocabulary refuses rows it cannot lay out ------------------------------------------------------------

def test_a_row_whose_values_do_not_match_its_variables_is_refused_naming_it():
    scene = load_scene(SCENES / "deploy_rigid.toml", ["aero.model=none"])
    two = Output("pair", "1", "two values for one variable", lambda reading, _: [1.0, 2.0])
    with pytest.raises(ValueError, match="output pair has 2 values for its 1 variables"):
        structure_layout(STRUCTURE.extended(two), scene)


def test_rows_that_cannot_be_laid_out_are_refused_when_declared():
    hinges = Items("<hinge>", "H", "hinges", lambda solver: solver.topology.hinge_names)
    value = lambda reading, items: []   # noqa: E731
    with pytest.raises(ValueError, match="needs the key"):
        Output("angle_<hinge>", "deg", "angle of <hinge>", value, hinges)
    with pytest.raises(ValueError, match="placeholder <hinge>"):
        Output("angle_<probe>", "deg", "angle", value, hinges, key="angles")
    with pytest.raises(ValueError, match="plain name"):
        Output("angle_<hinge>", "deg", "angle", value)
    with pytest.raises(ValueError, match="is one variable"):
        Output("angle_<hinge>", "deg", "angle", value, hinges, key="angles", monitor=True)
    with pytest.raises(ValueError, match="an output block needs a value"):
        Block("e", "output", "coordinate", "node", "coordinates")
    with pytest.raises(ValueError, match="declared twice"):
        Interface("unit", STRUCTURE.blocks, (Output("e", "m", "again", value),), Parameters("none"), "other")


def test_a_row_reads_each_solver_query_once_per_publication():
    calls = []

    def query(solver):
        calls.append(solver)
        return {"a": 1.0, "b": 2.0}

    reading = Reading("solver", start_time=0.5)
    assert [reading.once(query)["a"], reading.once(query)["b"]] == [1.0, 2.0] and calls == ["solver"]
    assert reading.start_time == 0.5
