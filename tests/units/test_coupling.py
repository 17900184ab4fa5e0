"""Implicit coupling of the structure and aero units (orchestrator/run/coupling.py): convergence at
every step with Aitken and IQN-ILS, agreement with Gauss-Seidel at a smaller step, the explicit schemes'
coupling error falling with the step, stability where Gauss-Seidel diverges, non-convergence and rollback
failures, the replay of the accepted aero inputs, and the fmu backend.

The case: scenes/deploy_rigid.toml with the uvlm-flat aero unit at 15 m/s (the wing deploys at about
0.20 s; structure-only it takes 0.16 s)."""
import csv
import json
import types

import numpy as np
import pytest

from orchestrator.run import units as real_units
from orchestrator.output import wake_view
from orchestrator.run.acceleration import IQNILS, Aitken, interface_residual
from orchestrator.run.master import run_scene
from orchestrator.output.results import deployment_time, summarize, write_results
from orchestrator.scene.load import load_scene
from orchestrator.run.port import UnitError
from repository import SCENES

SCENE = SCENES / "deploy_rigid.toml"
AERO = ["aero.model=uvlm-flat", "flow.speed=15"]
TOLERANCE = 1e-6       # the default coupling.tolerance


def scene(algorithm, step, stop, *overrides):
    return load_scene(SCENE, [*AERO, f"coupling.algorithm={algorithm}", f"coupling.step={step!r}",
                              f"time.stop={stop!r}", *overrides])


def run(algorithm, step, stop, *overrides, units=None, backend="direct", fmu_dir=None):
    result = run_scene(scene(algorithm, step, stop, *overrides), backend=backend, fmu_dir=fmu_dir, units=units)
    return result


def fold(result, times):
    """The fold angle (deg) at ``times``, linearly interpolated between the samples."""
    return np.interp(times, result.series.time, result.series.fold_angles_deg[:, 0])


# --- the accelerations on a linear fixed point x = A x + b ------------------------------------------

def _iterate(acceleration, A, b, tolerance=1e-12, max_iterations=50):
    x = np.zeros(len(b))
    acceleration.start()
    for k in range(1, max_iterations + 1):
        x_tilde = A @ x + b
        if interface_residual(x_tilde, x) < tolerance:
            return x, k
        x = acceleration.update(x, x_tilde)
    raise AssertionError(f"{type(acceleration).__name__} did not converge in {max_iterations} iterations")


def test_accelerations_converge_where_the_plain_fixed_point_iteration_diverges():
    rng = np.random.default_rng(1)
    n = 6
    b = rng.normal(size=n)
    # a scalar map x -> -2 x + b (plain iteration diverges): Aitken's secant step is exact after two updates
    A = -2.0 * np.eye(n)
    x, k = _iterate(Aitken(0.5), A, b)
    np.testing.assert_allclose(x, b / 3.0, rtol=1e-10)
    assert k <= 4
    # a general map with spectral radius > 1: IQN-ILS is a secant method, exact for a linear map after
    # at most n + 1 updates
    A = rng.normal(size=(n, n))
    assert max(abs(np.linalg.eigvals(A))) > 1
    x, k = _iterate(IQNILS(0.5), A, b)
    np.testing.assert_allclose(x, np.linalg.solve(np.eye(n) - A, b), rtol=1e-8)
    assert k <= n + 3


def test_iqn_ils_filters_linearly_dependent_columns():
    """A map that only acts in one direction gives parallel V columns after two updates; the QR filter
    drops them instead of solving a singular system."""
    b = np.array([1.0, 2.0, 3.0])
    A = np.outer([1.0, 0.0, 0.0], [1.0, 0.0, 0.0]) * 0.5
    x, _ = _iterate(IQNILS(0.5), A, b)
    np.testing.assert_allclose(x, np.linalg.solve(np.eye(3) - A, b), rtol=1e-10)


# --- convergence at every step ----------------------------------------------------------------------

@pytest.fixture(scope="module")
def implicit_runs():
    return {a: run("implicit", 1e-3, 0.05, f"coupling.acceleration={a}") for a in ("aitken", "iqn-ils")}


@pytest.mark.parametrize("acceleration", ["aitken", "iqn-ils"])
def test_implicit_coupling_converges_at_every_step_and_reports_its_iterations(implicit_runs, acceleration,
                                                                            tmp_path):
    result = implicit_runs[acceleration]
    assert result.status == "ok", result.message
    assert "implicit coupling" in result.message and acceleration in result.message
    series = result.series
    assert series.columns[-4:] == ["CL", "lift", "coupling_iterations", "coupling_residual"]
    iterations, residual = series.column("coupling_iterations"), series.column("coupling_residual")
    assert len(series) == 51 and iterations[0] == 0 and np.isnan(residual[0])
    # Q changes from step to step, so every step needs a second iteration at least
    assert np.all((iterations[1:] >= 2) & (iterations[1:] <= 10))
    assert np.all(residual[1:] < TOLERANCE)
    assert np.all(np.isfinite(series.CL)) and np.max(np.abs(series.CL)) > 0.01      # the wing is loaded
    # only the accepted iterate of each step is recorded for the replay
    assert len(result.aero_inputs) == 50

    write_results(result, tmp_path)
    summary = json.loads((tmp_path / "summary.json").read_text())
    assert summary["coupling"] == {"algorithm": "implicit", "acceleration": acceleration,
                                   "total_iterations": int(iterations.sum()),
                                   "max_iterations_used": int(iterations.max()),
                                   "max_residual": pytest.approx(float(np.max(residual[1:])), rel=1e-12)}
    with (tmp_path / "timeseries.csv").open() as f:
        rows = list(csv.reader(f))
    assert rows[0][-2:] == ["coupling_iterations [-]", "coupling_residual [-]"]
    np.testing.assert_array_equal(np.array([r[-2] for r in rows[1:]], float), iterations)


def test_both_accelerations_reach_the_same_fixed_point(implicit_runs):
    a, b = implicit_runs["aitken"], implicit_runs["iqn-ils"]
    np.testing.assert_allclose(a.series.fold_angles_deg, b.series.fold_angles_deg, rtol=0, atol=1e-5)
    np.testing.assert_allclose(a.series.CL, b.series.CL, rtol=0, atol=1e-6)


def test_explicit_runs_have_no_coupling_columns_or_summary():
    result = run("gauss-seidel", 1e-3, 0.003)
    assert result.status == "ok" and result.series.columns[-2:] == ["CL", "lift"]
    assert "coupling" not in summarize(result)


# --- accuracy -------------------------------------------------------------------------------------

@pytest.mark.parametrize("step", [2e-3, pytest.param(1e-3, marks=pytest.mark.slow)])
def test_implicit_and_gauss_seidel_at_a_four_times_smaller_step_agree_on_the_deployment_time(step):
    implicit = run("implicit", step, 0.22)
    explicit = run("gauss-seidel", step / 4, 0.22)
    assert implicit.status == "ok" and explicit.status == "ok", implicit.message + explicit.message
    t_implicit = deployment_time(implicit.latch_times, implicit.scene)
    t_explicit = deployment_time(explicit.latch_times, explicit.scene)
    assert t_implicit is not None and t_explicit is not None
    assert 0.19 < t_implicit < 0.215                       # aero slows it down (0.163 s in still air)
    assert abs(t_explicit - t_implicit) < 0.01 * t_implicit


def test_the_explicit_schemes_coupling_error_falls_with_the_step():
    """Fold angle over the first 60 ms against implicit coupling at the smallest step: the explicit
    schemes' error is first order in the step (the force lags the motion by one step)."""
    steps, stop = (4e-3, 2e-3, 1e-3), 0.06
    reference = run("implicit", steps[-1], stop)
    assert reference.status == "ok", reference.message
    times = np.arange(0.0, stop + 1e-12, steps[0])
    for algorithm in ("gauss-seidel", "jacobi"):
        errors = []
        for step in steps:
            result = run(algorithm, step, stop)
            assert result.status == "ok", result.message
            errors.append(np.max(np.abs(fold(result, times) - fold(reference, times))))
        assert errors[0] > errors[1] > errors[2] > 0, (algorithm, errors)
        assert errors[0] / errors[2] > 2.5, (algorithm, errors)    # about 4 for first order


def test_implicit_coupling_is_stable_where_gauss_seidel_diverges():
    """A light wing in dense air (200 kg/m^3): the aero force reacts strongly to the motion it causes and
    the staggered scheme blows up within a few steps; the implicit one converges at every step."""
    dense = "flow.density=200"
    explicit = run("gauss-seidel", 1e-3, 0.02, dense)
    assert explicit.status == "diverged" and explicit.simulated_time_s < 0.02
    implicit = run("implicit", 1e-3, 0.02, dense, "coupling.acceleration=iqn-ils")
    assert implicit.status == "ok", implicit.message
    assert np.all(implicit.series.column("coupling_residual")[1:] < TOLERANCE)
    assert implicit.series.column("coupling_iterations").max() <= 10


# --- failures -------------------------------------------------------------------------------------

def wrapped_units(kind, wrap):
    """orchestrator.run.units, with ``wrap(unit)`` applied to the unit of ``kind``."""
    def make_unit(**kwargs):
        unit = real_units.make_unit(**kwargs)
        if kwargs["kind"] == kind:
            wrap(unit)
        return unit
    return types.SimpleNamespace(make_unit=make_unit, UnitError=UnitError)


FAIL_AT = 0.005


def test_non_convergence_stops_as_diverged_with_the_step_residual_and_a_hint(tmp_path):
    """From t = 5 ms the aero unit's Q is perturbed by noise at every call: no iteration can converge."""
    rng = np.random.default_rng(0)

    def noisy(unit):
        get_outputs, do_step, at = unit.get_outputs, unit.do_step, [0.0]

        def step(t, h):
            at[0] = t
            do_step(t, h)

        def outputs():
            q, = get_outputs()
            if at[0] >= FAIL_AT - 1e-12:
                q = q + 1e-3 * np.linalg.norm(q) * rng.normal(size=q.shape)
            return (q,)
        unit.do_step, unit.get_outputs = step, outputs

    result = run("implicit", 1e-3, 0.02, "coupling.max_iterations=6", units=wrapped_units("aero", noisy))
    assert result.status == "diverged"
    message = result.message
    assert "implicit coupling" in message and "t = 0.005 s" in message and "after 6 iterations" in message
    assert "residual" in message and "Hint" in message and "coupling.max_iterations" in message
    np.testing.assert_allclose(result.series.time, np.arange(6) * 1e-3, atol=1e-15)   # accepted steps kept
    assert result.simulated_time_s == pytest.approx(FAIL_AT)
    write_results(result, tmp_path)
    summary = json.loads((tmp_path / "summary.json").read_text())
    assert summary["status"] == "diverged" and summary["coupling"]["max_residual"] < TOLERANCE
    assert len((tmp_path / "timeseries.csv").read_text().splitlines()) == 1 + 6


def test_a_failed_rollback_stops_as_diverged_and_keeps_the_samples():
    def breaks_at_5ms(unit):
        set_state, get_state, at = unit.set_state, unit.get_state, [0]

        def saving():
            at[0] += 1
            return get_state()

        def restoring(state):
            if at[0] > 5:                    # the sixth step is the one from t = 5 ms
                raise UnitError("structure (direct): set_fmu_state failed: the state was lost")
            set_state(state)
        unit.get_state, unit.set_state = saving, restoring

    result = run("implicit", 1e-3, 0.02, units=wrapped_units("structure", breaks_at_5ms))
    assert result.status == "diverged"
    assert "rolling the structure unit back to t = 0.005 s" in result.message
    assert "the state was lost" in result.message and "Hint" in result.message
    assert len(result.series) == 6 and result.simulated_time_s == pytest.approx(FAIL_AT)


# --- the replay of the accepted aero inputs --------------------------------------------------------

def test_replay_of_an_implicit_run_reproduces_the_aero_unit_from_the_accepted_inputs():
    """The rejected iterates are rolled back: the aero unit's final state, and every CL, come out of one
    advance per step with the recorded (accepted) e, de. A prescribed wake makes the state carry history.
    Not bit for bit: the unit reused its factorization, built at a rejected iterate's geometry, for the
    accepted one (within aero_fmu.factorization.RIGID_TOLERANCE), the replay builds it at the accepted one."""
    kept = {}

    def keep_state(unit):
        terminate = unit.terminate

        def keep_then_terminate():
            kept["state"] = unit._port._slave._solver.get_state()
            terminate()
        unit.terminate = keep_then_terminate

    result = run("implicit", 1e-3, 0.02, "aero.model=uvlm-prescribed", units=wrapped_units("aero", keep_state))
    assert result.status == "ok", result.message
    assert result.series.column("coupling_iterations")[1:].min() >= 2        # there were rejected iterates
    inputs = result.aero_inputs
    assert len(inputs) == 20 and inputs.complete
    snapshots, solver, stopped = wake_view.replay(result.scene, inputs, range(len(inputs)))
    assert not stopped
    np.testing.assert_allclose([s.outputs["CL"] for s in snapshots], result.series.CL[1:], rtol=1e-8, atol=0)
    final, unit = solver.state, kept["state"]
    assert final.time == unit.time and final.wake.n_rows == unit.wake.n_rows > 0
    assert np.array_equal(final.wake.corners, unit.wake.corners)     # convected with U: geometry only
    for a, b in [(final.wake.gamma, unit.wake.gamma), (final.gamma, unit.gamma), (final.loads.Q, unit.loads.Q)]:
        np.testing.assert_allclose(a, b, rtol=1e-8, atol=1e-12 * np.max(np.abs(b)))


def test_without_factorization_reuse_the_replay_is_bit_for_bit(monkeypatch):
    """The only difference between the unit and the replay is the reused factorization: rebuilt at every
    step, the replay reproduces the implicitly coupled unit exactly."""
    import aero_fmu.factorization

    monkeypatch.setattr(aero_fmu.factorization, "RIGID_TOLERANCE", -1.0)     # never reuse
    result = run("implicit", 1e-3, 0.01)
    assert result.status == "ok", result.message
    snapshots, _, _ = wake_view.replay(result.scene, result.aero_inputs, range(len(result.aero_inputs)))
    assert np.array_equal([s.outputs["CL"] for s in snapshots], result.series.CL[1:])


# --- the fmu backend ------------------------------------------------------------------------------

def test_implicit_coupling_of_the_two_fmus_matches_the_direct_backend(built_fmus):
    implicit = scene("implicit", 1e-3, 0.02)
    fmu_dir = built_fmus("deploy_rigid", *AERO)
    runs = {b: run_scene(implicit, backend=b, fmu_dir=fmu_dir) for b in ("fmu", "direct")}
    for r in runs.values():
        assert r.status == "ok", r.message
        assert np.all(r.series.column("coupling_residual")[1:] < TOLERANCE)
    np.testing.assert_array_equal(runs["fmu"].series.column("coupling_iterations"),
                                  runs["direct"].series.column("coupling_iterations"))
    np.testing.assert_allclose(runs["fmu"].series.table(), runs["direct"].series.table(), rtol=0, atol=1e-12)
    # the replay of the accepted inputs reproduces the FMU's CL (to the factorization reuse, see above)
    snapshots, _, _ = wake_view.replay(implicit, runs["fmu"].aero_inputs, range(len(runs["fmu"].aero_inputs)))
    np.testing.assert_allclose([s.outputs["CL"] for s in snapshots], runs["fmu"].series.CL[1:], rtol=1e-8, atol=0)


def test_unknown_acceleration_is_refused_with_the_allowed_names():
    from orchestrator.run.acceleration import make_acceleration
    with pytest.raises(ValueError, match="aitken, iqn-ils"):
        make_acceleration({"acceleration": "broyden"})


def test_the_held_force_hint_counts_the_structure_steps_of_a_communication_step():
    """The structure's steps in a communication step as the slave takes them (the last one shortened to land on
    the communication point): 1 ms over 0.1 ms is 10, over 0.3 ms is 4 (three and a shortened one); a step equal
    to or longer than the communication step is 1, and then the hint is empty."""
    from orchestrator.run.coupling import held_force_hint, structure_substeps
    assert structure_substeps(1e-3, 1e-4) == 10
    assert structure_substeps(1e-3, 3e-4) == 4
    assert structure_substeps(5e-4, 5e-4) == structure_substeps(5e-4, 1e-3) == 1
    assert held_force_hint(1, 5e-4) == ""
    assert "10 steps per communication step" in held_force_hint(10, 1e-3)
    assert "500 Hz" in held_force_hint(10, 1e-3)
