"""The structure unit's step on the ANCF models in compiled calls: step_kernels.c on buffers allocated once per model.

For generalized-alpha, `StepKernel.alpha_step` takes a whole step in one C call: the predictor, the iteration matrix
formed and factorized where the step asks, the Newton corrections (the residual of the equations of motion and of
the scaled constraints, its solve with the factorized matrix, the update of q, q', q'' and lambda) with the
convergence test and the refactorizations of integrators.GeneralizedAlpha's control; `StepKernel.alpha_steps` takes
the steps of a communication step in one call, each checked as the solver checks a step, up to one the per-step path
must take; `StepKernel.correct` and `StepKernel.factor` are one correction and one factorization alone (the tests
check each against the reference). For RK4, `StepKernel.rk4_step` takes the whole step (four stages of the index-1
accelerations and the projection onto the constraints) in one call. The numpy path of model.StructureModel,
iteration_lu.IterationLU and integrators.RK4 stays the reference ($WINGSIM_KERNELS=numpy): the iteration matrix is
the same bit for bit, the residual, the accelerations and the states equal to round-off, and the Newton iterations
the same (tests/units/test_step_kernel.py).

The kernel covers the rigid and flexible ANCF bodies with prescribed motions, unit-length, orthogonality and linear
constraint rows, chord-axis hinges, and damping of either model (`unsupported` names what else a model has); any
other model takes the numpy path.
"""
import ctypes
import weakref
from dataclasses import dataclass
from pathlib import Path
from typing import NamedTuple

import numpy as np
import scipy.sparse
from scipy.linalg import cython_lapack

from fmu_common import c_library
from fmu_common.c_library import address
from fmu_common.compiled import selected

from . import element
from .iteration_lu import IterationLU
from .joints import actuator_spring, hinge_coordinates
from .model import StructureModel
from .strain_model import StrainBasedModel

C_SOURCE = Path(__file__).with_name("step_kernels.c")    # the compiled step (fmu_common.c_library)
_LONG = np.dtype(ctypes.c_long)                            # C long: 64 bits on Linux, 32 on Windows
WORK = ("E", "dE", "F", "Fq", "values", "S", "G", "rhs", "ordered", "MinvGt", "schur", "stage_q", "stage_v",
        "accelerations", "multipliers", "vector", "body_work")      # step_kernels.c's work arrays
_FIELDS = ([(name, ctypes.c_long) for name in ("n", "n_q", "m")]
           + [(name, ctypes.c_void_p) for name in ("t_ptr", "t_col", "t_val", "offset", "rate_offset", "accel_offset")]
           + [("moving", ctypes.c_long)]
           + [(name, ctypes.c_void_p) for name in ("f_constant", "r_constant", "m_ptr", "m_col", "m_val", "mass",
                                                    "mass_inverse")]
           + [("damped", ctypes.c_long)] + [(name, ctypes.c_void_p) for name in ("c_ptr", "c_col", "c_val", "damping")]
           + [("n_elements", ctypes.c_long), ("gauss", ctypes.c_long)]
           + [(name, ctypes.c_void_p) for name in ("table", "dofs", "add_elastic_force", "elastic_jacobian",
                                                    "element_scratch")]
           + [("n_hinges", ctypes.c_long), ("hinge_index", ctypes.c_void_p), ("hinge_parameters", ctypes.c_void_p)]
           + [("n_damped", ctypes.c_long)]
           + [(name, ctypes.c_void_p) for name in ("body_start", "body_size", "body_mass_offset", "body_alpha",
                                                    "body_mass")]
           + [("n_products", ctypes.c_long)]
           + [(name, ctypes.c_void_p) for name in ("row_a", "row_b", "row_coefficient", "row_constant")]
           + [("n_jacobian", ctypes.c_long)]
           + [(name, ctypes.c_void_p) for name in ("pair", "jacobian_source", "jacobian_target", "jacobian_weight")]
           + [(name, ctypes.c_void_p) for name in ("l_ptr", "l_col", "lt_ptr", "lt_col", "l_val", "l_offset",
                                                    "lt_val")]
           + [("n_values", ctypes.c_long), ("n_assembly", ctypes.c_long), ("hessian_row", ctypes.c_void_p),
              ("n_hessian", ctypes.c_long)]
           + [(name, ctypes.c_void_p) for name in ("assembly_source", "assembly_target", "assembly_weight")]
           + [(name, ctypes.c_long) for name in ("banded", "lower", "upper", "rows", "n_s", "n_g")]
           + [(name, ctypes.c_void_p) for name in ("s_target", "s_source", "g_target", "g_source", "gt_target",
                                                    "gt_source", "order", "getrf", "getrs")]
           + [(name, ctypes.c_void_p) for name in WORK] + [("nonzero", ctypes.c_void_p)])
STAGES = 3      # step_kernels.c: the times a step evaluates (generalized-alpha: its end; RK4: t, t + h/2, t + h)


class _Struct(ctypes.Structure):
    _fields_ = _FIELDS       # step_kernels.c's StepKernel, field for field


_DOUBLES = ctypes.POINTER(ctypes.c_double)


def c_kernels():
    """The C library of step_kernels.c (fmu_common.c_library), typed; None when $WINGSIM_KERNELS selects the
    numpy path (or the library can be neither found nor compiled: then one warning says why)."""
    pointer = ctypes.c_void_p
    return c_library.kernels(C_SOURCE, {
        "newton_correction": (ctypes.c_int, [ctypes.POINTER(_Struct), pointer, pointer, pointer, pointer,
                                             ctypes.c_double, ctypes.c_double, pointer, pointer, _DOUBLES]),
        "newton_factor": (ctypes.c_int, [ctypes.POINTER(_Struct), pointer, pointer, pointer, ctypes.c_double,
                                         ctypes.c_double, pointer, pointer]),
        "alpha_step": (ctypes.c_int, [ctypes.POINTER(_Struct)] + [pointer] * 13),
        "alpha_steps": (ctypes.c_int, [ctypes.POINTER(_Struct)] + [pointer] * 24),
        "rk4_step": (ctypes.c_int, [ctypes.POINTER(_Struct), pointer, pointer, ctypes.c_double, pointer, pointer,
                                    pointer, pointer]),
        "index1_accelerations": (ctypes.c_int, [ctypes.POINTER(_Struct), pointer, pointer, pointer, pointer]),
        "evaluate_state": (ctypes.c_double, [ctypes.POINTER(_Struct)] + [pointer] * 5)})


def _lapack(name):
    """The address of scipy's LAPACK routine `name` (scipy.linalg.cython_lapack: the Fortran calling convention,
    every argument by pointer)."""
    capsule = cython_lapack.__pyx_capi__[name]
    get_name, get_pointer = ctypes.pythonapi.PyCapsule_GetName, ctypes.pythonapi.PyCapsule_GetPointer
    get_name.restype, get_name.argtypes = ctypes.c_char_p, [ctypes.py_object]
    get_pointer.restype, get_pointer.argtypes = ctypes.c_void_p, [ctypes.py_object, ctypes.c_char_p]
    return get_pointer(capsule, get_name(capsule))


_KERNELS: "weakref.WeakKeyDictionary" = weakref.WeakKeyDictionary()     # model -> its StepKernel or None


def kernel_for(model):
    """The model's StepKernel (with the IterationLU of its iteration pattern), built at the first call for the model
    and shared by its integrator and its other constrained solves; None when the model is `unsupported` or
    $WINGSIM_KERNELS selects the numpy path (read at every call).

    Args:
        model: the StructuralModel.
    """
    if selected() == "numpy":
        return None
    if model not in _KERNELS:
        lu = None
        if unsupported(model) is None:
            lu = IterationLU(len(model.initial_coordinates()), model.constraint_count, model.iteration_pattern())
        _KERNELS[model] = StepKernel.for_model(model, lu)
    return _KERNELS[model]


def unsupported(model):
    """Why the compiled iteration cannot take this model (a sentence), or None when it can.

    Args:
        model: the StructuralModel (structure_fmu.fidelities).
    """
    if isinstance(model, StrainBasedModel):
        return "a strain-based model"
    if type(model) is not StructureModel:
        return "a model other than the ANCF StructureModel"
    if model.flexible and model._law[0] is not element:
        return "a shear-deformable element"
    if not len(model.initial_coordinates()):
        return "no free coordinates"
    blocks = model.constraints.blocks
    if blocks["axis"].stop > blocks["axis"].start or blocks["sliding"].stop > blocks["sliding"].start:
        return "axis or sliding constraint rows"
    if model.constraint_count != model.constraints.count:
        return "redundant constraint rows"
    if any(h.axis_slot is None for h in model.hinges):
        return "a revolute joint whose axis is not a shared chord"
    return None


GAUSS_POINTS_REFUSED = ("the element C kernels cannot take this many Gauss points (element_kernels.c, "
                        "MAX_GAUSS)")


def _solved(status, outputs):
    """The outputs of an index-1 solve (`accelerations`, `rk4_step`) by its C status: 0 as computed; 1 (a hinge's
    angle vanished) all NaN, for the solver's finite check to report; 2 ValueError (the element kernel's Gauss
    points); 3 numpy.linalg.LinAlgError (a Schur complement G M_q^-1 G^T not positive definite)."""
    if status == 1:
        for output in outputs:
            output.fill(np.nan)
    elif status == 2:
        raise ValueError(GAUSS_POINTS_REFUSED)
    elif status == 3:
        raise np.linalg.LinAlgError("constraint Jacobian rank deficient (Schur complement, compiled step)")
    return outputs


@dataclass(frozen=True)
class Factorization:
    """One factorized iteration matrix in LAPACK's storage (band or dense, iteration_lu.IterationLU's choice) with
    LAPACK's pivots (1-based), and the addresses of both. Never modified after it is made, so that a saved solver
    state may hold it."""

    lu: np.ndarray
    pivots: np.ndarray
    addresses: tuple


class Steps(NamedTuple):
    """What `StepKernel.alpha_steps` took: the steps committed (fewer than asked where it stopped before a step the
    per-step path must take), and at the last committed state (meaningless where none was committed): (q, q', q'',
    a, lambda), its evaluation (E (n,), dE (n,), the fold angles (n_hinges,) in rad, max |Phi|), then the
    corrections taken, eta, the Factorization of the iteration matrix and its h (s), the power of the external force
    (W) and the work (J)."""

    committed: int
    state: tuple
    evaluation: tuple
    corrections: int
    eta: float
    factorization: Factorization | None
    matrix_h: float
    power: float
    work: float


class StepKernel:
    """The compiled step of one model (module docstring). Build it with `for_model`.

    Args:
        model: a StructureModel that `unsupported` accepts.
        lu: the model's iteration_lu.IterationLU (its storage: banded or dense), or None: no Newton iteration
            (`factor` and `correct` refuse; RK4 needs none).
        kernels: the library of step_kernels.c (`c_kernels`).
        elements: the library of element_kernels.c (element.c_kernels).
    """

    def __init__(self, model, lu, kernels, elements):
        self._correct, self._factor, self._rk4 = kernels.newton_correction, kernels.newton_factor, kernels.rk4_step
        self._alpha_step = kernels.alpha_step
        # alpha_step's predictor coefficients, control and results, and their addresses
        self._coefficients, self._control, self._out = np.zeros(11), np.zeros(8), np.zeros(6)
        self._addresses = tuple(address(a) for a in (self._coefficients, self._control, self._out))
        self._spare = None       # (lu, pivots) where alpha_step factorizes, made when needed
        self._alpha_steps = kernels.alpha_steps
        self._owned = [None, None]  # alpha_steps' two (lu, pivots) buffers, made when needed
        self._loop_control, self._loop_out = np.zeros(8), np.zeros(8)
        self._loop_scratch = None
        self._accelerations = kernels.index1_accelerations
        self._evaluate = kernels.evaluate_state
        self._hinge_names = [h.name for h in model.hinges]
        self._model = weakref.proxy(model)      # not a reference: kernel_for keeps the kernel while the model lives
        n, n_q, m = model.n, model.T.shape[1], model.constraint_count
        self.n_q, self.m = n_q, m
        keep = self._keep = {}     # every array the struct points at, held for the object's life

        def hold(name, array, dtype=float):
            keep[name] = np.ascontiguousarray(array, dtype=dtype)
            return keep[name].ctypes.data if keep[name].size else None

        t_ptr, t_col, t_val = model.map.csr()
        mass = scipy.sparse.csr_array(model.mass_q)
        damping = model.reduced_damping
        no_damping = np.zeros((n_q, n_q))
        sparse_damping = scipy.sparse.csr_array(damping if damping is not None else no_damping)
        # set per step (`prepare`), per stage: P p, P p', P p'', the force on E that does not depend on E and the
        # reduced force's terms that depend on time only
        self.offset, self.rate_offset, self.accel_offset, self.f_constant = (np.zeros((STAGES, n)) for _ in range(4))
        self.r_constant = np.zeros((STAGES, n_q))
        self._moving = model.motion_offsets(0.0)[1] is not None
        struct = dict(n=n, n_q=n_q, m=m, t_ptr=hold("t_ptr", t_ptr, _LONG), t_col=hold("t_col", t_col, _LONG),
                      t_val=hold("t_val", t_val), offset=self.offset.ctypes.data,
                      rate_offset=self.rate_offset.ctypes.data, accel_offset=self.accel_offset.ctypes.data,
                      moving=int(self._moving), f_constant=self.f_constant.ctypes.data,
                      r_constant=self.r_constant.ctypes.data, m_ptr=hold("m_ptr", mass.indptr, _LONG),
                      m_col=hold("m_col", mass.indices, _LONG), m_val=hold("m_val", mass.data),
                      mass=hold("mass", model.mass_q), mass_inverse=hold("mass_inverse", model.mass_inverse),
                      damped=int(damping is not None), c_ptr=hold("c_ptr", sparse_damping.indptr, _LONG),
                      c_col=hold("c_col", sparse_damping.indices, _LONG), c_val=hold("c_val", sparse_damping.data),
                      damping=hold("damping", damping if damping is not None else no_damping))
        n_values = 0
        if model.flexible:
            table, _, g = element._table(model.lengths, model._law[1])
            keep["table"] = table
            struct.update(n_elements=len(model.lengths), gauss=g, table=table.ctypes.data,
                          dofs=hold("dofs", model.dofs, np.int64),
                          add_elastic_force=ctypes.cast(elements.add_elastic_force, ctypes.c_void_p).value,
                          elastic_jacobian=ctypes.cast(elements.elastic_jacobian, ctypes.c_void_p).value,
                          element_scratch=hold("element_scratch", np.zeros(36 * len(model.lengths))))
            n_values += 324 * len(model.lengths)
        self._hinges = model.hinges
        self.hinge_parameters = np.zeros((len(self._hinges), 4))
        struct.update(n_hinges=len(self._hinges),
                      hinge_index=hold("hinge_index", [hinge_coordinates(h) for h in self._hinges] or
                                       np.zeros((0, 9)), _LONG),
                      hinge_parameters=self.hinge_parameters.ctypes.data if self._hinges else None)
        if m:
            ia, ib, coefficient, constant, pair, (source, target, weight) = model.constraints.product_rows()
            hessian_rows = model.constraints.quadratic_hessian[1]
            L, offset, LT = (scipy.sparse.csr_array(a) if a.ndim == 2 else a for a in model.constraints.linear_rows())
            struct.update(l_ptr=hold("l_ptr", L.indptr, _LONG), l_col=hold("l_col", L.indices, _LONG),
                          l_val=hold("l_val", L.data), l_offset=hold("l_offset", offset),
                          lt_ptr=hold("lt_ptr", LT.indptr, _LONG), lt_col=hold("lt_col", LT.indices, _LONG),
                          lt_val=hold("lt_val", LT.data))
            struct.update(n_products=len(ia), row_a=hold("row_a", ia, _LONG), row_b=hold("row_b", ib, _LONG),
                          row_coefficient=hold("row_coefficient", coefficient),
                          row_constant=hold("row_constant", constant), n_jacobian=len(source),
                          pair=hold("pair", pair, _LONG), jacobian_source=hold("jacobian_source", source, _LONG),
                          jacobian_target=hold("jacobian_target", target, _LONG),
                          jacobian_weight=hold("jacobian_weight", weight),
                          hessian_row=hold("hessian_row", hessian_rows, _LONG), n_hessian=len(hessian_rows))
            n_values += len(hessian_rows)
        n_values += 81 * len(self._hinges)
        bodies = model.damped_bodies if model.mass_damping is None else []     # damping.py's, by body
        sizes = [len(idx) for _, idx, _ in bodies]
        struct.update(n_damped=len(bodies), body_start=hold("body_start", [idx[0] for _, idx, _ in bodies], _LONG),
                      body_size=hold("body_size", sizes, _LONG),
                      body_mass_offset=hold("body_mass_offset", np.cumsum([0] + [k * k for k in sizes])[:-1], _LONG),
                      body_alpha=hold("body_alpha", [alpha for alpha, _, _ in bodies]),
                      body_mass=hold("body_mass", np.concatenate([mass.ravel() for _, _, mass in bodies] or [[]])))
        if any(np.any(np.diff(idx) != 1) for _, idx, _ in bodies):
            raise ValueError("a damped body's coordinates are not contiguous in E")
        n_values += sum(k * k for k in sizes)
        assembly = model.tangent_assembly
        if assembly is not None:
            struct.update(n_assembly=len(assembly.source),
                          assembly_source=hold("assembly_source", assembly.source, _LONG),
                          assembly_target=hold("assembly_target", assembly.target, _LONG),
                          assembly_weight=hold("assembly_weight", assembly.weight))
        size = n_q + m
        self._storage = None
        if lu is not None:
            rows, (s_target, s_source), (g_target, g_source), (gt_target, gt_source) = lu.storage()
            self._storage = (rows * size, 3 * size)    # the pivots and the band's extents (step_kernels.c, band_lu)
            struct.update(banded=int(lu.banded), lower=lu.lower if lu.banded else 0,
                          upper=lu.upper if lu.banded else 0, rows=rows, n_s=len(s_target), n_g=len(g_target),
                          s_target=hold("s_target", s_target, _LONG), s_source=hold("s_source", s_source, _LONG),
                          g_target=hold("g_target", g_target, _LONG), g_source=hold("g_source", g_source, _LONG),
                          gt_target=hold("gt_target", gt_target, _LONG),
                          gt_source=hold("gt_source", gt_source, _LONG),
                          order=hold("order", lu.order if lu.banded else np.zeros(0), _LONG),
                          getrf=_lapack("dgetrf"), getrs=_lapack("dgetrs"))
        lengths = {"E": n, "dE": n, "F": n, "Fq": n_q, "values": n_values, "S": n_q * n_q, "G": m * n_q, "rhs": size,
                   "ordered": size, "MinvGt": n_q * m, "schur": m * m, "stage_q": n_q, "stage_v": n_q,
                   "accelerations": 3 * n_q, "multipliers": m, "vector": max(n_q, m),
                   "body_work": 18 * max(sizes, default=0)}
        struct.update({name: hold(name, np.zeros(max(lengths[name], 1))) for name in WORK})
        struct["nonzero"] = hold("nonzero", np.zeros(max(m * (n_q + 1), 1)), _LONG)
        self._struct = _Struct(n_values=n_values, **struct)
        self._pointer = ctypes.pointer(self._struct)
        self._bound = (None,) * 8
        self._size = ctypes.c_double()
        self._size_pointer = ctypes.pointer(self._size)

    @classmethod
    def for_model(cls, model, lu):
        """The StepKernel of `model` (with its IterationLU `lu`, or None for RK4), or None: the model is
        `unsupported`, or $WINGSIM_KERNELS selects the numpy path (or a library is unavailable: one warning has said
        why).

        Args:
            model: the StructuralModel.
            lu: its iteration_lu.IterationLU, or None.
        """
        if unsupported(model) is not None:
            return None
        kernels = c_kernels()
        elements = element.c_kernels() if model.flexible else kernels
        if kernels is None or elements is None:
            return None
        return cls(model, lu, kernels, elements)

    def prepare(self, times, Q, latched, rows=None):
        """Set what depends on time only, at each stage's time: the prescribed motion, the force that does not depend
        on E, the inertia of the prescribed motion; and the hinges' springs.

        Args:
            times: the stages' times, s: (t,) for generalized-alpha (the step's end), (t, t + h/2, t + h) for RK4.
            Q: (n,) generalized external force on E, N and N m, global frame.
            latched: {hinge: latched}.
            rows: where the time-dependent terms go, one row per time: `step_terms`' views; None: the stages.
        """
        model = self._model
        offset, rate_offset, accel_offset, f_constant, r_constant = rows or (
            self.offset, self.rate_offset, self.accel_offset, self.f_constant, self.r_constant)
        for stage, t in enumerate(times):
            Pp, Pdp, ddp = model.motion_offsets(t)
            offset[stage] = Pp
            f_constant[stage] = model.constant_force_E(t, Q)
            if self._moving:      # model.force_q's -T^T M_E P p'' and force_E's damping -C_E P p'
                rate_offset[stage] = Pdp
                accel_offset[stage] = model.P @ ddp
                r_constant[stage] = model.mass_prescribed @ ddp
                if model.mass_damping is not None:
                    f_constant[stage] -= model.mass_damping @ Pdp
        for k, h in enumerate(self._hinges):
            stiffness, neutral = actuator_spring(h, latched.get(h.name, False))
            self.hinge_parameters[k] = stiffness, neutral, h.damping, h.torque

    def step_terms(self, times, Q, latched):
        """`prepare`'s time-dependent terms at each of `times` (s), one row per time in `alpha_steps`' layout: (k,
        4 n + n_q) of P p, P p', P p'', the force on E that does not depend on E, the reduced force's terms that
        depend on time only.

        Args:
            times: the steps' end times, s.
            Q: (n,) generalized external force on E, N and N m, global frame.
            latched: {hinge: latched}.
        """
        n = self._model.n
        terms = np.zeros((len(times), 4 * n + self.n_q))
        self.prepare(times, Q, latched, tuple(terms[:, k * n:(k + 1) * n] for k in range(4)) + (terms[:, 4 * n:],))
        return terms

    def factor(self, q, dq, lam, beta_p, gamma_p):
        """The factorized iteration matrix at (q, q', lambda) and the first stage's time (model.StructureModel.
        iteration_matrix with iteration_lu.IterationLU.factor); numpy.linalg.LinAlgError if it is singular.

        Args:
            q: (n_q,) generalized coordinates (float64, C-contiguous, writable, as all arrays here).
            dq: (n_q,) their rates, per s.
            lam: (m,) the constraint multipliers.
            beta_p: beta', 1/s^2.
            gamma_p: gamma', 1/s.

        Returns:
            the Factorization.
        """
        if self._storage is None:
            raise ValueError("this StepKernel was built without an IterationLU: it has no iteration matrix")
        lu, pivots = np.empty(self._storage[0]), np.empty(self._storage[1], dtype=np.intc)
        status = self._factor(self._pointer, address(q), address(dq), address(lam) if lam.size else None,
                              beta_p, gamma_p, address(lu), address(pivots))
        if status == -2:
            raise ValueError(GAUSS_POINTS_REFUSED)
        if status != 0:      # -1: a hinge without an angle (vanished vectors): no tangent either
            raise np.linalg.LinAlgError(f"singular iteration matrix (compiled Newton iteration, status {status})")
        return Factorization(lu, pivots, (address(lu), address(pivots)))

    def alpha_step(self, state, coefficients, control, factorization):
        """One generalized-alpha step to the first stage's time (set by `prepare`) in one call (step_kernels.c,
        alpha_step): the predictor, the iteration matrix factorized at it where asked, Newton corrections (`correct`)
        until converged, refactorizing (`factor`) where convergence slows; integrators.GeneralizedAlpha._newton's
        arithmetic and control. ValueError where the element kernel refuses its Gauss points or LAPACK's solve fails;
        numpy.linalg.LinAlgError where a factorization is singular.

        Args:
            state: the integrators.State at the step's start (not modified).
            coefficients: (11,) the predictor's: alpha_f, alpha_m, 1 - alpha_m, (1 - alpha_f) / (1 - alpha_m),
                h (1 - gamma), h gamma, h, h^2 (1/2 - beta), h^2 beta, -(1/2 - beta) / beta, 1 - alpha_f (Peng et al.
                2019, Eqs. 23-24).
            control: (8,) beta' (1/s^2), gamma' (1/s), the Newton tolerance, the velocity tolerance over it, the first
                correction's error estimate factor eta, 1 to factorize at the predictor, the iterations allowed, 1 for
                the displacement predictor (0: the acceleration one).
            factorization: the Factorization to start with; None where the step factorizes at its predictor.

        Returns:
            (status, (q, q', q'', a, lambda) at the step's end, corrections taken, last correction, first correction,
            eta, the Factorization at the end: a new one where the step factorized); status 0 converged, 1 a residual
            not finite, 4 diverging, 5 not converged within the iterations allowed (the predictor where none is).
        """
        if self._storage is None:
            raise ValueError("this StepKernel was built without an IterationLU: it has no iteration matrix")
        n_q = self.n_q
        x = np.empty(5 * n_q + self.m)      # q, q', q'', a, a_known, lambda (the state keeps views of its rows)
        self._coefficients[:] = coefficients
        self._control[:] = control
        if self._spare is None:
            self._spare = (np.empty(self._storage[0]), np.empty(self._storage[1], dtype=np.intc))
        spare = self._spare
        given = factorization.addresses if factorization is not None else (None, None)
        status = self._alpha_step(self._pointer, address(state.q), address(state.dq), address(state.ddq),
                                  address(state.accel), address(state.multipliers) if self.m else None,
                                  self._addresses[0], self._addresses[1], *given, address(spare[0]),
                                  address(spare[1]), address(x), self._addresses[2])
        iterations, size, first, eta, factorized, factor_status = self._out.tolist()
        if factorized:
            factorization, self._spare = Factorization(*spare, (address(spare[0]), address(spare[1]))), None
        if status == 2:
            raise ValueError(GAUSS_POINTS_REFUSED)
        if status == 3:
            raise ValueError("compiled Newton correction failed: LAPACK's solve")
        if status == 6:
            if factor_status == -2:
                raise ValueError(GAUSS_POINTS_REFUSED)
            raise np.linalg.LinAlgError(f"singular iteration matrix (compiled Newton iteration, status "
                                        f"{int(factor_status)})")
        values = (x[:n_q], x[n_q:2 * n_q], x[2 * n_q:3 * n_q], x[3 * n_q:4 * n_q], x[5 * n_q:])
        return status, values, int(iterations), size, first, eta, factorization

    def alpha_steps(self, state, h, coefficients, beta_gamma, terms, control, factorization, force, stops, angles):
        """Generalized-alpha steps in one call (step_kernels.c, alpha_steps): `alpha_step` with the acceleration
        predictor for each step at its time-dependent terms, each end state evaluated (`evaluate`), checked and its
        external work integrated as solver.StructureSolver.advance does; the loop stops before a step that needs the
        per-step path (a Newton failure, a check that may fail, a latch).

        Args:
            state: the integrators.State at the start (not modified).
            h: (k,) the steps, s.
            coefficients: (k, 11) each step's predictor coefficients (`alpha_step`).
            beta_gamma: (k, 2) each step's beta' (1/s^2) and gamma' (1/s).
            terms: each step's time-dependent terms (`step_terms`), or None: those `prepare` set for the first hold
                for every step (a model that does not vary in time).
            control: (7,) the Newton tolerance, the velocity tolerance over it, eta, the iterations allowed, the h of
                `factorization` (s), the power of `force` at the start (W), the work so far (J).
            factorization: the Factorization to start with, or None.
            force: the external force whose power the work integrates, N and N m: (n,), or (k, n) with terms.
            stops: (n_hinges,) each hinge's stop angle, rad, NaN where it has none or is latched.
            angles: (n_hinges,) the fold angles at the start, rad.

        Returns:
            the Steps taken.
        """
        n_q, m, n = self.n_q, self.m, self._model.n
        size = 5 * n_q + m
        if self._loop_scratch is None:
            self._loop_scratch = np.empty(2 * size + 2 * n + max(len(self._hinge_names), 1))
        owned = self._owned
        for k in (0, 1):
            if owned[k] is None:
                owned[k] = (np.empty(self._storage[0]), np.empty(self._storage[1], dtype=np.intc))
        x, E, dE = np.empty(size), np.empty(n), np.empty(n)
        angles = np.array(angles if len(angles) else [0.0])
        self._loop_control[:7] = control
        self._loop_control[7] = len(h)
        given = factorization.addresses if factorization is not None else (None, None)
        self._alpha_steps(self._pointer, address(h), address(coefficients), address(beta_gamma),
                          address(self._loop_control), None if terms is None else address(terms),
                          address(state.q), address(state.dq), address(state.ddq), address(state.accel),
                          address(state.multipliers) if self.m else None, *given,
                          address(owned[0][0]), address(owned[0][1]), address(owned[1][0]), address(owned[1][1]),
                          address(force), address(stops) if stops.size else None, address(angles),
                          address(self._loop_scratch), address(x), address(E), address(dE), address(self._loop_out))
        committed, corrections, eta, current, matrix_h, power, work, residual = self._loop_out.tolist()
        if current:        # the matrix is now an owned buffer: it becomes a Factorization, and a new buffer its place
            lu, pivots = owned[int(current) - 1]
            factorization, owned[int(current) - 1] = Factorization(lu, pivots, (address(lu), address(pivots))), None
        return Steps(int(committed), (x[:n_q], x[n_q:2 * n_q], x[2 * n_q:3 * n_q], x[3 * n_q:4 * n_q], x[5 * n_q:]),
                     (E, dE, angles[:len(self._hinge_names)], residual), int(corrections), eta, factorization,
                     matrix_h, power, work)

    def correct(self, q, dq, ddq, lam, beta_p, gamma_p, factorization):
        """One Newton correction at the first stage's time, in place on q, q', q'' and lambda; the largest correction
        of q (NaN if any is), or None when the residual is not finite (nothing updated).

        Args:
            q: (n_q,) generalized coordinates, updated.
            dq: (n_q,) their rates, per s, updated.
            ddq: (n_q,) their accelerations, per s^2, updated.
            lam: (m,) the constraint multipliers, updated.
            beta_p: beta', 1/s^2.
            gamma_p: gamma', 1/s.
            factorization: the Factorization of the iteration matrix (`factor`).
        """
        bound = self._bound      # the addresses of the arrays of the last call: a step's iterations pass the same
        if not (q is bound[0] and dq is bound[1] and ddq is bound[2] and lam is bound[3]):
            bound = self._bound = (q, dq, ddq, lam, address(q), address(dq), address(ddq),
                                   address(lam) if lam.size else None)
        status = self._correct(self._pointer, *bound[4:], beta_p, gamma_p, *factorization.addresses,
                               self._size_pointer)
        if status == 1:
            return None
        if status == 2:
            raise ValueError(GAUSS_POINTS_REFUSED)
        if status != 0:
            raise ValueError(f"compiled Newton correction failed: LAPACK's solve (status {status})")
        return self._size.value

    def accelerations(self, q, v):
        """q'' and lambda of the index-1 equations at (q, q') and the first stage's time set by `prepare`
        (integrators.constrained_accelerations); numpy.linalg.LinAlgError when the Schur complement G M_q^-1 G^T
        is not positive definite.

        Args:
            q: (n_q,) generalized coordinates.
            v: (n_q,) their rates, per s.

        Returns:
            (q'' (n_q,) per s^2, lambda (m,)); both NaN where a hinge's angle vanished.
        """
        a, lam = np.empty(self.n_q), np.empty(self.m)
        return tuple(_solved(self._accelerations(self._pointer, address(q), address(v), address(a),
                                                 address(lam) if self.m else None), (a, lam)))

    def evaluate(self, q, dq, t):
        """What the solver checks and reports of a state, in one call: E, dE/dt, the fold angles and the largest
        |Phi| (model.coordinates, model.constraint_violation, model.fold_angles).

        Args:
            q: (n_q,) generalized coordinates.
            dq: (n_q,) their rates, per s.
            t: time, s.

        Returns:
            (E (n,), dE (n,), {hinge: fold angle, rad}, max |Phi|).
        """
        model = self._model
        Pp, Pdp, _ = model.motion_offsets(t)
        self.offset[0] = Pp
        if self._moving:
            self.rate_offset[0] = Pdp
        E, dE, angles = np.empty(model.n), np.empty(model.n), np.empty(max(len(self._hinge_names), 1))
        residual = self._evaluate(self._pointer, address(q), address(dq), address(E), address(dE), address(angles))
        return E, dE, dict(zip(self._hinge_names, angles.tolist())), residual

    def rk4_step(self, q, v, h):
        """One RK4 step of h with the projection onto the constraints, at the stages' times set by `prepare`
        (integrators.RK4.step); numpy.linalg.LinAlgError when a Schur complement G M_q^-1 G^T is not positive
        definite.

        Args:
            q: (n_q,) generalized coordinates at t.
            v: (n_q,) their rates, per s.
            h: the step, s.

        Returns:
            (q (n_q,), q' (n_q,)) at t + h, the accelerations q'' (n_q,) and multipliers lambda (m,) at t; a state with
            all NaN where a hinge's angle vanished (the solver's finite check reports it).
        """
        q_new, v_new, a1, lam = np.empty(self.n_q), np.empty(self.n_q), np.empty(self.n_q), np.empty(self.m)
        return _solved(self._rk4(self._pointer, address(q), address(v), h, address(q_new), address(v_new),
                                 address(a1), address(lam) if self.m else None), (q_new, v_new, a1, lam))
