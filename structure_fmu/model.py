"""The structural model in reduced coordinates: M q'' + Phi_q^T lambda = F (Otsuka et al. 2019, Eq. 4).

E = T q + P p(t) (topology.py). Since T is constant, the reduced mass matrix M_q = T^T M_E T is constant
(Otsuka et al. 2019, Eq. 5) and is factorized once. Forces are computed on E and mapped by T^T; a prescribed motion
p(t) adds -T^T M_E P p''(t). T is applied through its nonzero entries (coordinate_map.py): generalized-alpha's
tangent is assembled from the element blocks, the constraint Hessian's entries, the hinges' and the damped bodies'
blocks straight into the reduced (n_q, n_q) matrix, never as the dense (n, n) one (`tangent_E` forms that one: the
reference the tests compare with).
"""
from dataclasses import replace

import numpy as np
from scipy.linalg import cho_factor, cho_solve

from fmu_common.errors import SceneError
from fmu_common.shape_functions import shape_row

from . import element, shear_element
from .constraints import Constraints
from .coordinate_map import Assembly, CoordinateMap
from .motion import Fixed
from .section import element_points, varies
from .damping import deformation_damping_force, deformation_damping_matrix
from .joints import actuator_energy, actuator_terms, hinge_coordinates


class StructureModel:
    """Mass, forces, constraints and energy of a StructureTopology with given tunable parameters.

    The model of the prescribed, rigid, flexible and shear-deformable fidelities (structure_fmu.fidelities): the
    flexible bodies' elastic force is that of `element` (Otsuka et al. 2019), or of `shear_element` (Peng et al.
    2019) for a shear-deformable fidelity.

    Args:
        topology: the StructureTopology.
        gravity: (3,) m/s^2, global frame.
        hinge_parameters: {hinge: {parameter: value}} replacing its actuator's (stiffness N m/rad, damping
            N m s/rad, ...); None: the topology's.
        body_damping: {body: alpha, 1/s}; None: the topology's.
        damping_model: "deformation" (-alpha (I-P)^T M (I-P) de, damping.py) or "mass-proportional" (-alpha M de).
    """

    ancf_elastic = True
    """Whether a deformable body carries the ANCF elastic force on E (Otsuka et al. 2019, Eqs. 7-11)."""

    newton_weights = None
    """(n_q,) factors on q (and q') in generalized-alpha's convergence test, or None: the coordinates are
    positions (m) and gradients (1) already, the units the Newton tolerance is stated in."""

    def __init__(self, topology, gravity, hinge_parameters=None, body_damping=None, damping_model="deformation"):
        self.top = topology
        self.n = topology.n_coordinates
        self.T, self.P = topology.maps()
        self.dofs = np.ascontiguousarray(topology.element_dofs(), dtype=np.int64)     # (elements, 18) into E
        self.lengths = topology.element_lengths()
        # the sections per element (n,), or at the Gauss points of each element (n, g) where a section varies along
        # its body: every property table below then has that extra axis (structure_fmu.element)
        sections = element_sections(topology)
        self.stiffness = section_property(sections, "stiffness")
        # the element law: (module with elastic_energy, elastic_force, elastic_jacobian; its per-element table)
        self._law = ((shear_element, shear_element.section_table(sections)) if topology.fidelity.shear_deformable
                     else (element, self.stiffness))
        mu, mu1, mu2, rotary = (section_property(sections, name) for name in ("mass_per_length", "first_moment",
                                                                              "chord_inertia", "rotary_inertia"))
        deformable = topology.fidelity.deformable
        self.flexible = deformable and self.ancf_elastic      # the ANCF elastic force (strain-based: K q instead)
        # constant mass matrix on E (Otsuka et al. 2019, Eq. 5) plus lumped masses on r
        self.mass_E = np.zeros((self.n, self.n))
        element_mass = element.mass_matrix(self.lengths, mu, mu1, mu2, rotary)
        for dofs, m in zip(self.dofs, element_mass):
            self.mass_E[np.ix_(dofs, dofs)] += m
        gravity = np.asarray(gravity, float)
        self.gravity_E = np.zeros(self.n)
        np.add.at(self.gravity_E, self.dofs, element.distributed_force(self.lengths, mu, mu1, gravity))
        for node, mass in topology.masses:
            self.mass_E[9 * node:9 * node + 3, 9 * node:9 * node + 3] += mass * np.eye(3)
            self.gravity_E[9 * node:9 * node + 3] += mass * gravity
        _check_finite_masses(topology, element_mass, self.gravity_E, gravity)
        self.mass_q = self.T.T @ self.mass_E @ self.T
        # M_q^-1, once: the explicit integrator's solves become products (M_q is SPD; its condition number,
        # 1e7-1e8 with 7-15 elements per body, costs at most ~1e-8 relative, below the projection's tolerance)
        n_q = self.T.shape[1]
        self.mass_inverse = cho_solve(cho_factor(self.mass_q), np.eye(n_q)) if n_q else np.zeros((0, 0))
        self.mass_prescribed = self.T.T @ self.mass_E @ self.P
        self.constraints = Constraints(topology, self.T)
        # the rows the integrators solve: a loop of rigid bodies closed by rows, planar, repeats one of them
        kept = (independent_rows(self.constraints.jacobian(topology.initial_coordinates())) if self.constraints.count
                else np.zeros(0, int))
        self._dropped = np.setdiff1d(np.arange(self.constraints.count), kept)
        self._row_count = len(kept)
        self._rows = kept if len(self._dropped) else None     # None: every row, used as evaluated
        self.hinges = [replace(h, **(hinge_parameters or {}).get(h.name, {})) for h in topology.hinges]
        self.damped_bodies = []
        # "deformation": -alpha (I-P)^T M (I-P) de (damping.py); "mass-proportional": -alpha M de, the
        # literal Otsuka et al. 2019, Sec. II.C / Otsuka et al. 2022, Sec. 5 force, which also damps the bodies'
        # rigid motion (a constant matrix, `mass_damping`)
        self.mass_damping = None
        if deformable:
            for name, body in topology.bodies.items():
                alpha = (body_damping or {}).get(name, body.damping)
                if alpha > 0:
                    idx = np.arange(9 * body.nodes[0], 9 * body.nodes[-1] + 9)
                    self.damped_bodies.append((alpha, idx, self.mass_E[np.ix_(idx, idx)]))
        if damping_model == "mass-proportional" and self.damped_bodies:
            self.mass_damping = np.zeros((self.n, self.n))
            for alpha, idx, mass in self.damped_bodies:
                self.mass_damping[np.ix_(idx, idx)] += alpha * mass
        # flat positions of the element blocks in an (n, n) matrix, to assemble tangents in one bincount
        self._element_entries = (self.dofs[:, :, None] * self.n + self.dofs[:, None, :]).ravel()
        self._dofs_flat = self.dofs.ravel()
        self._force_scratch = np.empty(36 * len(self.dofs))       # element.add_elastic_force's work space
        self.map = CoordinateMap(self.T)
        # where iteration_matrix's values go in the reduced matrix, and the reduced mass-proportional damping T^T C T
        self.tangent_assembly, self.reduced_damping = self._assemble_tangent()
        self.loads = topology.loads
        self._group_prescribed()

    # ---------------------------------------------------------------- kinematics
    def prescribed(self, t):
        """The stacked prescribed vectors and rates at time t.

        A point x = pivot + R (x0 - pivot) + h and a gradient g = R g0 of their motion law (structure_fmu.motion),
        with the rates from dR/dt = spin R and d2R/dt2 = turn R.

        Args:
            t: time, s.

        Returns:
            (p, p', p''), each (3 n_prescribed,), global frame; new arrays.
        """
        out = self._at_rest.copy()     # (3, n_prescribed, 3): p, p', p''; the clamps' rows stay as they are
        for motion, rows, arms, at_points in self._moving:
            k = motion.kinematics(t)
            block = out[:, rows]        # a view: the rows are consecutive
            block[0] = u = np.dot(arms, k.rotation.T)       # the vectors from the pivot, turned
            block[1] = np.dot(u, k.spin.T)
            block[2] = np.dot(u, k.turn.T)
            block += at_points * np.array((motion.pivot + k.translation, k.velocity, k.acceleration))[:, None]
        return out[0].ravel(), out[1].ravel(), out[2].ravel()

    def _group_prescribed(self):
        """Prescribed vectors grouped by motion, in runs of consecutive rows (a body's root, topology.py); the fixed
        ones (clamps) are computed once."""
        top = self.top
        p0 = np.array(top.prescribed_initial).reshape(-1, 3)
        is_pos = np.array(top.prescribed_is_position, dtype=float).reshape(-1, 1)
        which = np.array(top.prescribed_motion, dtype=int)
        self._moving = []
        for m, motion in enumerate(top.motions):
            rows = np.flatnonzero(which == m)
            if not len(rows) or isinstance(motion, Fixed):
                continue
            for run in np.split(rows, np.flatnonzero(np.diff(rows) != 1) + 1):
                run = slice(int(run[0]), int(run[-1]) + 1)
                arms = p0[run] - is_pos[run] * motion.pivot     # position vectors from the pivot; gradients as they are
                self._moving.append((motion, run, arms, is_pos[run]))
        self._at_rest = np.stack([p0, np.zeros_like(p0), np.zeros_like(p0)])
        # without moving prescribed vectors, P p(t) is constant and P p' = p'' = 0
        self._fixed_offset = None if self._moving else self.P @ p0.ravel()
        self._motion_at = (None, None)         # (t, (P p, P p', p'')) of the last t asked

    def coordinates(self, q, dq, t):
        """E, dE/dt, and the prescribed acceleration p'' at time t (None when nothing prescribed moves).

        Args:
            q: (n_q,) generalized coordinates.
            dq: (n_q,) their rates, per s.
            t: time, s.
        """
        if self._fixed_offset is not None:
            return self.map.apply(q, self._fixed_offset), self.map.apply(dq), None
        Pp, Pdp, ddp = self.motion_offsets(t)
        return self.map.apply(q, Pp), self.map.apply(dq, Pdp), ddp

    @property
    def varies_in_time(self) -> bool:
        """Whether the equations change with time at a given state: a prescribed motion moves or a point load ramps
        (otherwise what `motion_offsets` and `constant_force_E` return is the same at every t)."""
        return self._fixed_offset is None or any(load.ramp_time is not None for load in self.loads)

    def motion_offsets(self, t):
        """The prescribed parts of E and dE/dt at time t, P p and P p' (n,), and p'' (3 n_prescribed,); (P p, None,
        None) when nothing prescribed moves.

        Args:
            t: time, s.
        """
        if self._fixed_offset is not None:
            return self._fixed_offset, None, None
        if self._motion_at[0] != t:     # a step's Newton iterations and RK4 stages ask for the same t
            p, dp, ddp = self.prescribed(t)
            self._motion_at = (t, (self.P @ p, self.P @ dp, ddp))
        return self._motion_at[1]

    # ---------------------------------------------------------------- forces
    def load_factor(self, load, t):
        """The factor (-) on a PointLoad's force at time t: 1, or the cosine ramp up to its ramp_time.

        Otsuka et al. 2019, Eq. 26

        Args:
            load: the PointLoad (structure_fmu.topology).
            t: time, s.
        """
        if load.ramp_time is not None:   # Otsuka et al. 2019, Eq. (26)
            ts = load.ramp_time
            return 0.5 * (1 - np.cos(np.pi * t / ts)) if t < ts else 1.0
        return 1.0

    def external_force_E(self, t, Q):
        """The external generalized force on E at time t: the point loads and Q.

        Its power on dE is what the energy monitor's external work integrates.

        Args:
            t: time, s.
            Q: (n,) generalized external force on E, N and N m, global frame.

        Returns:
            (n,) N and N m, global frame.
        """
        F = np.array(Q, dtype=float)
        for load in self.loads:
            k = load.element
            s = shape_row(load.x, load.y, self.lengths[k])
            F[self.dofs[k]] += np.kron(s, load.force * self.load_factor(load, t))
        return F

    def constant_force_E(self, t, Q):
        """The part of `force_E` that does not depend on E or dE: gravity, point loads and Q.

        Args:
            t: time, s.
            Q: (n,) generalized external force on E, N and N m, global frame.

        Returns:
            (n,) N and N m, global frame.
        """
        return self.gravity_E + (self.external_force_E(t, Q) if self.loads else Q)

    def force_E(self, E, dE, t, Q, latched):
        """Generalized force on E: elastic, gravity, point loads, actuators, damping and external Q.

        Args:
            E: (n,) exchanged coordinates, global frame.
            dE: (n,) their rates, per s.
            t: time, s.
            Q: (n,) generalized external force on E, N and N m, global frame.
            latched: {hinge: latched}.

        Returns:
            (n,) N and N m, global frame.
        """
        F = self.constant_force_E(t, Q)
        if self.flexible:
            law, table = self._law
            if law is element:          # one compiled call: gathered from E, added into F
                element.add_elastic_force(E, self.dofs, self.lengths, table, F, self._force_scratch)
            else:
                F += np.bincount(self._dofs_flat, law.elastic_force(E[self.dofs], self.lengths, table).ravel(), self.n)
        for idx, torque, _, _, grad in actuator_terms(self.hinges, E, dE, latched):
            F[idx] -= torque * grad
        if self.mass_damping is not None:
            F -= self.mass_damping @ dE
        else:
            for alpha, idx, mass in self.damped_bodies:
                F[idx] += deformation_damping_force(E[idx], dE[idx], mass, alpha)
        return F

    def tangent_E(self, E, dE, latched):
        """The tangents of `force_E` (point loads, gravity and Q do not depend on E).

        Args:
            E: (n,) exchanged coordinates, global frame.
            dE: (n,) their rates, per s.
            latched: {hinge: latched}.

        Returns:
            (K_E, C_E), each (n, n): -dF/dE (elastic exact, actuator Gauss-Newton: K grad grad^T) and -dF/d(dE)
            (damping, actuator C grad grad^T).
        """
        n = self.n
        if self.flexible:
            law, table = self._law
            jac = law.elastic_jacobian(E[self.dofs], self.lengths, table)
            K = np.bincount(self._element_entries, jac.ravel(), n * n).reshape(n, n)
        else:
            K = np.zeros((n, n))
        C = np.zeros((n, n))
        for idx, _, stiffness, damping, grad in actuator_terms(self.hinges, E, dE, latched):
            outer = np.outer(grad, grad)
            K[np.ix_(idx, idx)] += stiffness * outer
            C[np.ix_(idx, idx)] += damping * outer
        if self.mass_damping is not None:
            C += self.mass_damping
        else:
            for alpha, idx, mass in self.damped_bodies:
                C[np.ix_(idx, idx)] += deformation_damping_matrix(E[idx], mass, alpha)
        return K, C

    def force_q(self, q, dq, t, Q, latched):
        """Reduced force T^T F - T^T M_E P p'' (the inertia of the prescribed motion) and the current E, dE, p''.

        Args:
            q: (n_q,) generalized coordinates.
            dq: (n_q,) their rates, per s.
            t: time, s.
            Q: (n,) generalized external force on E, N and N m, global frame.
            latched: {hinge: latched}.

        Returns:
            (force (n_q,), E (n,), dE (n,), p'' or None).
        """
        E, dE, ddp = self.coordinates(q, dq, t)
        F = self.map.transpose_apply(self.force_E(E, dE, t, Q, latched))
        if ddp is not None:
            F -= self.mass_prescribed @ ddp
        return F, E, dE, ddp

    # ---------------------------------------------------------------- the integrators' interface
    def initial_coordinates(self):
        """q at t = 0 (n_q,)."""
        return self.top.initial_free()

    def mass_matrix(self, q, t):
        """M_q at q and t, constant here.

        Args:
            q: (n_q,) generalized coordinates.
            t: time, s.

        Returns:
            (n_q, n_q).
        """
        return self.mass_q

    def mass_product(self, q, t, x):
        """M_q x at q and t.

        Args:
            q: (n_q,) generalized coordinates.
            t: time, s.
            x: (n_q,) accelerations.

        Returns:
            (n_q,).
        """
        return np.dot(self.mass_q, x)

    def solve_mass(self, q, t, b):
        """M_q^-1 b at q and t.

        Args:
            q: (n_q,) generalized coordinates.
            t: time, s.
            b: (n_q,) or (n_q, k).

        Returns:
            the shape of b.
        """
        return np.dot(self.mass_inverse, b)

    @property
    def constraint_count(self):
        """Rows the integrators solve: the independent ones (`independent_rows`)."""
        return self._row_count

    def _kept(self, values):
        """The rows of `values` (count of all rows, ...) that the integrators solve."""
        return values if self._rows is None else values[self._rows]

    def constraint_residual(self, q, E):
        """Phi at the state whose exchanged coordinates are E.

        Args:
            q: (n_q,) generalized coordinates.
            E: (n,) the exchanged coordinates at q, global frame.

        Returns:
            (count,).
        """
        return self._kept(self.constraints.residual(E))

    def constraint_violation(self, q, E):
        """Largest |Phi| of every row, the redundant ones the integrators leave out included (the monitor).

        Args:
            q: (n_q,) generalized coordinates.
            E: (n,) the exchanged coordinates at q, global frame.
        """
        residual = self.constraints.residual(E) if len(self._dropped) else self.constraint_residual(q, E)
        return float(np.abs(residual).max(initial=0.0))

    def constraint_jacobian(self, q, E):
        """Phi_q.

        Args:
            q: (n_q,) generalized coordinates.
            E: (n,) the exchanged coordinates at q, global frame.

        Returns:
            (count, n_q).
        """
        return self._kept(self.constraints.jacobian(E))

    def constraint_rate(self, q, dq, E, dE):
        """dPhi/dt.

        Args:
            q: (n_q,) generalized coordinates.
            dq: (n_q,) their rates, per s.
            E: (n,) the exchanged coordinates at q, global frame.
            dE: (n,) their rates, per s.

        Returns:
            (count,) per s.
        """
        return self._kept(self.constraints.rate(E, dE))

    def constraint_gamma(self, q, dq, E, dE, ddp):
        """-(d2Phi/dt2 - Phi_q q''): the right-hand side of the acceleration-level constraints.

        Args:
            q: (n_q,) generalized coordinates.
            dq: (n_q,) their rates, per s.
            E: (n,) the exchanged coordinates at q, global frame.
            dE: (n,) their rates, per s.
            ddp: (3 n_prescribed,) the prescribed acceleration p'', or None.

        Returns:
            (count,) per s^2.
        """
        gamma = -self.constraints.velocity_quadratic(dE, E)
        if ddp is not None:
            gamma -= self.constraints.rate(E, self.P @ ddp)
        return self._kept(gamma)

    def iteration_matrix(self, t, q, dq, latched, lam, beta_p, gamma_p):
        """Generalized-alpha's iteration matrix without the constraint rows, with the constraint Hessian in K_t.

        Peng et al. 2019, Fig. 3

        Args:
            t: time, s.
            q: (n_q,) generalized coordinates.
            dq: (n_q,) their rates, per s.
            latched: {hinge: latched}.
            lam: (count,) the constraint multipliers.
            beta_p: beta', 1/s^2.
            gamma_p: gamma', 1/s.

        Returns:
            (beta' M_q + gamma' C_t + K_t (n_q, n_q), E (n,)).
        """
        E, dE, _ = self.coordinates(q, dq, t)
        assembly, reduced_damping = self.tangent_assembly, self.reduced_damping
        values = []
        if self.flexible:
            law, table = self._law
            values.append(law.elastic_jacobian(E[self.dofs], self.lengths, table).ravel())
        multipliers = lam
        if self.constraints.count:
            if self._rows is not None:      # zero on the rows left out
                multipliers = np.zeros(self.constraints.count)
                multipliers[self._rows] = lam
            values.append(multipliers[self.constraints.quadratic_hessian[1]])
        for _, _, stiffness, damping, grad in actuator_terms(self.hinges, E, dE, latched):
            values.append(((stiffness + gamma_p * damping) * np.outer(grad, grad)).ravel())
        if self.mass_damping is None:
            for alpha, idx, mass in self.damped_bodies:
                values.append(gamma_p * deformation_damping_matrix(E[idx], mass, alpha).ravel())
        S = self.map.reduce(assembly, np.concatenate(values)) if values else np.zeros_like(self.mass_q)
        if self.constraints.count:
            beyond = self.constraints.nonquadratic_hessian_sum(multipliers, E)
            if beyond is not None:
                S += self.map.congruence(beyond)
        if reduced_damping is not None:
            S += gamma_p * reduced_damping
        S += beta_p * self.mass_q
        return S, E

    def _assemble_tangent(self):
        """(Assembly, T^T C_mass T or None): where `iteration_matrix`'s values go in the reduced matrix, in its
        order (the element blocks, the quadratic constraint rows' Hessian entries, each hinge's block, each
        damped body's block, those present), and the reduced constant mass-proportional damping matrix."""
        parts = []
        if self.flexible:
            parts.append(self._element_entries)
        if self.constraints.count:
            parts.append(self.constraints.quadratic_hessian[0])
        parts += [_block(hinge_coordinates(h), self.n) for h in self.hinges]
        if self.mass_damping is None:
            parts += [_block(idx, self.n) for _, idx, _ in self.damped_bodies]
        assembly = Assembly.joined([self.map.assembly(p) for p in parts], [len(p) for p in parts]) if parts else None
        reduced_damping = None if self.mass_damping is None else self.map.congruence(self.mass_damping)
        return assembly, reduced_damping

    def iteration_pattern(self):
        """(n_q + m, n_q + m) bool: the entries of generalized-alpha's iteration matrix [[S, G^T], [G, 0]]
        (structure_fmu.iteration_lu) that can be nonzero, read from the matrix at a generic state (coordinates,
        rates and multipliers perturbed at random about the initial ones, gamma' = beta' = 1), where no entry
        vanishes by accident: the elements couple neighbouring nodes, each constraint row a few coordinates."""
        rng = np.random.default_rng(0)
        q0 = self.initial_coordinates()
        n_q, m = len(q0), self.constraint_count
        q = q0 + 0.1 * rng.standard_normal(n_q)
        dq, lam = rng.standard_normal(n_q), rng.standard_normal(m)
        S, E = self.iteration_matrix(0.0, q, dq, {}, lam, 1.0, 1.0)
        pattern = np.zeros((n_q + m, n_q + m), dtype=bool)
        pattern[:n_q, :n_q] = S != 0
        if m:
            G = self.constraint_jacobian(q, E) != 0
            pattern[n_q:, :n_q], pattern[:n_q, n_q:] = G, G.T
        return pattern

    def acceleration_E(self, q, dq, ddq, t):
        """d2E/dt2 for q'' = ddq: T q'' + P p''(t).

        Args:
            q: (n_q,) generalized coordinates.
            dq: (n_q,) their rates, per s.
            ddq: (n_q,) their accelerations, per s^2.
            t: time, s.

        Returns:
            (n,) per s^2, global frame.
        """
        if self._fixed_offset is not None:          # p'' = 0
            return self.map.apply(ddq)
        return self.map.apply(ddq, self.P @ self.motion_offsets(t)[2])

    def velocity_map(self, q, t):
        """dE/dq: T, constant here.

        Args:
            q: (n_q,) generalized coordinates.
            t: time, s.

        Returns:
            (n, n_q).
        """
        return self.T

    def rates_of(self, q, dE, t):
        """The q' whose exchanged rates come closest to dE (least squares; exact when dE is reachable).

        Args:
            q: (n_q,) generalized coordinates.
            dE: (n,) wanted rates of E, per s, global frame.
            t: time, s.

        Returns:
            (n_q,) per s.
        """
        _, dp, _ = self.prescribed(t)
        return np.linalg.lstsq(self.T, dE - self.P @ dp, rcond=None)[0]

    def fold_angles(self, q, E):
        """{revolute: fold angle, rad} at the state whose exchanged coordinates are E.

        Args:
            q: (n_q,) generalized coordinates.
            E: (n,) the exchanged coordinates at q, global frame.
        """
        return self.top.fold_angles(E)

    # ---------------------------------------------------------------- monitors
    def element_curvatures(self, q):
        """None: the ANCF element's own flap curvature is the cubic field of its nodal vectors, which the strain
        gauges read from E (structure_fmu.sensors).

        Args:
            q: (n_q,) generalized coordinates.
        """
        return None

    def potential_energy(self, q, E, latched, angles):
        """Elastic + gravity potential + actuator spring potential, J.

        The energy monitor is this plus 1/2 dE^T M_E dE.

        Args:
            q: (n_q,) generalized coordinates.
            E: (n,) the exchanged coordinates at q, global frame.
            latched: {hinge: latched}.
            angles: {hinge: fold angle, rad} of E (`StructureTopology.fold_angles`).
        """
        law, table = self._law
        elastic = float(np.sum(law.elastic_energy(E[self.dofs], self.lengths, table))) if self.flexible else 0.0
        potential = -float(np.dot(self.gravity_E, E))
        spring = 0.0
        for h in self.hinges:
            spring += actuator_energy(h, angles[h.name], latched.get(h.name, False))
        return elastic + potential + spring


def element_sections(topology):
    """The Sections of the elements: (n_elements, g) nested lists, at the g = element.VARYING_POINTS Gauss points of
    each element (structure_fmu.section.section_at), when a section varies along its body or a swept planform moves
    the chord about the reference line (the mass follows the chord: its first moment and chord inertia vary); else
    (n_elements,) each element's body's one Section.

    Args:
        topology: the StructureTopology.
    """
    bodies = topology.bodies
    if not any(_varies(body) for body in bodies.values()):
        return [bodies[b].section for b in topology.element_body]
    xi, _ = element.gauss_rule(element.VARYING_POINTS)
    fractions, specs, leads = [], [], []
    for k, name in enumerate(topology.element_body):
        body = bodies[name]
        index, count = list(body.elements).index(k), len(body.elements)
        fraction = (index + xi) / count
        fractions.append(fraction)
        specs.append(body.section_spec)
        leads.append(body.planform.leading_edge(fraction * body.length) if _swept(body) else [None] * len(xi))
    return element_points(specs, fractions, leads)


def _swept(body) -> bool:
    """Whether the body's planform moves its chord about the reference line: the leading edge is not at the fraction
    axis_position of every chord (a sweep_deg other than the one that keeps it there, fmu_common.planform)."""
    planform = body.planform
    if planform is None:
        return False
    kept = -planform.axis_position * planform.chord_tip
    return abs(planform.leading_edge_tip - kept) > 1e-12 * planform.chord_tip


def _varies(body) -> bool:
    """Whether the body's section differs between Gauss points: tip values given, or a swept planform."""
    return (body.section_spec is not None and varies(body.section_spec)) or _swept(body)


def section_property(sections, name):
    """The property `name` of a Section (its attribute) for every element: (n,) (or (n, k) for a tuple) from the
    per-element Sections of `element_sections`, (n, g) (or (n, g, k)) from Sections at Gauss points.

    Args:
        sections: `element_sections`'s list.
        name: an attribute of structure_fmu.section.Section (mass_per_length, stiffness, ...).
    """
    return np.array([[getattr(p, name) for p in row] if isinstance(row, list) else getattr(row, name)
                     for row in sections])


def _check_finite_masses(topology, element_mass, gravity_E, gravity) -> None:
    """SceneError naming the key unless every element's mass matrix and every weight are finite, after the
    products of finite scene values that give them (rho A L, rho A L^3; m g of the elements and lumped masses).

    Args:
        topology: the StructureTopology.
        element_mass: (elements, 18, 18) element mass matrices, kg (and kg m, kg m^2).
        gravity_E: (n,) generalized gravity force on E, N.
        gravity: (3,) m/s^2.
    """
    for body, mass in zip(topology.element_body, element_mass):
        if not np.all(np.isfinite(mass)):
            raise SceneError(f"structure.bodies.{body}.length", topology.bodies[body].length,
                             "a length whose elements have a finite mass matrix with the section's mass per length "
                             "(rho A L and rho A L^3 overflow)")
    if not np.all(np.isfinite(gravity_E)):
        raise SceneError("structure.gravity", gravity.tolist(), "a gravity whose weights m g of the bodies and "
                                                                "masses are finite numbers (they overflow)")


def _block(idx, n):
    """(k, k) flat positions i n + j of the block idx x idx of an (n, n) matrix.

    Args:
        idx: (k,) indices into E.
        n: the number of coordinates of E.
    """
    idx = np.asarray(idx, dtype=np.intp)
    return (idx[:, None] * n + idx[None, :]).ravel()


REDUNDANCY_TOLERANCE = 1e-8
"""A row whose gradient is within this (relative) of the span of the rows before it is redundant."""


def independent_rows(jacobian):
    """Indices of the rows of `jacobian` that are independent of the rows before them, in order.

    Modified Gram-Schmidt, twice. A planar closed loop of rigid bodies closed by the rows X_a - X_b = 0
    (pins.py) repeats one of them (the out-of-plane one) at every configuration; judged at t = 0, so a
    mechanism must not start in a singular configuration (the constraint_residual monitor, which includes
    the rows left out, shows it if it did).

    Args:
        jacobian: (m, n_q) constraint Jacobian.

    Returns:
        (k,) int row indices.
    """
    rows = np.asarray(jacobian, dtype=float)
    basis = np.zeros_like(rows)             # orthonormal rows spanning the kept ones
    keep = []
    for i, row in enumerate(rows):
        v = row.copy()
        for _ in range(2):
            v -= basis[:len(keep)].T @ (basis[:len(keep)] @ v)
        norm = np.linalg.norm(v)
        if norm > REDUNDANCY_TOLERANCE * max(np.linalg.norm(row), np.finfo(float).tiny):
            basis[len(keep)] = v / norm
            keep.append(i)
    return np.array(keep, dtype=int)
