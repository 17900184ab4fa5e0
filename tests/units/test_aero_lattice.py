"""The vortex-ring lattice from the structural shape functions (Otsuka et al. 2019, Eqs. 12, 20, 21, 24)."""
import numpy as np
import pytest

from aero_fmu.lattice import Lattice
from fmu_common.wing_spec import StructureSpec
from fmu_common.vectors import rotation_about
from fmu_common.scene_schema import resolve_scene
from fmu_common.topology import Topology

RNG = np.random.default_rng(11)
SECTION = {"chord": 0.3, "axis_position": 0.4, "thickness": 0.01, "density": 100.0, "youngs_modulus": 1e9,
           "torsional_rigidity": 1.0}


def folded_scene(angle_deg=30.0):
    """Two flexible bodies (3 and 2 elements) hinged at `angle_deg`, chords 0.3 m and 0.2 m."""
    outer = dict(SECTION, chord=0.2, axis_position=0.25)
    return resolve_scene({"time": {"stop": 1.0}, "structure": {
        "fidelity": "flexible", "elements_per_body": 3,
        "bodies": [{"name": "inner", "length": 1.2, "root": [0.1, -0.2, 0.3], "span_axis": [0, 1, 0],
                    "chord_axis": [1, 0, 0], "section": SECTION},
                   {"name": "outer", "length": 0.7, "section": outer}],
        "joints": [{"type": "clamp", "body": "inner"},
                   {"type": "revolute", "name": "fold", "parent": "inner", "child": "outer",
                    "initial_angle_deg": angle_deg}]}}, "folded")


def analytic(root, span_axis, chord_axis, length, chord, axis_position, spans, fractions):
    """r = root + s x0 + (f - a) c y0 for span stations s (m) and chord fractions f, shape (len f, len s, 3)."""
    s, f = np.meshgrid(spans, fractions)
    return root + s[..., None] * span_axis + ((f - axis_position) * chord)[..., None] * chord_axis


def test_undeformed_lattice_points_are_analytic():
    """Undeformed bodies: r(s, f) = root + s x0 + (f - a) c y0 exactly (Otsuka et al. 2019, Eq. 2 with r_y = y0).

    Panel edges at f = i/M (leading edge f = 0, trailing edge f = 1), ring corners at the panels' quarter
    chords f = (i + 1/4)/M (the last a quarter panel behind the trailing edge), collocation points at
    f = (i + 3/4)/M and mid-panel span, force points at f = (i + 1/4)/M and mid-panel span; r_x = x0,
    r_y = y0, n = x0 x y0 and panel area = L c / (M N). M = 3, N = 7 puts points inside elements and on
    their ends (3 elements per body); the outer body is folded by 30 degrees about the hinge's chord axis.
    """
    M, N = 3, 7
    top = Topology.from_spec(StructureSpec.from_scene(folded_scene()))
    lat = Lattice(top, M, N)
    E = top.initial_coordinates()
    geo = lat.geometry(E)
    grid = lat.grid_points(E)
    y0 = np.array([1.0, 0, 0])
    inner_x = np.array([0, 1.0, 0])
    outer_x = rotation_about(y0, np.radians(30.0)) @ inner_x
    inner_root = np.array([0.1, -0.2, 0.3])
    bodies = [(inner_root, inner_x, 1.2, 0.3, 0.4), (inner_root + 1.2 * inner_x, outer_x, 0.7, 0.2, 0.25)]
    nc, n_p = (M + 1) * (N + 1), M * N
    for b, (root, x0, L, c, a) in enumerate(bodies):
        edges, mids = L * np.arange(N + 1) / N, L * (np.arange(N) + 0.5) / N
        ref = lambda spans, fractions: analytic(root, x0, y0, L, c, a, spans, fractions).reshape(-1, 3)  # noqa: B023
        np.testing.assert_allclose(grid[b * nc:(b + 1) * nc], ref(edges, np.arange(M + 1) / M), atol=1e-12)
        np.testing.assert_allclose(grid[b * nc:b * nc + N + 1], ref(edges, [0.0]), atol=1e-12)       # leading edge
        np.testing.assert_allclose(grid[(b + 1) * nc - N - 1:(b + 1) * nc], ref(edges, [1.0]), atol=1e-12)
        np.testing.assert_allclose(geo.corners[b * nc:(b + 1) * nc], ref(edges, (np.arange(M + 1) + 0.25) / M),
                                   atol=1e-12)
        panels = slice(b * n_p, (b + 1) * n_p)
        np.testing.assert_allclose(geo.collocation[panels], ref(mids, (np.arange(M) + 0.75) / M), atol=1e-12)
        np.testing.assert_allclose(geo.application[panels], ref(mids, (np.arange(M) + 0.25) / M), atol=1e-12)
        np.testing.assert_allclose(geo.r_x[panels], np.broadcast_to(x0, (n_p, 3)), atol=1e-12)
        np.testing.assert_allclose(geo.r_y[panels], np.broadcast_to(y0, (n_p, 3)), atol=1e-12)
        np.testing.assert_allclose(geo.normal[panels], np.broadcast_to(np.cross(x0, y0), (n_p, 3)), atol=1e-12)
        np.testing.assert_allclose(geo.area[panels], L * c / (M * N), rtol=1e-12)
    assert lat.reference_area == pytest.approx(1.2 * 0.3 + 0.7 * 0.2)
    # rings close: corner (i, j) -> (i+1, j) -> (i+1, j+1) -> (i, j+1), right-handed about -n
    ring = geo.corners[lat.rings[0]]
    assert np.cross(ring[1] - ring[0], ring[3] - ring[0]) @ geo.normal[0] < 0


def test_matrices_are_the_element_shape_functions_on_any_E():
    """For an arbitrary (deformed, non-physical) E the lattice matrices reproduce Otsuka et al. 2019, Eq. (20):
    every point equals r = S(x, y) e of its element (structure_fmu's point_position), kron(Sc, I3) @ E is
    the same product, Sx @ X is dr/dx (central difference of a cubic: error h^2 r'''/6) and Sy @ X is
    dr/dy = r_y(x) (exact: r is linear in y)."""
    M, N = 2, 5
    top = Topology.from_spec(StructureSpec.from_scene(folded_scene()))
    lat = Lattice(top, M, N)
    E = top.initial_coordinates() + 0.2 * RNG.standard_normal(top.n_coordinates)
    geo = lat.geometry(E)
    np.testing.assert_allclose(Lattice.full(lat.corner_matrix) @ E, geo.corners.ravel(), atol=1e-14)
    h = 1e-5
    for b, name in enumerate(["inner", "outer"]):
        body = top.bodies[name]
        L, c = body.length, body.chord
        for i in range(M):
            for j in range(N):
                p = b * M * N + i * N + j
                s, f = L * (j + 0.5) / N, (i + 0.75) / M
                np.testing.assert_allclose(geo.collocation[p], top.point_position(E, name, s, f), atol=1e-13)
                dx = (top.point_position(E, name, s + h, f) - top.point_position(E, name, s - h, f)) / (2 * h)
                np.testing.assert_allclose(geo.r_x[p], dx, atol=1e-8)
                dy = (top.point_position(E, name, s, f + 0.1) - top.point_position(E, name, s, f)) / (0.1 * c)
                np.testing.assert_allclose(geo.r_y[p], dy, atol=1e-12)
                cx = np.cross(geo.r_x[p], geo.r_y[p])
                # Otsuka et al. 2019, Eq. (21)
                np.testing.assert_allclose(geo.normal[p], cx / np.linalg.norm(cx), atol=1e-14)
                corner = b * (M + 1) * (N + 1) + (i + 1) * (N + 1) + j
                np.testing.assert_allclose(geo.corners[corner], top.point_position(E, name, L * j / N, (i + 1.25) / M),
                                           atol=1e-13)


def test_generalized_force_is_virtual_work():
    """Q = sum S(x_a, y_a)^T a (Otsuka et al. 2019, Eq. 12): Q . dE = sum_panels a . dr_a for any virtual
    displacement dE, and for a rigid translation dE (dr = d on r slots, 0 on gradients) Q . dE = (sum a) . d."""
    top = Topology.from_spec(StructureSpec.from_scene(folded_scene()))
    lat = Lattice(top, 3, 4)
    forces = RNG.standard_normal((lat.n_panels, 3))
    Q = lat.generalized_force(forces)
    dE = RNG.standard_normal(top.n_coordinates)
    dr = Lattice.full(lat.application_matrix) @ dE
    assert Q @ dE == pytest.approx(np.sum(forces.ravel() * dr), rel=1e-12)
    d = np.array([0.3, -1.0, 2.0])
    translation = np.zeros((top.n_nodes, 3, 3))
    translation[:, 0] = d
    assert Q @ translation.ravel() == pytest.approx(forces.sum(axis=0) @ d, rel=1e-12)
