"""The strain-based structural model: B^T M B q'' + B^T M dB/dt q' + K q + Psi_q^T lambda = B^T F
(Otsuka et al. 2022, Eq. 9).

Generalized coordinates q, body after body (parents first): the joint parameters eta at the body's root
(Otsuka et al. 2022, Eq. 11: theta of a revolute joint, four Euler parameters of a ball joint, nine direction
cosines of a universal joint; none for a clamp or a driven root), then per element the constant strains
[eps_x, kappa_x, kappa_y, kappa_z] (Eq. 12). The nodal vectors follow from the recursion (Eqs. 7-8,
structure_fmu.strain_kinematics); the exchanged coordinates E keep r, r_x, r_y of every node, so the unit
exchanges exactly what the ANCF units do, on the same node slots.

Inertia and every force but the elastic one are those of the ANCF model on E (structure_fmu.model): the
constant ANCF mass M_E and the loads, gravity, actuators and damping act on E and reach q through
B = dE/dq (Otsuka et al. 2022, Eq. 9 and Appendix A: Q -> B^T Q). The elastic force is K q with the constant
diagonal K = ds diag(EA, GJ, EI_yy, EI_zz) per element. What remains as constraints are the joint parameters'
own (Psi: |zeta| = 1, Eq. 22; mu orthonormal with the universal joint's axis product, Eq. 18), kept by
Lagrange multipliers in the integrators (index-1 with projection for RK4, index-3 for generalized-alpha).
"""
import numpy as np
import scipy.sparse
from scipy.linalg import cho_factor, cho_solve

from fmu_common.errors import SceneError
from fmu_common.vectors import cross

from . import element
from . import strain_kinematics as sk
from .model import StructureModel
from .motion import SpinUp

SUPPORTED_ROOTS = ("clamp", "pin", "driven", "revolute", "ball", "universal")
"""Every joint type of the scene schema holds a root here; only a body without a root joint has no parameters."""


class _Root:
    """How a body's root node is held: kind ('fixed', 'revolute', 'ball', 'universal', 'driven'), the parent
    body (None: the ground), its axis, orientation, child axis and initial fold angle (rad)
    (fmu_common.topology.JointLine), the ground point (m), the offset of its parameters in q, and the SpinUp
    law of a driven root."""

    def __init__(self, kind, parent, axis, orientation, point, offset, motion=None, child_axis=None,
                 initial_angle=0.0):
        self.kind, self.parent, self.axis, self.orientation = kind, parent, axis, orientation
        self.child_axis, self.initial_angle = child_axis, initial_angle
        self.point, self.offset, self.motion = point, offset, motion
        self.size = 0 if kind == "driven" else sk.PARAMETERS[kind]
        self.parent_node = -1           # the parent's tip node (set by the model), -1: the ground
        self._ground = np.zeros((3, 4, 3))
        self._ground[0] = self.ground()

    def ground(self):
        """H (4, 3) of the ground the root hangs from: its point and the global axes."""
        return np.vstack([self.point, np.eye(3)])

    def terms(self, q, dq, t):
        """strain_kinematics.RootTerms at q, q', t: a driven root hangs from its own moving ground with c = I."""
        if self.kind == "driven":
            zero = np.zeros((3, 3))
            return sk.RootTerms(np.eye(3), np.zeros((0, 3, 3)), zero, zero, self.offset, np.stack(self.driven(t)))
        eta, rate = q[self.offset:self.offset + self.size], dq[self.offset:self.offset + self.size]
        return sk.RootTerms(*sk.joint_terms(self.kind, eta, rate, self.axis, self.orientation), self.offset,
                            self._ground)

    def driven(self, t):
        """(H, dH/dt, d2H/dt2) (4, 3) each of a driven root at t (s): x(t) = pivot + R (x0 - pivot) + h and
        g(t) = R g0 of the motion law (structure_fmu.motion)."""
        k = self.motion.kinematics(t)
        frame = (k.rotation @ self.orientation).T                  # rows r_x, r_y, r_z
        arm = k.rotation @ (self.point - self.motion.pivot)
        spin = lambda v: cross(k.alpha, v) + cross(k.omega, cross(k.omega, v))
        return (np.vstack([self.motion.pivot + arm + k.translation, frame]),
                np.vstack([cross(k.omega, arm) + k.velocity, cross(k.omega, frame)]),
                np.vstack([spin(arm) + k.acceleration, spin(frame)]))


class StrainBasedModel(StructureModel):
    """The StructureModel's inertia and forces on E, over the strain-based coordinates q (see the module).

    Args:
        topology: the StructureTopology.
        gravity: (3,) m/s^2, global frame.
        hinge_parameters: {hinge: {parameter: value}} replacing its actuator's; None: the topology's.
        body_damping: {body: alpha, 1/s}; None: the topology's.
        damping_model: "deformation" or "mass-proportional" (StructureModel).
    """

    ancf_elastic = False      # the elastic force is K q (Otsuka et al. 2022, Eq. 9)

    def __init__(self, topology, gravity, hinge_parameters=None, body_damping=None, damping_model="deformation"):
        super().__init__(topology, gravity, hinge_parameters, body_damping, damping_model)
        self._dropped = np.zeros(0, int)     # its own joint rows (_JointConstraints) are all independent
        self.roots, self.strain_slices, eta0 = {}, {}, []
        offset = 0
        for name, body in topology.bodies.items():
            root = self._root(name, body, offset)
            if root.parent is not None:
                root.parent_node = topology.bodies[root.parent].nodes[-1]
            self.roots[name] = root
            eta0.append(sk.initial_parameters(root.kind, root.initial_angle, root.orientation)
                        if root.size else np.zeros(0))
            offset += root.size
            n_el = len(body.elements)
            self.strain_slices[name] = slice(offset, offset + sk.STRAINS * n_el)
            eta0.append(np.zeros(sk.STRAINS * n_el))
            offset += sk.STRAINS * n_el
        self.n_q = offset
        self._q0 = np.concatenate(eta0)
        # K = ds diag(EA, GJ, EI_yy, EI_zz) per element (Otsuka et al. 2022, Eq. 9's constant K); a section that
        # varies along the span gives the element's integral of each stiffness, exact on the Gauss points of
        # self.stiffness (the strains being constant over the element, int K(x) xi^2 dx = xi^2 int K dx)
        stiffness = self.stiffness
        if stiffness.ndim == 3:
            stiffness = np.einsum("ngk,g->nk", stiffness, element.gauss_rule(stiffness.shape[1])[1])
        self.stiffness_diagonal = np.zeros(self.n_q)
        for name, body in topology.bodies.items():
            k = stiffness[body.elements][:, [0, 3, 1, 2]]       # EA, GJ, EI_yy, EI_zz
            self.stiffness_diagonal[self.strain_slices[name]] = (k * self.lengths[body.elements, None]).ravel()
        self._element_columns = {}       # the column of each element's first strain in q, by body
        for name, body in topology.bodies.items():
            first, first_element = body.nodes[0], body.elements[0] if body.elements else 0
            if (list(body.nodes) != list(range(first, first + len(body.elements) + 1))
                    or list(body.elements) != list(range(first_element, first_element + len(body.elements)))
                    or any(tuple(topology.element_nodes[e]) != (body.nodes[k], body.nodes[k + 1])
                           for k, e in enumerate(body.elements))):
                raise ValueError(f"body {name}: its nodes and elements are not consecutive (strain-based sweep)")
            start = self.strain_slices[name].start
            self._element_columns[name] = start + sk.STRAINS * np.arange(len(body.elements), dtype=np.int64)
        # generalized-alpha's convergence test on ds eps_x (m) and ds kappa (rad), an element's elongation and
        # relative rotation, in place of strains in 1/m: the units of the ANCF coordinates' tolerance
        self.newton_weights = np.ones(self.n_q)
        for name, body in topology.bodies.items():
            self.newton_weights[self.strain_slices[name]] = np.repeat(self.lengths[body.elements], sk.STRAINS)
        self._body_lines = [sk.BodyLine(body.nodes[0], body.elements[0] if body.elements else 0,
                                        self.roots[name].parent_node, self._element_columns[name])
                            for name, body in topology.bodies.items()]
        self._strain_columns = np.zeros((len(self.lengths), sk.STRAINS), dtype=np.int64)   # q's column of xi_ep
        for name, body in topology.bodies.items():
            self._strain_columns[body.elements] = self._element_columns[name][:, None] + np.arange(sk.STRAINS)
        self._constraints = _JointConstraints(self.roots, self.n_q)
        self._mass_E_sparse = scipy.sparse.csr_array(self.mass_E)     # banded: element blocks along the bodies
        self._cache_evaluation = (None, None)
        self._cache_mass = (None, None)
        self._cache_factor = (None, None)

    # ---------------------------------------------------------------- construction
    def _root(self, name, body, offset):
        joint = self.top.root_joints.get(name)
        if joint is None:
            raise SceneError(f"structure.bodies.{name}", name, "a body held at its root by a joint: the "
                             f"strain-based fidelity supports {', '.join(SUPPORTED_ROOTS)} (a free body has none)")
        kind = joint.kind
        start = np.column_stack([body.span_axis, body.chord_axis, np.cross(body.span_axis, body.chord_axis)])
        if kind == "clamp":
            return _Root("fixed", None, None, start, body.root, offset)
        if kind == "driven":   # law spin_up about the root's chord axis (Otsuka et al. 2019, Eq. 27)
            return _Root("driven", None, None, start, body.root, offset,
                         SpinUp(body.chord_axis, body.root, joint.omega, joint.ramp_time))
        if kind == "pin" and joint.axis == "free":   # a ball joint to the ground
            return _Root("ball", None, np.zeros(3), start, body.root, offset)
        if kind == "pin":      # a revolute joint to the ground about the root's chord or section normal
            axis = body.chord_axis if joint.axis == "chord" else start[:, 2]
            return _Root("revolute", None, axis, start, body.root, offset)
        line = next(j for j in self.top.joint_lines if j.child == name)
        return _Root(kind, line.parent, line.axis, line.orientation, body.root, offset, child_axis=line.child_axis,
                     initial_angle=line.initial_angle)

    # ---------------------------------------------------------------- kinematics
    def _evaluate(self, q, dq, t):
        """(H, dH/dq, dH/dt at fixed q, dH/dt, d2H/dt2 at q'' = 0) at q, q', t: the nodal vectors (n_nodes, 4, 3;
        dH/dq (n_nodes, 4, 3, n_q)) by one sweep along each body, parents first (Otsuka et al. 2022, Eqs. 7-8);
        cached for the last q, q', t."""
        key = (q.tobytes(), dq.tobytes(), t)
        if self._cache_evaluation[0] == key:
            return self._cache_evaluation[1]
        transfers = sk.transfers(q[self._strain_columns], dq[self._strain_columns], self.lengths)
        value = sk.kinematics(self._body_lines, [root.terms(q, dq, t) for root in self.roots.values()], transfers,
                              dq, self.top.n_nodes)
        self._cache_evaluation = (key, value)
        return value

    def _configuration(self, q, t):
        """(H (n_nodes, 4, 3), dH/dq (n_nodes, 4, 3, n_q), dH/dt at fixed q (n_nodes, 4, 3)) at q, t: those of the
        last evaluation when it was at q, t (whatever its q'), else of one at q' = 0."""
        key = self._cache_evaluation[0]
        if key is None or key[0] != q.tobytes() or key[2] != t:
            return self._evaluate(q, np.zeros_like(q), t)[:3]
        return self._cache_evaluation[1][:3]

    def _motion(self, q, dq, t):
        """(E, dE, a (n,)): exchanged coordinates, their rates and d2E/dt2 at q'' = 0 (dB/dt q' plus a driven
        root's acceleration)."""
        H, _, _, Hd, Hdd = self._evaluate(q, dq, t)
        return _exchanged(H), _exchanged(Hd), _exchanged(Hdd)

    def acceleration_E(self, q, dq, ddq, t):
        """d2E/dt2 for q'' = ddq: B q'' + dB/dt q' (plus a driven root's acceleration).

        Args:
            q: (n_q,) strain-based coordinates.
            dq: (n_q,) their rates, per s.
            ddq: (n_q,) their accelerations, per s^2.
            t: time, s.

        Returns:
            (n,) per s^2, global frame.
        """
        return self.velocity_map(q, t) @ ddq + self._motion(q, dq, t)[2]

    def velocity_map(self, q, t):
        """B = dE/dq at q.

        Otsuka et al. 2022, Eq. 9

        Args:
            q: (n_q,) strain-based coordinates.
            t: time, s.

        Returns:
            (n, n_q).
        """
        dH = self._configuration(q, t)[1]
        return dH[:, :3].reshape(-1, self.n_q)

    # ---------------------------------------------------------------- the integrators' interface
    def initial_coordinates(self):
        return self._q0.copy()

    def coordinates(self, q, dq, t):
        """E, dE/dt and None (the prescribed acceleration is inside the force, see force_q).

        Args:
            q: (n_q,) strain-based coordinates.
            dq: (n_q,) their rates, per s.
            t: time, s.
        """
        E, dE, _ = self._motion(q, dq, t)
        return E, dE, None

    def mass_matrix(self, q, t):
        """B^T M_E B at q and t (t matters with a driven root); cached for the last q, t.

        Otsuka et al. 2022, Eq. 9

        Args:
            q: (n_q,) strain-based coordinates.
            t: time, s.

        Returns:
            (n_q, n_q).
        """
        key = (q.tobytes(), t)
        if self._cache_mass[0] != key:
            B = self.velocity_map(q, t)
            self._cache_mass = (key, B.T @ (self._mass_E_sparse @ B))
            self._cache_factor = (None, None)
        return self._cache_mass[1]

    def mass_product(self, q, t, x):
        """B^T (M_E (B x)) at q and t: M x without forming M (generalized-alpha's residual, once per Newton
        iteration; M itself is only needed where the iteration matrix is refreshed).

        Otsuka et al. 2022, Eq. 9

        Args:
            q: (n_q,) strain-based coordinates.
            t: time, s.
            x: (n_q,) accelerations, per s^2.

        Returns:
            (n_q,).
        """
        B = self.velocity_map(q, t)
        return B.T @ (self._mass_E_sparse @ (B @ x))

    def _factor(self, q, t):
        """The Cholesky factor of M + Psi_q^T w Psi_q, cached for the last q, t. The direction cosines of a
        universal joint make M singular: E carries no r_z, so a change of mu's third row alone moves no
        mass. Adding the constraint term (w = the mean diagonal of M) makes the matrix definite without
        changing q'' (the constrained solution satisfies Psi_q q'' = gamma, so the added term only shifts the
        multipliers by w gamma) nor the metric of the projection on the constraint manifold's tangent."""
        key = (q.tobytes(), t)
        if self._cache_factor[0] != key:
            M = self.mass_matrix(q, t)
            regular = M
            if self._constraints.count:
                G = self._constraints.jacobian(q)
                regular = M + np.trace(M) / len(M) * (G.T @ G)
            # unchecked: a state gone NaN reaches the solver's divergence check, which names the time
            self._cache_factor = (key, cho_factor(regular, check_finite=False))
        return self._cache_factor[1]

    def solve_mass(self, q, t, b):
        """(M + Psi_q^T w Psi_q)^-1 b at q and t: the integrators' index-1 solve and projection metric (see
        _factor).

        Args:
            q: (n_q,) strain-based coordinates.
            t: time, s.
            b: (n_q,) or (n_q, k).

        Returns:
            the shape of b.
        """
        return cho_solve(self._factor(q, t), b, check_finite=False)

    def force_q(self, q, dq, t, Q, latched):
        """B^T (F_E - M_E dB/dt q') - K q and the current E, dE; no separate prescribed term.

        Otsuka et al. 2022, Eq. 9

        F_E is the ANCF model's force on E (gravity, loads, actuators, damping, Q).

        Args:
            q: (n_q,) strain-based coordinates.
            dq: (n_q,) their rates, per s.
            t: time, s.
            Q: (n,) generalized external force on E, N and N m, global frame.
            latched: {hinge: latched}.

        Returns:
            (force (n_q,), E (n,), dE (n,), None).
        """
        E, dE, a = self._motion(q, dq, t)
        B = self.velocity_map(q, t)
        F = B.T @ (self.force_E(E, dE, t, Q, latched) - self._mass_E_sparse @ a) - self.stiffness_diagonal * q
        return F, E, dE, None

    @property
    def constraint_count(self):
        return self._constraints.count

    def constraint_residual(self, q, E):
        return self._constraints.residual(q)

    def constraint_jacobian(self, q, E):
        return self._constraints.jacobian(q)

    def constraint_rate(self, q, dq, E, dE):
        return self._constraints.jacobian(q) @ dq

    def constraint_gamma(self, q, dq, E, dE, ddp):
        return -self._constraints.velocity_quadratic(dq)

    def iteration_matrix(self, t, q, dq, latched, lam, beta_p, gamma_p):
        """Generalized-alpha's matrix with the tangent of the forces on E mapped by B.

        beta' M + B^T (gamma' C_E + K_E) B + K + sum lambda_i Psi_i,qq (the derivatives of B itself left out: modified
        Newton).

        Args:
            t: time, s.
            q: (n_q,) strain-based coordinates.
            dq: (n_q,) their rates, per s.
            latched: {hinge: latched}.
            lam: the constraint multipliers.
            beta_p: beta', 1/s^2.
            gamma_p: gamma', 1/s.

        Returns:
            (S (n_q, n_q), E (n,)).
        """
        E, dE, _ = self._motion(q, dq, t)
        B = self.velocity_map(q, t)
        K_E, C_E = self.tangent_E(E, dE, latched)
        tangent = scipy.sparse.csr_array(gamma_p * C_E + K_E)     # banded like M_E: element and hinge blocks
        S = beta_p * self.mass_matrix(q, t) + B.T @ (tangent @ B) + np.diag(self.stiffness_diagonal)
        if self._constraints.count:
            S = S + self._constraints.hessian_sum(lam)
        return S, E

    def iteration_pattern(self):
        """None: the configuration-dependent mass B^T M_E B couples every coordinate of a body and its
        descendants, so the iteration matrix is factorized dense (structure_fmu.iteration_lu)."""
        return None

    def rates_of(self, q, dE, t):
        B = self.velocity_map(q, t)
        Ht = self._configuration(q, t)[2]
        return np.linalg.lstsq(B, dE - _exchanged(Ht), rcond=None)[0]

    # ---------------------------------------------------------------- monitors
    def element_curvatures(self, q):
        """Each element's own flap curvature, the constant -kappa_y / (1 + eps_x) (1/m, by element): the curvature
        of its reference line toward +n per unit deformed length, as structure_fmu.element.flap_curvature measures
        it (r'' = (1 + eps_x) r_x' = -(1 + eps_x) kappa_y r_z, Otsuka et al. 2022, Eq. 6), which the strain gauges
        reading the model's curvature take (Otsuka et al. 2022, Sec. 5: h/2 x kappa_y).

        Args:
            q: (n_q,) strain-based coordinates.

        Returns:
            (n_elements,) 1/m.
        """
        strains = q[self._strain_columns]
        return -strains[:, 2] / (1.0 + strains[:, 0])

    def potential_energy(self, q, E, latched, angles):
        """ANCF model's gravity and actuator potential plus the strain energy 1/2 q^T K q, J.

        Args:
            q: (n_q,) strain-based coordinates.
            E: (n,) the exchanged coordinates at q, global frame.
            latched: {hinge: latched}.
            angles: {hinge: fold angle, rad} of E.
        """
        return super().potential_energy(q, E, latched, angles) + 0.5 * float(q @ (self.stiffness_diagonal * q))



def _exchanged(H):
    """E (9 n_nodes,) from nodal H (n_nodes, 4, 3): r, r_x, r_y of every node."""
    return H[:, :3].reshape(-1)


class _JointConstraints:
    """The joint parameters' constraints Psi_i(q) = 1/2 q^T H_i q + g_i . q + c_i (Otsuka et al. 2022, Eqs. 18,
    22): quadratic, so the Jacobian is linear in q (dense: a few rows)."""

    def __init__(self, roots, n_q):
        rows = []      # (hessian entries [(i, j, value)], linear entries [(i, value)], constant)
        for root in roots.values():
            o = root.offset
            if root.kind == "ball":          # |zeta|^2 - 1 (Eq. 22)
                rows.append(([(o + k, o + k, 2.0) for k in range(4)], [], -1.0))
            elif root.kind == "universal":   # rows of mu orthonormal, the cross's axes perpendicular (Eq. 18)
                mu = lambda a, b, o=o: o + 3 * a + b
                for a in range(3):
                    rows.append(([(mu(a, k), mu(a, k), 2.0) for k in range(3)], [], -1.0))
                for a, b in ((0, 1), (1, 2), (2, 0)):
                    rows.append(([(mu(a, k), mu(b, k), 1.0) for k in range(3)]
                                 + [(mu(b, k), mu(a, k), 1.0) for k in range(3)], [], 0.0))
                # (F_parent a) . (F_child b) = b^T mu a with F_child = F_parent mu^T
                rows.append(([], [(mu(i, j), root.child_axis[i] * root.axis[j]) for i in range(3) for j in range(3)],
                             0.0))
        self.count = len(rows)
        self.hessians = np.zeros((self.count, n_q, n_q))
        self.linear = np.zeros((self.count, n_q))
        self.constant = np.zeros(self.count)
        for r, (quadratic, linear, constant) in enumerate(rows):
            for i, j, value in quadratic:
                self.hessians[r, i, j] += value
            for i, value in linear:
                self.linear[r, i] += value
            self.constant[r] = constant

    def residual(self, q):
        return 0.5 * np.einsum("rij,i,j->r", self.hessians, q, q) + self.linear @ q + self.constant

    def jacobian(self, q):
        return self.hessians @ q + self.linear

    def velocity_quadratic(self, dq):
        """dq^T H_i dq: the part of d2Psi/dt2 that is not Psi_q q''."""
        return np.einsum("rij,i,j->r", self.hessians, dq, dq)

    def hessian_sum(self, multipliers):
        return np.einsum("r,rij->ij", multipliers, self.hessians)
