"""Long runs announced: the time left in the progress line, a note after the warm-up for a long run, a note
before a run for a large timeseries.csv, plausibility notes for values far outside the scenes' physics."""
import io

import orchestrator.output.plots
import orchestrator.run.progress as progress_module
from orchestrator.cli import main
from orchestrator.output.results import write_results
from orchestrator.run.master import run_scene
from orchestrator.run.estimate import LARGE_OUTPUT_BYTES, csv_bytes, output_note
from orchestrator.run.progress import Progress
from orchestrator.scene.load import load_scene
from orchestrator.scene.plausibility import plausibility_notes
from repository import SCENES

RIGID = SCENES / "deploy_rigid.toml"


class Clock:
    """A wall clock the test advances."""

    def __init__(self):
        self.now = 100.0

    def perf_counter(self):
        return self.now


def test_the_time_left_is_the_remaining_simulated_time_over_the_stepping_rate(monkeypatch):
    clock = Clock()
    monkeypatch.setattr(progress_module, "_time", clock)
    stream = io.StringIO()
    bar = Progress(10.0, label="x", stream=stream, live=True, min_interval=0.0, warm_up=1e9)
    clock.now += 5.0            # loading the units: not part of the rate
    bar.update(0.5)
    clock.now += 2.0
    bar.update(1.5)             # 1 s simulated in 2 s of wall: 8.5 s left take 17 s
    assert bar.remaining(1.5) == 17.0
    assert stream.getvalue().rsplit("\r", 1)[1] == f"x: [{'#' * 4}{'-' * 26}] t = 1.5 / 10 s, wall 7.0 s, about 17 s " \
                                                 "left\x1b[K"
    bar.finish(10.0, "ok")
    assert stream.getvalue().endswith("wall 7.0 s: ok\x1b[K\n")   # no time left once finished


def test_a_long_run_gets_one_note_after_the_warm_up_a_short_one_none(monkeypatch):
    clock = Clock()
    monkeypatch.setattr(progress_module, "_time", clock)
    for stop, expect in ((400.0, True), (100.0, False)):
        stream = io.StringIO()
        bar = Progress(stop, stream=stream, live=False, warm_up=3.0, long_run=300.0)
        for k in range(1, 8):   # 0.5 s of wall per 0.5 s simulated: a rate of 1
            bar.update(0.5 * k)
            clock.now += 0.5
        # at t = 3.5 s, 3 s of stepping after the first step at t = 0.5 s: (400 - 3.5) s left, (100 - 3.5) s for
        # the short run
        assert stream.getvalue().count("note: this run will take about") == int(expect)
        if expect:
            assert "about 6.6 min more" in stream.getvalue() and "time.stop" in stream.getvalue()


def test_the_csv_estimate_bounds_the_written_file(tmp_path):
    scene = load_scene(RIGID, ["time.stop=0.3"])   # the whole deployment, the aero unit on
    result = run_scene(scene, backend="direct")
    assert result.status == "ok"
    write_results(result, tmp_path)
    written = (tmp_path / "timeseries.csv").stat().st_size
    header = len((tmp_path / "timeseries.csv").read_text().splitlines()[0]) + 1
    estimated = csv_bytes(scene)
    assert written - header <= estimated < 4 * written   # a bound (the widest %.12g value), not far above


def test_a_large_output_is_announced_with_its_size_and_how_to_reduce_it(tmp_path, capsys, monkeypatch):
    long = load_scene(RIGID, ["time.stop=300", "coupling.step=1e-4"])
    assert csv_bytes(long) > LARGE_OUTPUT_BYTES
    note = output_note(long)
    assert "3,000,001 rows" in note and "shorten time.stop" in note
    assert output_note(load_scene(RIGID)) is None


def test_flow_values_outside_the_plausible_range_get_a_note_and_the_run_goes_ahead(tmp_path, capsys, monkeypatch):
    fast = load_scene(RIGID, ["flow.speed=1000"])
    assert [n.split(" is ")[0] for n in plausibility_notes(fast)] == ["flow.speed = 1000 m/s"]
    assert "Mach 0.3" in plausibility_notes(fast)[0]
    water = load_scene(RIGID, ["flow.density=1000"])
    assert [n.split(" is ")[0] for n in plausibility_notes(water)] == ["flow.density = 1000 kg/m^3"]
    # 102 m/s (Mach 0.3 at 340.3 m/s) is inside; without an aero unit the flow does not matter
    assert plausibility_notes(load_scene(RIGID, ["flow.speed=102"])) == []
    assert plausibility_notes(load_scene(RIGID, ["flow.speed=1000", "aero.model=none"])) == []
    monkeypatch.chdir(tmp_path)
    # the note is the point
    monkeypatch.setattr(orchestrator.output.plots, "write_plots", lambda result, out, workers=1: [])
    assert main(["run", str(RIGID), "--set", "flow.speed=1000", "--set", "time.stop=0.002", "--backend", "direct",
                 "--out", "out"]) == 0
    assert "note: flow.speed = 1000 m/s is outside the plausible range [0, 102.1] m/s" in capsys.readouterr().err
