"""Linear rows on several slots and sliding rows on another body (structure_fmu.constraints, joint_rows): each row
kind against its defining formula written out here, the sliding row against the geometry of a rigid frame, and
every derivative of the assembled constraints against central differences of the residual.

Every row is a polynomial of degree at most 4 in E, so the five-point central differences below are exact up to
round-off (their truncation error involves the fifth derivative): the steps can be large and the tolerances
tight."""
from types import SimpleNamespace

import numpy as np
import pytest

from fmu_common.vectors import rotation_about
from structure_fmu.constraints import AxisProduct, Constraints, LinearRow
from structure_fmu.joint_rows import SlidingRow, SlidingRows

N_NODES = 4
N = 9 * N_NODES
E_X, E_Y, E_Z = np.eye(3)


def r(node):
    """Slot of a node's position r (slot of r_x, r_y: +1, +2)."""
    return 3 * node


def fake_topology(linear=True, axes=True, sliding=True):
    """The attributes Constraints reads, on four nodes: the r_x, r_y rows of nodes 0-2, a fixed plane, a loop's pin
    between nodes 0 and 3 and a gradient row, two axis products (one with the ground) and three sliding rows
    (node 3 on a line of node 1's body, node 2 on a plane of node 0's body)."""
    unit = [r(k) + j for k in range(3) for j in (1, 2)]
    linear_rows = [LinearRow((r(2),), (1.0,), np.array([0.0, 0.6, 0.8]), 0.3)]
    linear_rows += [LinearRow((r(0), r(3)), (1.0, -1.0), e, 0.0) for e in np.eye(3)]
    linear_rows += [LinearRow((r(1) + 2, r(2) + 1, r(0)), (2.0, -0.5, 1.5), np.array([1.0, -2.0, 0.5]), -0.7)]
    axis_products = [AxisProduct(r(0) + 1, np.array([0.0, 0.6, 0.8]), r(1) + 1, np.array([0.8, 0.0, -0.6])),
                     AxisProduct(None, E_Z, r(2) + 1, np.array([0.0, 1.0, 0.0]))]
    sliding_rows = [SlidingRow(r(3), r(1), r(1) + 1, E_Y, 0.1), SlidingRow(r(3), r(1), r(1) + 1, E_Z, -0.2),
                    SlidingRow(r(2), r(0), r(0) + 1, np.array([0.48, 0.6, 0.64]), 0.4)]
    return SimpleNamespace(unit_slots=unit, orthogonal_slots=[(r(k) + 1, r(k) + 2) for k in range(3)],
                           linear_rows=linear_rows if linear else [], axis_products=axis_products if axes else [],
                           sliding_rows=sliding_rows if sliding else [], n_coordinates=N)


def first(f, x, u, s=0.1):
    """d f(x + t u)/dt at t = 0, five-point central difference."""
    return (8 * (f(x + s * u) - f(x - s * u)) - (f(x + 2 * s * u) - f(x - 2 * s * u))) / (12 * s)


def second(f, x, u, s=0.1):
    """d2 f(x + t u)/dt2 at t = 0, five-point central difference."""
    return (-f(x + 2 * s * u) + 16 * f(x + s * u) - 30 * f(x) + 16 * f(x - s * u) - f(x - 2 * s * u)) / (12 * s**2)


def close(actual, reference, relative=1e-12):
    """Equal to `relative` times the reference's largest magnitude."""
    return np.allclose(actual, reference, rtol=0, atol=relative * np.max(np.abs(reference)))


def test_sliding_row_on_a_rigid_frame_is_the_distance_from_the_body_fixed_plane():
    """On a rigid frame (r_x, r_y) = (R e_x, R e_y), v_Q(c) = R c: a point at r_Q + R a is on the body's plane
    a . c = offset, moves along the plane without changing Phi, and off it by the distance it moves along R c."""
    R = rotation_about(np.array([1.0, 2.0, -0.5]) / np.linalg.norm([1.0, 2.0, -0.5]), 0.9)
    c = np.array([0.36, -0.48, 0.8])                         # unit, in the body's frame
    a = np.array([0.7, -0.2, 0.3])
    E = np.zeros(9 * 2)
    E[0:3], E[3:6], E[6:9] = [0.4, -1.0, 2.0], R @ E_X, R @ E_Y     # node 0: Q
    rows = SlidingRows([SlidingRow(r(1), r(0), r(0) + 1, c, float(a @ c))], np.eye(E.size), E.size)
    in_plane = R @ np.cross(c, [1.0, 0.0, 0.0])
    for step, expected in ((0.0, 0.0), (0.37, 0.0), (-1.2, 0.0)):
        E[9:12] = E[0:3] + R @ a + step * in_plane
        assert rows.residual(E)[0] == pytest.approx(expected, abs=1e-15)
    E[9:12] = E[0:3] + R @ a - 0.25 * (R @ c)
    assert rows.residual(E)[0] == pytest.approx(-0.25, abs=1e-15)


def test_linear_row_on_two_slots_is_the_loop_pin_gap():
    """A loop's pin rows X_a . e_k - X_b . e_k are the gap's components; their Jacobian on q is T_a - T_b, their rate
    the gap's rate, and they add no velocity term or Hessian. A repeated slot sums its coefficients."""
    rng = np.random.default_rng(11)
    T = rng.standard_normal((N, 17))
    E, dE = rng.standard_normal(N), rng.standard_normal(N)
    top = SimpleNamespace(unit_slots=[], orthogonal_slots=[], axis_products=[], sliding_rows=[], n_coordinates=N,
                          linear_rows=[LinearRow((r(0), r(3)), (1.0, -1.0), e, 0.0) for e in np.eye(3)]
                          + [LinearRow((r(2), r(2)), (1.0, 2.0), np.array([0.0, 3.0, 4.0]), 1.5)])
    cons = Constraints(top, T)
    gap, gap_T = E[0:3] - E[27:30], T[0:3] - T[27:30]     # slots 0 and 9
    assert cons.count == 4
    assert np.array_equal(cons.residual(E)[:3], gap)
    assert cons.residual(E)[3] == pytest.approx(3.0 * (3.0 * E[19] + 4.0 * E[20]) - 1.5, rel=1e-15)
    assert np.array_equal(cons.jacobian(E)[:3], gap_T)
    assert np.allclose(cons.rate(E, dE)[:3], dE[0:3] - dE[27:30], rtol=1e-15, atol=0)
    assert not cons.velocity_quadratic(dE, E).any()
    assert not cons.hessian_sum(rng.standard_normal(4), E).any()


@pytest.mark.parametrize("bad, message", [(dict(slots=(0, 1), coefficients=(1.0,)), "one coefficient per slot"),
                                          (dict(slots=(), coefficients=()), "at least one slot"),
                                          (dict(normal=np.ones(2)), "3-vector")])
def test_linear_row_refuses_inconsistent_fields(bad, message):
    fields = dict(slots=(0,), coefficients=(1.0,), normal=E_Z, offset=0.0) | bad
    with pytest.raises(ValueError, match=message):
        LinearRow(**fields)


def test_linear_row_refuses_a_slot_outside_the_coordinates():
    top = fake_topology(axes=False, sliding=False)
    top.linear_rows = [LinearRow((N // 3,), (1.0,), E_Z, 0.0)]
    with pytest.raises(ValueError, match="outside the 12 slots"):
        Constraints(top, np.eye(N))


def _rows_written_out(top, E):
    """Each kind's residuals from its definition, with np.cross: (|X|^2 - 1)/2, X_a . X_b, sum a_k X_k . n - c,
    v_A(a) . v_B(b), (X_p - X_q) . v_Q(c) - offset."""
    X = E.reshape(-1, 3)
    v = lambda frame, c: c[0] * X[frame] + c[1] * X[frame + 1] + c[2] * np.cross(X[frame], X[frame + 1])
    return {"unit": [(X[s] @ X[s] - 1) / 2 for s in top.unit_slots],
            "orthogonal": [X[a] @ X[b] for a, b in top.orthogonal_slots],
            "linear": [sum(k * X[s] for s, k in zip(row.slots, row.coefficients)) @ row.normal - row.offset
                       for row in top.linear_rows],
            "axis": [(row.parent_axis if row.parent is None else v(row.parent, row.parent_axis))
                     @ v(row.child, row.child_axis) for row in top.axis_products],
            "sliding": [(X[row.point] - X[row.origin]) @ v(row.frame, row.components) - row.offset
                        for row in top.sliding_rows]}


@pytest.mark.parametrize("kinds", [dict(), dict(linear=False), dict(axes=False), dict(sliding=False),
                                   dict(linear=False, axes=False, sliding=False)])
def test_rows_are_counted_and_ordered_unit_orthogonal_linear_axis_sliding(kinds):
    top = fake_topology(**kinds)
    E = np.random.default_rng(2).standard_normal(N)
    cons = Constraints(top, np.eye(N))
    expected = _rows_written_out(top, E)
    assert list(cons.blocks) == ["unit", "orthogonal", "linear", "axis", "sliding"]
    assert cons.count == sum(len(rows) for rows in expected.values())
    assert cons.residual(E).shape == cons.rate(E, E).shape == cons.velocity_quadratic(E, E).shape == (cons.count,)
    assert cons.jacobian(E).shape == (cons.count, N)
    for kind, rows in expected.items():
        assert cons.blocks[kind].stop - cons.blocks[kind].start == len(rows)
        assert np.allclose(cons.residual(E)[cons.blocks[kind]], rows, rtol=1e-14, atol=1e-14)


def _assembled(seed=5):
    """Constraints of the fake topology with a random map T (n, 20), and a random E off the constraint manifold."""
    rng = np.random.default_rng(seed)
    T = rng.standard_normal((N, 20))
    return Constraints(fake_topology(), T), T, rng.standard_normal(N), rng


def test_jacobian_on_q_and_on_E_match_central_differences():
    cons, T, E, rng = _assembled()
    offset = E - T @ rng.standard_normal(T.shape[1])           # E = T q + P p with a fixed P p
    q = np.linalg.lstsq(T, E - offset, rcond=None)[0]
    phi = lambda x: cons.residual(T @ x + offset)
    numeric = np.array([first(phi, q, u) for u in np.eye(q.size)]).T
    assert close(cons.jacobian(T @ q + offset), numeric)
    # on E (T = I), for the sliding rows' own gradient
    on_E = Constraints(fake_topology(), np.eye(N))
    numeric = np.array([first(on_E.residual, E, u) for u in np.eye(N)]).T
    assert close(on_E.jacobian(E), numeric)
    sliding = on_E.sliding
    scattered = np.zeros((sliding.count, N))
    for i, index in enumerate(sliding._index):
        np.add.at(scattered[i], index, sliding.gradient(E)[i])
    assert close(scattered, numeric[on_E.blocks["sliding"]])


def test_rate_is_the_gradient_times_the_rate():
    cons, _, E, rng = _assembled()
    dE = rng.standard_normal(N)
    gradient = Constraints(fake_topology(), np.eye(N)).jacobian(E)
    assert close(cons.rate(E, dE), gradient @ dE, relative=1e-14)
    assert close(cons.rate(E, dE), first(cons.residual, E, dE))


def test_velocity_term_matches_the_second_derivative_along_the_rate():
    """d2Phi/dt2 along E(t) = E + t dE (E'' = 0) is the velocity term alone."""
    cons, _, E, rng = _assembled()
    dE = rng.standard_normal(N)
    reference = second(cons.residual, E, dE)
    assert close(cons.velocity_quadratic(dE, E), reference)
    assert close(cons.velocity_quadratic(dE, E)[cons.blocks["sliding"]], reference[cons.blocks["sliding"]])


def test_hessian_sum_matches_central_differences_of_the_residual():
    """u^T H w = (D2(u + w) - D2(u - w)) / 4 with D2 the second directional derivative of lambda . Phi, on every
    pair of E's unit vectors; once with all rows' multipliers and once with the sliding rows' alone."""
    cons, _, E, rng = _assembled()
    lam = rng.standard_normal(cons.count)
    sliding_only = np.zeros(cons.count)
    sliding_only[cons.blocks["sliding"]] = lam[cons.blocks["sliding"]]
    for weights in (lam, sliding_only):
        weighted = lambda x, w=weights: w @ cons.residual(x)
        numeric = np.zeros((N, N))
        for i, j in zip(*np.triu_indices(N)):
            u, w = np.eye(N)[i], np.eye(N)[j]
            numeric[i, j] = numeric[j, i] = (second(weighted, E, u + w) - second(weighted, E, u - w)) / 4
        hessian = cons.hessian_sum(weights, E)
        assert np.array_equal(hessian, hessian.T)
        assert close(hessian, numeric)
