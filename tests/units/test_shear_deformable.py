"""The shear-deformable fidelity (`structure.fidelity = "shear-deformable"`): the scene's refusals, the constraint
rows it drops, and the model's natural modes against Timoshenko's frequency equation."""
import numpy as np
import pytest

from fmu_common.errors import SceneError
from fmu_common.specs import StructureUnitSpec
from orchestrator.scene.load import load_scene, resolve_scene
from repository import SCENES
from structure_fmu.modes import natural_modes
from structure_fmu.solver import StructureSolver
from test_shear_element import E_AL, G_AL, RHO_AL, timoshenko_frequencies

PLATE = {"chord": 0.02, "thickness": 0.005, "density": RHO_AL, "youngs_modulus": E_AL, "torsional_rigidity": 10.0,
         "poissons_ratio": E_AL / (2 * G_AL) - 1}


def cantilever(section, fidelity="shear-deformable", length=0.08, elements=16):
    """A clamped plate along x, chord along y, centred on its reference line."""
    return resolve_scene({
        "time": {"stop": 0.1},
        "structure": {"fidelity": fidelity, "elements_per_body": elements,
                      "bodies": [{"name": "bar", "length": length, "span_axis": [1.0, 0.0, 0.0],
                                  "chord_axis": [0.0, 1.0, 0.0], "section": section}],
                      "joints": [{"type": "clamp", "body": "bar"}]},
    }, "cantilever")


def solver_of(scene):
    return StructureSolver(StructureUnitSpec.from_scene(scene))


@pytest.mark.parametrize("section, key", [
    ({"chord": 0.02, "torsional_rigidity": 1.0, "axial_stiffness": 1e6, "bending_stiffness_flap": 1.0,
      "bending_stiffness_chord": 10.0, "mass_per_length": 0.3}, "thickness"),
    ({**PLATE, "axial_stiffness": 1e6}, "axial_stiffness"),
    ({**PLATE, "bending_stiffness_chord": 10.0}, "bending_stiffness_chord"),
])
def test_a_section_the_element_cannot_integrate_is_refused_naming_the_key(section, key):
    """The element integrates E over the plate's chord and thickness: an explicit section, or a plate whose EA or
    EI_zz is overridden, is refused before anything runs, naming the key; the flexible fidelity takes them."""
    with pytest.raises(SceneError) as err:
        solver_of(cantilever(section))
    assert err.value.key == f"structure.bodies.bar.section.{key}"
    solver_of(cantilever(section, fidelity="flexible"))


def test_scissor_array_has_no_constraint_row_with_the_shear_deformable_bars():
    """scenes/scissor_array.toml (4 elements per bar, 3 SLEs): the flexible fidelity solves 52 rows, its unit-length
    and orthogonality rows (Otsuka et al. 2019, Eq. 6, once per distinct vector: 30 r_x . r_y and 22 |r_y|); the
    shear-deformable one, whose r_y is free, whose pins share coordinates and whose slider a_1 is a free scalar along
    its line, none: its equations of motion are an ODE."""
    counts = {}
    for fidelity in ("flexible", "shear-deformable"):
        scene = load_scene(SCENES / "scissor_array.toml", [f"structure.fidelity={fidelity}"])
        counts[fidelity] = solver_of(scene).model.constraint_count
    assert counts == {"flexible": 52, "shear-deformable": 0}


@pytest.mark.parametrize("slenderness", [4.0, 20.0])
def test_the_models_in_plane_bending_modes_are_timoshenko_frequency_equation(slenderness):
    """structure_fmu.modes on a clamped aluminium plate cantilever, 16 elements, nu from G = 26.3 GPa: the three
    lowest modes that move the reference line along the chord (more than 99% of the nodes' displacement along y)
    within 1.5% of the roots of Timoshenko's frequency equation (shear coefficient 1, rotary inertia; the element
    checks give the second-order convergence behind it), the first within 0.2% (measured: 1.1e-3, 6.8e-3, 1.2e-2 at
    L / c = 4; 7.7e-4, 5.4e-3, 1.3e-2 at 20)."""
    c, h = PLATE["chord"], PLATE["thickness"]
    length = slenderness * c
    solver = solver_of(cantilever(PLATE, length=length))
    omega, shapes = natural_modes(solver)
    moved = (solver.model.velocity_map(solver.state.q, 0.0) @ shapes).reshape(-1, 3, 3, len(omega))[:, 0]
    along_chord = np.sum(moved[:, 1] ** 2, axis=0) / np.sum(moved ** 2, axis=(0, 1))
    in_plane = omega[along_chord > 0.99][:3]
    reference = timoshenko_frequencies(length, E_AL, G_AL, RHO_AL, c * h, h * c**3 / 12, 3)
    np.testing.assert_allclose(in_plane, reference, rtol=1.5e-2)
    assert in_plane[0] == pytest.approx(reference[0], rel=2e-3)
