"""Cantilever statics: the locking test of Otsuka et al. 2019, Sec. VI.A and the large-deflection elastica."""
import json

import numpy as np
import pytest

from orchestrator.cli import main
from orchestrator.scene.load import load_scene
from elastica import elastica_tip
from repository import SCENES


def run(tmp_path, scene, *overrides):
    args = ["run", str(scene), "--backend", "direct", "--out", str(tmp_path)]
    for item in overrides:
        args += ["--set", item]
    assert main(args) == 0
    return json.loads((tmp_path / "summary.json").read_text())


def test_quasi_static_cantilever_is_locking_free(tmp_path):
    """Tip deflection with 3 elements within 1% of F L^3 / (3 EI) (Otsuka et al. 2019, Sec. VI.A, Eq. 26)."""
    scene = load_scene(SCENES / "cantilever_static.toml")
    body = scene["structure"]["bodies"][0]
    force = scene["structure"]["loads"][0]["force"][2]
    expected = force * body["length"] ** 3 / (3 * body["section"]["bending_stiffness_flap"])
    summary = run(tmp_path, SCENES / "cantilever_static.toml")
    assert scene["structure"]["elements_per_body"] == 3
    tip = summary["probes"]["tip"]
    assert tip["final"][2] - tip["initial"][2] == pytest.approx(expected, rel=0.01)


@pytest.mark.parametrize("parameter", [1.0, 10.0])
def test_large_deflection_matches_elastica(tmp_path, parameter):
    summary = run(tmp_path, SCENES / "cantilever_large_deflection.toml", f"load.parameter={parameter}")
    length = summary["scene"]["structure"]["bodies"][0]["length"]
    dx, dz = elastica_tip(parameter)
    tip = np.array(summary["probes"]["tip"]["final"]) - np.array(summary["probes"]["tip"]["initial"])
    expected = length * np.array([dx, 0.0, -dz])
    assert np.linalg.norm(tip - expected) < 0.01 * np.linalg.norm(expected)
