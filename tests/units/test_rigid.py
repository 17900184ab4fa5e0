"""Rigid fidelity (Otsuka et al. 2019, Sec. IV, Eq. 17): shape preservation and the physical pendulum."""
import numpy as np
import pytest
from scipy.special import ellipk

from orchestrator.scene.load import load_scene
from fmu_common.scene_schema import resolve_scene
from fmu_common.specs import StructureUnitSpec
from repository import SCENES
from structure_fmu.solver import StructureSolver


def tumbling_scene(integrator):
    """A free rigid plate spinning near its unstable intermediate axis: a tumbling motion."""
    return resolve_scene({"time": {"stop": 1.0}, "structure": {
        "fidelity": "rigid", "integrator": integrator, "step": 1e-3, "rho_inf": 0.9,
        "bodies": [{"name": "plate", "length": 0.6, "span_axis": [1, 0, 0], "chord_axis": [0, 1, 0],
                    "angular_velocity": [0.4, 6.0, 0.3],
                    "section": {"chord": 0.2, "thickness": 0.01, "density": 2700.0,
                                "youngs_modulus": 70e9, "torsional_rigidity": 50.0}}],
        "joints": []}}, "tumbling")


def corner_distances(top, e):
    corners = [top.point_position(e, "plate", s, c) for s in (0.0, 0.6) for c in (0.0, 1.0)]
    return np.array([np.linalg.norm(a - b) for i, a in enumerate(corners) for b in corners[i + 1:]])


@pytest.mark.parametrize("integrator", ["rk4", "generalized-alpha"])
def test_tumbling_rigid_body_keeps_its_shape(integrator):
    solver = StructureSolver(StructureUnitSpec.from_scene(tumbling_scene(integrator)))
    top = solver.topology
    reference = corner_distances(top, solver.e)
    worst, turned = 0.0, 0.0
    x0 = solver.e[3:6].copy()
    for k in range(1, 101):
        solver.advance(0.01 * k)
        worst = max(worst, np.max(np.abs(corner_distances(top, solver.e) / reference - 1)))
        turned = max(turned, np.arccos(np.clip(solver.e[3:6] @ x0, -1, 1)))
    assert solver.time == pytest.approx(1.0)
    assert turned > 1.0          # it really tumbled (rad)
    assert worst < 1e-8
    assert solver.constraint_residual() < 1e-8


def pendulum_angles(solver, stop):
    """Angle from the downward vertical (rad) of the pendulum bar, sampled every internal step."""
    times, angles = [], []
    tip = lambda: solver.topology.point_position(solver.e, "bar", 1.0, 0.5)
    while solver.time < stop - 1e-12:
        solver.advance(solver.time + solver.step_size)
        x, _, z = tip()
        times.append(solver.time)
        angles.append(np.arctan2(x, -z))
    return np.array(times), np.array(angles)


def downward_crossings(times, angles):
    """Times where the angle crosses zero going negative, linearly interpolated."""
    i = np.flatnonzero((angles[:-1] > 0) & (angles[1:] <= 0))
    return times[i] + angles[i] / (angles[i] - angles[i + 1]) * (times[i + 1] - times[i])


def exact_period(g=9.81, length=1.0, amplitude=np.pi / 2):
    """Physical pendulum of a uniform bar: T = 4 sqrt(I / (m g d)) K(k), I = m L^2 / 3, d = L / 2."""
    return 4 * np.sqrt(2 * length / (3 * g)) * ellipk(np.sin(amplitude / 2) ** 2)


def energy_scale(scene):
    """m g L / 2: the energy the bar exchanges between potential and kinetic (J), from the scene data."""
    body = scene["structure"]["bodies"][0]
    section = body["section"]
    mass = section["density"] * section["chord"] * section["thickness"] * body["length"]
    return mass * 9.81 * body["length"] / 2


def test_rigid_pendulum_period_and_rk4_energy():
    scene = load_scene(SCENES / "pendulum_rigid.toml")
    solver = StructureSolver(StructureUnitSpec.from_scene(scene))
    energy0 = solver.monitors()["energy"]
    assert solver.monitors()["kinetic_energy"] == 0.0
    period = exact_period()
    times, angles = pendulum_angles(solver, 10.2 * period)
    crossings = downward_crossings(times, angles)
    assert len(crossings) >= 10
    measured = (crossings[-1] - crossings[0]) / (len(crossings) - 1)
    assert measured == pytest.approx(period, rel=1e-3)
    drift = abs(solver.monitors()["energy"] - energy0) / energy_scale(scene)
    assert drift < 1e-6


def test_rigid_pendulum_energy_bounded_with_generalized_alpha():
    scene = load_scene(SCENES / "pendulum_rigid.toml", ["structure.integrator=generalized-alpha",
                                                           "structure.step=0.005"])
    solver = StructureSolver(StructureUnitSpec.from_scene(scene))
    energy0 = solver.monitors()["energy"]
    energies = []
    for k in range(1, 21):
        solver.advance(k)
        energies.append(solver.monitors()["energy"])
    relative = (np.array(energies) - energy0) / energy_scale(scene)
    # no growth: the scheme dissipates only at high frequency, so the energy stays within 1e-3
    assert np.max(relative) < 1e-6
    assert np.min(relative) > -1e-3
    times, angles = pendulum_angles(solver, 20 + 3 * exact_period())
    crossings = downward_crossings(times, angles)
    assert np.diff(crossings).mean() == pytest.approx(exact_period(), rel=1e-3)
