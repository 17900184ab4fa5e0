"""The picture of the mechanism at several instants (orchestrator/output/mechanism_view.py): the structure coordinates
the master records, the reference lines drawn from them, the plane of a planar mechanism, and `wingsim run`
writing mechanism.png without ever failing a run for it."""
import sys

import numpy as np
import pytest

from fmu_common import scene_bounds
from fmu_common.topology import Topology
from fmu_common.wing_spec import StructureSpec
from orchestrator import cli
from orchestrator.output import mechanism_view
from orchestrator.run.master import StructureCoordinates, run_scene
from orchestrator.output.plots import write_plots
from orchestrator.scene.load import load_scene
from repository import SCENES

PNG = b"\x89PNG\r\n\x1a\n"


def double_pendulum(*overrides):
    """Two 1.8 m bars, 2 elements each: A along x from the origin, B from A's tip along z, joined by a ball
    joint (scenes/double_pendulum.toml), falling under gravity along -y."""
    return load_scene(SCENES / "double_pendulum.toml", ["time.stop=0.05", *overrides])


@pytest.fixture(scope="module")
def fallen():
    """(scene, result) of the double pendulum's first 0.05 s, in-process."""
    scene = double_pendulum()
    result = run_scene(scene, backend="direct")
    assert result.status == "ok", result.message
    return scene, result


# --- the record ------------------------------------------------------------------------------------------

@pytest.mark.parametrize("backend", ["direct", "fmu"])
def test_the_recorded_coordinates_start_at_the_scene_geometry(backend, built_fmus):
    scene = double_pendulum()
    fmu_dir = built_fmus("double_pendulum") if backend == "fmu" else None
    result = run_scene(scene, backend=backend, fmu_dir=fmu_dir)
    assert result.status == "ok", result.message
    record = result.structure_coordinates
    np.testing.assert_array_equal(record.t, result.series.time)         # every communication point
    # E at t = 0 from the scene file by hand: per node r, r_x, r_y; A along x, B along z from A's tip, chord y
    x, y, z = np.eye(3)
    expected = [np.concatenate([s * x, x, y]) for s in (0.0, 0.9, 1.8)]
    expected += [np.concatenate([1.8 * x + s * z, z, y]) for s in (0.0, 0.9, 1.8)]
    np.testing.assert_allclose(record.e[0], np.concatenate(expected), rtol=0, atol=1e-12)
    # every sample is the E of its communication point: B's tip node is the unit's own tip probe output
    tip = np.array([e[45:48] for e in record.e])
    np.testing.assert_allclose(tip, result.series.positions[:, 0], rtol=0, atol=1e-12)
    assert np.ptp(tip[:, 1]) > 1e-3                                       # and it has fallen


def test_a_long_record_is_thinned_and_ends_at_the_latest_point():
    record = StructureCoordinates.for_run(points=11, n=3, max_values=12)  # 33 numbers: every 3rd point
    assert record.stride == 3
    for k in range(8):
        record.append(0.1 * k, np.full(3, k))
    assert [round(t / 0.1) for t in record.t] == [0, 3, 6, 7]           # 7: the latest, off the stride
    for k in range(8, 11):
        record.append(0.1 * k, np.full(3, k))
    assert [int(e[0]) for e in record.e] == [0, 3, 6, 9, 10]
    assert StructureCoordinates.for_run(points=4, n=3, max_values=12).stride == 1


@pytest.mark.parametrize("limit", [scene_bounds.AERO_INPUT_RECORD_VALUES, 20_000])
def test_the_memory_estimate_counts_the_record(limit, monkeypatch):
    """The estimate of the record against the bytes a record of the run takes (arrays and times in lists),
    also once thinned (a small bound, so that the test stays short)."""
    monkeypatch.setattr(scene_bounds, "AERO_INPUT_RECORD_VALUES", limit)
    scene = load_scene(SCENES / "deploy_flexible.toml", ["time.stop=1.0"])
    estimate = scene_bounds.memory_estimate(scene)["structure coordinate record"][1]
    n = Topology.from_spec(StructureSpec.from_scene(scene)).n_coordinates
    record = StructureCoordinates.for_run(scene_bounds.communication_steps(scene), n, limit)
    for k in range(scene_bounds.communication_steps(scene)):
        record.append(1e-3 * k, np.zeros(n))
    measured = sum(sys.getsizeof(e) + 8 + sys.getsizeof(t) + 8 for t, e in zip(record.t, record.e))
    assert measured <= estimate <= 1.2 * measured
    assert (len(record) < 1001) == (limit < 1001 * n)


# --- the drawing -----------------------------------------------------------------------------------------

def test_reference_lines_pass_through_the_recorded_nodes(fallen):
    scene, result = fallen
    topology = Topology.from_spec(StructureSpec.from_scene(scene))
    e = result.structure_coordinates.e[-1]
    lines = mechanism_view.reference_lines(topology, e, points_per_element=8)
    nodes = e.reshape(-1, 9)[:, :3]
    for name, body in topology.bodies.items():
        assert lines[name].shape == (8 * len(body.elements) + 1, 3)
        np.testing.assert_array_equal(lines[name][::8], nodes[body.nodes])


def test_reference_lines_are_the_cubic_through_the_nodes():
    """Nodes on the cubic r(s) = root + s span + c s^3 normal, with its slope as r_x: the Hermite curve of each
    element is that cubic (it reproduces cubics exactly)."""
    scene = load_scene(SCENES / "rotating_beam.toml")
    topology = Topology.from_spec(StructureSpec.from_scene(scene))
    (name, body), = topology.bodies.items()
    normal, c = np.cross(body.span_axis, body.chord_axis), 0.3
    s = np.linspace(0.0, body.length, len(body.nodes))
    e = np.concatenate([np.concatenate([body.root + si * body.span_axis + c * si**3 * normal,
                                        body.span_axis + 3 * c * si**2 * normal, body.chord_axis]) for si in s])
    line = mechanism_view.reference_lines(topology, e, points_per_element=5)[name]
    along = np.linspace(0.0, body.length, 5 * len(body.elements) + 1)
    exact = body.root + along[:, None] * body.span_axis + c * along[:, None] ** 3 * normal
    np.testing.assert_allclose(line, exact, rtol=0, atol=1e-14)


def test_the_nodes_where_bodies_meet_are_the_joints_nodes(fallen):
    scene, result = fallen
    topology = Topology.from_spec(StructureSpec.from_scene(scene))
    found = mechanism_view.joint_nodes(topology, result.structure_coordinates.e, 1e-9)
    # the ball joint PQ joins A's tip and B's root; O joins A to the ground, not to a body
    assert [topology.node_names[k] for k in found] == ["A.2", "B.0"]


def test_the_instants_are_spread_from_the_start_to_the_end():
    times = np.arange(9) * 0.125
    assert mechanism_view.instant_indices(times) == [0, 2, 4, 6, 8]
    assert mechanism_view.instant_indices([0.0, 0.1]) == [0, 1]
    assert mechanism_view.instant_indices([]) == []


def test_a_planar_mechanism_is_drawn_in_its_plane():
    rng = np.random.default_rng(0)
    flat = rng.normal(size=(50, 3)) * [1.0, 0.0, 2.0]                      # the x-z plane
    plane = mechanism_view.drawing_plane(flat)
    assert plane.labels == ("x (m)", "z (m)")
    np.testing.assert_array_equal(plane.basis, [[1, 0, 0], [0, 0, 1]])
    # a tilted plane: two orthonormal in-plane directions named by their components, distances kept
    u, v = np.array([1.0, 1.0, 0.0]) / np.sqrt(2), np.array([0.0, 0.0, 1.0])
    tilted = rng.normal(size=(50, 1)) * u + rng.normal(size=(50, 1)) * v
    plane = mechanism_view.drawing_plane(tilted)
    assert plane.labels[0].startswith("in-plane 1 (m), along (") and plane.labels[1].startswith("in-plane 2 (m)")
    np.testing.assert_allclose(plane.basis @ plane.basis.T, np.eye(2), atol=1e-12)
    np.testing.assert_allclose(plane.basis, [u, v], atol=1e-12)          # z, in the plane, drawn upward
    # a plane through x tilted about it: x across, its steepest upward direction up
    swing = rng.normal(size=(50, 1)) * [1.0, 0.0, 0.0] + rng.normal(size=(50, 1)) * [0.0, -1.0, 1.0]
    np.testing.assert_allclose(mechanism_view.drawing_plane(swing).basis,
                               [[1, 0, 0], [0, -np.sqrt(0.5), np.sqrt(0.5)]], atol=1e-12)
    projected = tilted @ plane.basis.T
    np.testing.assert_allclose(np.linalg.norm(projected[1:] - projected[0], axis=1),
                               np.linalg.norm(tilted[1:] - tilted[0], axis=1), rtol=1e-12)
    # out of the plane by 1e-4 of the extent: 3D; by 1e-8: still planar
    bumped = tilted.copy()
    extent = np.ptp(tilted, axis=0).max()
    bumped[0] += 1e-4 * extent * np.cross(u, v)
    assert mechanism_view.drawing_plane(bumped) is None
    bumped[0] = tilted[0] + 1e-8 * extent * np.cross(u, v)
    assert mechanism_view.drawing_plane(bumped) is not None
    assert mechanism_view.drawing_plane(rng.normal(size=(20, 3))) is None
    # a straight bar along y lies in a coordinate plane
    assert mechanism_view.drawing_plane(np.outer(np.linspace(0, 1, 5), [0, 1, 0])).labels == ("x (m)", "y (m)")


# --- the picture in a run ------------------------------------------------------------------------------

def test_a_run_writes_the_mechanism_picture(tmp_path, capsys):
    out = tmp_path / "out"
    code = cli.main(["run", str(SCENES / "pendulum_rigid.toml"), "--backend", "direct", "--out", str(out),
                     "--set", "time.stop=0.5"])
    assert code == 0, capsys.readouterr()
    picture = out / mechanism_view.MECHANISM_FILE
    assert picture.is_file() and picture.read_bytes()[:8] == PNG
    assert "warning" not in capsys.readouterr().err


def test_a_failing_mechanism_picture_only_warns(tmp_path, capsys, monkeypatch):
    result = run_scene(load_scene(SCENES / "pendulum_rigid.toml", ["time.stop=0.05"]), backend="direct")
    (tmp_path / mechanism_view.MECHANISM_FILE).write_bytes(b"stale")

    def broken(*args, **kwargs):
        raise RuntimeError("no picture today")
    monkeypatch.setattr(mechanism_view, "mechanism_figure", broken)
    written = write_plots(result, tmp_path)
    assert (tmp_path / "energy_residual.png") in written
    assert not (tmp_path / mechanism_view.MECHANISM_FILE).exists()
    assert "warning: mechanism picture not written: RuntimeError: no picture today" in capsys.readouterr().err


def test_a_run_without_a_record_has_no_picture(tmp_path):
    result = run_scene(load_scene(SCENES / "pendulum_rigid.toml", ["time.stop=0.05"]), backend="direct")
    result.structure_coordinates = None
    (tmp_path / mechanism_view.MECHANISM_FILE).write_bytes(b"stale")
    assert mechanism_view.write_mechanism_view(result, tmp_path) is None
    assert not (tmp_path / mechanism_view.MECHANISM_FILE).exists()
