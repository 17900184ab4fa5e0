"""The scissor-deployed wing (scenes/scissor_wing.toml): in still air without aerodynamics, its rigid deployment
against the one-degree-of-freedom Lagrange model of the mechanism (tests/scissor_mechanism.py: inertia J(theta)
and the gravity's generalized force) with the root joint's actuator, -(K theta + C theta' + T_const), integrated
independently by scipy's DOP853; and in the wind, the coupled run through the FMUs equals the in-process one."""
import numpy as np
from scipy.integrate import solve_ivp

import scissor_mechanism
from orchestrator.run.master import run_scene
from orchestrator.scene.load import load_scene
from repository import SCENES
from structure_fmu.solver import StructureSolver
from fmu_common.specs import StructureUnitSpec

WING = SCENES / "scissor_wing.toml"
N, L, MASS = 4, 0.3, 1600.0 * 0.08 * 0.003 * 0.3          # SLEs, bar length (m), bar mass (kg)
K, C, T, START, STOP = 2.0, 0.01, 2.0, np.radians(75.0), np.radians(15.0)
GRAVITY, SPAN, DOWN = (0.0, 0.0, -9.81), (0.0, 1.0, 0.0), (0.0, 0.0, -1.0)


def reference(times):
    """(theta (rad) at `times`, the time (s) theta reaches the latch angle)."""
    mechanism = scissor_mechanism.Mechanism.of(N, L, MASS, gravity=GRAVITY, d=SPAN, h_ax=DOWN)

    def rhs(t, y):
        theta, rate = y
        J, dJ = scissor_mechanism.inertia(theta, N, L, MASS)
        Q = scissor_mechanism.generalized_force(theta, mechanism)
        return [rate, (Q - (K * theta + C * rate + T) - 0.5 * dJ * rate**2) / J]
    latch = lambda t, y: y[0] - STOP
    latch.terminal = True
    solution = solve_ivp(rhs, (0.0, 1.0), [START, 0.0], method="DOP853", rtol=1e-12, atol=1e-12, events=latch,
                         dense_output=True)
    return solution.sol(times)[0], solution.t_events[0][0]


def test_the_rigid_wing_deploys_in_still_air_as_its_one_dof_model():
    """The root joint's fold angle is the mechanism's angle theta: within 1e-9 rad of the reference until the
    latch (RK4 at 1 ms: measured 2.5e-12 rad), and the latch time, interpolated linearly within the step, within
    1e-5 s (measured 2.5e-6 s of 0.397 s)."""
    solver = StructureSolver(StructureUnitSpec.from_scene(load_scene(WING, ["aero.model=none", "flow.speed=0"])))
    times = np.arange(0.0, 0.35, 0.01)
    theta_ref, latch_ref = reference(times)
    for t, expected in zip(times, theta_ref):
        solver.advance(t)
        assert abs(np.radians(solver.fold_angles_deg()["deploy"]) - expected) < 1e-9, t
    solver.advance(latch_ref + 0.01)
    assert abs(solver.monitors()["latch_times"]["deploy"] - latch_ref) < 1e-5
    assert solver.monitors()["constraint_residual"] < 1e-9


def test_the_wing_in_the_wind_runs_through_the_fmus_as_in_process(built_fmus):
    overrides = ["time.stop=0.05"]
    scene = load_scene(WING, overrides)
    through_fmus = run_scene(scene, backend="fmu", fmu_dir=built_fmus("scissor_wing", *overrides))
    direct = run_scene(scene, backend="direct")
    assert through_fmus.status == direct.status == "ok", through_fmus.message
    np.testing.assert_allclose(through_fmus.series.table(), direct.series.table(), rtol=1e-10, atol=1e-12)
    assert np.abs(direct.series.column("lift")).max() > 0.1           # the aero unit loads the wing
