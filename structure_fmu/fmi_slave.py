"""What the structure and aero FMI slaves share: pythonfmu plumbing, no physics.

`SolverSlave` is an abstract pythonfmu slave over a solver (`StructureSolver`, `AeroSolver`): one Real value
buffer laid out contiguously (get/set by numpy fancy indexing), variables with SI units and a
UnitDefinitions block, tunable parameters applied at exitInitializationMode, the complete state (solver
internals, inputs, parameters) saved, restored and pickled. Pythonfmu's builder skips abstract classes, so a
slave module that imports it still exposes exactly one concrete slave.

Facts about pythonfmu 0.7.0 this encodes (measured, see docs/fmu.md):
  * a Python exception in an FMI call becomes fmi2Fatal and the wrapper then releases the slave class and
    instance twice (reference counts corrupted, the host segfaults later in the garbage collector): after
    construction no call raises; failures are logged at error status, do_step returns False
    (fmi2Discard) with the state unchanged, and a unit that cannot go on refuses every later step;
  * log text is passed to the FMI logger as a printf format: '%' is doubled;
  * pythonfmu has no unit attribute on variables: `UnitReal` adds one.
"""
from __future__ import annotations

import json
import math
import os
import pickle
import re
import traceback
from xml.etree.ElementTree import Element, SubElement

import numpy as np
from pythonfmu import Fmi2Causality, Fmi2Initial, Fmi2Slave, Fmi2Variability, Real, String
from pythonfmu.enums import Fmi2Status

from .errors import InputError, SolverDiverged

SCENE_RESOURCE = "scene.json"
_COMPONENTS = [(vec, axis) for vec in ("r", "r_x", "r_y") for axis in "xyz"]
_BNAME = re.compile(r"[A-Za-z_][A-Za-z0-9_]*")
COORDINATE_UNITS = {"r": ("m", "m/s", "N"), "r_x": ("1", "1/s", "N.m"), "r_y": ("1", "1/s", "N.m")}
"""Per vector of a node: units of e, de and the work-conjugate generalized force Q (000 Eq. 12)."""


def fmi_name(name: str) -> str:
    """FMI structured name for a dotted name: parts that are not identifiers are quoted ('outer wing')."""
    return ".".join(p if _BNAME.fullmatch(p) else "'" + p.replace("'", "_") + "'" for p in name.split("."))


def read_scene(resources: str | None, label: str) -> dict:
    """The resolved scene stored as `scene.json` in the resources folder (a path or a file:// URI)."""
    if not resources:
        raise FileNotFoundError(f"{label}: no resources folder given, so no scene.json to read")
    folder = resources[len("file://"):] if resources.startswith("file://") else resources
    path = os.path.join(folder, SCENE_RESOURCE)
    try:
        with open(path, encoding="utf-8") as f:
            return json.load(f)
    except FileNotFoundError:
        raise FileNotFoundError(f"{label}: resource {path} is missing; rebuild the FMU") from None


def coordinate_description(topology, k: int) -> tuple[str, str, str]:
    """(node name, component label like 'r_x[z]', vector 'r' | 'r_x' | 'r_y') of 0-based coordinate k."""
    vec, axis = _COMPONENTS[k % 9]
    return topology.node_names[k // 9], f"{vec}[{axis}]", vec


class UnitReal(Real):
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


class SolverSlave(Fmi2Slave):
    """Abstract slave over a solver. Subclasses set `label` and `solver_class`, lay out `self._real`
    (with `self._settable` and `self.sl_par`, the parameters' slice), register their variables with `_reg`
    and `_register_parameters_and_hash`, and implement `_publish` and `do_step` (using `_advance`)."""

    label = "unit"
    solver_class = None

    def _start(self, tunables: dict, solver_parameters: dict | None = None):
        """Common construction: the tunables, a solver with the defaults, the bookkeeping of a run."""
        self.tunables = tunables
        self.defaults = {name: float(v[0]) for name, v in tunables.items()}
        self._solver = self.solver_class(self.scene, parameters=solver_parameters)
        self._solver_parameters = dict(self.defaults)
        self._t0 = 0.0                                  # FMI start time; solver time = t - t0
        self._initialized = False
        self._checked_references = {}   # ("get" | "set", value references) -> index array, checked once
        self._failure: str | None = None                # set when the unit cannot go on

    # ---- variables ------------------------------------------------------------------------------
    def _reg(self, name, index, unit, description, **kw):
        var = UnitReal(name, unit=unit, description=description,
                       getter=lambda i=index: float(self._real[i]), **kw)
        if self._settable[index]:
            var.setter = lambda v, i=index: self.set_real([i], [v])
        self.register_variable(var, nested=False)
        assert var.value_reference == index, "value references must follow the buffer layout"

    def _register_parameters_and_hash(self, other_unit: str):
        for j, (name, (default, unit, text)) in enumerate(self.tunables.items()):
            self._reg(fmi_name(name), self.sl_par.start + j, unit, text, causality=Fmi2Causality.parameter,
                      variability=Fmi2Variability.fixed, initial=Fmi2Initial.exact, start=float(default))
        self.register_variable(String("topology_hash", causality=Fmi2Causality.output,
                                      variability=Fmi2Variability.constant, initial=Fmi2Initial.exact,
                                      description=f"hash of the structural topology; must match the {other_unit}'s",
                                      getter=lambda: self.topology_hash), nested=False)

    def to_xml(self, model_options=dict()):
        """pythonfmu's model description plus the UnitDefinitions of every declared unit."""
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
        at = next(i for i, c in enumerate(list(root)) if c.tag == "CoSimulation") + 1
        root.insert(at, defs)
        return root

    # ---- logging --------------------------------------------------------------------------------
    def log(self, msg: str, status: Fmi2Status = Fmi2Status.ok, category: str | None = None, debug=None):
        """Log for the host, '%' doubled (pythonfmu passes the text to the FMI logger as a printf format)."""
        super().log(msg.replace("%", "%%"), status, category)

    def _error(self, msg: str) -> None:
        self.log(msg, Fmi2Status.error)

    def _fail(self, msg: str) -> None:
        """Log an error and refuse every further step until a good state is set (the call itself returns)."""
        self._failure = msg
        self._error(msg)

    # ---- FMI calls: none raises ------------------------------------------------------------------
    def get_real(self, vrs):
        key = ("get", tuple(vrs))
        idx = self._checked_references.get(key)
        if idx is None:
            idx = np.asarray(vrs, dtype=np.intp)
            ok = (idx >= 0) & (idx < self._real.size)
            if not ok.all():
                self._error(f"{self.label}: value references {idx[~ok].tolist()} are not Real variables")
                out = np.full(idx.size, np.nan)
                out[ok] = self._real[idx[ok]]
                return out.tolist()
            self._checked_references[key] = idx
        return self._real[idx].tolist()

    def set_real(self, vrs, values):
        key = ("set", tuple(vrs))
        idx = self._checked_references.get(key)
        if idx is None:
            idx = np.asarray(vrs, dtype=np.intp)
            if idx.size == 0:
                return
            ok = (idx >= 0) & (idx < self._real.size)
            ok[ok] = self._settable[idx[ok]]
            if not ok.all():
                names = [self.vars[int(i)].name if int(i) in self.vars else str(int(i)) for i in idx[~ok]]
                self._error(f"{self.label}: cannot set {', '.join(names)}: only the inputs and the parameters are "
                            "settable; nothing was set")
                return
            if self._initialized and idx.max() >= self.sl_par.start:
                names = [self.vars[int(i)].name for i in idx[idx >= self.sl_par.start]]
                self._error(f"{self.label}: cannot set {', '.join(names)} after initialization (parameters have "
                            "variability 'fixed'); nothing was set")
                return
            if idx.max() < self.sl_par.start:        # inputs only: settable in every mode, check them once
                self._checked_references[key] = idx
        self._real[idx] = values

    def setup_experiment(self, start_time, stop_time=None, tolerance=None):
        self._t0 = float(start_time)

    def exit_initialization_mode(self):
        self._initialized = True
        parameters = dict(zip(self.tunables, self._real[self.sl_par].tolist()))
        if parameters == self._solver_parameters:
            return
        try:
            self._solver = self.solver_class(self.scene, parameters=parameters)
            self._solver_parameters = parameters
            self._publish()
        except Exception as exc:  # noqa: BLE001
            self._fail(f"{self.label}: the parameters were refused: {type(exc).__name__}: {exc}")

    def _non_finite(self, label: str, block: slice, what: str, current_time) -> str | None:
        """The reason the input block `label` (e.g. Q) cannot be used (NaN or inf), or None."""
        x = self._real[block]
        finite = np.isfinite(x)
        if finite.all():
            return None
        k = int(np.argmin(finite))
        node, comp, _ = coordinate_description(self.topology, k)
        value = "NaN" if np.isnan(x[k]) else ("+inf" if x[k] > 0 else "-inf")
        return (f"input {label}[{k + 1}] ({what} node {node} {comp}) is {value} ({int((~finite).sum())} of "
                f"{x.size} {label} inputs are NaN or inf): step at t = {current_time:.6g} s rejected, "
                "state unchanged")

    def _advance(self, current_time, advance) -> bool:
        """Run `advance()` (the solver's step); log any failure with its reason and return False."""
        if self._failure is not None:
            self._error(f"{self.label} cannot step: {self._failure}")
            return False
        try:
            advance()
            self._publish()
        except SolverDiverged as exc:
            self._error(f"{self.label}: solver diverged at t = {exc.time:.6g} s: {exc.reason}. Hint: {exc.hint}")
            return False
        except InputError as exc:
            self._error(f"{self.label} rejected its input at t = {current_time:.6g} s: {exc}")
            return False
        except Exception as exc:  # noqa: BLE001 - any failure must reach the host as a logged reason
            where = traceback.extract_tb(exc.__traceback__)[-1]
            self._error(f"{self.label} failed at t = {current_time:.6g} s: {type(exc).__name__}: {exc} "
                        f"({os.path.basename(where.filename)}:{where.lineno})")
            return False
        return True

    # ---- state: complete (solver internals, inputs, outputs, parameters), arrays copied ----------
    def _get_fmu_state(self):
        try:
            return {"solver": self._solver.get_state(), "real": self._real.copy(), "t0": self._t0,
                    "initialized": self._initialized, "failure": self._failure,
                    "solver_parameters": dict(self._solver_parameters)}
        except Exception as exc:  # noqa: BLE001
            self._error(f"{self.label}: getting the state failed: {type(exc).__name__}: {exc}")
            return {"error": f"the state could not be saved ({type(exc).__name__}: {exc})"}

    def _set_fmu_state(self, state):
        try:
            if "error" in state:
                raise ValueError(state["error"])
            if state["solver_parameters"] != self._solver_parameters:
                self._solver = self.solver_class(self.scene, parameters=state["solver_parameters"])
                self._solver_parameters = dict(state["solver_parameters"])
            self._solver.set_state(state["solver"])
            self._real[:] = state["real"]
            self._t0, self._initialized, self._failure = state["t0"], state["initialized"], state["failure"]
        except Exception as exc:  # noqa: BLE001
            self._fail(f"{self.label}: setting the state failed: {type(exc).__name__}: {exc}")

    @staticmethod
    def _fmu_state_to_bytes(state) -> bytes:
        try:
            return pickle.dumps(state, protocol=pickle.HIGHEST_PROTOCOL)
        except Exception as exc:  # noqa: BLE001 - never raise
            return pickle.dumps({"error": f"the state could not be serialized ({type(exc).__name__}: {exc})"})

    @staticmethod
    def _fmu_state_from_bytes(state: bytes):
        try:
            return pickle.loads(state)
        except Exception as exc:  # noqa: BLE001
            return {"error": f"the serialized state could not be read ({type(exc).__name__}: {exc})"}
