"""A Python host that drives one unpacked FMU through fmpy, step by step as its arguments say (not a test module).

    python fmpy_host.py FOLDER ACTION [ACTION ...]

Actions, carried out in order, each printing one JSON line {"action", "status" (FMI status or null), "log"
(the messages logged during it), ...}:

    host          what the host process has of its own: its BLAS libraries' thread counts (threadpoolctl), its
                  signal masks and dispositions (/proc/self/status SigBlk, SigIgn, SigCgt) and Python's handlers
    instantiate   fmi2Instantiate, fmi2SetupExperiment (start 0), enter and exit initialization mode
    step:N        N communication steps of the FMU's default step
    read:NAME     fmi2GetReal of one output ("value"), or fmi2GetString for topology_hash
    workers       the pids of this process's child processes ("pids")
    kill:SIG      kill every child process with signal SIG (a number)
    free          fmi2FreeInstance
    wait          print "waiting" and block until standard input closes or a line arrives
    exit          os._exit(0) at once, the FMU not freed

The host never raises on an FMI status: a refused call is reported, and it goes on with the next action.
"""
import ctypes
import json
import os
import signal
import sys
from pathlib import Path

from fmpy import read_model_description
from fmpy.fmi1 import FMICallException, calloc, free
from fmpy.fmi2 import (FMU2Slave, fmi2CallbackAllocateMemoryTYPE, fmi2CallbackFreeMemoryTYPE, fmi2CallbackFunctions,
                       fmi2CallbackLoggerTYPE)


def host_state() -> dict:
    from threadpoolctl import threadpool_info
    status = dict(line.split(":\t", 1) for line in Path("/proc/self/status").read_text().splitlines() if ":\t" in line)
    handlers = {}
    for signum in signal.valid_signals():
        try:
            handlers[int(signum)] = repr(signal.getsignal(signum))
        except (ValueError, OSError):
            continue
    return {"blas": sorted([info["filepath"], info["num_threads"]] for info in threadpool_info()),
            "masks": {key: status[key].strip() for key in ("SigBlk", "SigIgn", "SigCgt")}, "handlers": handlers}


def children() -> list[int]:
    pids = []
    for task in Path(f"/proc/{os.getpid()}/task").iterdir():
        pids += [int(p) for p in (task / "children").read_text().split()]
    return pids


def main(folder: str, actions: list[str]) -> None:
    md = read_model_description(folder)
    log = []

    def logger(env, name, status, category, message):
        log.append([status, (category or b"").decode(), message.decode("utf-8", "replace").replace("%%", "%")])

    callbacks = fmi2CallbackFunctions()
    callbacks.logger = fmi2CallbackLoggerTYPE(logger)
    callbacks.allocateMemory = fmi2CallbackAllocateMemoryTYPE(calloc)
    callbacks.freeMemory = fmi2CallbackFreeMemoryTYPE(free)
    fmu = FMU2Slave(guid=md.guid, unzipDirectory=folder, modelIdentifier=md.coSimulation.modelIdentifier,
                    instanceName="unit")
    variables = {v.name: v for v in md.modelVariables}
    step, t, component = float(md.defaultExperiment.stepSize), 0.0, None

    def call(name, *args):
        try:
            getattr(fmu, name)(component, *args)
        except FMICallException as exc:
            return exc.status
        return 0

    for action in actions:
        verb, _, argument = action.partition(":")
        out = {"action": action, "status": None}
        if verb == "host":
            out.update(host_state())
        elif verb == "instantiate":
            resources = (Path(folder) / "resources").as_uri().encode()
            component = fmu.fmi2Instantiate(b"unit", 1, md.guid.encode(), resources, ctypes.byref(callbacks), 0, 1)
            statuses = [call("fmi2SetupExperiment", 0, 0.0, 0.0, 0, 0.0), call("fmi2EnterInitializationMode"),
                        call("fmi2ExitInitializationMode")] if component else []
            out["status"] = max(statuses) if component else 3
        elif verb == "step":
            statuses = []
            for _ in range(int(argument)):
                statuses.append(call("fmi2DoStep", t, step, 1))
                t += step
            out["status"] = max(statuses)
        elif verb == "read":
            var = variables[argument]
            if var.type == "String":
                value = (ctypes.c_char_p * 1)()
                out["status"] = call("fmi2GetString", (ctypes.c_uint * 1)(var.valueReference), 1, value)
                out["value"] = value[0].decode()
            else:
                value = (ctypes.c_double * 1)()
                out["status"] = call("fmi2GetReal", (ctypes.c_uint * 1)(var.valueReference), 1, value)
                out["value"] = value[0]
        elif verb == "workers":
            out["pids"] = children()
        elif verb == "kill":
            for pid in children():
                os.kill(pid, int(argument))
        elif verb == "free":
            fmu.fmi2FreeInstance(component)
            component = None
        elif verb == "wait":
            print(json.dumps({"action": "wait", "status": None, "log": log}), flush=True)
            sys.stdin.readline()
            log.clear()
            continue
        elif verb == "exit":
            sys.stdout.flush()
            os._exit(0)
        out["log"], log[:] = list(log), []
        print(json.dumps(out), flush=True)


if __name__ == "__main__":
    main(sys.argv[1], sys.argv[2:])
