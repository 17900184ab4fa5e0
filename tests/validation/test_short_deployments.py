"""Short deployments in the default suite, each against a reference computed here another way, with
tolerances a few times the measured discretization error: a change of a few percent in the physics fails
here, not only in the slow set (tests/validation/test_deployment.py, test_coupled_deployment.py).

- deploy_rigid in still air: the outer body as a pendulum of one degree of freedom about the hinge (an ODE
  solved by scipy to 1e-11), its fold angle and latch time;
- deploy_rigid at 10 m/s with the uvlm-flat aero unit: the scene's 1 ms coupling step against 0.25 ms;
- deploy_flexible at 10 m/s with the uvlm-flat aero unit, the first 0.08 s: the scene's structure step and
  mesh (2e-4 s, 7 elements per body) against 5e-5 s and 14 elements per body.

A 3% change of one physics input in the run under test (not in its reference) fails each test; what each
change moves is in the test's docstring. A change that moves the run and its refined reference alike is
caught by the pendulum here and by the papers' numbers in the slow set.
"""
import numpy as np
import pytest
from scipy.integrate import solve_ivp

from orchestrator.studies import metrics
from orchestrator.run.master import run_scene
from orchestrator.output.results import summarize
from orchestrator.scene.load import load_scene
from repository import SCENES

RIGID, FLEXIBLE = SCENES / "deploy_rigid.toml", SCENES / "deploy_flexible.toml"
STILL_AIR = "aero.model=none"


def run(path, *overrides):
    """The RunResult of a scene with `--set` overrides (direct backend), checked to have run to its end."""
    result = run_scene(load_scene(path, list(overrides)), backend="direct")
    assert result.status == "ok", result.message
    return result


def one_dof_pendulum(scene):
    """(latch time in s, fold angle in deg as a function of t in s) of the outer body as a pendulum of one
    degree of freedom about the chordwise hinge, until it reaches the stop at 0 deg.

    I theta'' = m g (L/2) sin(theta) - (K theta + C theta' + T_const): I = rho h c L^3 / 3 about the hinge
    (the hinge lies along the chord, the lumped actuator mass sits on the axis), gravity along -span of the
    vertical inner body, so the centre of mass height is L/2 cos(theta) above the hinge.
    """
    body = scene["structure"]["bodies"][1]
    section = body["section"]
    hinge = next(j for j in scene["structure"]["joints"] if j["type"] == "revolute")
    L = body["length"]
    mass = section["density"] * section["thickness"] * section["chord"] * L
    inertia = mass * L**2 / 3
    g = -scene["structure"]["gravity"][2]
    K, C, T = hinge["stiffness"], hinge["damping"], hinge["torque"]

    def rhs(t, y):
        theta, rate = y
        return [rate, (mass * g * L / 2 * np.sin(theta) - (K * theta + C * rate + T)) / inertia]

    def latched(t, y):
        return y[0]
    latched.terminal, latched.direction = True, -1
    sol = solve_ivp(rhs, (0, 1), [np.radians(hinge["initial_angle_deg"]), 0.0], events=latched,
                    rtol=1e-11, atol=1e-12, dense_output=True)
    return sol.t_events[0][0], lambda t: np.degrees(sol.sol(t)[0])


def differences(result, reference):
    """What separates a run from its reference over the run's samples (the reference read at the same times,
    linearly interpolated: exact where the run's times are among the reference's):

    fold_deg      largest |fold angle difference|, deg
    tip_mm        largest distance between the tip probe's positions, mm
    latch_pct     latch time difference, % (None if either run did not latch)
    cl_pct        CL error of Otsuka et al. 2019, Eq. 28, %
    cl_mean_pct, lift_mean_pct        CL and lift averaged over the samples, difference in %
    strain_end_pct                    strain_20mm at the end, difference in %
    bending_peak_pct                  peak |out-of-plane (y) displacement| of bending_100mm, difference in %
    """
    s, r = result.series, reference.series
    at = lambda values: np.interp(s.time, r.time, values)
    tip = np.stack([s.column(f"tip_{c}") for c in "xyz"], axis=1)
    tip_reference = np.stack([at(r.column(f"tip_{c}")) for c in "xyz"], axis=1)
    out = {
        "fold_deg": float(np.max(np.abs(s.fold_angles_deg[:, 0] - at(r.fold_angles_deg[:, 0])))),
        "tip_mm": 1e3 * float(np.max(np.linalg.norm(tip - tip_reference, axis=1))),
        "latch_pct": metrics.relative_error_pct(result.latch_times.get("fold"), reference.latch_times.get("fold")),
        "cl_pct": metrics.cl_error_pct(s.time, s.CL, r.time, r.CL),
        "cl_mean_pct": metrics.relative_error_pct(np.mean(s.CL), np.mean(at(r.CL))),
        "lift_mean_pct": metrics.relative_error_pct(np.mean(s.column("lift")), np.mean(at(r.column("lift")))),
    }
    if result.scene["structure"]["fidelity"] == "flexible":
        out["strain_end_pct"] = metrics.relative_error_pct(s.column("strain_20mm")[-1], r.column("strain_20mm")[-1])
        out["bending_peak_pct"] = metrics.relative_error_pct(metrics.peak_displacement(s, "bending_100mm", "y"),
                                                             metrics.peak_displacement(r, "bending_100mm", "y"))
    return out


@pytest.mark.parametrize("backend, step", [("direct", 1e-3), ("fmu", 1e-3), ("fmu", 1e-2)])
def test_rigid_deployment_in_still_air_follows_the_one_dof_pendulum(built_fmus, backend, step):
    """The deployment time is the structure unit's latch time, found within its own 1 ms RK4 step: a 10 ms
    communication step reads it as exactly (the fold angle sampled at the communication points and
    interpolated could be late by up to 10 ms, 6%).

    Measured: the latch time 7e-7 relative and the fold angle 5e-7 deg from the pendulum's (RK4 at 1 ms, the
    same with either backend and communication step); the tolerances are 3 times that. The actuator torque
    3% larger moves the latch time by 0.9% and the fold angle by 2.1 deg, the actuator stiffness 3% larger by
    1.2% and 2.8 deg, the outer body's density 3% larger by 1.7% and 3.9 deg.
    """
    overrides = [STILL_AIR, "time.stop=0.2", f"coupling.step={step}"]
    scene = load_scene(RIGID, overrides)
    result = run_scene(scene, backend=backend, fmu_dir=built_fmus("deploy_rigid", STILL_AIR))
    assert result.status == "ok", result.message
    latch, fold_angle = one_dof_pendulum(scene)
    summary = summarize(result)
    assert summary["deployment_time_s"] == pytest.approx(latch, rel=2e-6)
    assert summary["max_constraint_residual"] < 1e-10
    before = result.series.time < latch
    assert before.sum() >= 15
    np.testing.assert_allclose(result.series.fold_angles_deg[before, 0], fold_angle(result.series.time[before]),
                               rtol=0, atol=1.5e-6)


def test_coupled_rigid_deployment_matches_a_four_times_finer_coupling_step():
    """deploy_rigid at 10 m/s, 0.2 s (the latch near 0.188 s and its first bounce), the scene's 1 ms
    coupling step against 0.25 ms.

    Measured, 1 ms against 0.25 ms: latch time 0.058%, fold angle 0.12 deg, tip 0.31 mm, CL (Eq. 28) 2.3%
    (0.25 ms against 0.125 ms: 0.009%, 0.026 deg, 0.07 mm, 0.9%); the tolerances are about 2.5 times the
    1 ms differences. In the 1 ms run, flow.density 3% larger gives 0.39%, 0.80 deg, 2.1 mm and 14%; the
    actuator torque 3% larger 1.1%, 2.4 deg, 6.2 mm and 30%; flow.speed 3% larger 0.37%, 0.76 deg, 2.0 mm
    and 14%.
    """
    coarse = run(RIGID, "time.stop=0.2")
    fine = run(RIGID, "time.stop=0.2", "coupling.step=2.5e-4")
    assert 0.18 < fine.latch_times["fold"] < 0.2
    d = differences(coarse, fine)
    assert d["latch_pct"] < 0.15, d
    assert d["fold_deg"] < 0.3, d
    assert d["tip_mm"] < 0.8, d
    assert d["cl_pct"] < 6.0, d


def test_short_flexible_deployment_matches_a_finer_step_and_mesh():
    """deploy_flexible at 10 m/s, the first 0.08 s (the fold angle from 170 to about 90 deg), the scene's
    structure step and mesh (2e-4 s, 7 elements per body) against 5e-5 s and 14 elements per body.

    Measured, against that reference (and the reference against 5e-5 s with 21 elements): fold angle 0.24
    (0.08) deg, tip 0.04 (0.13) mm, strain at the end 0.004% (0.21%), peak bending 0.01% (0.12%), mean CL
    and lift 0.07% (0.19%). Each tolerance is 2.3 to 2.9 times the larger of the two: halving the elements'
    length again changes some of these more than the scene's discretization differs from the reference. CL's
    Eq. 28 error between the levels is 4-6%, from the vibrations the meshes resolve differently, more than a
    3% input moves it; the averages over the window are compared instead. In the scene's run, flow.density
    3% larger moves the tip 0.95 mm, the strain 1.0%, the peak bending 0.93% and the mean lift 2.3%; the
    actuator torque 3% larger the fold angle 1.05 deg, the tip 2.1 mm, the strain 2.4%; Young's modulus 3%
    larger (smaller) the tip 0.44 (0.39) mm, the strain 1.3% (0.76%), the peak bending 1.1% (0.92%);
    flow.speed 3% larger the tip 0.89 mm, the mean CL 3.5%, the mean lift 2.4%.
    """
    coarse = run(FLEXIBLE, "time.stop=0.08")
    fine = run(FLEXIBLE, "time.stop=0.08", "structure.step=5e-5", "structure.elements_per_body=14")
    assert 80.0 < fine.series.fold_angles_deg[-1, 0] < 120.0   # deploying, not yet latched
    d = differences(coarse, fine)
    assert d["fold_deg"] < 0.6, d
    assert d["tip_mm"] < 0.35, d
    assert d["strain_end_pct"] < 0.5, d
    assert d["bending_peak_pct"] < 0.35, d
    assert d["cl_mean_pct"] < 0.5, d
    assert d["lift_mean_pct"] < 0.5, d
