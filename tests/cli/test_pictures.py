"""The pictures and geometry files of a run and a sweep, read back by independent readers: every PNG plot rendered
and measured with matplotlib's renderer (its legend and title do not overlap, its title is not clipped, an all-zero
panel carries a note), the animation's frames counted with pillow, the ParaView files parsed with xml.etree and
compared with the scene's topology and with timeseries.csv, and the sweep's plot against the pendulum's own
geometry."""
import csv
import xml.etree.ElementTree as ET

import numpy as np
import pytest
from matplotlib.backends.backend_agg import FigureCanvasAgg
from PIL import Image

from fmu_common.topology import Topology
from fmu_common.wing_spec import StructureSpec
from orchestrator import cli
from orchestrator.output import animation, mechanism_view, plots, sweep_plot, vtk, wake_view
from orchestrator.output.mechanism_view import instant_indices
from orchestrator.run.master import run_scene
from orchestrator.scene.load import load_scene
from repository import SCENES


@pytest.fixture(scope="module")
def scissor():
    """The scissor-deployed wing (14 probes, a hinge with a stop, the uvlm-flat aero unit), its first 0.02 s."""
    result = run_scene(load_scene(SCENES / "scissor_wing.toml", ["time.stop=0.02"]), backend="direct")
    assert result.status == "ok", result.message
    return result


@pytest.fixture(scope="module")
def pendulum_run(tmp_path_factory):
    """`wingsim run --animate --vtk` of the double pendulum's first 0.1 s (ball joints, 2 bodies of 2 elements):
    (the output folder, the scene)."""
    out = tmp_path_factory.mktemp("double_pendulum")
    scene_file = SCENES / "double_pendulum.toml"
    code = cli.main(["run", str(scene_file), "--backend", "direct", "--out", str(out), "--set", "time.stop=0.1",
                     "--animate", "--vtk"])
    assert code == 0
    return out, load_scene(scene_file, ["time.stop=0.1"])


def rendered(fig):
    """(renderer, figure box) of a figure drawn by Agg."""
    FigureCanvasAgg(fig)
    fig.canvas.draw()
    renderer = fig.canvas.get_renderer()
    return renderer, fig.bbox


def assert_readable(fig):
    """Every title (axes titles and the suptitle) lies within the figure, and no legend overlaps one."""
    renderer, box = rendered(fig)
    titles = [ax.title for ax in fig.axes if ax.get_title()] + ([fig._suptitle] if fig._suptitle else [])
    legends = [ax.get_legend() for ax in fig.axes if ax.get_legend() is not None] + list(fig.legends)
    assert titles
    for title in titles:
        extent = title.get_window_extent(renderer)
        assert box.x0 - 0.5 <= extent.x0 and extent.x1 <= box.x1 + 0.5, f"title clipped: {title.get_text()!r}"
        assert box.y0 - 0.5 <= extent.y0 and extent.y1 <= box.y1 + 0.5, f"title clipped: {title.get_text()!r}"
        for legend in legends:
            assert not legend.get_window_extent(renderer).overlaps(extent), f"legend over {title.get_text()!r}"


def notes(ax) -> list[str]:
    return [t.get_text() for t in ax.texts]


def test_every_plot_of_the_scissor_wing_keeps_its_title_clear(scissor):
    figures = [plots.fold_angles_figure(scissor), plots.probe_displacements_figure(scissor),
               plots.probe_velocities_figure(scissor), plots.probe_accelerations_figure(scissor),
               plots.monitors_figure(scissor), plots.lift_figure(scissor), mechanism_view.mechanism_figure(scissor)]
    for fig in figures:
        plots.note_flat_panels(fig)
        assert_readable(fig)
    # 14 probes: the legend is the figure's, outside the axes, not over the curves
    displacements = figures[1]
    assert len(displacements.legends) == 1 and all(ax.get_legend() is None for ax in displacements.axes)


def test_an_all_zero_panel_carries_a_note_and_a_varying_one_none(scissor):
    fig = plots.probe_displacements_figure(scissor)
    plots.note_flat_panels(fig)
    # the scissor wing moves in its y-z plane: every probe's x displacement is zero, y and z are not
    dx, dy, dz = fig.axes[:3]
    assert not np.any(scissor.series.positions[:, :, 0] - scissor.series.positions[:1, :, 0])
    assert notes(dx) == [plots.FLAT_NOTE] and notes(dy) == [] and notes(dz) == []


def test_the_energy_plot_balances_the_energy_against_the_external_work(scissor):
    """The energy panel draws E - E_0, the external work W and E - E_0 - W, the last being summary.json's
    energy_drift times its scale: equal to the difference of the other two at every sample."""
    energy_ax = plots.monitors_figure(scissor).axes[0]
    lines = {line.get_label().split(" (")[0]: line.get_ydata() for line in energy_ax.lines}
    assert set(lines) == {"energy - E_0", "external work", "energy - E_0 - external work"}
    series = scissor.series
    np.testing.assert_allclose(lines["external work"], series.external_work, rtol=0, atol=0)
    np.testing.assert_allclose(lines["energy - E_0"], series.energy - series.energy[0], rtol=0, atol=1e-15)
    np.testing.assert_allclose(lines["energy - E_0 - external work"],
                               lines["energy - E_0"] - lines["external work"], rtol=0, atol=1e-15)
    assert np.ptp(series.external_work) > 1e-4      # the actuator and the air do work: not a trivial balance


def test_the_3d_views_are_legible(tmp_path):
    scene = load_scene(SCENES / "heaving_wing.toml", ["time.stop=0.3"])
    result = run_scene(scene, backend="direct")
    snapshots, _, _ = wake_view.replay(scene, result.aero_inputs, wake_view.instant_steps(len(result.aero_inputs)))
    fig = wake_view.wake_figure(scene, snapshots)
    renderer, _ = rendered(fig)
    for ax in fig.axes:
        if ax.name == "3d":
            assert ax.xaxis.label.get_fontsize() >= 9 and ax.title.get_fontsize() >= 9
            assert all(t.get_fontsize() >= 8 for t in ax.get_xticklabels())
    assert_readable(fig)


def test_the_animation_has_one_frame_per_instant(pendulum_run):
    out, scene = pendulum_run
    with Image.open(out / animation.ANIMATION_FILE) as gif:
        assert gif.format == "GIF"
        # 11 communication points (0.1 s in steps of 0.01 s): every one is an instant of the 60 asked for
        assert gif.n_frames == len(instant_indices(np.linspace(0.0, 0.1, 11), animation.ANIMATION_FRAMES)) == 11
        assert gif.size[0] >= 400


def vtu(path):
    """(points (P, 3), cells (C, k), cell types (C,), {data array name: values}) of a VTK XML unstructured grid
    with ASCII data, parsed with xml.etree."""
    root = ET.parse(path).getroot()
    assert root.get("type") == "UnstructuredGrid"
    piece = root.find("UnstructuredGrid/Piece")
    arrays = {}
    for tag in ("PointData", "CellData"):
        for array in piece.find(tag):
            arrays[array.get("Name")] = np.array(array.text.split(), dtype=float)
    points = np.array(piece.find("Points/DataArray").text.split(), dtype=float).reshape(-1, 3)
    cells = {a.get("Name"): np.array(a.text.split(), dtype=np.int64) for a in piece.find("Cells")}
    offsets = cells["offsets"]
    width = offsets[0]
    assert np.array_equal(offsets, width * np.arange(1, len(offsets) + 1))
    assert len(points) == int(piece.get("NumberOfPoints")) and len(offsets) == int(piece.get("NumberOfCells"))
    return points, cells["connectivity"].reshape(-1, width), cells["types"], arrays


def collection(path):
    """[(time, file)] of a .pvd collection."""
    root = ET.parse(path).getroot()
    assert root.get("type") == "Collection"
    return [(float(d.get("timestep")), d.get("file")) for d in root.iter("DataSet")]


def test_the_structure_history_for_paraview_is_the_topology_and_the_csv(pendulum_run):
    out, scene = pendulum_run
    topology = Topology.from_spec(StructureSpec.from_scene(scene))
    frames = collection(out / "vtk" / "structure.pvd")
    with (out / "timeseries.csv").open() as handle:
        rows = list(csv.reader(handle))
    header = [cell.partition(" [")[0] for cell in rows[0]]
    table = np.array(rows[1:], dtype=float)
    column = {name: table[:, k] for k, name in enumerate(header)}
    assert [t for t, _ in frames] == pytest.approx(column["time"], abs=1e-12)   # every recorded sample
    assert not (out / "vtk" / "lattice.pvd").exists()                          # no aero unit
    for k, (_, name) in enumerate(frames):
        points, cells, types, arrays = vtu(out / "vtk" / name)
        assert len(points) == topology.n_nodes == 6
        assert cells.tolist() == [list(pair) for pair in topology.element_nodes]
        assert set(types) == {vtk.VTK_LINE}
        assert arrays["body"].tolist() == [0, 0, 1, 1] and arrays["node"].tolist() == list(range(6))
        # the probes sit on the bodies' last nodes: B's tip (node 5) and A's tip (node 2), as the CSV has them
        for probe, node in (("tip", 5), ("P", 2)):
            measured = points[node]
            expected = [column[f"{probe}_{axis}"][k] for axis in "xyz"]
            np.testing.assert_allclose(measured, expected, rtol=0, atol=1e-10)
    assert np.ptp(column["tip_y"]) > 1e-3                                      # and the pendulum has moved


def test_the_lattice_history_holds_the_wing_panels_and_the_wake_rings(tmp_path):
    """heaving_wing: one body of M x N = 10 x 5 panels (uvlm-prescribed); with a wake of 0.5 chords the shed wake
    holds at most 2 rows of rings after 0.3 s (3 aero steps of 0.1 s)."""
    scene = load_scene(SCENES / "heaving_wing.toml", ["time.stop=0.3", "aero.wake_length=0.5"])
    result = run_scene(scene, backend="direct")
    vtk.write_vtk(result, tmp_path)
    frames = collection(tmp_path / "vtk" / "lattice.pvd")
    assert [t for t, _ in frames] == pytest.approx([0.1, 0.2, 0.3])                # none at t = 0
    snapshots, _, _ = wake_view.replay(scene, result.aero_inputs, [2])
    points, cells, types, arrays = vtu(tmp_path / "vtk" / frames[-1][1])
    wake_rings = snapshots[0].vortex["wake_gamma"].size
    assert wake_rings == 2 * 5
    assert len(cells) == 10 * 5 + wake_rings and set(types) == {vtk.VTK_QUAD}
    assert arrays["part"].tolist() == [0] * 50 + [1] * wake_rings
    # the files carry 12 significant digits, as timeseries.csv does
    np.testing.assert_allclose(arrays["circulation"][50:], snapshots[0].vortex["wake_gamma"].ravel(), rtol=1e-11)
    np.testing.assert_allclose(points[cells[:50]].reshape(-1, 3),
                               wake_view.quads(snapshots[0].wing).reshape(-1, 3), rtol=0, atol=1e-12)


def test_a_run_asked_for_pictures_lists_them_in_its_record(pendulum_run):
    import json

    out, _ = pendulum_run
    record = json.loads((out / "run.json").read_text())
    assert record["complete"] and "animation.gif" in record["files"] and "vtk/structure.pvd" in record["files"]


def test_the_sweep_plot_draws_each_figure_against_each_grid_key(tmp_path):
    """A rigid pendulum released horizontal swings through to the other side within half a period (0.97 s for
    the 1 m bar): a probe at span s then has moved by 2 s along x, its largest displacement. Swept over s and the
    integrator, the plot's panel of that figure holds 2 s at each s, for both integrators."""
    out = tmp_path / "sweep"
    code = cli.main(["sweep", str(SCENES / "pendulum_rigid.toml"), "--grid", "probes.tip.span=0.5,1.0",
                     "--grid", "structure.integrator=rk4,generalized-alpha", "--set", "time.stop=1.0",
                     "--out", str(out), "--jobs", "2"])
    assert code == 0
    assert (out / sweep_plot.SWEEP_PLOT).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    rows = sweep_plot.read_rows(out / "sweep.csv")
    fig = sweep_plot.sweep_figure(rows, ["probes.tip.span", "structure.integrator"], "pendulum")
    plots.note_flat_panels(fig, sweep_plot.NO_VALUE_NOTE)
    assert_readable(fig)
    labels = [ax.get_ylabel() for ax in fig.axes[::2]]
    assert labels[0] == "deployment time (s)" and "largest displacement of tip (m)" in labels
    assert notes(fig.axes[0]) == [sweep_plot.NO_VALUE_NOTE]           # a pendulum has no latch: no deployment
    span_panel = fig.axes[2 * labels.index("largest displacement of tip (m)")]
    assert span_panel.get_xlabel() == "" and fig.axes[-2].get_xlabel() == "probes.tip.span"
    for line in span_panel.lines:
        np.testing.assert_allclose(line.get_xdata(), [0.5, 1.0])
        np.testing.assert_allclose(line.get_ydata(), 2 * np.array([0.5, 1.0]), rtol=1e-4)


def test_an_animation_asked_for_and_not_written_fails_the_command(tmp_path, capsys, monkeypatch):
    def broken(*args, **kwargs):
        raise RuntimeError("no frames")

    monkeypatch.setattr(animation, "write_animation", broken)
    code = cli.main(["run", str(SCENES / "pendulum_rigid.toml"), "--backend", "direct", "--out", str(tmp_path),
                     "--set", "time.stop=0.05", "--animate", "--vtk"])
    err = capsys.readouterr().err
    assert code == 1 and "error: animation.gif not written: RuntimeError: no frames" in err
    assert (tmp_path / "summary.json").is_file() and (tmp_path / "timeseries.csv").is_file()   # the data stay


def test_the_animation_and_the_vtk_files_of_one_run_replay_the_aero_unit_once(tmp_path, monkeypatch):
    """`--animate --vtk` draw 60 and 101 instants of the same run: one replay of the aero unit serves both (the
    run's other replay is the wake picture's, wake_3d.png), and the lattice files are those `write_vtk` alone
    writes from its own replay."""
    alone = tmp_path / "alone"
    scene = ["time.stop=0.3", "aero.wake_length=0.5"]
    result = run_scene(load_scene(SCENES / "heaving_wing.toml", scene), backend="direct")
    vtk.write_vtk(result, alone)
    replays = []
    original = wake_view.replay

    def counted(*args, **kwargs):
        replays.append(args[2])
        return original(*args, **kwargs)

    monkeypatch.setattr(wake_view, "replay", counted)
    monkeypatch.setattr(plots, "plot_workers", lambda: 1)   # the wake picture's replay counted here, not in a fork
    out = tmp_path / "both"
    code = cli.main(["run", str(SCENES / "heaving_wing.toml"), "--backend", "direct", "--out", str(out),
                     "--set", scene[0], "--set", scene[1], "--animate", "--vtk"])
    assert code == 0 and len(replays) == 2
    assert (out / animation.ANIMATION_FILE).is_file()
    frames = collection(out / "vtk" / "lattice.pvd")
    assert frames == collection(alone / "vtk" / "lattice.pvd") and len(frames) == 3
    for _, name in frames:
        assert (out / "vtk" / name).read_bytes() == (alone / "vtk" / name).read_bytes()
