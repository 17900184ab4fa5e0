"""The 3D picture of wing and wake (orchestrator/output/wake_view.py): written by `wingsim run` for aero scenes,
drawn from a replay of the aero unit that reproduces the unit's wake bit for bit, and never able to fail
a run."""
import types

import numpy as np
import pytest

from aero_fmu.solver import AeroSolver
from fmu_common.specs import AeroUnitSpec, StructureUnitSpec
from orchestrator import cli
from orchestrator.run import units as real_units
from orchestrator.output import wake_view
from orchestrator.run.master import communication_times, run_scene
from orchestrator.output.plots import write_plots
from orchestrator.scene.load import load_scene
from structure_fmu.solver import StructureSolver
from repository import SCENES

PNG = b"\x89PNG\r\n\x1a\n"


def heave(*overrides):
    """heaving_wing (uvlm-prescribed, M = 10, N = 5), 12 steps of 0.1 s with a wake of 0.5 chords, so the
    truncation acts too."""
    return load_scene(SCENES / "heaving_wing.toml", ["time.stop=1.2", "aero.wake_length=0.5", *overrides])


def test_run_of_an_aero_scene_writes_the_wake_picture(tmp_path, capsys):
    out = tmp_path / "out"
    code = cli.main(["run", str(SCENES / "heaving_wing.toml"), "--backend", "direct", "--out", str(out),
                     "--set", "time.stop=0.4"])
    assert code == 0, capsys.readouterr()
    picture = out / wake_view.WAKE_FILE
    assert picture.is_file() and picture.read_bytes()[:8] == PNG
    assert "warning" not in capsys.readouterr().err


def recording_units():
    """orchestrator.run.units, but the aero unit's solver state is kept when the unit is terminated."""
    kept = {}

    def make_unit(kind, **kw):
        unit = real_units.make_unit(kind=kind, **kw)
        if kind == "aero":
            terminate = unit.terminate

            def keep_then_terminate():
                kept["state"] = unit._port._slave._solver.get_state()
                terminate()
            unit.terminate = keep_then_terminate
        return unit
    return types.SimpleNamespace(make_unit=make_unit, UnitError=real_units.UnitError), kept


@pytest.mark.parametrize("algorithm", ["gauss-seidel", "jacobi"])
def test_replayed_wake_is_bit_identical_to_the_units_wake_and_a_directly_driven_solver(algorithm):
    scene = heave(f"coupling.algorithm={algorithm}")
    units, kept = recording_units()
    result = run_scene(scene, backend="direct", units=units)
    assert result.status == "ok", result.message
    inputs = result.aero_inputs
    assert len(inputs) == 12 and inputs.complete

    snapshots, replayed, stopped = wake_view.replay(scene, inputs, range(len(inputs)))
    assert not stopped and len(snapshots) == 12
    final = replayed.state
    assert 0 < final.wake.n_rows < 6                  # truncated at 0.5 chords (rows of 0.1 c)

    # 1. the aero unit that ran in the master
    unit = kept["state"]
    assert final.time == unit.time
    for a, b in [(final.wake.corners, unit.wake.corners), (final.wake.gamma, unit.wake.gamma),
                 (final.gamma, unit.gamma), (final.loads.Q, unit.loads.Q)]:
        assert np.array_equal(a, b)
    # every replayed CL is the recorded one, bit for bit
    assert np.array_equal([s.outputs["CL"] for s in snapshots], result.series.CL[1:])

    # 2. an AeroSolver driven directly with the structure's e, de (the prescribed heave), no master
    structure = StructureSolver(StructureUnitSpec.from_scene(scene))
    direct = AeroSolver(AeroUnitSpec.from_scene(scene), parameters=wake_view.aero_parameters(scene))
    times = communication_times(1.2, 0.1)            # k h, the last one 1.2: the master's time grid
    e, de = structure.e.copy(), structure.de.copy()
    for t0, t1 in zip(times[:-1], times[1:]):
        structure.advance(t0 + (t1 - t0))
        if algorithm == "jacobi":                     # the aero step sees e, de of t0
            direct.advance(t0 + (t1 - t0), e, de)
            e, de = structure.e.copy(), structure.de.copy()
        else:
            e, de = structure.e.copy(), structure.de.copy()
            direct.advance(t0 + (t1 - t0), e, de)
    geometry, ours = direct.vortex_geometry(), replayed.vortex_geometry()
    for key in ("rings", "wake", "wake_gamma"):
        assert np.array_equal(geometry[key], ours[key]), key
    assert np.array_equal(direct.Q, replayed.Q)


def test_snapshots_carry_the_wing_and_the_vortex_system_of_each_model():
    for model, wake, legs in [("uvlm-prescribed", True, False), ("uvlm-free", True, False),
                              ("uvlm-flat", False, True), ("strip", False, False)]:
        scene = heave(f"aero.model={model}", "time.stop=0.3")
        result = run_scene(scene, backend="direct")
        snapshots, solver, _ = wake_view.replay(scene, result.aero_inputs, [0, 2])
        assert [s.time for s in snapshots] == pytest.approx([0.1, 0.3])
        last = snapshots[-1]
        M = 1 if model == "strip" else 10
        assert last.wing.shape == (1, M + 1, 6, 3)
        assert (last.vortex["wake"] is not None) == wake and (last.vortex["legs"] is not None) == legs
        assert (last.vortex["rings"] is None) == (model == "strip")
        if wake:
            assert last.vortex["wake"].shape == (1, 3, 6, 3) and last.vortex["wake_gamma"].shape == (1, 2, 5)
        if legs:   # finite legs: wake_length chords along the stream
            direction, length = last.vortex["legs"]
            assert np.allclose(direction, [1, 0, 0]) and np.allclose(length, [0.5])


def test_the_replay_budget_caps_the_picture_and_says_so(tmp_path, capsys):
    scene = heave()
    result = run_scene(scene, backend="direct")
    path = wake_view.write_wake_view(result, tmp_path, budget_s=1e-9)
    assert path is not None and path.read_bytes()[:8] == PNG
    assert "replay capped" in capsys.readouterr().err
    # budget 0 switches the picture off and removes a stale one
    assert wake_view.write_wake_view(result, tmp_path, budget_s=0) is None
    assert not path.exists()


def test_a_failing_wake_picture_only_warns(tmp_path, capsys, monkeypatch):
    result = run_scene(heave(), backend="direct")
    (tmp_path / wake_view.WAKE_FILE).write_bytes(b"stale")

    def broken(*args, **kwargs):
        raise RuntimeError("no picture today")
    monkeypatch.setattr(wake_view, "replay", broken)
    written = write_plots(result, tmp_path)
    assert (tmp_path / "lift_coefficient.png") in written
    assert not (tmp_path / wake_view.WAKE_FILE).exists()
    assert "warning: wake picture not written: RuntimeError: no picture today" in capsys.readouterr().err


def test_structure_only_runs_have_no_wake_picture(tmp_path):
    scene = load_scene(SCENES / "pendulum_rigid.toml", ["time.stop=0.01"])
    result = run_scene(scene, backend="direct")
    assert result.aero_inputs is None
    (tmp_path / wake_view.WAKE_FILE).write_bytes(b"stale")
    assert wake_view.WAKE_FILE not in [p.name for p in write_plots(result, tmp_path)]
    assert not (tmp_path / wake_view.WAKE_FILE).exists()


def test_a_slender_picture_is_windowed_to_scale():
    # the AR-1000 wing: 1000 m of span, about 1.5 m of wing and wake streamwise
    points = np.array([[0.0, -500.0, 0.0], [1.5, 500.0, 0.1]])
    axis, low, high = wake_view._window(points)
    assert axis == 1 and high - low == pytest.approx(wake_view.WINDOW * 1.5) and low + high == pytest.approx(0)
    assert wake_view._window(np.array([[0.0, 0.0, 0.0], [1.0, 4.0, 0.0]])) is None
    # a quad straddling the window is clipped to it
    quad = np.array([[[0.0, -10.0, 0.0], [1.0, -10.0, 0.0], [1.0, 10.0, 0.0], [0.0, 10.0, 0.0]]])
    kept, values = wake_view._select(quad, (1, -2.0, 3.0), np.array([7.0]))
    assert len(kept) == 1 and values.tolist() == [7.0]
    assert kept[0][:, 1].min() == pytest.approx(-2.0) and kept[0][:, 1].max() == pytest.approx(3.0)
