"""The fmu backend of a unit: its FMU loaded with fmpy (FMU2Slave), every get and set batched over
precomputed value references and ctypes buffers, every status checked, every log message kept with its
category; the FMU refused before any step if it was built from another scene or declares its variables
otherwise than its unit's code registers them (`orchestrator.run.layout`)."""
from __future__ import annotations

import json
import os
import shutil
import sys
import weakref
from ctypes import byref
from pathlib import Path

import numpy as np
from fmpy.fmi1 import FMICallException

from fmu_common.scene_schema import without_tunables
from orchestrator.run.port import (ERROR_STATUS, KINDS, LogEntry, UnitError, reported_divergence,
                                   warnings_and_errors)

FMI2_WARNING = 1      # fmi2Warning: a status above it is a failed call (fmpy raises for it)
FMI2_FALSE = 0        # fmi2False: fmi2DoStep's noSetFMUStatePriorToCurrentPoint


class FmuState:
    """An fmi2FMUstate of one instance, freed when collected (or when the instance goes away first)."""

    def __init__(self, port: "FmuPort", handle):
        self._port, self.handle = weakref.ref(port), handle
        port._live_states.add(self)

    def free(self):
        port = self._port()
        if self.handle is not None and port is not None and port._fmu is not None:
            try:
                port._fmu.fmi2FreeFMUstate(port._fmu.component, byref(self.handle))
            except Exception:  # noqa: BLE001 - freeing is best effort
                pass
        self.handle = None

    def __del__(self):
        self.free()


class FmuPort:
    backend = "fmu"

    def __init__(self, fmu_path: Path, scene: dict, instance_name: str, kind: str = "structure",
                 check_layout: bool = True):
        from fmpy import extract, read_model_description
        from fmpy.fmi1 import calloc, free
        from fmpy.fmi2 import (FMU2Slave, fmi2CallbackAllocateMemoryTYPE, fmi2CallbackFreeMemoryTYPE,
                               fmi2CallbackFunctions, fmi2CallbackLoggerTYPE)

        self.label = f"{instance_name} ({fmu_path.name}, fmu)"
        self._fmu_path = fmu_path
        self.kind, spec = kind, KINDS[kind]
        self._fmu = None
        self._do_step = None     # (fmi2DoStep, the instance), once the first step is taken
        self._dir = None
        self._live_states = weakref.WeakSet()
        self._initialized = False
        self.log: list[LogEntry] = []
        if not fmu_path.is_file():
            what = "a folder, not an FMU file" if fmu_path.is_dir() else "not found"
            raise UnitError(f"{self.label}: {fmu_path} {what}; build it first (wingsim build SCENE)")
        try:
            self._dir = extract(str(fmu_path))
            md = read_model_description(self._dir)   # of the files extracted: the GUID their binary carries
        except Exception as exc:
            self.close()
            raise UnitError(f"{self.label}: cannot read {fmu_path}: {exc}") from exc
        try:
            self._check_scene(scene, spec.scene_sections)
            if check_layout:
                self._check_layout(md)
        except UnitError:
            self.close()
            raise
        self._vr = {v.name: v.valueReference for v in md.modelVariables}

        def logger(env, inst, status, category, message):
            # The FMU's printf-style message arrives unformatted: fmpy's formatting proxy (addLoggerProxy) is
            # not used, as it keeps ONE logger for the whole process (messages of every instance would go to
            # the last one registered, and into freed memory once that one is gone). The slave doubles '%'.
            text = message.decode("utf-8", "replace") if message else ""
            self.log.append(LogEntry(int(status), category.decode("utf-8", "replace") if category else "",
                                     text.replace("%%", "%")))

        self._callbacks = fmi2CallbackFunctions()
        self._callbacks.logger = fmi2CallbackLoggerTYPE(logger)
        self._callbacks.allocateMemory = fmi2CallbackAllocateMemoryTYPE(calloc)
        self._callbacks.freeMemory = fmi2CallbackFreeMemoryTYPE(free)
        cwd = os.getcwd()
        try:
            fmu = FMU2Slave(guid=md.guid, unzipDirectory=self._dir,
                            modelIdentifier=md.coSimulation.modelIdentifier, instanceName=instance_name)
        except Exception as exc:        # fmpy: the binary is missing or not a library of this platform
            os.chdir(cwd)               # fmpy changed to the binary's folder and did not change back
            message = self._inside(str(exc))
            self.close()
            raise UnitError(f"{self.label}: cannot load {fmu_path}: {message}") from None
        try:
            self._call("fmi2Instantiate", fmu.instantiate, callbacks=self._callbacks, loggingOn=True)
        except UnitError:
            self.close()
            raise
        self._fmu = fmu

    def _inside(self, text: str) -> str:
        """`text` with the temporary folder the FMU is unpacked in written as the FMU file the user gave:
        `<fmu>:binaries/linux64/structure.so` (the folder is deleted with the port and means nothing to them)."""
        return text if self._dir is None else text.replace(f"{self._dir}/", f"{self._fmu_path}:").replace(
            str(self._dir), str(self._fmu_path))

    def _check_scene(self, scene: dict, sections: tuple[str, ...]) -> None:
        """Refuse an FMU built from a different scene than `scene` in `sections`, but for their tunable keys
        (stale build)."""
        try:
            built = json.loads(Path(self._dir, "resources", "scene.json").read_text(encoding="utf-8"))
        except OSError as exc:
            raise UnitError(f"{self.label}: resources/scene.json missing ({exc}); rebuild the FMU") from exc
        # the tunable keys may differ: the unit gets the scene's values as parameters (orchestrator.run.units)
        try:
            built = without_tunables(built)
        except (KeyError, TypeError, AttributeError) as exc:
            raise UnitError(f"{self.label}: resources/scene.json is not a resolved scene ({type(exc).__name__}: "
                            f"{exc}); rebuild the FMU") from exc
        scene = without_tunables(scene)
        keys = []
        for section in sections:
            want = json.loads(json.dumps(scene.get(section)))
            if built.get(section) != want:
                keys += differing_keys(built.get(section), want, section)
        if keys:
            raise UnitError(f"{self.label} was built from a different scene (differs at {', '.join(keys[:5])}); "
                            "rebuild it (wingsim build SCENE)")

    def _check_layout(self, md) -> None:
        """Refuse an FMU whose model description declares its variables otherwise than its unit's code
        registers them (names, value references, causality, variability, type, unit: `orchestrator.run.layout`)."""
        from orchestrator.run.layout import check

        problems = check(md, self.kind, Path(self._dir, "resources"))
        if problems:
            raise UnitError(f"{self.label}: refused: " + "; ".join(problems))

    def _reasons(self, since: int) -> str:
        entries = [entry._replace(text=" ".join(entry.text.split())) for entry in self.log[since:] if entry.text]
        return warnings_and_errors(entries) or "no reason logged by the unit"

    def _call(self, what: str, fn, *args, **kwargs):
        """fn(*args); UnitError if it fails (fmpy raises on a status above warning) or logs an error."""
        mark = len(self.log)
        try:
            result = fn(*args, **kwargs)
        except Exception as exc:
            raise UnitError(self._inside(f"{self.label}: {what} failed ({exc}): {self._reasons(mark)}"),
                            diverged=reported_divergence(self.log[mark:])) from None
        if any(entry.status >= ERROR_STATUS for entry in self.log[mark:]):
            raise UnitError(self._inside(f"{self.label}: {what} failed: {self._reasons(mark)}"),
                            diverged=reported_divergence(self.log[mark:]))
        return result

    def value_references(self) -> dict[str, int]:
        return dict(self._vr)

    def _stepping_call(self, name: str):
        """The FMU's C function `name` (fmi2GetReal, fmi2SetReal, fmi2DoStep; fmpy declared its argument types) and
        its instance, called directly by the calls a communication step repeats: fmpy's Python layer over it adds
        nothing the status check after it (`_checked`) does not do."""
        return getattr(self._fmu.dll, name), self._fmu.component

    def _checked(self, what, function: str, status: int, mark: int) -> None:
        """After a direct call of the C function `function` that returned `status`: UnitError if the status is
        above fmi2Warning (as fmpy raises) or the call logged an error since the log held `mark` entries.
        `what` (text, or a callable giving it) names the call in the message."""
        if status <= FMI2_WARNING and len(self.log) == mark:
            return
        what = what() if callable(what) else what
        entries = self.log[mark:]
        if status > FMI2_WARNING:
            raise UnitError(self._inside(f"{self.label}: {what} failed ({FMICallException(function, status)}): "
                                         f"{self._reasons(mark)}"), diverged=reported_divergence(entries))
        if any(entry.status >= ERROR_STATUS for entry in entries):
            raise UnitError(self._inside(f"{self.label}: {what} failed: {self._reasons(mark)}"),
                            diverged=reported_divergence(entries))

    def _live(self, function: str) -> None:
        """UnitError for a call after `close()` (the instance is freed: calling into it would crash the host)."""
        if self._fmu is None:
            raise UnitError(f"{self.label}: {function} after the unit was terminated")

    def reader(self, vrs: list[int]):
        from fmpy.fmi2 import fmi2Real, fmi2ValueReference
        n = len(vrs)
        vr_arr, buf = (fmi2ValueReference * n)(*vrs), (fmi2Real * n)()
        view = np.ctypeslib.as_array(buf)
        get, component = self._stepping_call("fmi2GetReal")

        def read() -> np.ndarray:
            self._live("fmi2GetReal")
            mark = len(self.log)
            self._checked("fmi2GetReal", "fmi2GetReal", get(component, vr_arr, n, buf), mark)
            return view.copy()
        return read

    def writer(self, vrs: list[int]):
        from fmpy.fmi2 import fmi2Real, fmi2ValueReference
        n = len(vrs)
        vr_arr, buf = (fmi2ValueReference * n)(*vrs), (fmi2Real * n)()
        view = np.ctypeslib.as_array(buf)
        set_real, component = self._stepping_call("fmi2SetReal")

        def write(values: np.ndarray) -> None:
            self._live("fmi2SetReal")
            view[:] = values
            mark = len(self.log)
            self._checked("fmi2SetReal", "fmi2SetReal", set_real(component, vr_arr, n, buf), mark)
        return write

    def get_string(self, vr: int) -> str:
        return self._call("fmi2GetString", self._fmu.getString, [vr])[0].decode("utf-8")

    def setup(self) -> None:
        self._call("fmi2SetupExperiment", self._fmu.setupExperiment, startTime=0.0)
        self._call("fmi2EnterInitializationMode", self._fmu.enterInitializationMode)

    def initialize(self) -> None:
        self._call("fmi2ExitInitializationMode", self._fmu.exitInitializationMode)
        self._initialized = True

    def do_step(self, t: float, h: float) -> None:
        self._live("fmi2DoStep")
        if self._do_step is None:
            self._do_step = self._stepping_call("fmi2DoStep")
        do_step, component = self._do_step
        mark = len(self.log)
        self._checked(lambda: f"fmi2DoStep(t = {t:.6g} s, h = {h:.6g} s)", "fmi2DoStep",
                      do_step(component, t, h, FMI2_FALSE), mark)

    def get_state(self) -> FmuState:
        return FmuState(self, self._call("fmi2GetFMUstate", self._fmu.getFMUstate))

    def set_state(self, state: FmuState) -> None:
        if not isinstance(state, FmuState) or state._port() is not self or state.handle is None:
            raise UnitError(f"{self.label}: set_state needs a live state from this unit's get_state()")
        self._call("fmi2SetFMUstate", self._fmu.setFMUstate, state.handle)

    def serialize_state(self, state: FmuState) -> bytes:
        return bytes(self._call("fmi2SerializeFMUstate", self._fmu.serializeFMUstate, state.handle))

    def deserialize_state(self, data: bytes) -> FmuState:
        return FmuState(self, self._call("fmi2DeSerializeFMUstate", self._fmu.deSerializeFMUstate, data))

    def close(self) -> None:
        if self._fmu is not None:
            for s in list(self._live_states):  # states are freed while the instance still exists
                s.free()
            fmu, self._fmu = self._fmu, None
            for fn in ((fmu.terminate,) if self._initialized else ()) + (fmu.freeInstance,):
                try:
                    fn()
                except Exception:  # noqa: BLE001 - e.g. terminate after a fatal status; free anyway
                    pass
        if self._dir is not None:
            # pythonfmu put <dir>/resources first on sys.path at instantiation: take it out with the folder
            resources = os.path.normpath(os.path.join(self._dir, "resources"))
            sys.path[:] = [p for p in sys.path if os.path.normpath(p) != resources]
            shutil.rmtree(self._dir, ignore_errors=True)
            self._dir = None


def differing_keys(a, b, prefix: str) -> list[str]:
    """Dotted keys at which two JSON-like values differ."""
    if isinstance(a, dict) and isinstance(b, dict):
        out = []
        for k in list(a) + [k for k in b if k not in a]:
            out += differing_keys(a.get(k), b.get(k), f"{prefix}.{k}")
        return out
    if isinstance(a, list) and isinstance(b, list) and len(a) == len(b):
        out = []
        for i, (x, y) in enumerate(zip(a, b)):
            out += differing_keys(x, y, f"{prefix}[{i}]")
        return out
    return [] if a == b else [prefix]
