"""AeroSolver: the aero unit's solver API (docs/aero_api.md), a thin owner of one aero model and its state.

Built from the aero unit's spec (fmu_common.specs.AeroUnitSpec): aero.model (strip | uvlm-flat |
uvlm-prescribed | uvlm-free), aero.chordwise_panels, aero.spanwise_panels, aero.wake_length (chords; inf
allowed), aero.step (s, or None), aero.span_correction, flow.speed, flow.density, flow.direction; the structure
table builds the same `fmu_common.topology.Topology` as the structure unit. Tunable parameters: flow.speed
(m/s), flow.density (kg/m^3), flow.direction[1], [2], [3] (the components of flow.direction, any length:
the solver normalizes them).

Multi-rate (aero.step): `advance(t_end, e, de)` takes k = ceil((t_end - t) / aero.step) equal model steps
over [t, t_end] when t_end - t exceeds aero.step (1e-9 relative slack, so a communication step equal to
k aero steps up to rounding is k steps, not k + 1). The unit only receives e, de at t_end, so the inner
steps use e, de interpolated linearly in time from the inputs of the previous advance (at t; held at the
first advance), the last one the inputs themselves. Those previous inputs are part of the saved state
(`AeroState`). Without aero.step every advance is one model step, exactly as before the key existed.

Pairing check (aero_fmu.pairing): the first advance (from a model state not started: after construction,
or after restoring a state saved before the first advance, so an implicit coupling's repeated first step is
checked each time) refuses an e whose node positions are not this unit's initial ones, within
1e-3 x the sum of the body lengths, plus 2 |de_r| (t_end - time) for the motion a correct structure may
already have made, plus the pose a prescribed pitch gives at t = 0: a structure unit of another wing
geometry, paired by a tool that does not compare `topology_hash`. Later advances are not checked (a
flexible wing may deform far from its initial shape).

Errors: SceneError (bad scene value or parameter, naming it), InputError (e or de of the wrong size or
with NaN/inf, naming the first bad entry by its FMI name e[k], de[k], 1-based; t_end before the current
time; at the first advance, an e of another wing geometry: the message names this unit's scene, lattice,
reference length and topology_hash, the node that is off with both positions, the distance and the
tolerance), SolverDiverged (a singular influence matrix from degenerate panels, or a non-finite result).
"""
import math
from dataclasses import dataclass

import numpy as np

from fmu_common.errors import InputError, SceneError, SolverDiverged, checked_input
from fmu_common.scene_schema import parameter_values
from fmu_common.topology import Topology
from fmu_common.scene_bounds import substep_count
from fmu_common.specs import AeroUnitSpec
from fmu_common.vectors import unit

from .hinge_moments import hinge_lines, hinge_moments
from .models import build_model
from .pairing import PairingCheck
from .wake import MAX_WAKE_ROWS

_HINT = "check the wing geometry (zero-area or coincident panels) and the aero time step"


@dataclass
class AeroState:
    """What AeroSolver.get_state() saves: `model`, the model's state (uvlm.UVLMState or strip.StripState),
    and `inputs`, the (e, de) (n,) of the last advance, at model.time (None before the first): where the
    next multi-rate advance starts its interpolation. The model state's attributes (time, gamma, wake,
    loads, ...) read through, so a saved state looks like the model's."""
    model: object
    inputs: tuple | None

    def copy(self) -> "AeroState":
        """A copy that shares no array with this state."""
        return AeroState(self.model.copy(), _copied(self.inputs))

    def __getattr__(self, name):
        if name == "model":         # not set yet (unpickling looks up __setstate__ first): no recursion
            raise AttributeError(name)
        return getattr(self.model, name)


def _copied(inputs):
    return None if inputs is None else tuple(a.copy() for a in inputs)


def interpolated_inputs(previous, e, de, k: int):
    """The inputs of k substeps, linearly interpolated over the interval.

    Args:
        previous: (e, de) at the interval's start; None: held at e, de.
        e: (n,) exchanged coordinates at its end, m and 1, global frame.
        de: (n,) their rates at its end, per s.
        k: number of substeps.

    Returns:
        [(s_j, e_j, de_j)] for j = 1..k, s_j = j / k the time fraction; the last one is e, de themselves (no
        rounding).
    """
    e0, de0 = previous if previous is not None else (e, de)
    inner = [(j / k, e0 + (j / k) * (e - e0), de0 + (j / k) * (de - de0)) for j in range(1, k)]
    return inner + [(1.0, e, de)]


class AeroSolver:
    """The aerodynamic solver of one scene. See docs/aero_api.md.

    Args:
        spec: the aero unit's spec (fmu_common.specs.AeroUnitSpec).
        parameters: {name: value} of tunable parameters (`tunable_parameters`), SI units; None: the defaults.
        max_wake_rows: keyword, not a scene key: cap of shed wake rows (wake.MAX_WAKE_ROWS by default).
    """

    def __init__(self, spec: AeroUnitSpec, parameters: dict | None = None, *, max_wake_rows: int = MAX_WAKE_ROWS):
        self.topology = Topology.from_spec(spec.structure)
        aero = spec.aero
        if not aero.model.builds_unit:
            raise SceneError("aero.model", aero.model.name, "an aero model: \"none\" builds no aero unit")
        self.step = aero.step
        values = parameter_values(self.tunable_parameters(spec), parameters)
        for name in ("flow.speed", "flow.density"):
            if values[name] < 0:
                raise SceneError(name, values[name], "a value >= 0")
        direction = np.array([values[f"flow.direction[{i}]"] for i in (1, 2, 3)])
        try:
            self.direction = unit(direction)
        except ValueError:
            raise SceneError("flow.direction", list(direction), "a non-zero direction") from None
        self.parameters = values
        self.U = values["flow.speed"] * self.direction                   # free stream, m/s
        self.density = values["flow.density"]
        self.model = build_model(self.topology, aero, max_wake_rows)
        self.model_name = aero.model.name
        self.state = self.model.initial_state()
        self.inputs = None          # (e, de) of the last advance, at self.state.time
        self.pairing = PairingCheck(self.topology, spec.structure, self._description(spec))
        self.hinges = hinge_lines(self.topology, self.model.lattice)     # aero_fmu.hinge_moments

    def _description(self, spec: AeroUnitSpec) -> str:
        """This unit in words for the pairing check's message: scene, model, bodies, nodes, panels."""
        bodies = list(self.topology.bodies)
        lattice = self.model.lattice
        return (f"scene {spec.scene.name!r}, {spec.aero.model.name} lattice of {len(bodies)} "
                f"bod{'y' if len(bodies) == 1 else 'ies'} ({', '.join(bodies)}), {self.topology.n_nodes} nodes, "
                f"{lattice.n_panels} panels")

    @staticmethod
    def tunable_parameters(spec: AeroUnitSpec) -> dict:
        """The scalars a system tool may change before a run.

        The tunable keys of the scene's `flow` table (`fmu_common.scene_schema.tunable_parameters`).

        Args:
            spec: the aero unit's spec.

        Returns:
            {name: (default, unit, description)}.
        """
        return dict(spec.parameters)

    # ---------------------------------------------------------------- stepping
    @property
    def time(self) -> float:
        """Time of the current state, s."""
        return self.state.time

    @property
    def lattice(self):
        """The model's lattice (aero_fmu.lattice.Lattice)."""
        return self.model.lattice

    def advance(self, t_end: float, e, de) -> None:
        """The aero state at t_end for the coordinates and rates at t_end (docs/aero_api.md).

        One model step, or with aero.step k substeps on interpolated inputs (module docstring). The first advance
        (from a state not started) first checks that e comes from a structure of this unit's wing geometry
        (aero_fmu.pairing, module docstring). On an error the state is unchanged.

        Args:
            t_end: time to reach, s.
            e: (n,) exchanged coordinates at t_end, m and 1, global frame.
            de: (n,) their rates, per s.
        """
        n = self.topology.n_coordinates
        e, de = checked_input("e", e, n, self.state.time), checked_input("de", de, n, self.state.time)
        t_end = float(t_end)
        if not np.isfinite(t_end) or t_end < self.state.time - 1e-12 * max(1.0, abs(self.state.time)):
            raise InputError(f"t_end = {t_end} s is before the aero time {self.state.time} s: restore a saved "
                             "state (set_state) to repeat a step")
        t, t_end = self.state.time, max(t_end, self.state.time)
        if not self.state.started:
            self.pairing.check(e, de, t_end - t, t)
        k = substep_count(t_end - t, self.step)
        state = self.state
        for s, e_s, de_s in interpolated_inputs(self.inputs, e, de, k):
            state = self._model_step(state, t_end if s == 1.0 else t + s * (t_end - t), e_s, de_s)
        self.state, self.inputs = state, (e.copy(), de.copy())

    def _model_step(self, state, t_end, e, de):
        """The model's state at t_end (s) from `state` for e, de at t_end; SolverDiverged on a singular
        system or non-finite forces."""
        try:
            new = self.model.advance(state, t_end, e, de, self.U, self.density, self.direction)
        except np.linalg.LinAlgError as exc:
            raise SolverDiverged(t_end, str(exc), _HINT) from None
        loads = new.loads
        # a NaN or inf in any entry makes the sums NaN or inf (two reductions instead of four numpy calls)
        if not math.isfinite(float(loads.Q.sum()) + float(loads.forces.sum())):
            raise SolverDiverged(t_end, "the aerodynamic forces became NaN/inf", _HINT)
        return new

    # ---------------------------------------------------------------- outputs
    @property
    def Q(self) -> np.ndarray:
        """Generalized aerodynamic force (n,), N on r slots, N.m on r_x, r_y slots (Otsuka et al. 2019, Eq. 12);
        a copy."""
        return self.state.loads.Q.copy()

    def outputs(self) -> dict:
        """{"CL", "lift" N, "wake_panels" int, "drag" N, "side_force" N, "CD", "moment_x/_y/_z" N.m}
        (`loads.py`: axes, moments about the global origin); the same keys before the first step."""
        return dict(self.state.loads.outputs)

    def hinge_moments(self) -> dict:
        """{hinge: aerodynamic moment about its axis, N m} of every revolute joint, in `topology.hinge_names` order:
        a . sum (x_p - x_h) x F_p over the panels outboard of the hinge, axis a and point x_h at the coordinates of
        the last advance (aero_fmu.hinge_moments: positive about the axis as declared, the sense in which the fold
        angle grows, so T_const / M is the deployment torque scale); 0 before the first step."""
        if self.inputs is None:
            return {line.name: 0.0 for line in self.hinges}
        loads = self.state.loads
        return hinge_moments(self.hinges, self.inputs[0], loads.points, loads.forces)

    def panel_forces(self):
        """(points (P, 3) m, forces (P, 3) N) of the last step: the panel forces and where they act."""
        return self.state.loads.points.copy(), self.state.loads.forces.copy()

    def vortex_geometry(self) -> dict:
        """Read-only view of the vortex system at the last step, for pictures (arrays copied; m, global frame):

        "rings": (B, M + 1, N + 1, 3) the bound vortex-ring corners (`lattice.Lattice` numbering), None for
                 strip theory and before the first step;
        "wake", "wake_gamma": (B, R + 1, N + 1, 3) the shed wake's ring corners and (B, R, N) m^2/s their
                 circulations (`wake.ShedWake`), None without a shed wake (strip, uvlm-flat, before the
                 first step);
        "legs": uvlm-flat only (else None): (direction (3,), length (B,) m), the horseshoe legs leaving the
                 trailing corners rings[:, -1] along the unit free-stream direction, wake_length chords of
                 each body long (inf: semi-infinite), as `vlm.horseshoe_wake` builds them."""
        return self.model.vortex_geometry(self.state, self.direction)

    def state_identity(self) -> dict:
        """What a state must have been saved with to be set here, by scene key: {"aero.model": name} (the
        lattice's sizes are those of the state's arrays, fmu_common.fmi_state.form_mismatch)."""
        return {"aero.model": self.model_name}

    def get_state(self) -> AeroState:
        """Complete state including the wake and the last inputs (for the multi-rate interpolation), arrays
        copied."""
        return AeroState(self.state.copy(), _copied(self.inputs))

    def set_state(self, state: AeroState) -> None:
        """Restore a state from get_state() (copied: the caller's object stays its own).

        Args:
            state: what get_state() returned.
        """
        self.state, self.inputs = state.model.copy(), _copied(state.inputs)
