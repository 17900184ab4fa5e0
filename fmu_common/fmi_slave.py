"""What the structure and aero FMI slaves share: pythonfmu plumbing, no physics.

`SolverSlave` is an abstract pythonfmu slave over a solver (`StructureSolver`, `AeroSolver`) and the unit's
interface table (fmu_common.interface): one Real value buffer laid out contiguously from the table (get/set by
numpy fancy indexing), its variables registered from the table with SI units and a UnitDefinitions block,
tunable parameters applied at exitInitializationMode, the complete state (solver internals, inputs,
parameters) saved, restored and pickled. Pythonfmu's builder skips abstract classes, so a slave module that
imports it still exposes exactly one concrete slave.

Outputs are computed when read. A step, a restored state or new parameters mark every output row of the table
out of date; fmi2GetReal (and pythonfmu's getter of one variable) computes the rows of the references it is
asked for that are out of date, from the solver as it is then, and keeps them until the solver changes
again: a row is computed at most once per step, and one the host never reads (the probes' accelerations, a
constrained solve of the structure, when no one records them) costs nothing. Outputs depend on the solver's
state only (inputs set after a step change them at the next step, as FMI 2.0 co-simulation has it), so a
value read is the one an eager publication after the step would have held; after a step that failed they are
those of the solver where it stopped. A row whose computation raises reads NaN, with the reason logged at
error status.

Errors. Every FMI call is answered as the FMI 2.0 standard says, without raising: a call the standard
forbids in the unit's state, or with arguments it cannot use, is refused by logging a message at error
status that names the problem, and returns normally with the state unchanged (do_step returns False). The
FMU's binary (a shim over pythonfmu's, orchestrator/build/native_binary.py) returns the worst status logged during a
call, so a refused call answers fmi2Error; with pythonfmu's own binary (no C compiler at build time) it
answers fmi2OK (fmi2Discard for do_step) with the error logged, and a host must read the log. Refused:
  * fmi2Get/SetInteger, -Boolean, -String on a value reference that is not a variable of that type (every
    variable is Real except the String `topology_hash`), fmi2GetReal/SetReal on one that is not Real, the
    message naming each reference with its actual type and name; a get returns zeros, False or "" for
    them. fmi2SetString on `topology_hash` (a constant); fmi2SetReal on an output, on a parameter after
    initialization, or after fmi2Terminate;
  * a call out of order: fmi2SetupExperiment or fmi2EnterInitializationMode after initialization began,
    fmi2ExitInitializationMode outside initialization mode, fmi2DoStep before fmi2ExitInitializationMode
    or after fmi2Terminate, fmi2Terminate before initialization or twice;
  * fmi2DoStep with a step size that is not finite and > 0, or a communication point that is not the
    unit's own time (FMI start time + solver time, within `TIME_TOLERANCE`): the message gives both;
  * fmi2SetFMUstate of anything but a complete state this unit saved, and fmi2DeSerializeFMUstate of bytes
    that do not hold one (`fmi_state.StateUnpickler` builds only numpy arrays and the solvers' state dataclasses, so
    foreign bytes never run code): a state of another unit, topology, model or integrator (the solver's
    `state_identity`, e.g. aero.model), whose solver state has other classes or sizes (`fmi_state.form_mismatch`),
    or that holds a NaN or infinite number (`fmi_state.non_finite`) is refused naming the mismatch.
A failure inside a step (non-finite input, `InputError`, `SolverDiverged`, any exception) is logged the
same way, a `SolverDiverged` in the category `DIVERGED_CATEGORY` (declared in the model description's
LogCategories) so that a host tells a divergence from other errors without reading the text; a unit that
cannot go on (refused parameters, a state that failed half-way) refuses every later step until a good state
is set. Values can be read in every state (the standard allows it from initialization mode on; before, they
are the start values). The shim checks what Python cannot: NULL or
foreign fmi2FMUstate pointers, a GUID that does not match. fmi2Reset is pythonfmu's: it constructs the
slave anew, which is the state after instantiation.

Facts about pythonfmu 0.7.0 this encodes (measured, see docs/fmu.md):
  * a Python exception in an FMI call becomes fmi2Fatal and the wrapper then releases the slave class and
    instance twice (reference counts corrupted, the host segfaults later in the garbage collector), hence
    no call raises after construction;
  * its default typed get/set raise on a value reference of another type: all are overridden;
  * `_fmu_state_to_bytes` and `_fmu_state_from_bytes` are called on the slave class, not on the instance
    (fmi2SerializeFMUstate, fmi2DeSerializeFMUstate): a refusal there is logged on the one live instance
    of the class; with several instances of the same FMU in one process it cannot tell which one called,
    and the refused state is then refused, with the same reason, by the fmi2SetFMUstate it is passed to;
  * log text is passed to the FMI logger as a printf format: '%' is doubled;
  * fmi2Instantiate looks for the slave class by executing the slave script again in its module's globals,
    and then releases a reference to those globals that it does not own, once per instance: the module's
    dictionary is freed under the slave (a segfault at the next fmi2Instantiate). A script whose classes define
    methods gets the reference back by accident (each run leaves a class whose methods hold the globals);
    our slave classes define none, so each run of a slave class statement takes one (`_SlaveClass`);
  * that run of the script is only a search (the class it uses is the module's): the class it defines is kept
    alive by a list fmi2Instantiate never releases, a class per instance (kilobytes each). `_SlaveClass` makes
    the run return the module's existing class instead of defining another, so instantiate/free cycles keep
    memory flat; and fmi2Instantiate puts the resources folder on sys.path once more per instance, which
    `SolverSlave.__init__` takes back;
  * pythonfmu has no unit attribute on variables: `fmi_units.UnitReal` adds one.
"""
from __future__ import annotations

import ctypes
import gc
import io
import json
import math
import os
import pickle
import sys
import traceback
import weakref
import xml.etree.ElementTree as ET
from abc import ABCMeta, abstractmethod
from typing import Callable

import numpy as np
from pythonfmu import (Boolean, DefaultExperiment, Fmi2Causality, Fmi2Initial, Fmi2Slave, Fmi2Variability, Integer,
                       Real, String)
from pythonfmu.enums import Fmi2Status

from .errors import InputError, SolverDiverged
from .fmi_state import (STATE_FORMAT, STATE_KEYS, ClassOrInstanceMethod, StateUnpickler, form_mismatch,
                         non_finite)
from .fmi_units import UnitReal, unit_definitions
from .interface import (CALCULATED, INPUT, OUTPUT, Block, Interface, Layout, Parameters, Reading, Variable,
                        layout)
from .threads import limit_blas_threads

SCENE_RESOURCE = "scene.json"
DIVERGED_CATEGORY = "wingsim.diverged"
"""Log category of the error a step logs when its solver diverged (`SolverDiverged`)."""


def read_scene(resources: str | None, label: str) -> dict:
    """The resolved scene stored as `scene.json` in the resources folder.

    Args:
        resources: the resources folder, a path or a file:// URI.
        label: the unit's label, for errors.
    """
    if not resources:
        raise FileNotFoundError(f"{label}: no resources folder given, so no scene.json to read")
    folder = resources[len("file://"):] if resources.startswith("file://") else resources
    path = os.path.join(folder, SCENE_RESOURCE)
    try:
        with open(path, encoding="utf-8") as f:
            return json.load(f)
    except FileNotFoundError:
        raise FileNotFoundError(f"{label}: resource {path} is missing; rebuild the FMU") from None


TIME_TOLERANCE = 1e-9
"""Relative tolerance, of max(1 s, |t|), within which fmi2DoStep's communication point must equal the unit's
time t. Both are sums of steps in double precision: the solver's time is the start time plus its internal
steps (the structure solver ends an advance within 1e-12 max(1, |t|) of the target), a host's point a sum
or multiple of its step sizes; after N steps they differ by about N x 2.2e-16 |t|. 1e-9 covers millions
of steps, and a point off by more is a skipped or repeated step (at least a fraction of a step, which is
far longer than 1e-9 s), not round-off."""

PHASES = ("instantiated", "initialization", "stepping", "terminated")
"""The FMI 2.0 co-simulation states a slave goes through, in order ("stepping": initialized, steps allowed)."""
_PHASE_TEXT = {"instantiated": "not initialized yet", "initialization": "in initialization mode",
               "stepping": "initialized", "terminated": "terminated"}
# FMI call -> (phases the standard allows it in, as said in a refusal)
_ALLOWED = {
    "fmi2SetupExperiment": (("instantiated",), "only after fmi2Instantiate, before fmi2EnterInitializationMode"),
    "fmi2EnterInitializationMode": (("instantiated",), "only once, after fmi2Instantiate"),
    "fmi2ExitInitializationMode": (("initialization",), "only once, after fmi2EnterInitializationMode"),
    "fmi2DoStep": (("stepping",), "only after fmi2ExitInitializationMode and before fmi2Terminate"),
    "fmi2Terminate": (("stepping",), "only once, after fmi2ExitInitializationMode"),
    "fmi2SetReal": (("instantiated", "initialization", "stepping"), "only before fmi2Terminate"),
}

_LIVE: "weakref.WeakKeyDictionary[type, weakref.WeakSet]" = weakref.WeakKeyDictionary()
"""Slave class -> its instances, to log a refusal made in a call on the class (see `_log_on`)."""


def _hold_module_globals(cls: type) -> None:
    """Take one reference to the globals of the module defining the class `cls`, for the one pythonfmu 0.7.0's
    fmi2Instantiate releases after running the slave script again, which defines the class again (module
    docstring). Where the class is defined once (in-process), the dictionary keeps one more reference it never
    loses: a module's dictionary lives as long as the process anyway."""
    module = sys.modules.get(cls.__module__)
    if module is not None:
        ctypes.pythonapi.Py_IncRef(ctypes.py_object(vars(module)))


class _SlaveClass(ABCMeta):
    """The metaclass of the slaves: a class statement that defines again a slave class its module already holds,
    with the same bases (pythonfmu's fmi2Instantiate running the slave script once more, module docstring),
    returns the module's class instead of a new one. Every class statement takes one reference to its module's
    globals (`_hold_module_globals`), the one fmi2Instantiate releases."""

    def __new__(mcls, name, bases, namespace, **kwargs):
        module = sys.modules.get(namespace.get("__module__"))
        existing = vars(module).get(name) if module is not None else None
        if (isinstance(existing, mcls) and existing.__bases__ == bases
                and existing.__qualname__ == namespace.get("__qualname__")):
            _hold_module_globals(existing)
            return existing
        cls = super().__new__(mcls, name, bases, namespace, **kwargs)
        _hold_module_globals(cls)
        return cls


def _drop_repeated_path(folder: str | None) -> None:
    """Keep one entry of `folder` in sys.path: fmi2Instantiate inserts the resources folder at its front for
    every instance (module docstring), which would grow it by one per instantiate/free cycle."""
    while folder and sys.path.count(folder) > 1:
        del sys.path[len(sys.path) - 1 - sys.path[::-1].index(folder)]


def _fmi_type(var) -> str:
    return next((t.__name__ for t in (Real, Integer, Boolean, String) if isinstance(var, t)), type(var).__name__)


def _output_rows(laid_out: Layout) -> list[tuple[slice, Callable, tuple, int | slice]]:
    """The output rows of a layout as (value references, value, items, slot): `value(reading, items)` gives the
    values of those references (a float for a row of one variable), `slot` is the one value reference of a row
    of one variable, else the slice again. Rows without variables are left out. Each row is computed on its
    own, when a value reference of it is read (`SolverSlave._current`)."""
    return [(laid.where, laid.row.value, laid.items,
             laid.where.start if laid.where.stop - laid.where.start == 1 else laid.where)
            for laid in laid_out.rows if laid.is_output and laid.where.start != laid.where.stop]


_CAUSALITY = {"input": Fmi2Causality.input, "output": Fmi2Causality.output, "parameter": Fmi2Causality.parameter}
_VARIABILITY = {"continuous": Fmi2Variability.continuous, "discrete": Fmi2Variability.discrete,
                "fixed": Fmi2Variability.fixed, "constant": Fmi2Variability.constant}


class SolverSlave(Fmi2Slave, metaclass=_SlaveClass):
    """Abstract slave over a solver. Subclasses set `label`, `model_name` (the modelIdentifier, the FMU binary's
    name), `solver_class`, `spec_class` (the unit's spec, fmu_common.specs, whose `fmi_model_name` and
    `fmi_description` give the model description's modelName and description) and `interface` (the unit's
    table); construction reads the scene, converts it
    to the spec once, builds the solver, lays the table out (`layout`: the value
    buffer `_real`, the parameters' slice `sl_par`, the input blocks `do_step` checks and hands to the solver's
    `advance(t_end, *inputs)`) and registers every variable; `_current` computes the output rows read that are
    out of date into the buffer (module docstring)."""

    label = "unit"
    model_name = "unit"
    solver_class = None
    spec_class = None
    log_categories = {**Fmi2Slave.log_categories,
                      DIVERGED_CATEGORY: "A step failed because the solver diverged (logged at fmi2Error)."}

    @property
    @abstractmethod
    def interface(self) -> Interface:
        """The unit's interface table (a class attribute of the concrete slave)."""

    def __init__(self, **kwargs):
        limit_blas_threads()   # the unit starts here, in whatever host: one BLAS thread (threads.py)
        super().__init__(**kwargs)
        _drop_repeated_path(self.resources)
        self.scene = read_scene(self.resources, self.label)
        self.spec = self.spec_class.from_scene(self.scene)   # the one read of the scene: the solver takes the spec
        self.modelName = self.model_name
        self._solver = self.solver_class(self.spec)
        self.layout = layout(self.interface, self._solver, self.spec)
        self.topology = self._solver.topology
        self.topology_hash = str(self.topology.topology_hash)
        self.n = int(self.topology.n_coordinates)
        self.tunables = self.layout.tunables
        self.defaults = {name: float(v[0]) for name, v in self.tunables.items()}
        self._solver_parameters = dict(self.defaults)
        reals = self.layout.reals
        self._real = np.array([v.start for v in reals], dtype=float)
        self._settable = np.array([v.causality != OUTPUT for v in reals], dtype=bool)
        self.sl_par = self.layout.where(Parameters)
        self.input_blocks = [laid for laid in self.layout.rows
                             if isinstance(laid.row, Block) and laid.row.causality == INPUT]
        bounds = sorted((block.where.start, block.where.stop) for block in self.input_blocks)
        contiguous = bounds and all(a[1] == b[0] for a, b in zip(bounds, bounds[1:]))
        # the input blocks side by side in the buffer (as the tables lay them out): one finiteness check per step
        self._inputs_span = slice(bounds[0][0], bounds[-1][1]) if contiguous else None
        self._outputs = _output_rows(self.layout)
        self._row_of = np.full(self._real.size, -1, dtype=np.intp)     # value reference -> its output row, or -1
        for k, (where, _, _, _) in enumerate(self._outputs):
            self._row_of[where] = k
        self._rows_read = {}            # value references -> the output rows they read, found once
        # the layout's start values are the solver's outputs now: every row is current until the solver changes
        self._current_rows = [True] * len(self._outputs)
        self._reading: Reading | None = None
        self._t0 = 0.0                                  # FMI start time; solver time = t - t0
        self._phase = "instantiated"                    # one of PHASES
        self._checked_references = {}   # ("get" | "set", value references) -> index array, checked once
        self._failure: str | None = None                # set when the unit cannot go on
        _LIVE.setdefault(type(self), weakref.WeakSet()).add(self)
        for variable in self.layout.variables:
            self._register(variable)
        stop, step = self.spec.time.stop, self.spec.coupling.step
        self.default_experiment = DefaultExperiment(start_time=0.0, stop_time=stop, step_size=step)

    @staticmethod
    def _state_packages() -> frozenset[str]:
        """Packages whose dataclasses a saved unit state may hold: the solvers' of the slave classes loaded
        (a state of another unit is then read, and refused as such by `_state_form_problem`)."""
        return frozenset(sub.solver_class.__module__.split(".")[0] for sub in SolverSlave.__subclasses__()
                         if sub.solver_class is not None)

    @property
    def unit_time(self) -> float:
        """The unit's time (s): the FMI start time plus the solver's time."""
        return self._t0 + float(self._solver.time)

    # ---- variables ------------------------------------------------------------------------------
    def _register(self, v: Variable) -> None:
        """Register one variable of the layout: a Real reads (and an input or parameter writes) its slot of the
        value buffer, the String `topology_hash` is a constant."""
        if not v.description or (v.type == "Real" and not v.unit):
            # construction may raise: a build then fails naming the variable
            raise ValueError(f"{self.label}: variable {v.name} needs a unit and a description")
        kw = dict(causality=_CAUSALITY[v.causality], variability=_VARIABILITY[v.variability], description=v.description,
                  initial=None if v.initial is None else Fmi2Initial[v.initial])
        if v.type == "String":
            var = String(v.name, getter=lambda: self.topology_hash, **kw)
        else:
            index = v.value_reference
            start = None if v.initial == CALCULATED else v.start   # FMI 2.0: a calculated variable has no start
            var = UnitReal(v.name, unit=v.unit, start=start, getter=lambda i=index: self._value(i), **kw)
            if self._settable[index]:
                var.setter = lambda value, i=index: self.set_real([i], [value])
        self.register_variable(var, nested=False)
        assert var.value_reference == v.value_reference, "value references must follow the layout"

    def to_xml(self, model_options: dict | None = None):
        """pythonfmu's model description, made truthful and self-describing.

        Added to what pythonfmu writes:
          * modelName and description say what this FMU is (the spec's `fmi_model_name`, `fmi_description`:
            scene, fidelity or aero model, integrator, lattice); the modelIdentifier, the binary's name, stays
            `model_name`;
          * the UnitDefinitions of every declared unit;
          * `dependencies=""` on every ModelStructure/Outputs/Unknown. Without the attribute FMI 2.0 reads
            "depends directly on every input", and a system tool then sees an algebraic loop between the
            structure and the aero unit; in truth no output depends directly on an input: outputs change only
            in fmi2DoStep (and, at initialization, with the scene and the parameters).
          * no start value that is not a finite number: a ValueError names the variable (a scene value that
            overflowed in the arithmetic giving it; the scene checks refuse the known ones first, naming the key),
            so a build never writes start="nan", which fmpy's validation refuses;
          * InitialUnknowns: FMI 2.0 lists there the outputs with initial "approx" or "calculated" and the
            calculated parameters (and states, which a co-simulation FMU without Derivatives has none of). Here
            they are the outputs whose table row is initial "calculated" (fmu_common.interface.Output: their
            value after initialization depends on the parameters a host sets before it), each depending on the
            parameters, none on an input; a calculated parameter or an "approx" output, which the tables do
            not declare, fails the build, naming it.

        Args:
            model_options: pythonfmu's model options; None: none.

        Returns:
            the root element, fmiModelDescription.
        """
        root = super().to_xml({} if model_options is None else model_options)
        for variable in root.iterfind("ModelVariables/ScalarVariable"):
            start = variable.find("Real")
            if start is not None and "start" in start.attrib and not math.isfinite(float(start.get("start"))):
                raise ValueError(f"{self.label}: the start value of {variable.get('name')} "
                                 f"({variable.get('description')}) is {start.get('start')}, not a finite number: a "
                                 "value of the scene overflowed in the arithmetic that gives it")
        root.set("modelName", self.spec.fmi_model_name())
        root.set("description", self.spec.fmi_description())
        at = next(i for i, c in enumerate(list(root)) if c.tag == "CoSimulation") + 1
        root.insert(at, unit_definitions(v.unit for v in self.vars.values() if getattr(v, "unit", None)))
        for unknown in root.iterfind("ModelStructure/Outputs/Unknown"):
            unknown.set("dependencies", "")
        variables = list(self.vars.values())
        undeclared = [v.name for v in variables
                      if (v.causality == Fmi2Causality.output and v.initial == Fmi2Initial.approx)
                      or v.causality == Fmi2Causality.calculatedParameter]
        if undeclared:
            raise ValueError(f"{self.label}: {', '.join(undeclared)} would be InitialUnknowns of the model "
                             "description, whose dependencies SolverSlave.to_xml does not declare")
        calculated = [i for i, v in enumerate(variables, start=1)
                      if v.causality == Fmi2Causality.output and v.initial == Fmi2Initial.calculated]
        if calculated:   # FMI 2.0 order: ModelStructure holds Outputs, Derivatives, InitialUnknowns
            parameters = " ".join(str(i) for i, v in enumerate(variables, start=1)
                                  if v.causality == Fmi2Causality.parameter)
            unknowns = ET.SubElement(root.find("ModelStructure"), "InitialUnknowns")
            for index in calculated:
                ET.SubElement(unknowns, "Unknown", index=str(index), dependencies=parameters)
        return root

    # ---- logging --------------------------------------------------------------------------------
    def log(self, msg: str, status: Fmi2Status = Fmi2Status.ok, category: str | None = None, debug=None):
        """Log for the host, '%' doubled (pythonfmu passes the text to the FMI logger as a printf format).

        Args:
            msg: the message.
            status: its FMI status.
            category: its log category; None: pythonfmu's default.
            debug: ignored (pythonfmu's signature).
        """
        super().log(msg.replace("%", "%%"), status, category)

    def _error(self, msg: str) -> None:
        self.log(msg, Fmi2Status.error)

    def _fail(self, msg: str) -> None:
        """Log an error and refuse every further step until a good state is set (the call itself returns)."""
        self._failure = msg
        self._error(msg)

    @classmethod
    def _log_on(cls, slave, msg: str) -> None:
        """Log `msg` at error status on `slave`, or, for a call pythonfmu made on the class (slave None), on
        the one live instance of the class; with several there is no telling which one called, and nothing
        is logged (the caller's result carries the reason instead)."""
        if slave is None:
            gc.collect()  # instances the host freed are held by their getters' cycles until collected
            live = list(_LIVE.get(cls, ()))
            if len(live) != 1:
                return
            slave = live[0]
        slave._error(msg)

    def _references(self, vrs) -> str:
        """'value reference 12 (Real Q[1])' or 'value references 12 (Real Q[1]), 4000 (no such variable)'."""
        return f"value reference{'' if len(vrs) == 1 else 's'} {self._describe(vrs)}"

    def _not_variables(self, vrs, kind: str) -> str:
        """'value reference 12 (Real Q[1]) is not a String variable', or the plural."""
        if len(vrs) == 1:
            return f"{self._references(vrs)} is not {'an' if kind[0] in 'AEIOU' else 'a'} {kind} variable"
        return f"{self._references(vrs)} are not {kind} variables"

    def _describe(self, vrs) -> str:
        """Value references with what they are, e.g. '12 (Real Q[1]), 4000 (no such variable)'."""
        words = []
        for vr in list(vrs)[:6]:
            vr = int(vr) & 0xFFFFFFFF  # pythonfmu passes the unsigned reference as a C int
            var = self.vars.get(vr)
            words.append(f"{vr} (no such variable)" if var is None else f"{vr} ({_fmi_type(var)} {var.name})")
        more = len(vrs) - len(words)
        return ", ".join(words) + (f" and {more} more" if more > 0 else "")

    def _refused_in_phase(self, call: str) -> bool:
        """True, with the reason logged at error status, if the standard does not allow `call` now."""
        phases, when = _ALLOWED[call]
        if self._phase in phases:
            return False
        self._error(f"{self.label}: {call} refused: it is allowed {when}, and the unit is "
                    f"{_PHASE_TEXT[self._phase]}; state unchanged")
        return True

    # ---- FMI calls: none raises ------------------------------------------------------------------
    def get_real(self, vrs):
        """fmi2GetReal: the values of Real variables; NaN (and the refusal logged) for a reference that is not one.

        An output is computed here, when read (`_current`): the rows of the references asked, once per step.

        Args:
            vrs: value references.
        """
        key = ("get", tuple(vrs))
        idx = self._checked_references.get(key)
        if idx is None:
            idx = np.asarray(vrs, dtype=np.intp)
            ok = (idx >= 0) & (idx < self._real.size)   # the Real value references are the buffer's indices
            rows = self._row_of[idx[ok]]
            self._rows_read[key] = tuple(np.unique(rows[rows >= 0]).tolist())
            if not ok.all():
                self._error(f"{self.label}: fmi2GetReal refused: {self._not_variables(idx[~ok], 'Real')}; NaN "
                            "returned instead")
                self._report_failed(self._current(self._rows_read.pop(key)))
                out = np.full(idx.size, np.nan)
                out[ok] = self._real[idx[ok]]
                return out.tolist()
            self._checked_references[key] = idx
        self._report_failed(self._current(self._rows_read[key]))
        return self._real[idx].tolist()

    def get_integer(self, vrs):
        """fmi2GetInteger: the unit has no Integer variable; 0 and the refusal logged for each reference.

        Args:
            vrs: value references.
        """
        return self._get_typed("fmi2GetInteger", Integer, vrs, int, 0)

    def get_boolean(self, vrs):
        """fmi2GetBoolean: the unit has no Boolean variable; False and the refusal logged for each reference.

        Args:
            vrs: value references.
        """
        return self._get_typed("fmi2GetBoolean", Boolean, vrs, bool, False)

    def get_string(self, vrs):
        """fmi2GetString: the String variables' values (topology_hash); "" and the refusal logged for other references.

        Args:
            vrs: value references.
        """
        return self._get_typed("fmi2GetString", String, vrs, str, "")

    def set_integer(self, vrs, values):
        """fmi2SetInteger: refused, saying why (the unit has no settable Integer).

        Args:
            vrs: value references.
            values: their values (ignored).
        """
        self._refuse_set("fmi2SetInteger", Integer, vrs)

    def set_boolean(self, vrs, values):
        """fmi2SetBoolean: refused, saying why (the unit has no settable Boolean).

        Args:
            vrs: value references.
            values: their values (ignored).
        """
        self._refuse_set("fmi2SetBoolean", Boolean, vrs)

    def set_string(self, vrs, values):
        """fmi2SetString: refused, saying why (the String topology_hash is a constant).

        Args:
            vrs: value references.
            values: their values (ignored).
        """
        self._refuse_set("fmi2SetString", String, vrs)

    def _get_typed(self, call: str, kind: type, vrs, convert, neutral) -> list:
        """Values of the variables of type `kind`; `neutral` (and the refusal logged) for the other references."""
        out, wrong = [], []
        for vr in vrs:
            var = self.vars.get(int(vr) & 0xFFFFFFFF)
            if isinstance(var, kind):
                out.append(convert(var.getter()))
            else:
                out.append(neutral)
                wrong.append(vr)
        if wrong:
            self._error(f"{self.label}: {call} refused: {self._not_variables(wrong, kind.__name__)}; {neutral!r} "
                        "returned instead")
        return out

    def _refuse_set(self, call: str, kind: type, vrs) -> None:
        """The unit has no settable variable but Real ones (its String is a constant): refuse, saying why."""
        vrs = list(vrs)
        if not vrs:
            return
        wrong = [vr for vr in vrs if not isinstance(self.vars.get(int(vr) & 0xFFFFFFFF), kind)]
        fixed = [self.vars[int(vr) & 0xFFFFFFFF] for vr in vrs if vr not in wrong]
        reasons = [self._not_variables(wrong, kind.__name__)] if wrong else []
        reasons += [f"{v.name} is {'a constant' if v.variability == Fmi2Variability.constant else 'an output'}"
                    for v in fixed]
        self._error(f"{self.label}: {call} refused: {'; '.join(reasons)}; nothing was set")

    def set_real(self, vrs, values):
        """fmi2SetReal: set inputs and, before initialization ends, parameters; refused (logged, nothing set) otherwise.

        Args:
            vrs: value references.
            values: their values, in the variables' units.
        """
        if self._phase == "terminated":
            self._refused_in_phase("fmi2SetReal")
            return
        key = ("set", tuple(vrs))
        idx = self._checked_references.get(key)
        if idx is None:
            idx = np.asarray(vrs, dtype=np.intp)
            if idx.size == 0:
                return
            ok = (idx >= 0) & (idx < self._real.size)
            ok[ok] = self._settable[idx[ok]]
            if not ok.all():
                self._error(f"{self.label}: fmi2SetReal refused: {self._references(idx[~ok])} cannot be set (only "
                            "the inputs and the parameters can); nothing was set")
                return
            parameter = (idx >= self.sl_par.start) & (idx < self.sl_par.stop)
            if parameter.any() and self._phase == "stepping":
                names = [self.vars[int(i)].name for i in idx[parameter]]
                self._error(f"{self.label}: fmi2SetReal refused: cannot set {', '.join(names)} after "
                            "initialization (parameters have variability 'fixed'); nothing was set")
                return
            if not parameter.any():        # inputs only: settable until fmi2Terminate, check them once
                self._checked_references[key] = idx
        try:
            if len(values) != idx.size:
                raise ValueError(f"{len(values)} values for {idx.size} value references")
            # fromiter converts each value once; assigning the list would first discover its type and shape
            self._real[idx] = np.fromiter(values, dtype=float, count=idx.size)
        except (TypeError, ValueError) as exc:
            self._error(f"{self.label}: fmi2SetReal refused: {type(exc).__name__}: {exc}; nothing was set")

    def setup_experiment(self, start_time, stop_time=None, tolerance=None):
        """fmi2SetupExperiment: take the start time; refused (logged) out of phase or for a start time not finite.

        Args:
            start_time: the FMI start time, s.
            stop_time: ignored (the scene's time.stop is the default experiment's).
            tolerance: ignored.
        """
        if self._refused_in_phase("fmi2SetupExperiment"):
            return
        t0 = float(start_time) if isinstance(start_time, (int, float)) else math.nan
        if not math.isfinite(t0):
            self._error(f"{self.label}: fmi2SetupExperiment refused: the start time {start_time!r} s is not a "
                        "finite number; state unchanged")
            return
        self._t0 = t0

    def enter_initialization_mode(self):
        """fmi2EnterInitializationMode; refused (logged) out of phase."""
        if not self._refused_in_phase("fmi2EnterInitializationMode"):
            self._phase = "initialization"

    def exit_initialization_mode(self):
        """fmi2ExitInitializationMode: rebuild the solver if the parameters changed; refused (logged) out of phase."""
        if self._refused_in_phase("fmi2ExitInitializationMode"):
            return
        self._phase = "stepping"
        parameters = dict(zip(self.tunables, self._real[self.sl_par].tolist()))
        if parameters == self._solver_parameters:
            return
        try:
            self._solver = self.solver_class(self.spec, parameters=parameters)
            self._solver_parameters = parameters
            self._outputs_changed()
        except Exception as exc:  # noqa: BLE001
            self._fail(f"{self.label}: the parameters were refused: {type(exc).__name__}: {exc}")

    def terminate(self):
        """fmi2Terminate; refused (logged) out of phase."""
        if not self._refused_in_phase("fmi2Terminate"):
            self._phase = "terminated"

    def _outputs_changed(self) -> None:
        """The solver changed (a step, a restored state, new parameters): every output row is out of date, and is
        computed again when a value reference of it is read (`_current`)."""
        self._current_rows = [False] * len(self._outputs)
        self._reading = None

    def _current(self, rows) -> list[str]:
        """Bring the output rows `rows` (indices into `_outputs`) up to date in the value buffer: each row out of
        date is computed from the solver, in one `Reading` per solver state, so that a query several rows share
        (e.g. the monitors) runs once however many of them are read, and a row is computed at most once per
        step. Never raises: returns the reasons of the rows that failed (their values are then NaN, and each read
        tries again and reports again)."""
        failed = []
        current, real = self._current_rows, self._real
        for k in rows:
            if current[k]:
                continue
            where, value, items, slot = self._outputs[k]
            if self._reading is None:
                self._reading = Reading(self._solver, self._t0)
            try:
                computed = value(self._reading, items)
                # a float into its one slot by index: a third of the cost of assigning it to the slice
                real[slot if type(computed) is float else where] = computed
                current[k] = True
            except Exception as exc:  # noqa: BLE001 - a read answers the host, never raises; the next read tries again
                real[where] = np.nan
                names = self.vars[where.start].name + (f" .. {self.vars[where.stop - 1].name}"
                                                       if where.stop - where.start > 1 else "")
                failed.append(f"{names}: {type(exc).__name__}: {exc}")
        return failed

    def _value(self, vr: int) -> float:
        """The current value of the Real variable `vr` (pythonfmu's getter), its output row computed if out of date."""
        row = self._row_of[vr]
        if row >= 0:
            self._report_failed(self._current((row,)))
        return float(self._real[vr])

    def _report_failed(self, failed: list[str]) -> None:
        if failed:
            self._error(f"{self.label}: fmi2GetReal: computing {'; '.join(failed)}; NaN returned instead")

    def do_step(self, current_time, step_size):
        """fmi2DoStep: the solver advances to current_time + step_size with the inputs held over the step.

        Refused (logged, False) out of phase, for a step size or a communication point it cannot take (`_step_refused`)
        or a non-finite input.

        Args:
            current_time: the communication point, s.
            step_size: s.
        """
        if self._step_refused(current_time, step_size):
            return False
        span = self._inputs_span
        if span is None or not np.isfinite(self._real[span]).all():    # then find the block, and say which
            for block in self.input_blocks:
                reason = self._non_finite(block.row.name, block.where, current_time)
                if reason is not None:
                    self._error(reason)
                    return False
        inputs = [self._real[block.where].copy() for block in self.input_blocks]
        t_end = current_time + step_size - self._t0
        return self._advance(current_time, lambda: self._solver.advance(t_end, *inputs))

    def _step_refused(self, current_time, step_size) -> bool:
        """True, with the reason logged at error status, when fmi2DoStep(current_time, step_size) must be
        refused: out of phase, a step size that is not finite and > 0, or a communication point that is not
        the unit's time (within TIME_TOLERANCE). Nothing is changed."""
        if self._refused_in_phase("fmi2DoStep"):
            return True
        number = (int, float, np.floating)
        t = float(current_time) if isinstance(current_time, number) else math.nan
        h = float(step_size) if isinstance(step_size, number) else math.nan
        now = self.unit_time
        tolerance = TIME_TOLERANCE * max(1.0, abs(now))
        if not (math.isfinite(h) and h > 0):
            reason = f"the step size {step_size!r} s is not a finite number > 0"
        elif not math.isfinite(t):
            reason = f"the communication point {current_time!r} s is not a finite number"
        elif abs(t - now) > tolerance:
            reason = (f"the communication point t = {t!r} s is not the unit's time {now!r} s ("
                      f"{'behind' if t < now else 'ahead'} by {abs(t - now):.3g} s, tolerance {tolerance:.1g} s): "
                      "step on from the unit's time, or restore a saved state (fmi2SetFMUstate) to repeat a step")
        else:
            return False
        self._error(f"{self.label}: fmi2DoStep refused: {reason}; state unchanged")
        return True

    def _non_finite(self, label: str, block: slice, current_time) -> str | None:
        """The reason the input block `label` (e.g. Q) at `block` cannot be used (NaN or inf), or None."""
        x = self._real[block]
        finite = np.isfinite(x)
        if finite.all():
            return None
        k = int(np.argmin(finite))
        what = self.layout.variables[block.start + k].description
        value = "NaN" if np.isnan(x[k]) else ("+inf" if x[k] > 0 else "-inf")
        return (f"input {label}[{k + 1}] ({what}) is {value} ({int((~finite).sum())} of "
                f"{x.size} {label} inputs are NaN or inf): step at t = {current_time:.6g} s rejected, "
                "state unchanged")

    def _advance(self, current_time, advance) -> bool:
        """Run `advance()` (the solver's step); log any failure with its reason and return False."""
        if self._failure is not None:
            self._error(f"{self.label} cannot step: {self._failure}")
            return False
        self._outputs_changed()   # also when the step fails: the solver may have taken internal steps
        try:
            advance()
        except SolverDiverged as exc:
            self.log(f"{self.label}: solver diverged at t = {exc.time:.6g} s: {exc.reason}. Hint: {exc.hint}",
                     Fmi2Status.error, DIVERGED_CATEGORY)
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

    # ---- state: complete (solver internals, inputs, outputs, parameters, phase), arrays copied ---
    def _get_fmu_state(self):
        try:
            return {"format": STATE_FORMAT, "unit": self.label, "topology_hash": self.topology_hash,
                    "identity": self._solver.state_identity(), "solver": self._solver.get_state(),
                    "real": self._real.copy(), "t0": self._t0,
                    "phase": self._phase, "failure": self._failure,
                    "solver_parameters": dict(self._solver_parameters)}
        except Exception as exc:  # noqa: BLE001
            self._error(f"{self.label}: fmi2GetFMUstate failed: {type(exc).__name__}: {exc}")
            return {"error": f"the state could not be saved ({type(exc).__name__}: {exc})"}

    def _set_fmu_state(self, state):
        problem = self._state_problem(state)
        if problem is not None:
            self._error(f"{self.label}: fmi2SetFMUstate refused: {problem}; state unchanged")
            return
        try:
            if state["solver_parameters"] != self._solver_parameters:
                self._solver = self.solver_class(self.spec, parameters=state["solver_parameters"])
                self._solver_parameters = dict(state["solver_parameters"])
            self._solver.set_state(state["solver"])
            self._real[:] = state["real"]
            self._t0, self._phase, self._failure = state["t0"], state["phase"], state["failure"]
            self._outputs_changed()   # the buffer's outputs may be of another time: computed again when read
        except Exception as exc:  # noqa: BLE001
            self._fail(f"{self.label}: setting the state failed: {type(exc).__name__}: {exc}")

    @classmethod
    def _state_form_problem(cls, state) -> str | None:
        """Why `state` is not a state saved by a unit of this class, or None."""
        if not isinstance(state, dict):
            return f"not a state of this unit (a {type(state).__name__})"
        if "error" in state:
            return str(state["error"])
        if state.keys() != STATE_KEYS or not isinstance(state["format"], str) or state["format"] != STATE_FORMAT:
            return "not a state saved by this version of the unit"
        if not isinstance(state["unit"], str) or state["unit"] != cls.label:
            return f"a state of the {state['unit']}, not of the {cls.label}"
        where = non_finite(state)
        if where is not None:
            return f"it holds a number that is not finite: {where}"
        return None

    def _state_problem(self, state) -> str | None:
        """Why `state` cannot be set on this unit, or None: it must be complete, hold finite numbers only, and be
        saved by a unit of the same class, topology, model and integrator (the solver's `state_identity`), its
        solver state of the same form and sizes (`fmi_state.form_mismatch`)."""
        try:
            problem = self._state_form_problem(state)
            if problem is not None:
                return problem
            real, parameters, failure = state["real"], state["solver_parameters"], state["failure"]
            if not isinstance(state["topology_hash"], str) or state["topology_hash"] != self.topology_hash:
                return "a state of a unit of another structural topology"
            identity, own = state["identity"], self._solver.state_identity()
            if not isinstance(identity, dict):
                return "its identity entry is not valid"
            for key, value in own.items():
                if identity.get(key) != value:
                    return f"a state saved with {key} = {identity.get(key)!r}, this unit runs {key} = {value!r}"
            mismatch = form_mismatch(state["solver"], self._solver.get_state(), "state.solver")
            if mismatch is not None:
                return f"its solver state is not of this unit's model and sizes: {mismatch}"
            if not (isinstance(real, np.ndarray) and real.dtype == np.float64 and real.shape == self._real.shape):
                return f"its value buffer is not {self._real.size} floats"
            if not (isinstance(state["phase"], str) and state["phase"] in PHASES
                    and isinstance(state["t0"], float) and math.isfinite(state["t0"])
                    and (failure is None or isinstance(failure, str))):
                return "its phase, start time or failure entry is not valid"
            if not (isinstance(parameters, dict) and parameters.keys() == self._solver_parameters.keys()
                    and all(isinstance(v, float) and math.isfinite(v) for v in parameters.values())):
                return "its parameters are not this unit's"
        except Exception as exc:  # noqa: BLE001 - a foreign object may fail any operation
            return f"it cannot be read ({type(exc).__name__}: {exc})"
        return None

    @ClassOrInstanceMethod
    def _fmu_state_to_bytes(cls, slave, state) -> bytes:
        try:
            return pickle.dumps(state, protocol=pickle.HIGHEST_PROTOCOL)
        except Exception as exc:  # noqa: BLE001 - never raise
            reason = f"the state could not be serialized ({type(exc).__name__}: {exc})"
            cls._log_on(slave, f"{cls.label}: fmi2SerializeFMUstate failed: {reason}")
            return pickle.dumps({"error": reason})

    @ClassOrInstanceMethod
    def _fmu_state_from_bytes(cls, slave, data):
        """The state serialized in `data`; for bytes that hold none, the refusal is logged (`_log_on`) and
        an {"error": reason} entry returned, which fmi2SetFMUstate refuses with the same reason."""
        try:
            state = StateUnpickler(io.BytesIO(data), cls._state_packages()).load()
            problem = cls._state_form_problem(state)
        except Exception as exc:  # noqa: BLE001 - garbage may fail in any way
            problem = f"the bytes do not hold a state of this unit ({type(exc).__name__}: {exc})"
        if problem is None:
            return state
        cls._log_on(slave, f"{cls.label}: fmi2DeSerializeFMUstate refused: {problem}")
        return {"error": problem}
