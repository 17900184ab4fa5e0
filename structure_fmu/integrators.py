"""Time integrators for M(q) q'' + Phi_q^T lambda = F(q, q', t), Phi(q, t) = 0.

The model (structure_fmu.model.StructureModel, constant M; structure_fmu.strain_model.StrainBasedModel,
configuration-dependent M) gives the mass (`mass_matrix`, `mass_product`, `solve_mass`), the force (`force_q`), the
constraints (`constraint_*`) and generalized-alpha's iteration matrix (`iteration_matrix`).

* RK4: explicit 4th-order Runge-Kutta on the index-1 (acceleration level) equations, the scheme of Otsuka et al. 2019
  Sec. VI, with constraint stabilization by mass-weighted projection of q and q' onto the constraint
  manifold after each step.
* GeneralizedAlpha: the generalized-alpha method of Peng et al. 2019, Eqs. (23)-(25) with spectral radius rho_inf, in
  the index-3 form of Arnold & Bruls (2007) for constrained systems: Newton iterations on q_{n+1} and
  lambda_{n+1} with the iteration matrix beta' M + gamma' C_t + K_t (Peng et al. 2019, Fig. 3), constraint rows scaled
  by beta' for conditioning. The iteration matrix is factorized banded where its sparsity allows
  (iteration_lu.py), reused across steps (modified Newton) and refreshed when convergence slows; the iteration
  stops when the error left, estimated from the observed contraction rate, is below the tolerance (Hairer and
  Wanner 1996, Sec. IV.8), which ends most steps on a freshly factorized matrix after one correction.
"""
import math
from dataclasses import dataclass, field, replace
from typing import Protocol

import numpy as np
from scipy.linalg.lapack import dposv

from fmu_common.errors import SceneError, SolverDiverged

from . import iteration_lu, step_kernel
from .iteration_lu import IterationLU


@dataclass
class State:
    """Complete integrator state (copied by StructureSolver.get_state)."""

    t: float
    q: np.ndarray
    dq: np.ndarray
    ddq: np.ndarray
    accel: np.ndarray            # generalized-alpha auxiliary acceleration a (Peng et al. 2019, Eq. 24)
    multipliers: np.ndarray
    latched: dict = field(default_factory=dict)
    latch_times: dict = field(default_factory=dict)
    work: float = 0.0            # J, work of the external forces since t = 0 (StructureSolver.advance)

    def copy(self):
        """A copy that shares no array or dict with this state."""
        return replace(self, q=self.q.copy(), dq=self.dq.copy(), ddq=self.ddq.copy(), accel=self.accel.copy(),
                       multipliers=self.multipliers.copy(), latched=dict(self.latched),
                       latch_times=dict(self.latch_times))


def _schur_solve(S, b):
    """x = S^-1 b for the symmetric positive definite Schur complement S = G_q M_q^-1 G_q^T (LAPACK posv:
    a tenth of numpy.linalg.solve's overhead on these few-row systems); LinAlgError if S is singular."""
    _, x, info = dposv(S, b)
    if info != 0:
        raise np.linalg.LinAlgError(f"constraint Jacobian rank deficient (Schur complement, LAPACK info {info})")
    return x


def constrained_accelerations(model, t, q, dq, Q, latched):
    """q'' and lambda from the index-1 equations by a Schur complement on the mass matrix.

    Args:
        model: the StructuralModel (structure_fmu.fidelities).
        t: time, s.
        q: (n_q,) generalized coordinates.
        dq: (n_q,) their rates, per s.
        Q: (n,) generalized external force on the exchanged coordinates E, N and N m, global frame.
        latched: {hinge: latched} (State.latched).

    Returns:
        (q'' (n_q,) per s^2, lambda (m,) the constraint multipliers).
    """
    kernel = step_kernel.kernel_for(model)
    if kernel is not None:                  # the same solve in one compiled call
        kernel.prepare((t,), Q, latched)
        return kernel.accelerations(q, dq)
    F, E, dE, ddp = model.force_q(q, dq, t, Q, latched)
    if model.constraint_count == 0:
        return model.solve_mass(q, t, F), np.zeros(0)
    Gq = model.constraint_jacobian(q, E)
    gamma = model.constraint_gamma(q, dq, E, dE, ddp)
    MinvF = model.solve_mass(q, t, F)
    MinvGt = model.solve_mass(q, t, Gq.T)
    # np.dot rather than @: a third of the operator's overhead on these few-row arrays (4-5 calls per step)
    lam = _schur_solve(np.dot(Gq, MinvGt), np.dot(Gq, MinvF) - gamma)
    return MinvF - np.dot(MinvGt, lam), lam


def project(model, t, q, dq, iterations=4, tol=1e-13):
    """Mass-weighted projection of q onto Phi = 0 and of q' onto dPhi/dt = 0.

    Args:
        model: the StructuralModel (structure_fmu.fidelities).
        t: time, s.
        q: (n_q,) generalized coordinates.
        dq: (n_q,) their rates, per s.
        iterations: at most this many Newton projections of q.
        tol: |Phi_i| below which q is on the constraints, in each row's unit.

    Returns:
        (q (n_q,), q' (n_q,)) projected.
    """
    if model.constraint_count == 0:
        return q, dq
    for _ in range(iterations):
        E, dE, _ = model.coordinates(q, dq, t)
        phi = model.constraint_residual(q, E)
        # every |Phi_i| < tol (false for NaN), by float comparisons: a third of numpy's abs().max() on few rows
        if all(-tol < value < tol for value in phi.tolist()):
            break
        Gq = model.constraint_jacobian(q, E)
        MinvGt = model.solve_mass(q, t, Gq.T)
        q = q - MinvGt @ _schur_solve(Gq @ MinvGt, phi)
    else:
        E, dE, _ = model.coordinates(q, dq, t)
    Gq = model.constraint_jacobian(q, E)
    MinvGt = model.solve_mass(q, t, Gq.T)
    dphi = model.constraint_rate(q, dq, E, dE)
    return q, dq - MinvGt @ _schur_solve(Gq @ MinvGt, dphi)


class RK4:
    """Explicit RK4 with post-step constraint projection (Otsuka et al. 2019, Sec. VI). It keeps nothing between
    steps (`memory` None, `reset` does nothing) but the model's compiled step (step_kernel.py), where it has one."""

    name = "rk4"
    divergence_hint = ("reduce structure.step below the explicit stability limit, or use structure.integrator = "
                       "\"generalized-alpha\"")
    memory = None

    def reset(self):
        """Nothing to forget: every step starts from the state alone."""

    def takes_steps(self, model):
        """False: RK4 takes its steps one call each (`Integrator.takes_steps`).

        Args:
            model: the StructuralModel.
        """
        return False

    def initialize(self, model, state, Q):
        """The state's accelerations and multipliers at its start, from the index-1 equations.

        Args:
            model: the StructuralModel.
            state: the State at the start; updated in place and returned.
            Q: (n,) generalized external force on E, N and N m, global frame.
        """
        state.ddq, state.multipliers = constrained_accelerations(model, state.t, state.q, state.dq, Q, state.latched)
        state.accel = state.ddq.copy()
        return state

    def step(self, model, state, h, Q):
        """The state at t + h: one RK4 step followed by the constraint projection.

        Args:
            model: the StructuralModel.
            state: the State at t (not modified).
            h: step, s.
            Q: (n,) generalized external force on E over the step, N and N m, global frame.
        """
        t, q, v = state.t, state.q, state.dq
        half = 0.5 * h
        kernel = step_kernel.kernel_for(model)
        if kernel is not None:      # the same step in one compiled call
            kernel.prepare((t, t + half, t + h), Q, state.latched)
            q_new, v_new, a1, lam = kernel.rk4_step(q, v, h)
            return State(t + h, q_new, v_new, a1, a1, lam, state.latched, state.latch_times)
        f = lambda tt, qq, vv: constrained_accelerations(model, tt, qq, vv, Q, state.latched)
        a1, lam = f(t, q, v)
        v2 = v + half * a1
        a2 = f(t + half, q + half * v, v2)[0]
        v3 = v + half * a2
        a3 = f(t + half, q + half * v2, v3)[0]
        v4 = v + h * a3
        a4 = f(t + h, q + h * v3, v4)[0]
        # the weights h/6 (1, 2, 2, 1) with the stage rates v_i = v + c_i h a_{i-1} substituted:
        # v + 2 v2 + 2 v3 + v4 = 6 v + h (a1 + a2 + a3)
        a23 = a2 + a3
        q_new = q + h * v + h * h / 6 * (a1 + a23)
        v_new = v + h / 6 * (a1 + a4 + 2.0 * a23)
        q_new, v_new = project(model, t + h, q_new, v_new)
        return State(t + h, q_new, v_new, a1, a1, lam, state.latched, state.latch_times)


VELOCITY_TOLERANCE = 1e-8
"""Relative tolerance of generalized-alpha's Newton iteration on q' (on q it is GeneralizedAlpha.tol).
Measured: a damped spinning plate then decays as exp(-alpha t) to 1e-4 over 1000 steps (with q alone at
1e-9: 6e-4, tests/units/test_damping.py), for about a third more iterations on deploy_flexible."""


START_DISPLACEMENT = 1.0
"""Bound on h_s^2 max|q''_0| / 2 in the units of the Newton tolerance (m and 1: the ANCF positions and gradients, of
unit length; the strain-based model's coordinates times its newton_weights) for the
short steps h_s of generalized-alpha's start-up (`start_up`). Measured on deploy_flexible in still air (energy of
the first ten steps against the start's, docs/structure.md, "Fine meshes"): at 0.3-0.4 no step creates energy; on
15-30 elements per body at 1.6-3.2 the start creates 0.9-1.4% of it, at 6-7 7-11%, at 25 65% (7 elements: none at
2.0, 0.9% at 8)."""

START_DECAY = 0.01
"""The start-up lasts the short steps over which generalized-alpha damps a high-frequency component to this
fraction: rho_inf^k <= START_DECAY (`start_up`)."""


def start_up(h, acceleration, rho_inf):
    """Generalized-alpha's start-up: (d, k), the first k steps are taken as d steps h / d each (d a power of two) so
    that (h / d)^2 max|q''_0| / 2 <= START_DISPLACEMENT, for the rho_inf^k' <= START_DECAY short steps k' that damp
    the start's transient, rounded up to whole steps h (at least one; rho_inf = 1 damps nothing: one step h).
    (1, 0) when h meets the bound.

    A load applied suddenly to a structure at rest gives its element-scale modes, far above 1 / h, initial
    accelerations q''_0 that grow as the elements shorten (a point torque: as elements^3, 1.6e7 to 1.3e9 per s^2
    from 7 to 30 elements per body in deploy_flexible). Generalized-alpha starts its auxiliary acceleration at
    a_0 = q''_0 (Peng et al. 2019, Eq. 24) and carries it with the spectral radius rho_inf per step, so the
    displacement h^2 a_0 of Eq. 23 puts energy growing with it into those modes; over a shorter step it stays
    bounded.

    Args:
        h: the structure step, s.
        acceleration: max |q''_0| at the start, in the units of the Newton tolerance per s^2 (m and 1: the
            model's coordinates times its newton_weights, where it has them).
        rho_inf: generalized-alpha's spectral radius at infinite frequency.

    Returns:
        (d, k): the divisor of the step and how many steps h the start-up lasts.
    """
    ratio = h * math.sqrt(0.5 * acceleration / START_DISPLACEMENT)
    if not ratio > 1.0:
        return 1, 0
    d = 2 ** math.ceil(math.log2(ratio))
    short = math.ceil(math.log(START_DECAY) / math.log(rho_inf)) if 0.0 < rho_inf < 1.0 else 1
    return d, max(1, math.ceil(short / d))


def _failure(status, predictor, size, first, max_iterations):
    """Why a Newton iteration failed, by step_kernels.c alpha_step's status: 1 a residual not finite, 4 diverging
    (the last correction `size` against the `first`), 5 not converged within `max_iterations`."""
    if status == 1:
        return f"Newton iteration produced NaN/inf ({predictor} predictor)"
    if status == 4:
        return f"Newton iteration diverged ({predictor} predictor, correction {size:.3g} after {first:.3g})"
    return f"Newton did not converge in {max_iterations} iterations ({predictor} predictor, last correction {size:.3g})"


class _NewtonDiverging(Exception):
    """The Newton iteration of one generalized-alpha step failed (internal: step() retries, then raises
    SolverDiverged)."""


class GeneralizedAlpha:
    """Generalized-alpha for index-3 constrained systems (Arnold & Bruls).

    Peng et al. 2019, Eqs. 23-25

    Args:
        rho_inf: spectral radius at infinite frequency, 0 to 1 (1: no high-frequency dissipation).
        tol: relative tolerance of the Newton iteration on q (times the model's newton_weights, where it has them).
        max_iterations: Newton iterations of a step before it counts as diverged.
    """

    name = "generalized-alpha"
    divergence_hint = "reduce structure.step, or lower structure.rho_inf to damp high frequencies"

    def __init__(self, rho_inf=0.8, tol=1e-9, max_iterations=30):
        r = float(rho_inf)
        self.alpha_m = (2 * r - 1) / (r + 1)        # Peng et al. 2019, Eq. (25), with alpha = rho_inf
        self.alpha_f = r / (r + 1)
        self.gamma = 0.5 - self.alpha_m + self.alpha_f
        self.beta = 0.25 * (1 - self.alpha_m + self.alpha_f) ** 2
        self.rho_inf, self.tol, self.max_iterations = r, tol, max_iterations
        self._start_acceleration = 0.0   # max |q''_0| of the state initialized last, per s^2 (`start_up`)
        self._start = None               # steps h of the start-up left; None: not planned yet
        self._matrix = None          # (h, iteration_lu.Factorization) of the iteration matrix
        self._lu = None              # (model, IterationLU): how that model's iteration matrix is factorized on the
                                     # numpy path (the compiled step has its own, step_kernel.py)
        self._eta = 1.0              # error estimate factor of a first correction (`_newton`)
        self._coefficients = (math.nan, None)   # (h, `coefficients(h)`) of the last h asked
        self.newton_iterations = 0   # total, for monitoring

    def reset(self):
        """Forget the iteration matrix and the error estimate factor (a latch changed the forces)."""
        self._matrix, self._eta = None, 1.0

    @property
    def memory(self):
        """What a step starts from besides the State: the factorized iteration matrix, the first correction's
        error estimate factor (`_newton`) and the start-up left (`start_up`). Saved with the solver's state, so that
        a repeated step repeats bit for bit; the factorization is replaced, never modified, so it is kept by
        reference."""
        return self._matrix, self._eta, self._start_acceleration, self._start

    @memory.setter
    def memory(self, saved):
        self._matrix, self._eta, self._start_acceleration, self._start = saved

    def initialize(self, model, state, Q):
        """The state's accelerations and multipliers at its start, from the index-1 equations.

        Args:
            model: the StructuralModel.
            state: the State at the start; updated in place and returned.
            Q: (n,) generalized external force on E, N and N m, global frame.
        """
        state.ddq, state.multipliers = constrained_accelerations(model, state.t, state.q, state.dq, Q, state.latched)
        state.accel = state.ddq.copy()
        weights = model.newton_weights      # to metres and radians where the coordinates are strains
        start = state.ddq if weights is None else weights * state.ddq
        self._start_acceleration = float(np.max(np.abs(start))) if start.size else 0.0
        self._start = None
        return state

    def _factor(self, model, t, q, dq, latched, lam, h):
        """The iteration matrix at (q, q', lambda) factorized into `_matrix` on the numpy path (the compiled step
        factorizes within its call, step_kernel.StepKernel.alpha_step)."""
        beta_p = (1 - self.alpha_m) / (h * h * self.beta * (1 - self.alpha_f))
        gamma_p = self.gamma / (h * self.beta)
        if self._lu is None or self._lu[0] is not model:
            self._lu = (model, IterationLU(len(q), model.constraint_count, model.iteration_pattern()))
        S, E = model.iteration_matrix(t, q, dq, latched, lam, beta_p, gamma_p)
        G = model.constraint_jacobian(q, E) if model.constraint_count else None
        self._matrix = (h, self._lu[1].factor(S, G, beta_p))

    def step(self, model, state, h, Q):
        """The state at t + h.

        Newton starts from the constant-acceleration predictor; if that iteration diverges it restarts from the
        displacement predictor with a fresh iteration matrix: a point torque on short elements gives the gradient
        coordinates huge initial accelerations (1e8 m/s^2 with 15 elements per body in deploy_flexible), and h^2 q''_n
        then predicts a far-off state. The first steps after `initialize` are each taken as d shorter ones where
        those accelerations ask for it (`start_up`).

        Args:
            model: the StructuralModel.
            state: the State at t (not modified).
            h: step, s.
            Q: (n,) generalized external force on E over the step, N and N m, global frame.
        """
        if self._start is None:
            self._start = start_up(h, self._start_acceleration, self.rho_inf)[1]
        if self._start == 0:
            return self._step(model, state, h, Q)
        self._start -= 1
        d = start_up(h, self._start_acceleration, self.rho_inf)[0]     # of this step (a shorter last one needs less)
        t_end = state.t + h
        for _ in range(d - 1):
            state = self._step(model, state, h / d, Q)
        return self._step(model, state, t_end - state.t, Q)     # ends at t + h exactly

    def _step(self, model, state, h, Q):
        """One step h: Newton from the acceleration predictor, else from the displacement predictor (`step`)."""
        try:
            return self._newton(model, state, h, Q, "acceleration")
        except _NewtonDiverging:
            try:
                return self._newton(model, state, h, Q, "displacement")
            except _NewtonDiverging as err:
                raise SolverDiverged(state.t, str(err), "reduce structure.step or check the scene's "
                                     "stiffness and masses") from None

    def _predictor(self, state, h, kind):
        """(q, dq, ddq, a_known) at the start of Newton: q''_{n+1} = q''_n ("acceleration") or
        q_{n+1} = q_n + h q'_n ("displacement"); a_{n+1} and the update formulas are Peng et al. 2019,
        Eqs. (23)-(24)."""
        am, af, g, b = self.alpha_m, self.alpha_f, self.gamma, self.beta
        a_known = (af * state.ddq - am * state.accel) / (1 - am)
        if kind == "acceleration":
            ddq = state.ddq.copy()
            a_new = a_known + (1 - af) / (1 - am) * ddq
        else:   # the a_{n+1} that cancels the acceleration terms of Eq. (23) for q
            a_new = -(0.5 - b) / b * state.accel
            ddq = (a_new - a_known) * (1 - am) / (1 - af)
        dq = state.dq + h * (1 - g) * state.accel + h * g * a_new          # Peng et al. 2019, Eq. (23)
        q = state.q + h * state.dq + h * h * (0.5 - b) * state.accel + h * h * b * a_new
        return q, dq, ddq, a_known

    def coefficients(self, h):
        """(beta' (1/s^2), gamma' (1/s), the predictor's 11 coefficients of `step_kernel.StepKernel.alpha_step`) of a
        step: Peng et al. 2019, Eqs. 23-25. The last is kept: the steps of a communication step share h.

        Args:
            h: the step, s.
        """
        if self._coefficients[0] != h:
            am, af, g, b = self.alpha_m, self.alpha_f, self.gamma, self.beta
            self._coefficients = (h, ((1 - am) / (h * h * b * (1 - af)), g / (h * b),
                                      (af, am, 1 - am, (1 - af) / (1 - am), h * (1 - g), h * g, h, h * h * (0.5 - b),
                                       h * h * b, -(0.5 - b) / b, 1 - af)))
        return self._coefficients[1]

    def takes_steps(self, model):
        """Whether `steps` can take the model's next steps: past the start-up, on the compiled kernels.

        Args:
            model: the StructuralModel.
        """
        return self._start == 0 and step_kernel.kernel_for(model) is not None

    def steps(self, model, state, hs, times, Q, force, power, stops, angles):
        """Steps of hs (s) from `state` in one compiled call (step_kernel.StepKernel.alpha_steps), each as `step`
        takes it and checked as StructureSolver.advance checks it, where `takes_steps`. The call stops before a step
        that needs the per-step path: a Newton iteration that fails, a check that may fail, a latch.

        Args:
            model: the StructuralModel.
            state: the State at the start (not modified).
            hs: the steps, s.
            times: their end times, s (state.t + hs[0], then each the last plus the next h).
            Q: (n,) generalized external force on E, N and N m, global frame.
            force: the external force whose power the work integrates (StructureModel.external_force_E), N and N m:
                (n,) for a model that does not vary in time, else (len(hs), n) at `times`.
            power: its power at the start, W.
            stops: (n_hinges,) each hinge's stop angle, rad, NaN where it has none or is latched.
            angles: (n_hinges,) the fold angles at the start, rad.

        Returns:
            (the step_kernel.Steps taken, the State at the last committed step or None).
        """
        kernel = step_kernel.kernel_for(model)
        terms = None                 # where the model does not vary in time, the first step's terms hold for all
        if model.varies_in_time:
            terms = kernel.step_terms(times, Q, state.latched)
        else:
            kernel.prepare((times[0],), Q, state.latched)
        rows = [self.coefficients(h) for h in hs]
        factorization = self._matrix[1] if self._matrix is not None else None
        if not isinstance(factorization, step_kernel.Factorization):    # none, or the numpy path's
            factorization = None
        control = (self.tol, VELOCITY_TOLERANCE / self.tol, self._eta, self.max_iterations,
                   self._matrix[0] if factorization is not None else math.nan, power, state.work)
        taken = kernel.alpha_steps(state, np.array(hs), np.array([row[2] for row in rows]),
                                   np.array([row[:2] for row in rows]), terms, control, factorization, force, stops,
                                   angles)
        if not taken.committed:
            return taken, None
        self._matrix = None if taken.factorization is None else (taken.matrix_h, taken.factorization)
        self._eta = taken.eta
        self.newton_iterations += taken.corrections
        q, dq, ddq, accel, lam = taken.state
        return taken, replace(state, t=times[taken.committed - 1], q=q, dq=dq, ddq=ddq, accel=accel, multipliers=lam,
                              work=taken.work)

    def _newton(self, model, state, h, Q, predictor):
        am, af = self.alpha_m, self.alpha_f
        beta_p, gamma_p, coefficients = self.coefficients(h)
        t = state.t + h
        kernel = step_kernel.kernel_for(model)
        # The matrix of an earlier step serves while it contracts fast enough (`_iterate`) and h is the same. h is
        # compared exactly: the last internal step of a communication step (t_end - t) differs from structure.step
        # by round-off, so the matrix is refreshed there and at the next step. Kept across such steps, the matrix
        # of a turning ANCF body goes stale within the step (the spin-up at 4 rad/s: 0.77 factorizations and 4.5
        # corrections per step instead of 1.0 and 1.5), and a factorization costs 5-8 corrections. A
        # factorization of the other path (restored from a state saved where $WINGSIM_KERNELS differed) is made
        # again.
        kind = iteration_lu.Factorization if kernel is None else step_kernel.Factorization
        factorized_here = (self._matrix is None or self._matrix[0] != h or predictor == "displacement"
                           or not isinstance(self._matrix[1], kind))
        if kernel is not None:        # the same step in one compiled call (step_kernel.py)
            kernel.prepare((t,), Q, state.latched)
            control = (beta_p, gamma_p, self.tol, VELOCITY_TOLERANCE / self.tol, self._eta, float(factorized_here),
                       self.max_iterations, float(predictor == "displacement"))
            status, (q, dq, ddq, accel, lam), iterations, size, first, self._eta, matrix = kernel.alpha_step(
                state, coefficients, control, None if factorized_here else self._matrix[1])
            self.newton_iterations += iterations
            if factorized_here or matrix is not self._matrix[1]:
                self._matrix = (h, matrix)
            if status:
                raise _NewtonDiverging(_failure(status, predictor, size, first, self.max_iterations))
            return replace(state, t=t, q=q, dq=dq, ddq=ddq, accel=accel, multipliers=lam)
        q, dq, ddq, a_known = self._predictor(state, h, predictor)
        lam = state.multipliers.copy()
        # the tolerance applies to q and to q' (corrections of q' are gamma' times those of q: a q-only test
        # would leave velocity errors of gamma' tol per step, growing as h shrinks)
        scale = 1.0
        if len(q):
            weights = model.newton_weights
            largest = [float(np.max(np.abs(v if weights is None else weights * v))) for v in (q, dq)]
            q_scale, dq_scale = max(1.0, largest[0]), max(1.0, largest[1])
            scale = min(q_scale, VELOCITY_TOLERANCE / self.tol * dq_scale / gamma_p)
        if factorized_here:
            self._factor(model, t, q, dq, state.latched, lam, h)
        # The error a first correction leaves is estimated as eta times it, eta = theta / (1 - theta) from the
        # contraction rate theta of an earlier step, raised to the power 0.8 at every step so that it drifts
        # back to 1 and a later step measures theta again (Hairer and Wanner 1996, Sec. IV.8). A tangent
        # factorized at the predictor makes theta small (Newton converges quadratically), so such a step whose
        # first correction is well inside the tolerance ends after one iteration. eta is measured on, and used
        # by, those steps only (a matrix reused from an earlier step contracts more slowly).
        if factorized_here:
            self._eta = max(self._eta, np.finfo(float).eps) ** 0.8
        self._iterate(model, t, Q, state.latched, q, dq, ddq, lam, h, beta_p, gamma_p, scale, factorized_here,
                      predictor)
        accel = a_known + (1 - af) / (1 - am) * ddq
        return replace(state, t=t, q=q, dq=dq, ddq=ddq, accel=accel, multipliers=lam)

    def _iterate(self, model, t, Q, latched, q, dq, ddq, lam, h, beta_p, gamma_p, scale, factorized_here,
                 predictor):
        """The Newton iteration of `_newton` on the numpy path, in place on q, q', q'' and lambda (step_kernels.c,
        alpha_step, is the same control in one compiled call)."""
        previous, first, fresh = 0.0, None, 0     # fresh: iterations since the matrix was last factorized
        rhs = np.empty(len(q) + model.constraint_count)    # `_correct`'s
        tolerance = self.tol * scale
        for iteration in range(self.max_iterations):
            size = self._correct(model, t, Q, latched, q, dq, ddq, lam, rhs, beta_p, gamma_p, predictor)
            self.newton_iterations += 1
            first = size if first is None else first
            # stop when the correction, or the error it leaves (rate/(1 - rate) times it, with the
            # observed contraction rate), is below the tolerance
            rate = size / previous if previous > 0 else 1.0
            if iteration == 1 and factorized_here and fresh == 1:     # theta on this step's own matrix
                self._eta = rate / (1 - rate) if rate < 1 else 1.0
            estimate = (self._eta if iteration == 0 and factorized_here else
                        rate / (1 - rate) if previous > 0 and rate < 0.5 else math.inf)
            if size <= tolerance or estimate * size <= tolerance:
                return
            if not np.isfinite(size) or size > 100 * max(first, tolerance):
                raise _NewtonDiverging(_failure(4, predictor, size, first, self.max_iterations))
            # a slow contraction means the matrix is no longer the tangent at the iterate (reused from an
            # earlier step, or factorized at a predictor far from the solution): refactorize it here,
            # after at least two iterations with the current one
            fresh += 1
            if fresh >= 2 and size > 0.3 * previous:
                self._factor(model, t, q, dq, latched, lam, h)
                fresh = 0
            previous = size
        raise _NewtonDiverging(_failure(5, predictor, size, first, self.max_iterations))

    def _correct(self, model, t, Q, latched, q, dq, ddq, lam, rhs, beta_p, gamma_p, predictor):
        """One Newton correction on the numpy path, in place on q, q', q'' and lambda: the residual
        rhs = [M_q q'' - F + G_q^T lambda, beta' Phi] solved with the factorized iteration matrix; returns the largest
        correction of q (times the model's newton_weights)."""
        n, m = len(q), len(lam)
        residual, scaled_phi = rhs[:n], rhs[n:]
        F, E, _, _ = model.force_q(q, dq, t, Q, latched)
        residual[:] = model.mass_product(q, t, ddq)   # M_q q'' without forming M_q where it varies
        residual -= F
        if m:
            residual += lam @ model.constraint_jacobian(q, E)
            np.multiply(model.constraint_residual(q, E), beta_p, out=scaled_phi)
        if not math.isfinite(rhs.sum()):      # any NaN or inf entry makes the sum NaN or inf
            raise _NewtonDiverging(_failure(1, predictor, math.nan, math.nan, 0))
        delta = self._matrix[1].solve(rhs)    # the Newton correction is -delta
        dq_step = delta[:n]
        q -= dq_step
        dq -= gamma_p * dq_step
        ddq -= beta_p * dq_step
        if m:
            lam -= beta_p * delta[n:]
        weights = model.newton_weights
        return float(np.max(np.abs(dq_step if weights is None else weights * dq_step))) if n else 0.0


class Integrator(Protocol):
    """What StructureSolver asks of a time integrator: `initialize` the state's accelerations at its start
    for the generalized force Q (n,), take one `step` of h (s) from a state to a new State, `reset` what it
    carries between steps (a latch changes the forces), and that carried `memory` read and restored with the
    solver's state, so that a rolled-back step repeats bit for bit; `divergence_hint` tells the user what to
    change when a step diverges; `takes_steps` says whether it takes several steps in one compiled call."""

    name: str
    divergence_hint: str
    memory: object

    def initialize(self, model, state: State, Q) -> State:
        """The state's accelerations at its start for the generalized force Q.

        Args:
            model: the StructuralModel (structure_fmu.fidelities).
            state: the State at the start.
            Q: (n,) generalized external force on E, N and N m, global frame.
        """

    def step(self, model, state: State, h: float, Q) -> State:
        """One step of h from a state to a new State.

        Args:
            model: the StructuralModel (structure_fmu.fidelities).
            state: the State at t.
            h: step, s.
            Q: (n,) generalized external force on E over the step, N and N m, global frame.
        """

    def reset(self) -> None:
        """Forget what is carried between steps (a latch changes the forces)."""

    def takes_steps(self, model) -> bool:
        """Whether the integrator's `steps` can take the model's next steps in one compiled call, each checked as
        StructureSolver checks a step (GeneralizedAlpha.steps); False where it takes them one `step` each.

        Args:
            model: the StructuralModel (structure_fmu.fidelities).
        """


INTEGRATORS = {"rk4": lambda structure: RK4(),
               "generalized-alpha": lambda structure: GeneralizedAlpha(structure.rho_inf)}
"""structure.integrator -> the Integrator built from the structure spec (fmu_common.wing_spec.StructureSpec)."""


def integrator_for(structure) -> Integrator:
    """The integrator the structure spec selects (structure.integrator, with its rho_inf).

    Args:
        structure: the structure spec (fmu_common.wing_spec.StructureSpec).
    """
    if structure.integrator not in INTEGRATORS:
        raise SceneError("structure.integrator", structure.integrator, f"one of {', '.join(map(repr, INTEGRATORS))}")
    return INTEGRATORS[structure.integrator](structure)
