"""summary.json's structure_counts for the three-SLE scissor array (scenes/scissor_array.toml) in the rigid,
flexible and shear-deformable fidelities, against counts derived by hand from the scene's layout:

  n SLEs of two bars, N elements per bar (N + 1 nodes); n pivots and 2 (n - 1) pins between SLEs about the
  chord (each shares the point r and the chord r_y of two nodes: 6 coordinates fewer), b_1 pinned to the ground
  (its r and r_y prescribed: 6 fewer), a_1 on a fixed line along y (its point, 3 coordinates, becomes one: its
  travel along the line; 2 fewer, no row).
  flexible: per node the unit-length row of r_y and the orthogonality row r_x . r_y (Otsuka et al. 2019, Eq. 6),
  the unit row once per distinct free r_y (a pin's two nodes share theirs, b_1's is prescribed);
  shear-deformable: no row at all (Peng et al. 2019, Eqs. 1-2: r_y is free; pins and the slider are coordinates):
  an ODE, as Peng et al. 2019 assemble theirs (Eq. 22);
  rigid: a one-degree-of-freedom mechanism (the Lagrange model of tests/scissor_mechanism.py), so coordinates
  minus independent rows = 1.
"""
import json

import pytest

from orchestrator.output.results import write_results
from orchestrator.run.master import run_scene
from orchestrator.scene.load import load_scene
from repository import SCENES

ARRAY = SCENES / "scissor_array.toml"
SLIDER_COORDINATES = 2      # a point (3) held on a line: its travel along it (1)


def counts(fidelity, tmp_path):
    """summary.json's structure_counts of a two-communication-step run of the array in `fidelity`."""
    scene = load_scene(ARRAY, [f"structure.fidelity={fidelity}", "time.stop=0.002"])
    result = run_scene(scene, backend="direct")
    assert result.status == "ok", result.message
    write_results(result, tmp_path)
    return json.loads((tmp_path / "summary.json").read_text())["structure_counts"]


def layout():
    """(SLEs n, elements per bar N) of the scene."""
    scene = load_scene(ARRAY)
    return scene["structure"]["scissors"][0]["count"], scene["structure"]["elements_per_body"]


@pytest.fixture(scope="module")
def deformable(tmp_path_factory):
    return {f: counts(f, tmp_path_factory.mktemp(f)) for f in ("flexible", "shear-deformable")}


def test_the_deformable_bars_coordinates_are_the_nodes_less_the_shared_and_prescribed(deformable):
    n, N = layout()
    nodes = 2 * n * (N + 1)
    chord_pins = n + 2 * (n - 1)
    for fidelity, c in deformable.items():
        assert c["fidelity"] == fidelity
        assert c["exchanged_coordinates"] == 9 * nodes
        assert c["coordinates"] == 9 * nodes - 6 * chord_pins - 6 - SLIDER_COORDINATES


def test_the_shear_deformable_bars_have_no_constraint_row_and_the_flexible_ones_only_their_internal_rows(deformable):
    n, N = layout()
    nodes = 2 * n * (N + 1)
    internal = nodes + (nodes - (n + 2 * (n - 1)) - 1)     # r_x . r_y per node; |r_y| per distinct free r_y
    assert deformable["shear-deformable"]["constraint_rows"] == 0
    assert deformable["flexible"]["constraint_rows"] == internal


def test_the_rigid_array_is_a_one_degree_of_freedom_mechanism(tmp_path):
    c = counts("rigid", tmp_path)
    assert c["coordinates"] - c["constraint_rows"] == 1
