"""Planform keys in scenes (docs/aero.md, Planform; docs/scenes.md): refusals that name the key, the dihedral and the
hinge continuity of the topology, the planform picture, and the two shipped planform scenes run in-process."""
import numpy as np
import pytest

from aero_fmu.vlm import SteadyVLM
from fmu_common.errors import SceneError
from fmu_common.topology import Topology
from fmu_common.wing_spec import StructureSpec
from orchestrator.output.planform_view import planform_figure, write_planform_view
from orchestrator.run.master import run_scene
from orchestrator.scene.load import load_scene
from repository import SCENES

PNG = b"\x89PNG\r\n\x1a\n"


def topology(scene, overrides=()):
    return Topology.from_spec(StructureSpec.from_scene(load_scene(SCENES / f"{scene}.toml", list(overrides))))


@pytest.mark.parametrize("overrides, key, allowed", [
    (["structure.bodies.wingtip.section.chord_tip=0"], "structure.bodies.wingtip.section.chord_tip",
     "a finite number > 0"),
    (["structure.bodies.wingtip.section.chord_tip=-0.01"], "structure.bodies.wingtip.section.chord_tip",
     "a finite number > 0"),
    (["structure.bodies.wingtip.sweep_deg=30"], "structure.bodies.wingtip.sweep_deg",
     "keeps the reference line within the chord"),
    (["structure.bodies.wingtip.sweep_deg=-60"], "structure.bodies.wingtip.sweep_deg",
     "keeps the reference line within the chord"),
    (["structure.bodies.wingtip.sweep_deg=90"], "structure.bodies.wingtip.sweep_deg", "a number in (-90, 90)"),
    (['structure.bodies.wingtip.section.airfoil="naca241"'], "structure.bodies.wingtip.section.airfoil",
     "NACA 4-digit"),
    (['structure.bodies.wingtip.section.airfoil="clarky"'], "structure.bodies.wingtip.section.airfoil",
     "NACA 4-digit"),
    (['structure.bodies.wingtip.section.airfoil="naca2012"'], "structure.bodies.wingtip.section.airfoil",
     "second digit"),
    (["structure.bodies.wingtip.root=[0, 0, 0.5]"], "structure.bodies.wingtip.root",
     "starts at its parent's tip"),
    (["structure.bodies.wingtip.dihedral_deg=5"], "structure.bodies.wingtip.dihedral_deg", "orientation_deg"),
])
def test_a_planform_that_cannot_be_built_is_refused_naming_the_key(overrides, key, allowed):
    """A tip chord of zero or less, a sweep that carries the leading edge behind the reference line (or the
    trailing edge ahead of it) or reaches 90 deg, a camber line that is not NACA 4-digit, a hinge's child that does
    not start at its parent's tip (its own root), a child's dihedral (its joint gives its frame): each refused
    before anything runs, naming the key as the scene writes it."""
    with pytest.raises(SceneError) as refused:
        topology("flared_wingtip", overrides)
    assert refused.value.key == key
    assert allowed in str(refused.value)


def test_dihedral_tilts_the_span_axis_toward_the_section_normal():
    """hale_wing: span +y, chord (-cos 3 deg, 0, -sin 3 deg), dihedral 3 deg: the tip node at
    L (cos 3 deg y + sin 3 deg n), n = y x chord the section normal (up, +z mostly), and r_x . r_y = 0."""
    top = topology("hale_wing")
    chord = np.array([-0.99863, 0.0, -0.05234])
    chord /= np.linalg.norm(chord)
    normal = np.cross([0.0, 1.0, 0.0], chord)
    gamma = np.radians(3.0)
    r, r_x, r_y = top.node_initial[top.bodies["wing"].nodes[-1]]
    np.testing.assert_allclose(r, 16.0 * (np.cos(gamma) * np.array([0.0, 1.0, 0.0]) + np.sin(gamma) * normal),
                               atol=1e-12)
    assert r[2] > 0.8 and abs(r_x @ r_y) < 1e-15


def test_a_hinge_child_continues_its_parents_tip_twist():
    """A child's root twist is its parent's tip twist: twist 0 -> -3 deg on the inner panel and -2 deg more on the
    wingtip give the wingtip -3 -> -5 deg."""
    top = topology("flared_wingtip", ["structure.bodies.inner.twist_deg=-3", "structure.bodies.wingtip.twist_deg=-2"])
    tip = top.bodies["wingtip"].planform
    assert np.degrees([tip.twist_root, tip.twist_tip]) == pytest.approx([-3.0, -5.0], abs=1e-12)


def test_the_planform_picture_draws_each_body_outline(tmp_path):
    """planform.png of flared_wingtip: each body's outline runs through its leading and trailing edges written out
    by hand (inner: +-0.025 m at the root, +-0.021 m at its tip; wingtip: leading edge -0.021 + 0.1 tan(10 deg)
    at its tip, trailing edge 0.025 m behind it), laid end to end along the span; a scene without an aero unit
    gets no picture and loses a stale one."""
    scene = load_scene(SCENES / "flared_wingtip.toml")
    outlines = [line for line in planform_figure(scene).axes[0].lines if line.get_linewidth() == 1.6]
    inner, wingtip = (np.column_stack(line.get_data()) for line in outlines)
    assert inner[0] == pytest.approx([0.0, 0.025]) and inner[7] == pytest.approx([0.15, 0.021])
    lead = -0.021 + 0.1 * np.tan(np.radians(10.0))
    assert wingtip[7] == pytest.approx([0.25, -lead]) and wingtip[8] == pytest.approx([0.25, -lead - 0.025])

    class Result:
        pass
    result = Result()
    result.scene = scene
    path = write_planform_view(result, tmp_path)
    assert path.read_bytes()[:8] == PNG
    result.scene = load_scene(SCENES / "flared_wingtip.toml", ["aero.model=none"])
    assert write_planform_view(result, tmp_path) is None and not path.exists()


def test_flared_wingtip_deploys_and_latches():
    """flared_wingtip in-process (its FMU run: tests/fmi, which take every shipped scene): the wingtip deploys
    about its skewed hinge and latches, sooner than deploy_rigid's wider, heavier tip (0.18 s)."""
    result = run_scene(load_scene(SCENES / "flared_wingtip.toml"), backend="direct")
    assert result.status == "ok", result.message
    assert 0.05 < result.latch_times["fold"] < 0.1


def test_hale_wing_lift_at_the_first_step_is_the_steady_lift_of_its_planform():
    """hale_wing in-process without gravity: the structure takes the first step before any aero force (Gauss-Seidel)
    and stays at rest, and uvlm-flat is quasi-steady, so the lift of the first step is the steady vortex-lattice
    lift of the undeformed planform at 25 m/s (SteadyVLM, its own solve), to 1e-9."""
    scene = load_scene(SCENES / "hale_wing.toml", ["time.stop=0.01", "structure.gravity=[0, 0, 0]"])
    result = run_scene(scene, backend="direct")
    assert result.status == "ok", result.message
    top = Topology.from_spec(StructureSpec.from_scene(scene))
    flow = scene["flow"]
    U = flow["speed"] * np.array(flow["direction"]) / np.linalg.norm(flow["direction"])
    steady = SteadyVLM(top, scene["aero"]["chordwise_panels"], scene["aero"]["spanwise_panels"],
                       scene["aero"]["wake_length"]).solve(top.initial_coordinates(), U, flow["density"])
    assert result.series.column("lift")[-1] == pytest.approx(steady.lift, rel=1e-9)
