"""orchestrator.studies.stability's run helpers: the judged sudden-load run, the kinetic-energy stop and the grid
search's ends, against energy conservation and hand-made searches."""
import math

import pytest

from orchestrator.studies import stability
from orchestrator.scene.load import load_scene
from repository import SCENES

SCENE = SCENES / "stability_wing.toml"


def test_a_sudden_load_run_stays_within_what_energy_conservation_allows_and_is_judged_stable():
    """An undamped linear structure under a dead load P applied at t = 0 reaches at most KE = P delta_s / 2 and a
    displacement of 2 delta_s (the dynamic amplification of a suddenly applied load is 2); the wing's
    generalized-alpha run (rho_inf = 0.8, 200 steps per 0.05 s) dissipates a little and is nearly linear."""
    record, series = stability.sudden_load_run(load_scene(SCENE), "wing", "tip")
    P, delta = stability.tip_load_scale(load_scene(SCENE), "wing")
    assert record["status"] == "ok" and record["stable"] and record["why"] == ""
    assert record["ke_bound"] == pytest.approx(P * delta) and record["tip_bound"] == pytest.approx(4 * delta)
    assert record["ke_max"] <= P * delta / 2 and record["tip_max"] <= 2 * delta
    assert record["tip_max"] == pytest.approx(2 * delta, rel=0.05)
    assert len(series) == 51 and record["simulated_s"] == pytest.approx(0.05)


def test_rk4_above_its_step_limit_is_judged_unstable_by_the_units_report():
    _, omega_max = stability.frequency_range(load_scene(SCENE))
    limit = stability.rk4_step_limit(omega_max)
    scene = load_scene(SCENE, ["structure.integrator=rk4", f"structure.step={1.1 * limit!r}",
                               f"coupling.step={30 * limit!r}", f"time.stop={300 * limit!r}"])
    record, _ = stability.sudden_load_run(scene, "wing", "tip")
    assert record["status"] == "diverged" and record["why"] == "solver" and not record["stable"]


def test_the_energy_limit_stops_a_run_at_the_first_communication_point_past_it():
    """A stop at a tenth of P delta_s, which the run's kinetic energy passes on its way to P delta_s / 2."""
    P, delta = stability.tip_load_scale(load_scene(SCENE), "wing")
    record, series = stability.sudden_load_run(load_scene(SCENE), "wing", "tip", runaway=0.1, message="stopped early")
    kinetic = series.kinetic_energy
    assert record["status"] == "diverged" and record["why"] == "runaway" and not record["stable"]
    assert record["message"].startswith("stopped early: kinetic energy")
    assert kinetic[-1] > 0.1 * P * delta and all(kinetic[:-1] <= 0.1 * P * delta)
    assert record["simulated_s"] == series.time[-1] < 0.05


def test_the_ends_of_a_grid_search_are_its_largest_stable_step_and_the_next_one_up():
    limit = 0.3
    search = stability.largest_stable_step(lambda h: {"stable": h <= limit, "h": h}, 1.0, fine=8, octaves=6)
    stable, unstable = stability.grid_step(search, "stable"), stability.grid_step(search, "unstable")
    assert stable <= limit < unstable and unstable / stable == pytest.approx(2 ** (1 / 8))
    assert stability.grid_probe(search, "stable")["h"] == stable
    assert stability.grid_probe(search, "unstable")["h"] == unstable
    top = stability.largest_stable_step(lambda h: {"stable": True}, 1.0, fine=8, octaves=6)
    assert stability.grid_step(top, "unstable") is None and stability.grid_probe(top, "unstable") is None
    assert stability.grid_step(top, "stable") == 1.0
    assert math.isclose(stability.grid_step({"top": 2.0, "fine": 4, "stable": 4}, "stable"), 1.0)
