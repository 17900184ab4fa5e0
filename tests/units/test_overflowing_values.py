"""Finite scene values whose arithmetic overflows are refused, naming the key, before a unit starts from NaN; a
model description never holds a start value that is not a finite number; a state whose vectors vanished is a
divergence, not a ZeroDivisionError."""
import json
import math

import numpy as np
import pytest

from fmu_common.errors import SceneError
from fmu_common.specs import StructureUnitSpec
from orchestrator.scene.load import load_scene
from repository import SCENES
from structure_fmu.joints import fold_angle_gradient
from structure_fmu.solver import StructureSolver
from structure_fmu.structure_slave import StructureSlave
from subprocesses import wingsim

PENDULUM = SCENES / "double_pendulum.toml"


def solver(*overrides):
    return StructureSolver(StructureUnitSpec.from_scene(load_scene(PENDULUM, list(overrides))))


@pytest.mark.parametrize("rate", ["1e308", "1e200"])
def test_an_initial_rotation_rate_whose_rates_or_energy_overflow_is_refused_naming_it(rate):
    """double_pendulum's body A (0.25 m, 0.5 kg) spun at 1e308 rad/s: omega x r overflows; at 1e200 rad/s the
    rates are finite but 1/2 m v^2 ~ 1e399 J is not."""
    with pytest.raises(SceneError) as refused:
        solver(f"structure.bodies.A.angular_velocity=[0, {rate}, 0]")
    assert refused.value.key == "structure.bodies.A.angular_velocity"


def test_build_of_an_overflowing_rate_exits_non_zero_naming_the_key(tmp_path):
    """Before, `wingsim build` wrote start="nan" for de and kinetic_energy and exited 0."""
    proc = wingsim("build", PENDULUM, "--set", "structure.bodies.A.angular_velocity=[0, 1e200, 0]", "--out",
                   tmp_path / "fmus", cwd=tmp_path)
    assert proc.returncode != 0
    assert "structure.bodies.A.angular_velocity" in proc.stderr and "Traceback" not in proc.stderr
    assert not (tmp_path / "fmus" / "structure.fmu").exists()


def test_the_model_description_refuses_a_start_value_that_is_not_finite(tmp_path):
    """A slave whose output starts at NaN (a value the scene checks did not foresee) builds no model
    description: the error names the variable."""
    (tmp_path / "scene.json").write_text(json.dumps(load_scene(PENDULUM)))
    slave = StructureSlave(instance_name="unit", resources=str(tmp_path))
    slave.to_xml()                                                       # finite: written
    variable = next(v for v in slave.vars.values() if v.name == "kinetic_energy")
    slave._real[variable.value_reference] = math.nan          # pythonfmu writes the value the unit holds
    with pytest.raises(ValueError, match="kinetic_energy"):
        slave.to_xml()


def test_a_hinge_whose_vectors_vanished_has_a_nan_gradient_not_a_division_error():
    """a = b = 0 (underflowed): atan2(0, 0) has no gradient; NaN, which the integrator reports as a divergence."""
    x = np.array([0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0])
    _, gradient = fold_angle_gradient(x)
    assert np.all(np.isnan(gradient))


def test_youngs_modulus_1e308_diverges_with_the_solvers_reason(tmp_path):
    """deploy_wind_tunnel_2019 with E = 1e308 Pa (EA, EI still finite): the first step diverges, reported as a
    divergence with its hint (before: status error, ZeroDivisionError)."""
    from orchestrator.run.master import run_scene
    scene = load_scene(SCENES / "deploy_wind_tunnel_2019.toml",
                       ["structure.bodies.0.section.youngs_modulus=1e308", "time.stop=0.002", "aero.model=none"])
    result = run_scene(scene, backend="direct")
    assert result.status == "diverged" and "ZeroDivisionError" not in result.message


@pytest.mark.parametrize("scene, overrides, key", [
    # a 2 m beam (3 elements of 0.667 m) whose root is 1e17 m away: its nodes coincide in double precision
    ("cantilever_static", ["structure.bodies.beam.root=[1e17, 0, 0]"], "structure.bodies.beam.root"),
    # bodies of 1e307 m: their mass matrices (rho A L^3) overflow
    ("deploy_rigid", ["structure.bodies.inner.length=1e307", "structure.bodies.outer.length=1e307"],
     "structure.bodies.inner.length"),
    # a lumped mass of 1e308 kg under 1e308 m/s^2: its weight overflows
    ("deploy_rigid", ["structure.masses.0.mass=1e308", "structure.gravity=[0, 0, -1e308]"], "structure.gravity"),
])
def test_finite_values_whose_products_overflow_are_refused_naming_the_key(scene, overrides, key):
    """Refused when the scene is loaded (the topology places the nodes) or when the solver is built."""
    with pytest.raises(SceneError) as refused:
        loaded = load_scene(SCENES / f"{scene}.toml", ["aero.model=none", *overrides])
        StructureSolver(StructureUnitSpec.from_scene(loaded))
    assert refused.value.key == key
