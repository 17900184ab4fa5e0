"""FMI 2.0 co-simulation slave of the structure unit (pythonfmu), a thin adapter over StructureSolver.

No physics lives here: every number comes from `structure_fmu.solver.StructureSolver` (docs/solver_api.md).
The resolved scene is read from the resource `scene.json` (inside the FMU, or the folder given as
`resources` when the class is instantiated in-process by the `direct` backend).

Variables, with value references laid out contiguously so that get/set are numpy fancy indexing
(n = Topology.n_coordinates, H = number of hinges, P = number of tunable parameters):

| vr                | name                      | causality / variability  | unit                              |
|-------------------|---------------------------|--------------------------|-----------------------------------|
| 0 .. n-1          | e[1] .. e[n]              | output, continuous       | m for r, 1 for r_x, r_y           |
| n .. 2n-1         | de[1] .. de[n]            | output, continuous       | m/s for r, 1/s for r_x, r_y       |
| 2n .. 3n-1        | Q[1] .. Q[n]              | input, continuous (0)    | N for r, N.m for r_x, r_y         |
| 3n .. 3n+H-1      | fold_angle_<hinge>        | output, continuous       | deg                               |
| 3n+H              | energy                    | output, continuous       | J                                 |
| 3n+H+1            | kinetic_energy            | output, continuous       | J                                 |
| 3n+H+2            | constraint_residual       | output, continuous       | 1                                 |
| 3n+H+3 ..         | <tunable parameter>       | parameter, fixed         | as StructureSolver declares       |
| last              | topology_hash (String)    | output, constant         | -                                 |

Per node the 9 coordinates are r (3), r_x (3), r_y (3) in the global frame; Q is work-conjugate to e,
hence N for r and N.m (= J) for the dimensionless gradients.

Errors: after construction no FMI call raises. A non-finite Q, `InputError`, `SolverDiverged` or any other
failure in `do_step` is logged at error status with its reason and `do_step` returns False, which
pythonfmu 0.7.0 reports as fmi2Discard; the host can roll back (set an earlier state) or stop. Other
refused calls (bad parameters at exitInitializationMode, setting an output, a state that cannot be set)
return normally with an error logged, and the ones that leave the unit unusable make every later
`do_step` fail with that reason. Hosts should treat an error-status log message as a failed call
(orchestrator.units does). Reason: in pythonfmu 0.7.0 a raised exception becomes fmi2Fatal AND its
wrapper then releases the slave class and instance twice, corrupting reference counts (the host process
segfaults later, in the garbage collector).
"""
from __future__ import annotations

import json
import math
import os
import pickle
import re
import sys
import traceback

import numpy as np
from pythonfmu import DefaultExperiment, Fmi2Causality, Fmi2Initial, Fmi2Slave, Fmi2Variability, Real, String
from pythonfmu.enums import Fmi2Status

try:
    from structure_fmu.errors import InputError, SolverDiverged
except ImportError:  # only the folder of this script is on sys.path: add the one holding structure_fmu/
    _here = os.path.dirname(os.path.abspath(__file__))
    for _cand in (_here, os.path.dirname(_here)):
        if os.path.isfile(os.path.join(_cand, "structure_fmu", "errors.py")):
            sys.path.append(_cand)
            break
    from structure_fmu.errors import InputError, SolverDiverged
from structure_fmu.solver import StructureSolver
from structure_fmu.topology import Topology

SCENE_RESOURCE = "scene.json"
_COMPONENTS = [(vec, axis) for vec in ("r", "r_x", "r_y") for axis in "xyz"]
_BNAME = re.compile(r"[A-Za-z_][A-Za-z0-9_]*")


def fmi_name(name: str) -> str:
    """FMI structured name for a dotted name: parts that are not identifiers are quoted ('outer wing')."""
    return ".".join(p if _BNAME.fullmatch(p) else "'" + p.replace("'", "_") + "'" for p in name.split("."))


def read_scene(resources: str | None) -> dict:
    """The resolved scene stored as `scene.json` in the resources folder (a path or a file:// URI)."""
    if not resources:
        raise FileNotFoundError("structure unit: no resources folder given, so no scene.json to read")
    folder = resources[len("file://"):] if resources.startswith("file://") else resources
    path = os.path.join(folder, SCENE_RESOURCE)
    try:
        with open(path, encoding="utf-8") as f:
            return json.load(f)
    except FileNotFoundError:
        raise FileNotFoundError(f"structure unit: resource {path} is missing; rebuild the FMU") from None


class _UnitReal(Real):
    """pythonfmu Real with a declared SI unit (pythonfmu 0.7.0 has no unit attribute)."""

    def __init__(self, name: str, unit: str | None = None, **kwargs):
        super().__init__(name, **kwargs)
        self.unit = unit

    def to_xml(self):
        node = super().to_xml()
        if self.unit:
            node.find("Real").set("unit", self.unit)
        return node


# Base-unit exponents (kg, m, s, A, K, mol, cd, rad) and factor of the symbols our units are made of.
_SYMBOLS = {
    "1": ({}, 1.0), "-": ({}, 1.0), "kg": ({"kg": 1}, 1.0), "m": ({"m": 1}, 1.0), "s": ({"s": 1}, 1.0),
    "rad": ({"rad": 1}, 1.0), "deg": ({"rad": 1}, math.pi / 180.0), "N": ({"kg": 1, "m": 1, "s": -2}, 1.0),
    "J": ({"kg": 1, "m": 2, "s": -2}, 1.0), "W": ({"kg": 1, "m": 2, "s": -3}, 1.0),
    "Pa": ({"kg": 1, "m": -1, "s": -2}, 1.0), "Hz": ({"s": -1}, 1.0), "K": ({"K": 1}, 1.0),
}


def base_unit(unit: str) -> tuple[dict, float] | None:
    """Exponents and factor of a unit string like 'N.m/rad', 'N m s/rad', 'm/s2', 'm/s^2', '1/s'.

    Symbols are separated by spaces, '.' or '*', with at most one '/'; None if not understood.
    """
    parts = unit.split("/")
    if len(parts) > 2:
        return None
    exps: dict[str, int] = {}
    factor = 1.0
    for sign, part in zip((1, -1), parts):
        for token in part.replace("*", " ").replace(".", " ").split():
            m = re.fullmatch(r"([A-Za-z]+|1|-)\^?(-?\d+)?", token)
            if m is None or m.group(1) not in _SYMBOLS:
                return None
            p = sign * int(m.group(2) or 1)
            for k, v in _SYMBOLS[m.group(1)][0].items():
                exps[k] = exps.get(k, 0) + p * v
            factor *= _SYMBOLS[m.group(1)][1] ** p
    return {k: v for k, v in exps.items() if v}, factor


def coordinate_description(topology, k: int) -> tuple[str, str, str]:
    """(node name, component label like 'r_x[z]', vector 'r' | 'r_x' | 'r_y') of 0-based coordinate k."""
    vec, axis = _COMPONENTS[k % 9]
    node = topology.node_names[k // 9]
    return node, f"{vec}[{axis}]", vec


class StructureSlave(Fmi2Slave):
    author = "wingsim"
    description = "Structure unit: ANCF wing bodies, hinges, actuators and latches (wingsim)"

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.scene = read_scene(self.resources)
        self.modelName = "structure"
        self.topology = Topology.from_scene(self.scene)
        self.topology_hash = str(self.topology.topology_hash)
        n = self.n = int(self.topology.n_coordinates)
        self.hinges = list(self.topology.hinge_names)
        self.tunables = StructureSolver.tunable_parameters(self.scene)
        self.defaults = {name: float(v[0]) for name, v in self.tunables.items()}

        self._solver = StructureSolver(self.scene)          # defaults; supplies the initial outputs
        self._solver_parameters = dict(self.defaults)
        self._t0 = 0.0                                      # FMI start time; solver time = t - t0
        self._initialized = False
        self._failure: str | None = None                    # set when the unit cannot go on

        nh, npar = len(self.hinges), len(self.tunables)
        self.sl_e, self.sl_de, self.sl_q = slice(0, n), slice(n, 2 * n), slice(2 * n, 3 * n)
        self.sl_fold = slice(3 * n, 3 * n + nh)
        self.i_energy, self.i_kinetic, self.i_residual = 3 * n + nh, 3 * n + nh + 1, 3 * n + nh + 2
        self.sl_par = slice(3 * n + nh + 3, 3 * n + nh + 3 + npar)
        self._real = np.zeros(self.sl_par.stop)
        self._real[self.sl_par] = list(self.defaults.values())
        self._settable = np.zeros(self._real.size, dtype=bool)
        self._settable[self.sl_q] = True
        self._settable[self.sl_par] = True
        self._publish()
        self._register(n)

        stop = self.scene.get("time", {}).get("stop")
        step = self.scene.get("coupling", {}).get("step")
        self.default_experiment = DefaultExperiment(start_time=0.0, stop_time=stop, step_size=step)

    # ---- variables ------------------------------------------------------------------------------
    def _reg(self, name, index, unit, description, **kw):
        var = _UnitReal(name, unit=unit, description=description,
                        getter=lambda i=index: float(self._real[i]), **kw)
        if self._settable[index]:
            var.setter = lambda v, i=index: self.set_real([i], [v])
        self.register_variable(var, nested=False)
        assert var.value_reference == index, "value references must follow the buffer layout"

    def _register(self, n):
        out = dict(causality=Fmi2Causality.output, variability=Fmi2Variability.continuous,
                   initial=Fmi2Initial.exact)
        units = {"r": ("m", "m/s", "N"), "r_x": ("1", "1/s", "N.m"), "r_y": ("1", "1/s", "N.m")}
        for k in range(n):
            node, comp, vec = coordinate_description(self.topology, k)
            self._reg(f"e[{k + 1}]", k, units[vec][0], f"node {node} {comp}", **out)
        for k in range(n):
            node, comp, vec = coordinate_description(self.topology, k)
            self._reg(f"de[{k + 1}]", n + k, units[vec][1], f"rate of node {node} {comp}", **out)
        for k in range(n):
            node, comp, vec = coordinate_description(self.topology, k)
            self._reg(f"Q[{k + 1}]", 2 * n + k, units[vec][2], f"generalized force on node {node} {comp}",
                      causality=Fmi2Causality.input, variability=Fmi2Variability.continuous, start=0.0)
        for j, hinge in enumerate(self.hinges):
            self._reg(fmi_name(f"fold_angle_{hinge}"), self.sl_fold.start + j, "deg",
                      f"fold angle of hinge {hinge} (child root r_x from parent tip r_x, about r_y)", **out)
        self._reg("energy", self.i_energy, "J", "energy monitor of the structure solver", **out)
        self._reg("kinetic_energy", self.i_kinetic, "J", "kinetic energy of the structure (1/2 de^T M de)",
                  **out)
        self._reg("constraint_residual", self.i_residual, "1", "constraint residual monitor (max norm)", **out)
        for j, (name, (default, unit, text)) in enumerate(self.tunables.items()):
            self._reg(fmi_name(name), self.sl_par.start + j, unit, text, causality=Fmi2Causality.parameter,
                      variability=Fmi2Variability.fixed, initial=Fmi2Initial.exact, start=float(default))
        self.register_variable(String("topology_hash", causality=Fmi2Causality.output,
                                      variability=Fmi2Variability.constant, initial=Fmi2Initial.exact,
                                      description="hash of the structural topology; must match the aero unit's",
                                      getter=lambda: self.topology_hash), nested=False)

    def to_xml(self, model_options=dict()):
        """pythonfmu's model description plus the UnitDefinitions of every declared unit."""
        from xml.etree.ElementTree import Element, SubElement
        root = super().to_xml(model_options)
        units = sorted({v.unit for v in self.vars.values() if getattr(v, "unit", None)})
        defs = Element("UnitDefinitions")
        for unit in units:
            node = SubElement(defs, "Unit", name=unit)
            parsed = base_unit(unit)
            if parsed is not None:
                exps, factor = parsed
                attrib = {k: str(v) for k, v in exps.items()}
                if factor != 1.0:
                    attrib["factor"] = repr(factor)
                SubElement(node, "BaseUnit", attrib)
        children = list(root)
        at = next(i for i, c in enumerate(children) if c.tag == "CoSimulation") + 1
        root.insert(at, defs)
        return root

    def log(self, msg: str, status: Fmi2Status = Fmi2Status.ok, category: str | None = None, debug=None):
        """Log for the host; '%' is doubled because pythonfmu passes the text to the FMI logger as a
        printf format (an unescaped '%s' would read garbage)."""
        super().log(msg.replace("%", "%%"), status, category)

    def _error(self, msg: str) -> None:
        self.log(msg, Fmi2Status.error)

    def _fail(self, msg: str) -> None:
        """Log an error and refuse every further step until a good state is set (the call itself returns)."""
        self._failure = msg
        self._error(msg)

    # ---- FMI calls ------------------------------------------------------------------------------
    # None of these raises: with pythonfmu 0.7.0 a Python exception in an FMI call is fmi2Fatal and the
    # wrapper then releases the slave class and instance twice (refcount corruption, later segfault).
    # Failures are logged at error status instead; do_step returns False (fmi2Discard).
    def get_real(self, vrs):
        idx = np.asarray(vrs, dtype=np.intp)
        ok = (idx >= 0) & (idx < self._real.size)
        if ok.all():
            return self._real[idx].tolist()
        self._error(f"structure unit: value references {idx[~ok].tolist()} are not Real variables")
        out = np.full(idx.size, np.nan)
        out[ok] = self._real[idx[ok]]
        return out.tolist()

    def set_real(self, vrs, values):
        idx = np.asarray(vrs, dtype=np.intp)
        if idx.size == 0:
            return
        ok = (idx >= 0) & (idx < self._real.size)
        ok[ok] = self._settable[idx[ok]]
        if not ok.all():
            names = [self.vars[int(i)].name if int(i) in self.vars else str(int(i)) for i in idx[~ok]]
            self._error(f"structure unit: cannot set {', '.join(names)}: only the inputs Q[...] and the "
                        "parameters are settable; nothing was set")
            return
        if self._initialized and idx.max() >= self.sl_par.start:
            names = [self.vars[int(i)].name for i in idx[idx >= self.sl_par.start]]
            self._error(f"structure unit: cannot set {', '.join(names)} after initialization (parameters "
                        "have variability 'fixed'); nothing was set")
            return
        self._real[idx] = values

    def setup_experiment(self, start_time, stop_time=None, tolerance=None):
        self._t0 = float(start_time)

    def exit_initialization_mode(self):
        self._initialized = True
        parameters = dict(zip(self.tunables, self._real[self.sl_par].tolist()))
        if parameters == self._solver_parameters:
            return
        try:
            self._solver = StructureSolver(self.scene, parameters=parameters)
            self._solver_parameters = parameters
            self._publish()
        except Exception as exc:  # noqa: BLE001
            self._fail(f"structure unit: the parameters were refused: {type(exc).__name__}: {exc}")

    def do_step(self, current_time, step_size):
        if self._failure is not None:
            self._error(f"structure unit cannot step: {self._failure}")
            return False
        q = self._real[self.sl_q]
        finite = np.isfinite(q)
        if not finite.all():
            k = int(np.argmin(finite))
            node, comp, _ = coordinate_description(self.topology, k)
            value = "NaN" if np.isnan(q[k]) else ("+inf" if q[k] > 0 else "-inf")
            self._error(f"input Q[{k + 1}] (generalized force on node {node} {comp}) is {value} "
                        f"({int((~finite).sum())} of {q.size} inputs are NaN or inf): step at "
                        f"t = {current_time:.6g} s rejected, state unchanged")
            return False
        try:
            self._solver.advance(current_time + step_size - self._t0, q.copy())
            self._publish()
        except SolverDiverged as exc:
            self._error(f"structure solver diverged at t = {exc.time:.6g} s: {exc.reason}. Hint: {exc.hint}")
            return False
        except InputError as exc:
            self._error(f"structure unit rejected its input at t = {current_time:.6g} s: {exc}")
            return False
        except Exception as exc:  # noqa: BLE001 - any failure must reach the host as a logged reason
            where = traceback.extract_tb(exc.__traceback__)[-1]
            self._error(f"structure unit failed at t = {current_time:.6g} s: {type(exc).__name__}: {exc} "
                        f"({os.path.basename(where.filename)}:{where.lineno})")
            return False
        return True

    def _publish(self):
        """Copy the solver's state and monitors into the output slots of the value buffer."""
        s = self._solver
        e = s.e
        self._real[self.sl_e] = e
        self._real[self.sl_de] = s.de
        if self.hinges:
            angles = s.fold_angles_deg()
            self._real[self.sl_fold] = [angles[h] for h in self.hinges]
        m = s.monitors()
        self._real[self.i_energy] = m["energy"]
        self._real[self.i_kinetic] = m["kinetic_energy"]
        self._real[self.i_residual] = m["constraint_residual"]

    # ---- state: complete (solver internals, inputs, parameters), arrays copied ------------------
    def _get_fmu_state(self):
        try:
            return {"solver": self._solver.get_state(), "real": self._real.copy(), "t0": self._t0,
                    "initialized": self._initialized, "failure": self._failure,
                    "solver_parameters": dict(self._solver_parameters)}
        except Exception as exc:  # noqa: BLE001
            self._error(f"structure unit: getting the state failed: {type(exc).__name__}: {exc}")
            return {"error": f"the state could not be saved ({type(exc).__name__}: {exc})"}

    def _set_fmu_state(self, state):
        try:
            if "error" in state:
                raise ValueError(state["error"])
            if state["solver_parameters"] != self._solver_parameters:
                self._solver = StructureSolver(self.scene, parameters=state["solver_parameters"])
                self._solver_parameters = dict(state["solver_parameters"])
            self._solver.set_state(state["solver"])
            self._real[:] = state["real"]
            self._t0, self._initialized, self._failure = state["t0"], state["initialized"], state["failure"]
        except Exception as exc:  # noqa: BLE001
            self._fail(f"structure unit: setting the state failed: {type(exc).__name__}: {exc}")

    @staticmethod
    def _fmu_state_to_bytes(state) -> bytes:
        try:
            return pickle.dumps(state, protocol=pickle.HIGHEST_PROTOCOL)
        except Exception as exc:  # noqa: BLE001 - see "FMI calls" above: never raise
            return pickle.dumps({"error": f"the state could not be serialized ({type(exc).__name__}: {exc})"})

    @staticmethod
    def _fmu_state_from_bytes(state: bytes):
        try:
            return pickle.loads(state)
        except Exception as exc:  # noqa: BLE001
            return {"error": f"the serialized state could not be read ({type(exc).__name__}: {exc})"}
