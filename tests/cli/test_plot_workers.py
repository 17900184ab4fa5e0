"""`write_plots` in forked workers (`wingsim run` on Linux): the same files, byte for byte, as drawn in turn; a
figure's failure raises and a picture's warns, as in turn."""

import sys

import pytest

import orchestrator.output.mechanism_view
from orchestrator.output import plots
from orchestrator.run.master import run_scene
from orchestrator.scene.load import load_scene
from repository import SCENES

pytestmark = pytest.mark.skipif(not sys.platform.startswith("linux"), reason="forked plot workers are Linux only")


@pytest.fixture(scope="module")
def coupled_run():
    """deploy_rigid's first 0.02 s with its aero unit: every figure and picture applies."""
    return run_scene(load_scene(SCENES / "deploy_rigid.toml", ["time.stop=0.02"]), backend="direct")


def test_workers_write_the_files_drawn_in_turn_byte_for_byte(coupled_run, tmp_path):
    in_turn = plots.write_plots(coupled_run, tmp_path / "in_turn")
    forked = plots.write_plots(coupled_run, tmp_path / "forked", workers=2)
    assert [p.name for p in forked] == [p.name for p in in_turn]          # the same files, in the same order
    assert len(in_turn) == len(plots.PLOT_FILES) + len(plots.PICTURES)
    for a, b in zip(in_turn, forked):
        assert a.read_bytes() == b.read_bytes(), a.name


def test_workers_warn_of_a_failed_picture_and_raise_a_failed_figure(coupled_run, tmp_path, monkeypatch, capsys):
    def fails(*args):
        raise RuntimeError("drawing refused")

    monkeypatch.setattr(orchestrator.output.mechanism_view, "write_mechanism_view", fails)
    (tmp_path / "mechanism.png").write_bytes(b"stale")
    written = plots.write_plots(coupled_run, tmp_path, workers=2)
    assert "mechanism.png" not in [p.name for p in written] and not (tmp_path / "mechanism.png").exists()
    assert "warning: mechanism picture not written: RuntimeError: drawing refused" in capsys.readouterr().err
    assert len(written) == len(plots.PLOT_FILES) + len(plots.PICTURES) - 1
    monkeypatch.setattr(plots, "FIGURES", (fails,) + plots.FIGURES[1:])
    with pytest.raises(RuntimeError, match="drawing refused"):
        plots.write_plots(coupled_run, tmp_path, workers=2)
