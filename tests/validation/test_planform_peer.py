"""Swept and tapered wings against PteraSoftware's steady ring vortex-lattice solver (an independent code, the `peers`
extra) on the same lattice: uniform panels, chords along the stream, ring leading segments at the panel quarter
chords, the wing in its plane and the stream turned by alpha.

The codes differ in how they take loads from the circulations: PteraSoftware applies the Kutta-Joukowski force
rho Gamma V x dl on each ring segment (normal to the local velocity), we the pressure jump along the panel normal
(Otsuka et al. 2019, Eqs. 23, 25), whose lift is smaller by cos(alpha) for a flat wing: at alpha = 2 deg by
0.06%. The fast sibling, the same wing kind against the lifting line, is in tests/units/test_aero_planform.py."""
import numpy as np
import pytest

from aero_fmu.vlm import SteadyVLM
from planform_wing import RHO, lift_direction, stream, tapered_wing, topology_of, wing_scene

ALPHA_DEG = 2.0
SPEED = 10.0


def pterasoftware_wing(span, root_chord, tip_chord, sweep_deg, axis_position, M, N):
    """PteraSoftware's (airplane, wing, problem) of `planform_wing.tapered_wing`: three cross sections (left tip,
    centre, right tip) with their leading edges where ours are, N uniform spanwise panels between each pair, M
    uniform chordwise panels, a symmetric section (PteraSoftware meshes its camber line: a flat plate)."""
    import pterasoftware as ps     # the `peers` extra; the slow set needs it (README, Tests), so a missing one fails

    half, section = 0.5 * span, ps.geometry.airfoil.Airfoil("naca0012")
    lead_tip = -axis_position * tip_chord                        # x of the tips' leading edges
    lead_centre = lead_tip - half * np.tan(np.radians(sweep_deg))
    cross = ps.geometry.wing_cross_section.WingCrossSection
    sections = [cross(airfoil=section, num_spanwise_panels=N, chord=tip_chord, spanwise_spacing="uniform"),
                cross(airfoil=section, num_spanwise_panels=N, chord=root_chord, spanwise_spacing="uniform",
                      Lp_Wcsp_Lpp=(lead_centre - lead_tip, half, 0.0)),
                cross(airfoil=section, num_spanwise_panels=None, chord=tip_chord,
                      Lp_Wcsp_Lpp=(lead_tip - lead_centre, half, 0.0))]
    wing = ps.geometry.wing.Wing(wing_cross_sections=sections, num_chordwise_panels=M, chordwise_spacing="uniform")
    airplane = ps.geometry.airplane.Airplane(wings=[wing], s_ref=span * (root_chord + tip_chord) / 2)
    problem = ps.problems.SteadyProblem(airplanes=[airplane], operating_point=ps.operating_point.OperatingPoint(
        rho=RHO, vCg__E=SPEED, alpha=ALPHA_DEG))
    ps.steady_ring_vortex_lattice_method.SteadyRingVortexLatticeMethodSolver(problem).run()
    return airplane, wing


@pytest.mark.slow
@pytest.mark.parametrize("sweep_deg", [0.0, 20.0])
def test_swept_tapered_wing_against_pterasoftware(sweep_deg):
    """b = 6 m, chords 1.4 m at the centre and 0.6 m at the tips (A = 6), leading edge swept back by sweep_deg,
    M x N = 4 x 12 per half, alpha = 2 deg: C_L and the lift of each spanwise strip within 1% of PteraSoftware's."""
    span, root, tip, a, M, N = 6.0, 1.4, 0.6, 0.25, 4, 12
    top = topology_of(wing_scene(tapered_wing(span, root, tip, sweep_deg, a)))
    ours = SteadyVLM(top, M, N).solve(top.initial_coordinates(), stream(ALPHA_DEG, SPEED), RHO)
    strips = (ours.forces @ lift_direction(ALPHA_DEG)).reshape(2, M, N).sum(axis=1).ravel()
    airplane, wing = pterasoftware_wing(span, root, tip, sweep_deg, a, M, N)
    # wind axes: PteraSoftware's force z points down, its lift is the negative
    peer_CL = -float(airplane.forceCoefficients_W[2])
    peer_strips = -np.array([[panel.forces_W[2] for panel in row] for row in wing.panels]).sum(axis=0)
    assert ours.CL == pytest.approx(peer_CL, rel=0.01)
    np.testing.assert_allclose(strips, peer_strips, rtol=0.01)
