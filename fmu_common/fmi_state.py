"""The complete state of a unit as bytes: what fmi2SerializeFMUstate writes and fmi2DeSerializeFMUstate
reads back, and nothing else.

A state is a dict with the keys `STATE_KEYS` marked by `STATE_FORMAT` (fmu_common.fmi_slave makes and checks
it). Bytes from a host are untrusted: `StateUnpickler` resolves only numpy's array constructors and the
solvers' state dataclasses, so bytes that are not a state raise instead of running code. What unpickles is then
checked before it is set: `non_finite` finds a NaN or infinite number anywhere in it, `form_mismatch` a solver
state of another model, integrator or size than the unit's own.
"""
from __future__ import annotations

import dataclasses
import functools
import math
import pickle
import sys

import numpy as np

STATE_FORMAT = "wingsim unit state 2"
STATE_KEYS = frozenset({"format", "unit", "topology_hash", "identity", "solver", "real", "t0", "phase", "failure",
                         "solver_parameters"})
# what a pickled numpy array refers to (numpy 1.x and 2.x names)
_NUMPY_GLOBALS = frozenset((module, name) for module in ("numpy.core.multiarray", "numpy._core.multiarray",
                                                         "numpy.core.numeric", "numpy._core.numeric", "numpy")
                           for name in ("_reconstruct", "_frombuffer", "scalar", "dtype", "ndarray"))


class StateUnpickler(pickle.Unpickler):
    """Unpickles a unit state and nothing else.

    The only globals it resolves are numpy's array and dtype constructors and the dataclasses of `packages`, so
    bytes that are not our state raise UnpicklingError instead of running code.

    Args:
        file: the binary file to read.
        packages: the units' solver packages, already imported.
    """

    def __init__(self, file, packages):
        super().__init__(file)
        self.packages = packages

    def find_class(self, module, name):
        """The global `module.name` if a unit state may hold it; UnpicklingError otherwise.

        Args:
            module: the global's module.
            name: its name in the module.
        """
        if (module, name) in _NUMPY_GLOBALS:
            return super().find_class(module, name)
        if module.split(".")[0] in self.packages and module in sys.modules and "." not in name:
            obj = getattr(sys.modules[module], name, None)
            if isinstance(obj, type) and dataclasses.is_dataclass(obj):
                return obj
        raise pickle.UnpicklingError(f"it refers to {module}.{name}, which no unit state holds")


class ClassOrInstanceMethod:
    """A method called as f(cls, instance, *args) whether it is looked up on an instance or on the class.

    On the class, instance is None: pythonfmu 0.7.0 calls the state (de)serialization on the slave class, the direct
    backend on the instance.

    Args:
        func: the function f.
    """

    def __init__(self, func):
        self.func = func
        functools.update_wrapper(self, func)

    def __get__(self, obj, objtype=None):
        return functools.partial(self.func, objtype if objtype is not None else type(obj), obj)


def non_finite(value, path: str = "state") -> str | None:
    """Where `value` (a unit state: dataclasses, tuples, lists, dicts, numpy arrays, numbers) holds a number that
    is NaN or infinite, e.g. "state.solver.model.gamma[3] = nan"; None when every number is finite.

    Args:
        value: the state or a part of it.
        path: the name of `value` in the message.
    """
    if isinstance(value, np.ndarray):
        if value.dtype.kind in "fc" and not np.all(np.isfinite(value)):
            k = int(np.flatnonzero(~np.isfinite(value.ravel()))[0])
            return f"{path}[{k}] = {value.ravel()[k]}"
        return None
    if isinstance(value, float):
        return None if math.isfinite(value) else f"{path} = {value}"
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        parts = ((f"{path}.{f.name}", getattr(value, f.name, None)) for f in dataclasses.fields(value))
    elif isinstance(value, (tuple, list)):
        parts = ((f"{path}[{i}]", v) for i, v in enumerate(value))
    elif isinstance(value, dict):
        parts = ((f"{path}[{k!r}]", v) for k, v in value.items())
    else:
        return None
    return next((found for name, part in parts if (found := non_finite(part, name)) is not None), None)


def form_mismatch(saved, own, path: str = "state", growing: int | None = None) -> str | None:
    """How the saved solver state `saved` differs in form from this unit's `own`, or None: another class (another
    model or integrator), another length of a tuple, another dtype or shape of an array (but along the axis a
    dataclass lists for that field in its `GROWING_AXES` {field: axis}, e.g. the rows of a shed wake). A None on
    either side (a part not made yet, before the first step) and dictionaries are not compared.

    Args:
        saved: the saved state or a part of it.
        own: the same part of this unit's state.
        path: the name of the part in the message.
        growing: for an array, the axis whose length may differ.
    """
    if saved is None or own is None or isinstance(own, dict):
        return None
    if type(saved) is not type(own):
        return f"{path} is a {type(saved).__name__}, this unit's a {type(own).__name__}"
    if isinstance(own, np.ndarray):
        same = (saved.dtype == own.dtype and saved.ndim == own.ndim
                and all(a == b for i, (a, b) in enumerate(zip(saved.shape, own.shape)) if i != growing))
        return None if same else f"{path} is {saved.dtype} {saved.shape}, this unit's {own.dtype} {own.shape}"
    if dataclasses.is_dataclass(own):
        axes = getattr(type(own), "GROWING_AXES", {})
        parts = ((getattr(saved, f.name, None), getattr(own, f.name, None), f"{path}.{f.name}", axes.get(f.name))
                 for f in dataclasses.fields(own))
    elif isinstance(own, (tuple, list)):
        if len(saved) != len(own):
            return f"{path} has {len(saved)} entries, this unit's {len(own)}"
        parts = ((a, b, f"{path}[{i}]", None) for i, (a, b) in enumerate(zip(saved, own)))
    else:
        return None
    return next((found for a, b, name, axis in parts if (found := form_mismatch(a, b, name, axis)) is not None),
                None)
