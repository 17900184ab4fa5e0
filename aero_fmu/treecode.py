"""Far-field approximation of the velocity of many vortex segments: a Barnes-Hut treecode (Barnes and Hut 1986;
for vortex filaments and particles, Lindsay and Krasny 2001).

Why. The free wake's convection evaluates the velocity of every wake corner from every bound and wake segment: for
R shed rows that is O(R^2) pairs per step and O(R^3) over a run. Far from a cluster of segments their velocity is
smooth and is represented by a few moments; the treecode evaluates a point's velocity with O(log S) clusters and
keeps the exact cored sum (biot_savart.py) for the segments near it, O(R log R) per step.

Expansion. A straight segment a -> b of circulation Gamma induces (Biot-Savart, the line integral of
Otsuka et al. 2019, Eq. 19 without its core)
    v(p) = Gamma int_a^b dl x G(p - x),   G(r) = r / (4 pi |r|^3) = -grad 1 / (4 pi |r|).
Expanding G(p - x) about a cluster centre c to first order, x = c + d, integrates exactly over each segment: the
zeroth term gives alpha_i = Gamma_i (b_i - a_i) (m^3/s), the first the midpoint m_i, so the cluster's velocity is
    v(p) ~ A x G(r) - sum_i alpha_i x (J(r) (m_i - c)),   r = p - c,  J = grad G,
with the monopole A = sum alpha_i and the dipole D_ab = sum alpha_ia (m_i - c)_b, i.e. (d = |r|)
    v(p) ~ [A x r - w + 3 (D r) x r / d^2] / (4 pi d^3),   w_a = eps_abc D_bc.

Error bound (per point, the sum over the far clusters it used). Every point x of the cluster's segments lies
within rho of c; the Taylor remainder of grad(1 / |r|) to first order is at most half its second derivative,
whose norm is at most 3! / |y|^4 on the segment |y| >= d - rho (the derivatives of 1 / |r| along any direction are
k! P_k(cos) / |r|^(k+1), |P_k| <= 1), times |x - c|^2 <= rho^2: per cluster
    |v - v_exact,uncored| <= 3 rho^2 sum_i |alpha_i| / (4 pi (d - rho)^4).
The cored kernel of the exact sum (Scully core delta, biot_savart.py) differs from the uncored one by
|v_uncored| delta^2 / (h^2 + delta^2) <= |Gamma| L delta / (8 pi (d - rho)^3) per segment (|v_uncored| <=
|Gamma| L h / (4 pi d_min^3) and h / (h^2 + delta^2) <= 1 / (2 delta)), so the treecode's bound is
    sum over far clusters of  sum_i |alpha_i| [3 rho^2 / (d - rho)^4 + delta / (2 (d - rho)^3)] / (4 pi),
returned beside the velocity. A cluster is far when rho < theta d (the opening parameter theta): its relative
share then shrinks like theta^2.

Tree. Octree of the segments' midpoints in Morton (Z) order: a node holds a contiguous range of the sorted
segments; its center c is the center of the box of their end points and rho the box's half diagonal (the box holds
every point of the segments); it is a leaf when it has at most LEAF_SIZE segments (or at the deepest level,
MORTON_BITS). Built level by level with numpy (a few array passes per level), so one tree serves both evaluations.

Evaluation. The C kernel `tree_velocity` of biot_savart.c walks the tree per point; `velocity_numpy` is its numpy
reference ($WINGSIM_KERNELS=numpy), walking all points level by level; the two agree to round-off (only the order
of the sums differs). The C kernel runs on the cores the process may use (`fmu_common.compiled.kernel_threads`),
each thread a block of points through ctypes, which releases the GIL: every point is evaluated on one thread in the
same order, so the result does not depend on the thread count.
"""
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass

import numpy as np

from fmu_common.compiled import kernel_threads

from .biot_savart import C_SOURCE, FOUR_PI, c_kernels, segment_velocity

LEAF_SIZE = 32          # segments per leaf at most: the exact sum over a leaf is cheaper than opening it further
MORTON_BITS = 21        # levels of the octree at most (3 x 21 bits of a Morton key in an int64)
NODE_FIELDS = 17        # center (3), radius, monopole (3), dipole (9), strength: biot_savart.c's NODE_FIELDS
POINTS_PER_TASK = 256   # points per threaded task: tasks of a few ms balance the threads
THREADED_PAIRS = 1 << 20   # below this many points x segments one thread runs (starting threads costs more)


@dataclass(frozen=True)
class SegmentTree:
    """Octree of S finite segments of known circulations (module docstring).

    nodes (K, NODE_FIELDS): center (m), radius (m), monopole (m^3/s), dipole (3 x 3 row-major, m^4/s), strength
    sum |alpha| (m^3/s); links (K, 4) int64: first segment, segment count, first child, child count (0: leaf);
    starts, ends (S, 3) m, gamma (S,) m^2/s: the segments in tree order; soa (7, S): their starts, b - a and |b - a|^2
    (the layout of biot_savart.c).
    """
    nodes: np.ndarray
    links: np.ndarray
    starts: np.ndarray
    ends: np.ndarray
    gamma: np.ndarray
    soa: np.ndarray


def _spread(q):
    """The bits of q (int64 < 2^21) spread to every third bit (Morton interleaving)."""
    q = q & 0x1FFFFF
    q = (q | q << 32) & 0x1F00000000FFFF
    q = (q | q << 16) & 0x1F0000FF0000FF
    q = (q | q << 8) & 0x100F00F00F00F00F
    q = (q | q << 4) & 0x10C30C30C30C30C3
    return (q | q << 2) & 0x1249249249249249


def _range_reduce(ufunc, padded, first, count):
    """ufunc.reduce of padded[first:first + count] per range (ranges non-empty, sorted, not overlapping; `padded`
    ends with one extra row, so that an index equal to the number of values stays in range)."""
    return ufunc.reduceat(padded, np.ravel(np.column_stack([first, first + count])), axis=0)[::2]


def build(starts, ends, gamma, leaf_size=LEAF_SIZE) -> SegmentTree:
    """The octree of finite segments (module docstring).

    Args:
        starts: (S, 3) m, global frame.
        ends: (S, 3) m, global frame.
        gamma: (S,) circulations, m^2/s.
        leaf_size: segments per leaf at most (except at the deepest level).
    """
    starts, ends = np.asarray(starts, dtype=float), np.asarray(ends, dtype=float)
    gamma = np.asarray(gamma, dtype=float).ravel()
    middle = 0.5 * (starts + ends)
    low = middle.min(axis=0)
    size = float((middle.max(axis=0) - low).max()) or 1.0
    q = np.minimum((middle - low) * ((1 << MORTON_BITS) / size), (1 << MORTON_BITS) - 1).astype(np.int64)
    key = _spread(q[:, 0]) | _spread(q[:, 1]) << 1 | _spread(q[:, 2]) << 2
    order = np.argsort(key, kind="stable")
    key, starts, ends, gamma, middle = key[order], starts[order], ends[order], gamma[order], middle[order]
    r0 = ends - starts
    soa = np.concatenate([starts.T, r0.T, (r0[:, 0] * r0[:, 0] + r0[:, 1] * r0[:, 1] + r0[:, 2] * r0[:, 2])[None]])
    alpha = gamma[:, None] * r0                                   # (S, 3) m^3/s
    pad = lambda a: np.concatenate([a, a[:1]])                    # noqa: E731 (see _range_reduce)
    sums = pad(np.column_stack([alpha, (alpha[:, :, None] * middle[:, None, :]).reshape(-1, 9),
                                np.sqrt(np.sum(alpha * alpha, axis=1))]))
    box = (pad(np.minimum(starts, ends)), pad(np.maximum(starts, ends)))
    S = len(gamma)
    levels = []                                                   # per level: (first, count, nodes (K_l, 17))
    first, count = np.zeros(1, dtype=np.int64), np.array([S], dtype=np.int64)
    for level in range(MORTON_BITS + 1):
        leaf = (count <= leaf_size) | (level == MORTON_BITS)
        levels.append((first, count, _moments(first, count, sums, *box)))
        if leaf.all():
            break
        # the children: the runs of the next level's key prefix inside this level's nodes that are not leaves (a
        # node's range is a run of its own prefix, so it ends where a run of the finer prefix ends)
        prefix = key >> (3 * (MORTON_BITS - level - 1))
        runs = np.flatnonzero(np.concatenate([[True], prefix[1:] != prefix[:-1]]))
        run_ends = np.append(runs[1:], S)
        marks = np.zeros(S + 1, dtype=np.int64)
        np.add.at(marks, first[~leaf], 1)
        np.add.at(marks, first[~leaf] + count[~leaf], -1)
        inside = np.cumsum(marks[:-1]) > 0                        # the segments of nodes that open
        runs, run_ends = runs[inside[runs]], run_ends[inside[runs]]
        first, count = runs, run_ends - runs
    return _packed(levels, starts, ends, gamma, soa)


def _moments(first, count, sums, low, high):
    """(K, NODE_FIELDS) of the nodes holding the sorted segments [first, first + count) (module docstring): the
    center c of the box of their end points, the radius of that box about c (every point of a segment lies in it),
    the monopole, the dipole sum alpha (x) m - A (x) c and the strength, from the segments' sums (alpha, alpha (x) m,
    |alpha|) and box corners, each padded (`_range_reduce`)."""
    low, high = _range_reduce(np.minimum, low, first, count), _range_reduce(np.maximum, high, first, count)
    center = 0.5 * (low + high)
    radius = 0.5 * np.sqrt(np.sum((high - low) ** 2, axis=1))
    total = _range_reduce(np.add, sums, first, count)
    monopole = total[:, 0:3]
    dipole = total[:, 3:12] - (monopole[:, :, None] * center[:, None, :]).reshape(-1, 9)
    return np.column_stack([center, radius, monopole, dipole, total[:, 12]])


def _cumulative(count):
    """Where each node's segments begin when the nodes' segments are concatenated."""
    return np.concatenate([[0], np.cumsum(count)[:-1]]).astype(np.int64)


def _packed(levels, starts, ends, gamma, soa) -> SegmentTree:
    """The SegmentTree of the levels [(first, count, nodes), ...] (breadth-first numbering: a node's children are
    consecutive nodes of the next level)."""
    child_first, child_count, offset = [], [], 0
    for (first, _, _), following in zip(levels, levels[1:] + [None]):
        n_children = np.zeros(len(first), dtype=np.int64)
        if following is not None:       # the parent of a child: the node whose range holds its first segment
            n_children = np.bincount(np.searchsorted(first, following[0], side="right") - 1, minlength=len(first))
        start = offset + len(first) + _cumulative(n_children)
        child_first.append(np.where(n_children > 0, start, 0))
        child_count.append(n_children)
        offset += len(first)
    links = np.column_stack([np.concatenate([f for f, _, _ in levels]), np.concatenate([c for _, c, _ in levels]),
                             np.concatenate(child_first), np.concatenate(child_count)]).astype(np.int64)
    nodes = np.concatenate([n for _, _, n in levels])
    return SegmentTree(np.ascontiguousarray(nodes), np.ascontiguousarray(links), starts, ends, gamma,
                       np.ascontiguousarray(soa))


def velocity(points, tree: SegmentTree, core, theta):
    """Velocity of the tree's segments at points by the treecode, and its error bound (module docstring).

    By the C kernel (threaded) unless $WINGSIM_KERNELS = numpy selects `velocity_numpy`.

    Args:
        points: (P, 3) m, global frame.
        tree: the SegmentTree.
        core: Scully core radius delta of the exact near-field sum, m.
        theta: opening parameter, 0 < theta < 1: a cluster of radius rho is far from a point at d when rho < theta d.

    Returns:
        (v (P, 3) m/s, bound (P,) m/s): |v - v_exact| <= bound, v_exact the cored sum over every segment.
    """
    if not 0.0 < theta < 1.0:
        raise ValueError(f"the treecode's opening parameter theta = {theta!r} must lie in (0, 1)")
    kernels = c_kernels()
    if kernels is None:
        return velocity_numpy(points, tree, core, theta)
    points = np.ascontiguousarray(points, dtype=float)
    P = len(points)
    out, bound = np.empty((P, 3)), np.empty(P)

    def run(lo):
        hi = min(lo + POINTS_PER_TASK, P)
        return kernels.tree_velocity(hi - lo, points[lo:hi].ctypes.data, tree.nodes.ctypes.data,
                                     tree.links.ctypes.data, len(tree.gamma), tree.soa.ctypes.data,
                                     tree.gamma.ctypes.data, float(core), float(theta),
                                     out[lo:hi].ctypes.data, bound[lo:hi].ctypes.data)

    threads = kernel_threads() if P * len(tree.gamma) >= THREADED_PAIRS else 1
    blocks = range(0, P, POINTS_PER_TASK)
    if threads > 1 and len(blocks) > 1:
        with ThreadPoolExecutor(max_workers=threads) as pool:
            statuses = list(pool.map(run, blocks))
    else:
        statuses = [run(lo) for lo in blocks]
    if any(status != 0 for status in statuses):
        raise RuntimeError(f"the treecode kernel of {C_SOURCE.name} refused the tree (status "
                           f"{min(statuses)}): deeper than its traversal stack")
    return out, bound


def velocity_numpy(points, tree: SegmentTree, core, theta):
    """`velocity` in numpy (the reference of the C kernel): the (point, node) pairs walked level by level; far pairs
    add their expansion, near leaves their segments exactly (`segment_velocity`), other near nodes open.

    Args:
        points: (P, 3) m, global frame.
        tree: the SegmentTree.
        core: Scully core radius delta of the exact near-field sum, m.
        theta: opening parameter, 0 < theta < 1 (`velocity`).

    Returns:
        (v (P, 3) m/s, bound (P,) m/s), as `velocity`.
    """
    points = np.asarray(points, dtype=float)
    P = len(points)
    out, bound = np.zeros((P, 3)), np.zeros(P)
    nodes, links = tree.nodes, tree.links
    at, node = np.arange(P), np.zeros(P, dtype=np.int64)
    while at.size:
        n = nodes[node]
        r = points[at] - n[:, 0:3]
        d2 = np.sum(r * r, axis=1)
        rho = n[:, 3]
        far = rho * rho < theta * theta * d2
        if far.any():
            v, e = _far_field(r[far], d2[far], n[far], core)
            np.add.at(out, at[far], v)
            np.add.at(bound, at[far], e)
        near_leaf = ~far & (links[node, 3] == 0)
        for k in np.unique(node[near_leaf]):
            mine = at[near_leaf][node[near_leaf] == k]
            f, c = links[k, 0], links[k, 1]
            pairs = segment_velocity(points[mine], tree.starts[f:f + c], tree.ends[f:f + c], core)   # (m, c, 3)
            out[mine] += np.einsum("psc,s->pc", pairs, tree.gamma[f:f + c])
        opening = ~far & ~near_leaf
        children = links[node[opening], 3]
        at = np.repeat(at[opening], children)
        node = np.repeat(links[node[opening], 2], children) + _ranks(children)
    return out, bound


def _ranks(counts):
    """0, 1, ..., c - 1 for each c of counts, concatenated."""
    total = int(counts.sum())
    return np.arange(total) - np.repeat(np.cumsum(counts) - counts, counts)


def _far_field(r, d2, n, core):
    """The monopole and dipole velocity (m, 3) of nodes n (m, NODE_FIELDS) at offsets r = p - c (m, 3), and the
    error bound (m,) (module docstring)."""
    A, D = n[:, 4:7], n[:, 7:16].reshape(-1, 3, 3)
    d = np.sqrt(d2)
    u = np.einsum("mab,mb->ma", D, r)                             # D r
    w = np.stack([D[:, 1, 2] - D[:, 2, 1], D[:, 2, 0] - D[:, 0, 2], D[:, 0, 1] - D[:, 1, 0]], axis=1)
    v = (np.cross(A, r) - w + 3.0 / d2[:, None] * np.cross(u, r)) / (FOUR_PI * d2 * d)[:, None]
    g, rho = d - n[:, 3], n[:, 3]
    return v, n[:, 16] * (3.0 * rho * rho / g ** 4 + core / (2.0 * g ** 3)) / FOUR_PI
