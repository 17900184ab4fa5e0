"""The complete state of a unit as bytes: what fmi2SerializeFMUstate writes and fmi2DeSerializeFMUstate
reads back, and nothing else.

A state is a dict with the keys `STATE_KEYS` marked by `STATE_FORMAT` (fmu_common.fmi_slave makes and checks
it). Bytes from a host are untrusted: `StateUnpickler` resolves only numpy's array constructors and the
solvers' state dataclasses, so bytes that are not a state raise instead of running code.
"""
from __future__ import annotations

import dataclasses
import functools
import pickle
import sys

STATE_FORMAT = "wingsim unit state 1"
STATE_KEYS = frozenset({"format", "unit", "topology_hash", "solver", "real", "t0", "phase", "failure",
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
