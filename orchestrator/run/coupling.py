"""Coupling schemes: how the master takes the structure and aero units over one communication step.

A scheme holds the units and the interface force Q (N and N m, (n,)) between steps. ``start()`` makes the
exchange at t = 0: the aero unit gets the structure's initial e, de and Q is its initial output (zero: no
circulation yet). ``advance(t0, t1)`` takes both units from t0 to t1 (s) and leaves them there, their
outputs ready to be recorded. Both return the coupling record of the communication point, (iterations,
residual) for ``Implicit``, None for the others. Every aero step's inputs go to ``aero_inputs``
(``AeroInputs``), for a replay of the aero unit after the run. A prescribed-motion structure ignores Q, but
Q is still passed (and checked by the structure unit).

- ``StructureAlone`` (``aero.model = "none"``): the structure steps with Q = 0 held.
- ``GaussSeidel`` (staggered, explicit, the default): the structure steps over [t0, t1] with the Q of the
  aero unit at t0; the aero unit then steps with the structure's new e, de at t1, and its Q at t1 is held for
  the next structure step.
- ``Jacobi`` (explicit): both units step from the outputs at t0 (the aero unit with e, de of t0 held), then
  exchange.
- ``Implicit``: each step is repeated until the interface force agrees with the motion it produces, i.e. a
  fixed point Q = H(Q) of one Gauss-Seidel pass H: Q_used -> structure step with Q_used held over [t0, t1]
  -> e, de at t1 -> aero step -> Q_new at t1. Per step:

  1. save both units' states (``get_state``); the first iterate Q_used is the accepted Q at t0;
  2. the structure steps with Q_used, the aero unit with its new e, de, giving Q_new;
  3. r = Q_new - Q_used; the step is accepted when ||r|| / max(||Q_new||, ``acceleration.RESIDUAL_FLOOR``)
     is below ``coupling.tolerance`` (2-norms over all n coordinates, N and N m mixed as the unit gives
     them); Q_new is then the Q at t1, the first iterate of the next step;
  4. else both units are rolled back (``set_state``) and the step is repeated with the next Q_used from the
     acceleration (``coupling.acceleration``, ``orchestrator.run.acceleration``), both starting with a relaxed
     first update Q_used + omega_0 r, omega_0 = ``coupling.relaxation``: ``aitken``, Aitken's dynamic
     relaxation (Kuettler and Wall 2008); ``iqn-ils``, interface quasi-Newton with an inverse Jacobian from
     a least-squares model (Degroote, Bathe and Vierendeels 2009) built from this step's iterations only;
  5. after ``coupling.max_iterations`` iterations without convergence (or a non-finite residual, or a
     failed rollback) ``CouplingDiverged`` is raised, naming the step, the residual and a hint.

  Only the accepted iterate's aero inputs are recorded (the rejected ones were rolled back). A
  prescribed-motion structure still iterates: Q converges to the aero force of the prescribed motion.

A divergence of an explicitly coupled run is explained by ``explain_divergence`` (``explicit_coupling_hint``);
of any coupled run whose structure takes several internal steps per communication step, also by
``held_force_hint`` (the aero force held over those steps can feed a structural mode near the communication
step's Nyquist frequency, whatever the scheme: docs/aero.md, "The held aero force and the structure's steps").
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from orchestrator.run.acceleration import interface_residual, make_acceleration
from orchestrator.run.timeseries import TimeSeries

HINT_WINDOW = 20        # communication steps compared by explicit_coupling_hint

CouplingRecord = tuple[int, float] | None
"""(iterations, residual) of a communication point for the time series (implicit coupling), else None."""


class CouplingDiverged(RuntimeError):
    """The implicit coupling did not converge in a step, or could not roll the units back (status
    "diverged")."""

    diverged = True


@dataclass
class AeroInputs:
    """The aero unit's steps in order: each ``do_step(t, h)`` (s) with the e (m, 1) and de (m/s, 1/s),
    (n,) each, it held at that step. The tunable parameters were the unit's defaults (the master sets
    none). Recording stops (``complete`` False) once ``max_values`` numbers are held (about 8 bytes each):
    a replay then covers only the recorded steps. With implicit coupling only the accepted iterate of each
    step is recorded (the rejected iterates were rolled back)."""

    t: list[float]
    h: list[float]
    e: list[np.ndarray]
    de: list[np.ndarray]
    complete: bool = True
    max_values: int = 20_000_000

    @classmethod
    def empty(cls) -> "AeroInputs":
        return cls([], [], [], [])

    def __len__(self) -> int:
        return len(self.t)

    def append(self, t: float, h: float, e: np.ndarray, de: np.ndarray) -> None:
        if not self.complete:
            return
        if (len(self.t) + 1) * 2 * len(e) > self.max_values:
            self.complete = False
            return
        self.t.append(float(t))
        self.h.append(float(h))
        self.e.append(np.array(e, dtype=float))
        self.de.append(np.array(de, dtype=float))


class Scheme:
    """What every scheme shares: the units, the held Q and the exchange at t = 0 (module docstring).
    Subclasses implement ``advance``."""

    name = ""

    def __init__(self, structure: Any, aero: Any = None, aero_inputs: AeroInputs | None = None):
        self.structure, self.aero, self.aero_inputs = structure, aero, aero_inputs
        self.q = np.zeros(structure.n)     # N and N m, the Q the structure steps with next
        self.held = None                   # (e, de) the aero unit holds
        self.step, self.substeps = None, 1  # s, communication step; the structure's internal steps in it

    def start(self) -> CouplingRecord:
        """The exchange at t = 0; returns the coupling record of t = 0."""
        e, de = self.structure.get_outputs()
        if self.aero is not None:
            self.aero.set_inputs(e, de)
            self.held = (e, de)
            self.q, = self.aero.get_outputs()
        return None

    def advance(self, t0: float, t1: float) -> CouplingRecord:
        """Take the units from t0 to t1 (s); returns the coupling record of t1."""
        raise NotImplementedError

    def statistics(self) -> str:
        """Text for the run's message, after the scheme's name ("" when there is nothing to add)."""
        return ""

    def explain_divergence(self, message: str, series: TimeSeries) -> str:
        """The message of a run that diverged, with what the scheme can tell about it."""
        if self.aero is None:
            return message
        return message.rstrip(" .") + "." + held_force_hint(self.substeps, self.step)


class StructureAlone(Scheme):
    """The structure unit alone, Q = 0 held."""

    def advance(self, t0: float, t1: float) -> CouplingRecord:
        self.structure.set_inputs(self.q)
        self.structure.do_step(t0, t1 - t0)
        self.structure.get_outputs()
        return None


class _Explicit(Scheme):
    """Gauss-Seidel and Jacobi: one pass per step, so the exchange itself can make a run diverge."""

    def explain_divergence(self, message: str, series: TimeSeries) -> str:
        return (message.rstrip(" .") + "." + explicit_coupling_hint(series, self.name)
                + held_force_hint(self.substeps, self.step))


class GaussSeidel(_Explicit):
    """Staggered: the structure with Q at t0, then the aero unit with the structure's e, de at t1."""

    name = "gauss-seidel"

    def advance(self, t0: float, t1: float) -> CouplingRecord:
        h = t1 - t0
        self.structure.set_inputs(self.q)
        self.structure.do_step(t0, h)
        e, de = self.structure.get_outputs()
        self.aero.set_inputs(e, de)
        self.held = (e, de)
        self.aero.do_step(t0, h)
        self.aero_inputs.append(t0, h, e, de)
        self.q, = self.aero.get_outputs()
        return None


class Jacobi(_Explicit):
    """Both units from the outputs at t0 (the aero unit with the e, de of t0 it holds), then exchange."""

    name = "jacobi"

    def advance(self, t0: float, t1: float) -> CouplingRecord:
        h = t1 - t0
        self.structure.set_inputs(self.q)
        self.aero.do_step(t0, h)
        self.aero_inputs.append(t0, h, *self.held)
        self.structure.do_step(t0, h)
        e, de = self.structure.get_outputs()
        self.q, = self.aero.get_outputs()
        self.aero.set_inputs(e, de)
        self.held = (e, de)
        return None


class Implicit(Scheme):
    """Each step iterated to the fixed point of a Gauss-Seidel pass, with rollback and ``acceleration``
    (module docstring). ``tolerance`` is the relative interface residual accepted, ``max_iterations`` the
    iterations per step before ``CouplingDiverged``."""

    name = "implicit"

    def __init__(self, structure: Any, aero: Any, aero_inputs: AeroInputs, acceleration: Any, tolerance: float,
                 max_iterations: int):
        super().__init__(structure, aero, aero_inputs)
        self.acceleration, self.tolerance, self.max_iterations = acceleration, tolerance, max_iterations
        self.steps = self.total_iterations = self.most_iterations = 0

    def start(self) -> CouplingRecord:
        super().start()
        return 0, np.nan

    def advance(self, t0: float, t1: float) -> CouplingRecord:
        h = t1 - t0
        structure, aero = self.structure, self.aero
        states = (structure.get_state(), aero.get_state())
        self.acceleration.start()
        x = np.array(self.q, dtype=float)
        residual = math.inf
        for k in range(1, self.max_iterations + 1):
            if k > 1:
                self._rollback(states, t0, k)
            structure.set_inputs(x)
            structure.do_step(t0, h)
            e, de = structure.get_outputs()
            aero.set_inputs(e, de)
            aero.do_step(t0, h)
            q_new, = aero.get_outputs()
            residual = interface_residual(q_new, x)
            if residual < self.tolerance:
                self.aero_inputs.append(t0, h, e, de)     # the accepted iterate only
                self.q, self.held = q_new, (e, de)
                self.steps += 1
                self.total_iterations += k
                self.most_iterations = max(self.most_iterations, k)
                return k, residual
            if not math.isfinite(residual):
                break
            x = self.acceleration.update(x, q_new)
        kind = getattr(self.acceleration, "name", type(self.acceleration).__name__)
        raise CouplingDiverged(
            f"implicit coupling diverged in the step from t = {t0:.6g} s to {t0 + h:.6g} s: interface residual "
            f"{residual:.3g} after {k} iterations (coupling.tolerance = {self.tolerance:g}, "
            f"coupling.max_iterations = {self.max_iterations}, coupling.acceleration = {kind!r}). Hint: reduce "
            "coupling.step, try coupling.acceleration = 'iqn-ils' or a smaller coupling.relaxation, or raise "
            "coupling.max_iterations")

    def _rollback(self, states: tuple, t0: float, iteration: int) -> None:
        for unit, state in zip((self.structure, self.aero), states):
            try:
                unit.set_state(state)
            except Exception as err:
                raise CouplingDiverged(
                    f"implicit coupling: rolling the {getattr(unit, 'kind', 'unit')} unit back to t = {t0:.6g} s "
                    f"for iteration {iteration} failed: {err}. Hint: the unit must support fmi2SetFMUstate "
                    "(canGetAndSetFMUstate); use coupling.algorithm = 'gauss-seidel' otherwise") from err

    def statistics(self) -> str:
        return (f", {self.acceleration.name}: {self.total_iterations / self.steps:.3g} iterations per step, "
                f"at most {self.most_iterations}")


SCHEMES = {"gauss-seidel": GaussSeidel, "jacobi": Jacobi, "implicit": Implicit}
"""Scene value of ``coupling.algorithm`` -> scheme coupling an aero unit."""


def make_scheme(scene: dict, structure: Any, aero: Any = None, aero_inputs: AeroInputs | None = None) -> Scheme:
    """The scheme of the scene's ``coupling`` table for these units (``StructureAlone`` without an aero unit);
    ``coupling.algorithm`` must be one of ``SCHEMES``."""
    if aero is None:
        return StructureAlone(structure)
    coupling = scene["coupling"]
    scheme = SCHEMES[coupling["algorithm"]]
    if scheme is Implicit:
        made = Implicit(structure, aero, aero_inputs, make_acceleration(coupling), coupling["tolerance"],
                        coupling["max_iterations"])
    else:
        made = scheme(structure, aero, aero_inputs)
    made.step = coupling["step"]
    made.substeps = structure_substeps(coupling["step"], scene["structure"]["step"])
    return made


def structure_substeps(step: float, structure_step: float) -> int:
    """Internal structure steps (-) in a communication step of ``step`` (s) at ``structure.step`` (s): the last
    one is shortened to land on the communication point (a remainder below 1e-9 of a step adds none)."""
    return max(1, math.ceil(step / structure_step - 1e-9))


def held_force_hint(substeps: int, step: float | None) -> str:
    """Text appended to the message of a coupled run that diverged while the structure took ``substeps`` > 1
    internal steps per communication step of ``step`` (s); empty otherwise. The aero force is held over the
    communication step, and its apparent-mass part, the backward difference of a circulation proportional to
    the velocity sampled once per communication step, can feed a structural mode near the Nyquist frequency
    1/(2 step) that the internal steps of generalized-alpha barely damp, whatever the coupling scheme; one
    structure step per communication step damps it (docs/aero.md, "The held aero force and the structure's
    steps")."""
    if substeps <= 1 or step is None:
        return ""
    return (f" The structure took {substeps} steps per communication step, the aero force held over them: a "
            f"structural mode near 1/(2 coupling.step) = {0.5 / step:.3g} Hz can then be fed by the held force "
            "faster than those steps damp it, with implicit coupling too; try coupling.step = structure.step.")


def explicit_coupling_hint(series: TimeSeries, algorithm: str, window: int = HINT_WINDOW) -> str:
    """Text appended to the message of an explicitly coupled run that diverged. The unit that stopped it
    names its own symptom (often the structure's Newton iteration), but the exchange itself can be what
    grew: the added-mass instability, or aeroelastic feedback through the lagged force. The swing
    (max - min) of the lift (N; not CL, which is 0 in still air) over the last `window` communication
    points, against the `window` before, tells the two apart (fewer samples: halves of them, at least 5
    each); implicit coupling removes the exchange's own instability (docs/studies/stability.md). Empty when
    the run failed in its first communication step: the structure then moved under the force of its initial
    state alone, and no exchange had happened that could have grown."""
    lift = series.column("lift")
    lift = lift[np.isfinite(lift)]
    if lift.size < 2:
        return ""
    text = (f" Explicit {algorithm} coupling can itself be unstable (added mass, or feedback through the lagged "
            "aero force)")
    window = min(window, lift.size // 2)
    if window >= 5:
        last, before = np.ptp(lift[-window:]), np.ptp(lift[-2 * window:-window])
        text += (f": the lift swung over {last:.3g} N in the last {window} communication steps against "
                 f"{before:.3g} N in the {window} before")
    return text + '; if it grew, try coupling.algorithm = "implicit".'
