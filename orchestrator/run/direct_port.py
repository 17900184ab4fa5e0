"""The direct backend of a unit: the same slave class the FMU carries (`StructureSlave`, `AeroSlave`),
instantiated in-process and driven through the same calls, its log drained after each call; used by
tests, studies and `--backend direct`, and to measure what the FMI boundary costs."""
from __future__ import annotations

import importlib
import json
import tempfile
from pathlib import Path

import numpy as np

from fmu_common.fmi_slave import SCENE_RESOURCE
from orchestrator.run.port import (ERROR_STATUS, KINDS, LogEntry, UnitError, UnitKind, reported_divergence,
                                   warnings_and_errors)


class DirectPort:
    backend = "direct"

    def __init__(self, scene: dict, instance_name: str, spec: UnitKind = KINDS["structure"]):
        module = importlib.import_module(spec.slave[0])
        slave_class = getattr(module, spec.slave[1])

        self.label = f"{instance_name} (direct)"
        self._slave = None
        self._tmp = tempfile.TemporaryDirectory(prefix="wingsim_direct_")
        Path(self._tmp.name, SCENE_RESOURCE).write_text(json.dumps(scene), encoding="utf-8")
        self.log: list[LogEntry] = []
        self._slave = self._call("instantiate", slave_class, instance_name=instance_name,
                                 resources=self._tmp.name)

    def _call(self, what: str, fn, *args, ok_on_false: bool = True, **kwargs):
        slave = self._slave
        try:
            result = fn(*args, **kwargs)
        except Exception as exc:  # noqa: BLE001 - as fmi2Fatal through the FMU: report, never crash
            reasons = warnings_and_errors(self._drain(slave))
            raise UnitError(f"{self.label}: {what} failed ({type(exc).__name__}: {exc})"
                            + (f": {reasons}" if reasons else "")) from exc
        new = self._drain(slave)
        if any(entry.status >= ERROR_STATUS for entry in new) or (result is False and not ok_on_false):
            reasons = warnings_and_errors(new) or "no reason logged by the unit"
            raise UnitError(f"{self.label}: {what} failed: {reasons}", diverged=reported_divergence(new))
        return result

    def _drain(self, slave) -> list[LogEntry]:
        """Move the slave's queued log messages to self.log; returns them."""
        if slave is None:
            return []
        # the slave doubles '%' for the FMI logger's printf formatting: undo it as that logger would
        new = [LogEntry(int(m.status), m.category or "", m.msg.replace("%%", "%")) for m in slave.log_queue]
        slave.log_queue.clear()
        self.log += new
        return new

    def value_references(self) -> dict[str, int]:
        return {v.name: vr for vr, v in self._slave.vars.items()}

    def reader(self, vrs: list[int]):
        vrs = list(vrs)

        def read() -> np.ndarray:
            return np.array(self._call("get_real", self._slave.get_real, vrs))
        return read

    def writer(self, vrs: list[int]):
        vrs = list(vrs)

        def write(values: np.ndarray) -> None:
            self._call("set_real", self._slave.set_real, vrs, np.asarray(values, float).tolist())
        return write

    def get_string(self, vr: int) -> str:
        return self._call("get_string", self._slave.get_string, [vr])[0]

    def setup(self) -> None:
        self._call("setup_experiment", self._slave.setup_experiment, 0.0, None, None)
        self._call("enter_initialization_mode", self._slave.enter_initialization_mode)

    def initialize(self) -> None:
        self._call("exit_initialization_mode", self._slave.exit_initialization_mode)

    def do_step(self, t: float, h: float) -> None:
        self._call(f"do_step(t = {t:.6g} s, h = {h:.6g} s)", self._slave.do_step, t, h, ok_on_false=False)

    def get_state(self):
        return self._call("get_fmu_state", self._slave._get_fmu_state)

    def set_state(self, state) -> None:
        self._call("set_fmu_state", self._slave._set_fmu_state, state)

    def serialize_state(self, state) -> bytes:
        return self._call("fmu_state_to_bytes", self._slave._fmu_state_to_bytes, state)

    def deserialize_state(self, data: bytes):
        return self._call("fmu_state_from_bytes", self._slave._fmu_state_from_bytes, data)

    def close(self) -> None:
        slave, self._slave = self._slave, None
        if slave is not None:
            try:
                slave.terminate()
            except Exception:  # noqa: BLE001
                pass
        if self._tmp is not None:
            self._tmp.cleanup()
            self._tmp = None
