"""Probes and strain gauges as outputs of the structure FMU, against independent computations.

The FMUs are driven by name through fmpy directly (not through orchestrator.run.units), their outputs compared
with: a rigid-body formula (deploy_rigid), the element's shape functions evaluated on the element's own
coordinates (deploy_flexible), a central difference of positions (velocities) and of the reference line
(curvature). The master's timeseries.csv columns are then compared with the same outputs read from a unit
driven with the master's call sequence.
"""
import shutil

import numpy as np
import pytest
from fmpy import extract, read_model_description
from fmpy.fmi2 import FMU2Slave

import structure_fmu.structure_slave  # noqa: F401  (the host's copy, shared by the FMUs loaded here)
from orchestrator.run.master import communication_times, new_series, run_scene
from orchestrator.scene.load import load_scene
from orchestrator.run.port import UnitError
from orchestrator.run.units import make_unit
from structure_fmu.solver import StructureSolver
from fmu_common.specs import StructureUnitSpec
from fmu_common.wing_spec import StructureSpec
from fmu_common.errors import SceneError
from fmu_common.interface import fmi_name
from fmu_common.shape_functions import shape_row
from fmu_common.topology import Topology
from repository import SCENES

RIGID, FLEXIBLE = SCENES / "deploy_rigid.toml", SCENES / "deploy_flexible.toml"
H = 1e-3   # communication step, s
STILL_AIR = "aero.model=none"


def still_air(path, *overrides):
    return load_scene(path, [STILL_AIR, *overrides])


@pytest.fixture(scope="module")
def rigid(built_fmus):
    return still_air(RIGID), built_fmus("deploy_rigid", STILL_AIR) / "structure.fmu"


@pytest.fixture(scope="module")
def flexible(built_fmus):
    return still_air(FLEXIBLE), built_fmus("deploy_flexible", STILL_AIR) / "structure.fmu"


def drive(fmu, times, names):
    """fmpy alone: instantiate, initialize, step through `times` (s) with Q at its start value 0, and read
    the Real variables `names` (FMI names) at every time: {name: (len(times),)}."""
    md = read_model_description(str(fmu))
    vr = {v.name: v.valueReference for v in md.modelVariables}
    unzipped = extract(str(fmu))
    slave = FMU2Slave(guid=md.guid, unzipDirectory=unzipped, modelIdentifier=md.coSimulation.modelIdentifier,
                      instanceName="sensors")
    try:
        slave.instantiate()
        slave.setupExperiment(startTime=0.0)
        slave.enterInitializationMode()
        slave.exitInitializationMode()
        refs = [vr[n] for n in names]
        rows = [slave.getReal(refs)]
        for t0, t1 in zip(times[:-1], times[1:]):
            slave.doStep(t0, t1 - t0)
            rows.append(slave.getReal(refs))
        slave.terminate()
        slave.freeInstance()
    finally:
        shutil.rmtree(unzipped, ignore_errors=True)
    return dict(zip(names, np.array(rows).T))


def coordinates(n):
    return [f"e[{k}]" for k in range(1, n + 1)] + [f"de[{k}]" for k in range(1, n + 1)]


def probe_names(scene, probe):
    return [fmi_name(f"{probe}_{s}") for s in ("x", "y", "z", "vx", "vy", "vz")]


# --- the model description -------------------------------------------------------------------------

def test_the_sensor_outputs_are_declared_as_the_timeseries_columns_with_units(rigid):
    scene, fmu = rigid
    md = read_model_description(str(fmu))
    variables = {v.name: v for v in md.modelVariables}
    columns = new_series(scene).columns
    probes = [p["name"] for p in scene["probes"]]
    gauges = [g["name"] for g in scene["strain_gauges"]]
    expected_units = {}
    for p in probes:
        expected_units.update({f"{p}_{a}": "m" for a in "xyz"})
        expected_units.update({f"{p}_v{a}": "m/s" for a in "xyz"})
        expected_units.update({f"{p}_a{a}": "m/s2" for a in "xyz"})
    expected_units.update({g: "1" for g in gauges})
    for name, unit in expected_units.items():
        v = variables[fmi_name(name)]
        assert (v.causality, v.variability, v.type, v.unit) == ("output", "continuous", "Real", unit), name
        assert v.description
    # every sensor output is a column, in the unit's order: the probes' positions, velocities, accelerations
    sensor_columns = [c for c in columns if c.rsplit("_", 1)[0] in probes or c in gauges]
    assert sensor_columns == [f"{p}_{kind}{a}" for kind in ("", "v", "a") for p in probes for a in "xyz"] + gauges
    assert all(fmi_name(c) in variables for c in sensor_columns)
    # contiguous after the latch times, before the joint monitors and the parameters
    refs = [variables[fmi_name(n)].valueReference for n in
            [f"{p}_{a}" for p in probes for a in "xyz"] + [f"{p}_v{a}" for p in probes for a in "xyz"]
            + [f"{p}_a{a}" for p in probes for a in "xyz"] + gauges]
    assert refs == list(range(refs[0], refs[0] + len(refs)))
    assert refs[0] == variables["latch_time_fold"].valueReference + 1
    joints = [variables[n].valueReference for n in ("fold_point_mismatch", "fold_axis_error")]
    assert joints == [refs[-1] + 1, refs[-1] + 2]
    assert joints[-1] + 1 == variables["structure.step"].valueReference


# --- values against independent computations -------------------------------------------------------

def test_rigid_probes_follow_the_rigid_body_formula_and_its_rate(rigid):
    """A rigid body's material point at span x and chord offset y is r^A + x r_x^A + y r_y^A (its root
    node's position and gradients), its velocity the same combination of their rates."""
    scene, fmu = rigid
    top = Topology.from_spec(StructureSpec.from_scene(scene))
    n = top.n_coordinates
    names = coordinates(n) + [v for p in scene["probes"] for v in probe_names(scene, p["name"])]
    out = drive(fmu, np.arange(41) * H, names)
    e = np.array([out[f"e[{k}]"] for k in range(1, n + 1)]).T
    de = np.array([out[f"de[{k}]"] for k in range(1, n + 1)]).T
    moved = False
    for p in scene["probes"]:
        body = top.bodies[p["body"]]
        root = body.nodes[0]
        y = (p["chord"] - body.axis_position) * body.chord
        combination = lambda c: (c[:, 9 * root:9 * root + 3] + p["span"] * c[:, 9 * root + 3:9 * root + 6]  # noqa: B023
                                 + y * c[:, 9 * root + 6:9 * root + 9])  # noqa: B023
        got = np.array([out[v] for v in probe_names(scene, p["name"])]).T
        np.testing.assert_allclose(got[:, :3], combination(e), rtol=0, atol=1e-14)
        np.testing.assert_allclose(got[:, 3:], combination(de), rtol=0, atol=1e-13)
        moved |= np.ptp(got[:, 3:]) > 0.1
    assert moved   # the outer body swings: the velocities are not trivially zero


def test_probe_velocity_is_the_rate_of_its_position(rigid):
    """Central difference of the tip position over steps of 1e-5 s (internal steps of the unit too): its
    truncation error h^2/6 |r'''| is below 3e-8 m/s here (|r'''| < 1.5e3 m/s^3 in the first 40 ms of the
    swing, from third differences of the velocity at 0.1 ms), its rounding about 1e-12 m/s."""
    scene, fmu = rigid
    h = 1e-5
    times = np.concatenate([[0.0], 0.02 + h * np.arange(-1, 2)])
    names = probe_names(scene, "tip")
    out = drive(fmu, times, names)
    position = np.array([out[v] for v in names[:3]]).T      # (4, 3): t = 0, 0.02 - h, 0.02, 0.02 + h
    velocity = np.array([out[v] for v in names[3:]]).T
    central = (position[3] - position[1]) / (2 * h)
    assert np.linalg.norm(velocity[2]) > 0.1
    np.testing.assert_allclose(velocity[2], central, rtol=0, atol=1e-7)


def test_flexible_probes_and_gauge_from_the_element_shape_functions(flexible):
    """deploy_flexible after 20 ms: each probe is S(x, y) e_el of its element (Otsuka et al. 2019, Eq. 2, on the
    element's own 18 coordinates), its velocity S(x, y) de_el; the gauge's strain is d x the flap curvature
    from central differences of the reference line r(x, 0) (exact for the cubic Hermite line but for
    rounding) and the chord vector r_y = r(x, 1) - r(x, 0)."""
    scene, fmu = flexible
    top = Topology.from_spec(StructureSpec.from_scene(scene))
    n = top.n_coordinates
    gauge = scene["strain_gauges"][0]
    names = (coordinates(n) + [v for p in scene["probes"] for v in probe_names(scene, p["name"])]
             + [fmi_name(gauge["name"])])
    out = {k: v[-1] for k, v in drive(fmu, np.arange(21) * H, names).items()}
    e = np.array([out[f"e[{k}]"] for k in range(1, n + 1)])
    de = np.array([out[f"de[{k}]"] for k in range(1, n + 1)])

    def element_point(body_name, span, c, y):
        body = top.bodies[body_name]
        l_el = body.length / len(body.elements)
        k = min(int(span / l_el), len(body.elements) - 1)
        a, b = top.element_nodes[body.elements[k]]
        slots = np.r_[9 * a:9 * a + 9, 9 * b:9 * b + 9]
        return np.kron(shape_row(span - k * l_el, y, l_el), np.eye(3)) @ c[slots]

    for p in scene["probes"]:
        body = top.bodies[p["body"]]
        y = (p["chord"] - body.axis_position) * body.chord
        got = np.array([out[v] for v in probe_names(scene, p["name"])])
        np.testing.assert_allclose(got[:3], element_point(p["body"], p["span"], e, y), rtol=0, atol=1e-14)
        np.testing.assert_allclose(got[3:], element_point(p["body"], p["span"], de, y), rtol=0, atol=1e-13)

    ds, s = 1e-4, gauge["span"]
    line = [element_point(gauge["body"], s + k * ds, e, 0.0) for k in (-1, 0, 1)]
    r1, r2 = (line[2] - line[0]) / (2 * ds), (line[2] - 2 * line[1] + line[0]) / ds ** 2
    ry = element_point(gauge["body"], s, e, 1.0) - line[1]
    normal = np.cross(r1, ry) / np.linalg.norm(np.cross(r1, ry))
    strain = gauge["surface_distance"] * (r2 @ normal) / (r1 @ r1)
    assert abs(strain) > 1e-5     # the inner body bends under the deploying outer body
    assert out[fmi_name(gauge["name"])] == pytest.approx(strain, rel=1e-8)   # rounding of r'': ~1e-9


# --- the master reads them ---------------------------------------------------------------------------

def test_timeseries_columns_are_the_units_outputs_through_the_fmu_backend(rigid):
    scene, fmu = rigid
    scene = {**scene, "time": {**scene["time"], "stop": 0.0205}}    # a shortened last step too
    result = run_scene(scene, backend="fmu", fmu_dir=fmu.parent)
    assert result.status == "ok", result.message
    columns = [c for c in result.series.columns
               if c.rsplit("_", 1)[0] in {p["name"] for p in scene["probes"]}
               or c in {g["name"] for g in scene["strain_gauges"]}]
    assert len(columns) == 9 * len(scene["probes"]) + len(scene["strain_gauges"])   # position, velocity, acceleration
    times = communication_times(scene["time"]["stop"], scene["coupling"]["step"])
    out = drive(fmu, times, [fmi_name(c) for c in columns])
    np.testing.assert_array_equal(result.series.time, times)
    for c in columns:
        assert np.array_equal(result.series.column(c), out[fmi_name(c)]), c


def test_the_unit_reports_velocities_in_both_backends_alike(rigid):
    scene, fmu = rigid
    readings = {}
    for backend in ("fmu", "direct"):
        unit = make_unit("structure", scene, backend, fmu.parent)
        try:
            for k in range(10):
                unit.set_inputs(np.zeros(unit.n))
                unit.do_step(k * H, H)
            readings[backend] = unit.monitors()
        finally:
            unit.terminate()
    for key in ("probe_positions", "probe_velocities"):
        for p, value in readings["fmu"][key].items():
            assert np.array_equal(value, readings["direct"][key][p])
    assert readings["fmu"]["strains"] == readings["direct"]["strains"]
    assert np.linalg.norm(readings["fmu"]["probe_velocities"]["tip"]) > 0.1


def test_an_fmu_built_with_other_probes_is_refused(rigid):
    scene, fmu = rigid
    moved = {**scene, "probes": [{**p, "span": 0.5 * p["span"]} if p["name"] == "tip" else p
                                 for p in scene["probes"]]}
    with pytest.raises(UnitError, match=r"probes\[1\]\.span.*rebuild"):
        make_unit("structure", moved, "fmu", fmu.parent)


# --- unique names ------------------------------------------------------------------------------------

@pytest.mark.parametrize("override, key, taken", [
    ("strain_gauges.strain_20mm.name=structure.step", "strain_gauges.structure.step.name",
     "'structure.step' is not already a parameter of the structure unit"),
    ("strain_gauges.strain_20mm.name=latch_time_fold", "strain_gauges.latch_time_fold.name",
     "'latch_time_fold' is not already an output of hinge fold"),
    ("strain_gauges.strain_20mm.name=tip_vx", "strain_gauges.tip_vx.name",
     "'tip_vx' is not already an output of probe tip"),
    ("strain_gauges.strain_20mm.name=topology_hash", "strain_gauges.topology_hash.name",
     "'topology_hash' is not already an output of the structure unit"),
])
def test_a_sensor_name_that_takes_another_outputs_name_is_refused(override, key, taken):
    with pytest.raises(SceneError) as err:
        still_air(RIGID, override)
    assert err.value.key == key and taken in str(err.value)


def test_probe_acceleration_of_a_released_rigid_pendulum():
    """pendulum_rigid at release, horizontal from its pin: angular acceleration 3 g / (2 L), so the tip (span L)
    accelerates by 3 g / 2 straight down and has no centripetal part yet."""
    solver = StructureSolver(StructureUnitSpec.from_scene(load_scene(SCENES / "pendulum_rigid.toml")))
    n = len(solver.sensors.probe_names)
    tip = solver.sensor_outputs()[6 * n:9 * n].reshape(-1, 3)[solver.sensors.probe_names.index("tip")]
    assert tip == pytest.approx([0.0, 0.0, -1.5 * 9.81], abs=1e-9)


@pytest.mark.parametrize("fidelity", ["rigid", "flexible", "strain-based"])
def test_probe_accelerations_are_the_rate_of_the_probe_velocities(fidelity):
    """The double pendulum in swing: each probe's acceleration output against the central difference of its
    velocity output over +-1e-5 s (RK4 at 1e-4 s, the ANCF bars at 4e-5 s; the bars vibrate up to thousands of
    rad/s, so the difference must resolve those)."""
    step = ["structure.step=4e-5"] if fidelity == "flexible" else []
    scene = load_scene(SCENES / "double_pendulum.toml", [f"structure.fidelity={fidelity}", *step])
    solver = StructureSolver(StructureUnitSpec.from_scene(scene))
    n, h = len(solver.sensors.probe_names), 1e-5
    readings = []
    for t in (0.1 - h, 0.1, 0.1 + h):
        solver.advance(t)
        readings.append(solver.sensor_outputs())
    velocity = lambda r: r[3 * n:6 * n]
    difference = (velocity(readings[2]) - velocity(readings[0])) / (2 * h)
    acceleration = readings[1][6 * n:9 * n]
    assert np.abs(acceleration - difference).max() < 2e-3 * np.abs(acceleration).max()
