"""StructureSolver: the structure unit's solver API (docs/solver_api.md).

Owns the model, the integrator and the state; advances with its own internal steps inside a
communication step; detects the latch; checks inputs and divergence; saves and restores its state.
"""
import math
from dataclasses import replace

import numpy as np

from fmu_common.errors import SceneError, SolverDiverged, checked_input
from fmu_common.scene_schema import parameter_values
from fmu_common.specs import StructureUnitSpec

from . import step_kernel
from .fidelities import model_class
from .integrators import State, constrained_accelerations, integrator_for, project
from .joint_monitors import joint_monitors, monitor_names
from .sensors import Sensors
from .topology import StructureTopology


def _short_of(t, t_end) -> bool:
    """Whether time t (s) is short of t_end (s) by more than round-off: another internal step is due."""
    return t < t_end - 1e-12 * max(1.0, abs(t_end))


class StructureSolver:
    """The structural solver of one scene. See docs/solver_api.md.

    Attributes:
        steps_in_one_call: True (default): the internal steps of a communication step that the integrator can take in
            one compiled call are taken so (`Integrator.steps`); False: one call each (the tests compare both).

    Args:
        spec: the structure unit's spec (fmu_common.specs.StructureUnitSpec).
        parameters: {name: value} of tunable parameters (`tunable_parameters`), SI units; None: the defaults.
    """

    steps_in_one_call = True

    def __init__(self, spec: StructureUnitSpec, parameters: dict | None = None):
        self.topology = StructureTopology.from_spec(spec.structure)
        self.sensors = Sensors.from_spec(spec, self.topology)
        structure = spec.structure
        values = parameter_values(self.tunable_parameters(spec), parameters)
        self.parameters = values
        if values["structure.step"] <= 0:
            raise SceneError("structure.step", values["structure.step"], "a time step > 0 (s)")
        hinge_parameters = {h: {k: values[f"structure.joints.{h}.{k}"]
                                for k in ("stiffness", "damping", "torque")} for h in self.topology.hinge_names}
        for h, p in hinge_parameters.items():
            if p["stiffness"] < 0 or p["damping"] < 0:
                raise SceneError(f"structure.joints.{h}.stiffness/damping", p, "K >= 0 and C >= 0")
        body_damping = {b: values[f"structure.bodies.{b}.damping"] for b in self.topology.bodies}
        gravity = [values[f"structure.gravity[{i}]"] for i in (1, 2, 3)]
        model = model_class(structure.fidelity)
        self.model = model(self.topology, gravity, hinge_parameters, body_damping, structure.damping_model)
        self.step_size = values["structure.step"]
        self.integrator = integrator_for(structure)
        self.fidelity_name = structure.fidelity.name
        q0 = self.model.initial_coordinates()
        n_q = len(q0)
        n_c = self.model.constraint_count
        with np.errstate(over="ignore", invalid="ignore"):     # an overflow is refused by _check_initial_rates
            rates = self._initial_rates()
        self.state = State(0.0, q0, rates, np.zeros(n_q), np.zeros(n_q), np.zeros(n_c))
        self._zero_Q = np.zeros(self.topology.n_coordinates)
        self._last_Q = self._zero_Q
        self._initialized = False
        self._cache = ((None, None), (None, None))   # (state, _evaluated values), newest first
        self._check_initial_rates()
        self._check_initial_constraints()

    def _initial_rates(self):
        """q' at t = 0: the bodies' rigid rotations about their roots (`angular_velocity`, rad/s), made
        consistent with the prescribed motions and constraints by the mass-weighted projection."""
        top, model = self.topology, self.model
        E = top.initial_coordinates()
        dE = np.zeros_like(E)
        for name, omega in top.angular_velocity.items():
            nodes = top.bodies[name].nodes
            block = E.reshape(-1, 3, 3)[nodes]
            arms = np.stack([block[:, 0] - block[0, 0], block[:, 1], block[:, 2]], axis=1)
            dE.reshape(-1, 3, 3)[nodes] = np.cross(omega, arms)
        q0 = model.initial_coordinates()
        if not q0.size:
            return np.zeros(0)
        return project(model, 0.0, q0, model.rates_of(q0, dE, 0.0))[1]

    @staticmethod
    def tunable_parameters(spec: StructureUnitSpec) -> dict:
        """The scalars a system tool may change before a run.

        The tunable keys of the scene's `structure` table (`fmu_common.scene_schema.tunable_parameters`).

        Args:
            spec: the structure unit's spec.

        Returns:
            {name: (default, unit, description)}.
        """
        return dict(spec.parameters)

    def _check_initial_rates(self):
        """SceneError naming the fastest body's `angular_velocity` unless the initial rates and their kinetic energy
        1/2 dE^T M dE are finite: finite rates (rad/s) can overflow in omega x r or in the energy, and would start
        the unit from NaN."""
        spins = self.topology.angular_velocity
        if not spins:
            return
        _, dE, _ = self.model.coordinates(self.state.q, self.state.dq, 0.0)
        with np.errstate(over="ignore", invalid="ignore"):
            kinetic = 0.5 * float(np.dot(dE, np.dot(self.model.mass_E, dE)))
        if np.all(np.isfinite(self.state.dq)) and math.isfinite(kinetic):
            return
        name = max(spins, key=lambda body: float(np.max(np.abs(spins[body]))))
        raise SceneError(f"structure.bodies.{name}.angular_velocity", spins[name].tolist(),
                         f"a rotation rate whose initial rates and kinetic energy are finite numbers (they are not: "
                         f"1/2 dE^T M dE = {kinetic:g} J)")

    def _check_initial_constraints(self):
        if self.model.constraint_count == 0:
            return
        E, _, _ = self.model.coordinates(self.state.q, self.state.dq, 0.0)
        G = self.model.constraint_jacobian(self.state.q, E)
        rank = np.linalg.matrix_rank(G)
        if rank < G.shape[0]:
            raise SceneError("structure.joints", None,
                             f"joints over-constrain the bodies ({G.shape[0]} constraints, rank {rank})")

    # ---------------------------------------------------------------- stepping
    @property
    def time(self) -> float:
        """Time of the current state, s."""
        return self.state.t

    def _initialize(self, Q):
        self.state = self.integrator.initialize(self.model, self.state, Q)
        self._initialized = True

    def advance(self, t_end: float, Q=None) -> None:
        """Take internal steps from `time` to `t_end` with the generalized force Q held constant.

        Args:
            t_end: time to reach, s.
            Q: (n,) generalized external force on E, N and N m, global frame; None: zero.
        """
        Q = self._zero_Q if Q is None else checked_input("Q", Q, self._zero_Q.size, self.state.t)
        self._last_Q = Q
        if self.state.q.size == 0:        # fully prescribed: no dynamics
            self.state = replace(self.state, t=float(t_end))
            return
        if not self._initialized:
            self._initialize(Q)
        power = None                      # of the step's start, the previous step's end
        one_call = self.steps_in_one_call
        while _short_of(self.state.t, t_end):
            one_call = one_call and self.integrator.takes_steps(self.model)
            if one_call:
                power = self._steps_in_one_call(t_end, Q, power)
                if not _short_of(self.state.t, t_end):
                    break
            h = self._next_step(self.state.t, t_end)
            previous = self.state
            try:
                new = self.integrator.step(self.model, previous, h, Q)
            except np.linalg.LinAlgError as exc:
                raise SolverDiverged(previous.t, f"singular system ({exc})",
                                     self.integrator.divergence_hint) from None
            self._check(new)
            self._update_latches(previous, new)
            start = self._power(previous, Q) if power is None else power
            power = self._power(new, Q)
            new.work = previous.work + 0.5 * h * (start + power)
            self.state = new

    def _next_step(self, t, t_end):
        """The internal step (s) from t towards t_end: structure.step, or what is left where that is shorter or would
        leave less than a billionth of it."""
        h = min(self.step_size, t_end - t)
        return t_end - t if t_end - (t + h) < 1e-9 * self.step_size else h

    def _steps_in_one_call(self, t_end, Q, power):
        """The internal steps towards t_end that the integrator takes in one compiled call (Integrator.steps), with
        the checks, the latch detection and the external work of the per-step loop of `advance`: up to the first step
        that needs that loop, where `Integrator.takes_steps`. Returns the power of the external force at the state
        reached (W), as the loop carries it (None: not computed yet)."""
        hs, times, t = [], [], self.state.t
        while _short_of(t, t_end):
            hs.append(self._next_step(t, t_end))
            t = t + hs[-1]                 # as the integrator's step sets its end time
            times.append(t)
        previous, model = self.state, self.model
        start = self._power(previous, Q) if power is None else power
        angles = self._evaluated(previous)[2]
        stops = np.array([math.nan if h.stop_angle is None or previous.latched.get(h.name) else h.stop_angle
                          for h in model.hinges])
        force = (np.array([model.external_force_E(t, Q) for t in times]) if model.varies_in_time else
                 model.external_force_E(times[0], Q))
        taken, new = self.integrator.steps(model, previous, hs, times, Q, force, start, stops, list(angles.values()))
        if new is None:                    # not one step: the per-step loop takes the next
            return power
        E, dE, fold, residual = taken.evaluation
        self._cache = ((new, (E, dE, dict(zip(angles, fold.tolist())), residual)), self._cache[0])
        self.state = new
        return taken.power

    def _check(self, state):
        hint = self.integrator.divergence_hint
        if not math.isfinite(state.q.sum() + state.dq.sum()):     # NaN or inf in any entry
            raise SolverDiverged(state.t, "the state became NaN/inf", hint)
        E, _, _, residual = self._evaluated(state)
        if residual > 1e-4:
            raise SolverDiverged(state.t, f"constraint residual {residual:.3g} (limit 1e-4)", hint)
        size = np.abs(E.reshape(-1, 3, 3)[:, 1:]).max()   # gradients stay O(1) in any physical motion
        if size > 1e3:
            raise SolverDiverged(state.t, f"gradient vectors grew to {size:.3g}", hint)

    def _power(self, state, Q):
        """Power (W) of the external forces (point loads and Q, `StructureModel.external_force_E`) at a state:
        the external work is its trapezoidal integral over the internal steps, second order like the steps."""
        return float(np.dot(self.model.external_force_E(state.t, Q), self._evaluated(state)[1]))

    def _update_latches(self, previous, new):
        hinges = [h for h in self.model.hinges if h.stop_angle is not None and not previous.latched.get(h.name)]
        if not hinges:
            return
        old, now = self._evaluated(previous)[2], self._evaluated(new)[2]
        for h in hinges:
            a, b = old[h.name] - h.stop_angle, now[h.name] - h.stop_angle
            # the fold angle reached the stop, from either side (a wing folded either way); not a jump of the
            # angle across +-180 deg, where it wraps (a step turns the hinge far less than half a turn)
            if a * b <= 0 and abs(a - b) < math.pi:
                new.latched = {**new.latched, h.name: True}
                fraction = a / (a - b) if a != b else 0.0
                new.latch_times = {**new.latch_times, h.name: previous.t + fraction * (new.t - previous.t)}
                self.integrator.reset()

    # ---------------------------------------------------------------- outputs
    def _evaluated(self, state):
        """(E, dE, fold angles {hinge: rad}, constraint residual max |Phi|) of `state`, computed once per
        state: the step's checks and latch detection and the slave's outputs all read them. The last two
        states are kept (latch detection compares a step's end with its start)."""
        for cached, values in self._cache:
            if cached is state:
                return values
        kernel = step_kernel.kernel_for(self.model)
        if kernel is not None:          # the same in one compiled call
            values = kernel.evaluate(state.q, state.dq, state.t)
        else:
            E, dE, _ = self.model.coordinates(state.q, state.dq, state.t)
            residual = self.model.constraint_violation(state.q, E)
            values = (E, dE, self.model.fold_angles(state.q, E), residual)
        self._cache = ((state, values), self._cache[0])
        return values

    @property
    def e(self) -> np.ndarray:
        """(n,) exchanged coordinates E at the current state, m and 1, global frame (a copy)."""
        return self._evaluated(self.state)[0].copy()

    @property
    def de(self) -> np.ndarray:
        """(n,) their rates dE/dt at the current state, m/s and 1/s, global frame (a copy)."""
        return self._evaluated(self.state)[1].copy()

    def constraint_residual(self) -> float:
        """Largest |Phi| of the internal constraints at the current state."""
        return self._evaluated(self.state)[3]

    def fold_angles_deg(self) -> dict:
        """{revolute: fold angle, deg} at the current state."""
        return {k: math.degrees(v) for k, v in self._evaluated(self.state)[2].items()}

    def sensor_outputs(self) -> np.ndarray:
        """The scene's probes and strain gauges at the current state, flat in the order of
        `self.sensors.output_names()`: probe positions (m), velocities (m/s) and accelerations (m/s^2), gauge
        strains (1)."""
        E, dE, _, _ = self._evaluated(self.state)
        return self.sensors.outputs(E, dE, self.acceleration_E() if self.sensors.probe_names else np.zeros_like(E),
                                    self.model.element_curvatures(self.state.q))

    def probe_positions(self) -> np.ndarray:
        """(n_probes, 3) global positions of the probes at the current state, m (`Sensors.positions`)."""
        return self.sensors.positions(self._evaluated(self.state)[0])

    def probe_velocities(self) -> np.ndarray:
        """(n_probes, 3) global velocities of the probes at the current state, m/s (`Sensors.velocities`)."""
        return self.sensors.velocities(self._evaluated(self.state)[1])

    def probe_accelerations(self) -> np.ndarray:
        """(n_probes, 3) global accelerations of the probes at the current state, m/s^2: S(x, y) d2E/dt2 with the
        accelerations of `acceleration_E`, a constrained solve."""
        if not self.sensors.probe_names:
            return np.zeros((0, 3))
        return self.sensors.velocities(self.acceleration_E())

    def gauge_strains(self) -> np.ndarray:
        """(n_gauges,) surface strains of the strain gauges at the current state, 1 (`Sensors.strains`)."""
        return self.sensors.strains(self._evaluated(self.state)[0], self.model.element_curvatures(self.state.q))

    def acceleration_E(self) -> np.ndarray:
        """d2E/dt2 (n,) at the current state under the generalized force of the last step (zero before the first):
        the index-1 accelerations evaluated here, not the integrator's (RK4 keeps those of a step's start)."""
        state = self.state
        if state.q.size == 0:
            return self.model.acceleration_E(state.q, state.dq, state.dq, state.t)
        ddq, _ = constrained_accelerations(self.model, state.t, state.q, state.dq, self._last_Q, state.latched)
        return self.model.acceleration_E(state.q, state.dq, ddq, state.t)

    def joint_monitor_names(self) -> list[str]:
        """Names of the joints' constraint monitors (`structure_fmu.joint_monitors`), in output order."""
        return [name for j in self.topology.joint_lines if j.parent is not None
                for name in monitor_names(j.name, j.kind)]

    def joint_monitors(self) -> dict:
        """{<joint>_point_mismatch (m), <joint>_axis_product / _axis_error (-)} at the current state."""
        return joint_monitors(self.topology.joint_lines, self.topology.bodies, self._evaluated(self.state)[0])

    def monitors(self) -> dict:
        """The monitors at the current state.

        Returns:
            {energy J, kinetic_energy J, external_work J, constraint_residual, latched {hinge: bool},
            latch_times {hinge: s}}.
        """
        kinetic = self.kinetic_energy()
        return {"energy": kinetic + self.potential_energy(),
                "kinetic_energy": kinetic,
                "external_work": self.state.work,
                "constraint_residual": self._evaluated(self.state)[3],
                "latched": {h: bool(self.state.latched.get(h)) for h in self.topology.hinge_names},
                "latch_times": dict(self.state.latch_times)}

    def kinetic_energy(self) -> float:
        """1/2 dE^T M dE at the current state, J."""
        dE = self._evaluated(self.state)[1]
        return 0.5 * float(np.dot(dE, np.dot(self.model.mass_E, dE)))

    def potential_energy(self) -> float:
        """Potential energy at the current state (springs, elastic energy, gravity: the model's), J."""
        E, _, angles, _ = self._evaluated(self.state)
        return self.model.potential_energy(self.state.q, E, self.state.latched, angles)

    def state_identity(self) -> dict:
        """What a state must have been saved with to be set here, by scene key: {"structure.fidelity": name,
        "structure.integrator": name} (the sizes are those of the state's arrays,
        fmu_common.fmi_state.form_mismatch)."""
        return {"structure.fidelity": self.fidelity_name, "structure.integrator": self.integrator.name}

    def get_state(self):
        """Complete internal state, deep-copied, with the integrator's `memory` (generalized-alpha's Newton matrix,
        by reference: it is replaced, never modified in place), so that a rolled-back step repeats bit for bit."""
        return (self.state.copy(), self._initialized, self.integrator.memory, self._last_Q.copy())

    def set_state(self, saved) -> None:
        """Restore a state made by `get_state` (copied, so that it can be restored again).

        Args:
            saved: what `get_state` returned.
        """
        state, initialized, memory, last_Q = saved
        self.state, self._initialized, self._last_Q = state.copy(), initialized, last_Q.copy()
        self.integrator.memory = memory
