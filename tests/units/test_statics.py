"""Cantilever statics: the locking test of Otsuka et al. 2019, Sec. VI.A and the large-deflection elastica."""
import json

import numpy as np
import pytest
from scipy.integrate import solve_ivp
from scipy.optimize import brentq

from orchestrator.cli import main
from orchestrator.scene.load import load_scene
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


def elastica_tip(k):
    """(dx, dz) / L of the tip of an inextensible cantilever under a dead transverse tip load, k = P L^2 / EI.

    Shooting on theta'' = -k cos(theta), theta(0) = 0, theta'(1) = 0 (no moment at the free end).
    """
    def rhs(s, y):
        return [y[1], -k * np.cos(y[0]), np.cos(y[0]), np.sin(y[0])]

    def end_moment(c):
        return solve_ivp(rhs, (0, 1), [0, c, 0, 0], rtol=1e-12, atol=1e-12).y[1, -1]
    slope = brentq(end_moment, 0.0, k)
    end = solve_ivp(rhs, (0, 1), [0, slope, 0, 0], rtol=1e-12, atol=1e-12).y[:, -1]
    return end[2] - 1.0, end[3]


@pytest.mark.parametrize("parameter", [1.0, 10.0])
def test_large_deflection_matches_elastica(tmp_path, parameter):
    summary = run(tmp_path, SCENES / "cantilever_large_deflection.toml", f"load.parameter={parameter}")
    length = summary["scene"]["structure"]["bodies"][0]["length"]
    dx, dz = elastica_tip(parameter)
    tip = np.array(summary["probes"]["tip"]["final"]) - np.array(summary["probes"]["tip"]["initial"])
    expected = length * np.array([dx, 0.0, -dz])
    assert np.linalg.norm(tip - expected) < 0.01 * np.linalg.norm(expected)
