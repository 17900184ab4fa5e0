"""Slots: the exchanged coordinates as linear combinations of free and prescribed vectors (Peng et al. 2019,
Eqs. 13-14: master/slave coordinates).

E (9 n_nodes,) is a sequence of 3-vector slots: slot s = 3 node + k occupies E[3s:3s+3], k = R (the point r, m),
RX (r_x, -) or RY (r_y, -). Each slot is a linear combination of free vectors q_j (the integrator's
coordinates), free scalars s_j along constant directions d_j (a slider's travel, m) and prescribed vectors
p_j(t), so that E = T q + P p(t) with q the free vectors and then the scalars. A joint that shares a point or an
axis makes two slots equal by `eliminate`: it solves the difference of the two slots for one of its free vectors
and substitutes it everywhere, so the shared slots are equal to round-off by construction. A slider on a fixed
line (plane) is the same substitution with the difference r - (r_0 + d_1 s_1 (+ d_2 s_2)): a free point vector
becomes one (two) scalars, and the slider has no constraint row.
"""
from dataclasses import dataclass, field

import numpy as np

R, RX, RY = 0, 1, 2  # slot kinds


@dataclass
class Slot:
    """A slot's combination: free vector index -> coefficient, prescribed vector index -> coefficient, free scalar
    index -> its direction (3,) (in the slot's unit per unit of the scalar, global frame)."""

    free: dict = field(default_factory=dict)
    prescribed: dict = field(default_factory=dict)
    along: dict = field(default_factory=dict)

    def plus(self, other, factor):
        """self + factor other, without the terms that cancel.

        Args:
            other: the Slot added.
            factor: its coefficient (-).
        """
        out = Slot(dict(self.free), dict(self.prescribed), dict(self.along))
        for src, dst in ((other.free, out.free), (other.prescribed, out.prescribed), (other.along, out.along)):
            for j, c in src.items():
                dst[j] = dst.get(j, 0.0) + factor * c
                if not np.any(dst[j]):
                    del dst[j]
        return out

    def signature(self):
        """A hashable form of the combination (coefficients rounded to 1e-12): equal slots have equal signatures."""
        return (tuple(sorted((j, round(c, 12)) for j, c in self.free.items())),
                tuple(sorted((j, round(c, 12)) for j, c in self.prescribed.items())),
                tuple(sorted((j, tuple(np.round(d, 12))) for j, d in self.along.items())))

    def value(self, free_values, prescribed_values, scalar_values=()):
        """The slot's 3-vector for the free vectors and scalars and the prescribed vectors.

        Args:
            free_values: the free vectors, a list of (3,) arrays.
            prescribed_values: the prescribed vectors, a list of (3,) arrays.
            scalar_values: the free scalars, a sequence of floats (m).

        Returns:
            (3,) in the slot's unit (m for R, - for RX, RY), global frame.
        """
        out = np.zeros(3)
        for j, c in self.free.items():
            out += c * free_values[j]
        for j, c in self.prescribed.items():
            out += c * prescribed_values[j]
        for j, d in self.along.items():
            out += d * scalar_values[j]
        return out


def eliminate(slots: list[Slot], difference: Slot, candidates) -> int | None:
    """Make `difference` zero by substituting one free vector.

    The candidate with the largest index among `candidates` that appears in it is substituted. Updates `slots` in
    place.

    Args:
        slots: the slots of E, updated in place.
        difference: a combination of slots that must vanish.
        candidates: free vector indices that may be eliminated.

    Returns:
        the eliminated index, or None when no candidate appears (the caller then keeps the equation as constraint
        rows).
    """
    usable = [j for j in difference.free if j in candidates and abs(difference.free[j]) > 1e-12]
    if not usable:
        return None
    j = max(usable)
    # q_j = q_j - difference / c_j: the combination without q_j that the equation gives it
    replacement = Slot({j: 1.0}).plus(difference, -1.0 / difference.free[j])
    replacement.free.pop(j, None)
    for s, slot in enumerate(slots):
        c = slot.free.get(j)
        if c is not None:
            rest = Slot(dict(slot.free), dict(slot.prescribed), dict(slot.along))
            del rest.free[j]
            slots[s] = rest.plus(replacement, c)
    return j


def compact(slots: list[Slot], *per_free: list) -> list[list]:
    """Renumber the free vectors that some slot still uses as 0, 1, ... (in order), in place in `slots`.

    Args:
        slots: the slots of E, renumbered in place.
        *per_free: lists with one entry per old free vector.

    Returns:
        each list of `per_free` restricted to the used free vectors.
    """
    used = sorted({j for slot in slots for j in slot.free})
    new = {j: i for i, j in enumerate(used)}
    slots[:] = [Slot({new[j]: c for j, c in slot.free.items()}, dict(slot.prescribed), dict(slot.along))
                for slot in slots]
    return [[values[j] for j in used] for values in per_free]
