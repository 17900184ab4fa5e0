"""The FMU's native binary (orchestrator/build/fmi_shim.c, built by orchestrator.build.native_binary).

What the shim checks itself, through fmpy (a Python host: the shim forwards to pythonfmu's binary in the
host's interpreter): the GUID, the FMU type, the resource location, the component and FMU state
pointers, the status rule. A build environment that is gone, in the FMI Compliance Checker (a host
without Python): fmi2Instantiate returns NULL and the logged message names the missing path.
Without a C compiler, `wingsim build` keeps pythonfmu's binary and says so.
"""
import ctypes
import shutil
import zipfile
from pathlib import Path

import pytest
from fmpy import extract, read_model_description
from fmpy.fmi1 import FMICallException, calloc, free
from fmpy.fmi2 import (FMU2Slave, fmi2CallbackAllocateMemoryTYPE, fmi2CallbackFreeMemoryTYPE,
                       fmi2CallbackFunctions, fmi2CallbackLoggerTYPE, fmi2CoSimulation, fmi2FMUstate,
                       fmi2ModelExchange)

import pythonfmu
from fmi_hosts import check
from orchestrator.build import native_binary
from orchestrator.cli import main
from repository import SCENES

PYTHONFMU_BINARY = Path(pythonfmu.__file__).parent / "resources" / "binaries" / "linux64" / "libpythonfmu-export.so"
OK, ERROR = 0, 3
H = 1e-3


@pytest.fixture(scope="module")
def structure_fmu(built_fmus):
    if native_binary.unavailable_reason() is not None:
        pytest.skip(f"the shim cannot be built: {native_binary.unavailable_reason()}")
    return built_fmus("deploy_rigid") / "structure.fmu"


class Host:
    """One FMU loaded by fmpy, instantiated with our own arguments; `log` holds (status, category, text)."""

    def __init__(self, fmu: Path, folder: Path | None = None):
        self.md = read_model_description(str(fmu))
        self.dir = extract(str(fmu), unzipdir=str(folder) if folder else None)
        self.log = []

        def logger(env, name, status, category, message):  # message: a printf format without arguments
            text = message.decode("utf-8", "replace").replace("%%", "%")
            self.log.append((status, (category or b"").decode(), text))
        self.callbacks = fmi2CallbackFunctions()
        self.callbacks.logger = fmi2CallbackLoggerTYPE(logger)
        self.callbacks.allocateMemory = fmi2CallbackAllocateMemoryTYPE(calloc)
        self.callbacks.freeMemory = fmi2CallbackFreeMemoryTYPE(free)
        self.fmu = FMU2Slave(guid=self.md.guid, unzipDirectory=self.dir,
                             modelIdentifier=self.md.coSimulation.modelIdentifier, instanceName="unit")
        self.c = None

    def instantiate(self, guid=None, kind=fmi2CoSimulation, resources=None, logging_on=True):
        uri = resources if resources is not None else (Path(self.dir) / "resources").as_uri()
        self.c = self.fmu.fmi2Instantiate(b"unit", kind, (guid or self.md.guid).encode(), uri.encode(),
                                          ctypes.byref(self.callbacks), 0, int(logging_on))
        return self.c

    def status(self, name, *args):
        """Status of the FMI function `name` called with (component, *args); fmpy raises above warning."""
        try:
            getattr(self.fmu, name)(self.c, *args)
        except FMICallException as exc:
            return exc.status
        return OK

    def errors(self):
        return [text for status, _, text in self.log if status >= ERROR]

    def initialize(self):
        assert self.status("fmi2SetupExperiment", 0, 0.0, 0.0, 0, 0.0) == OK
        assert self.status("fmi2EnterInitializationMode") == OK
        assert self.status("fmi2ExitInitializationMode") == OK

    def close(self):
        if self.c is not None:
            self.fmu.fmi2FreeInstance(self.c)
        self.fmu.freeLibrary()
        shutil.rmtree(self.dir, ignore_errors=True)


def assert_steps(fmu: Path) -> None:
    """The FMU instantiates, initializes and takes one step in this process (fmpy), every call fmi2OK."""
    h = Host(fmu)
    try:
        assert h.instantiate() is not None, h.log
        h.initialize()
        assert h.status("fmi2DoStep", 0.0, H, 0) == OK
    finally:
        h.close()


@pytest.fixture
def host(structure_fmu):
    made = []

    def make(**kwargs):
        h = Host(structure_fmu, **kwargs)
        made.append(h)
        return h
    yield make
    for h in made:
        h.close()


def test_the_fmu_binary_is_the_shim_with_pythonfmus_binary_beside_it(structure_fmu):
    with zipfile.ZipFile(structure_fmu) as z:
        names = z.namelist()
        inner = z.read(f"{native_binary.PLATFORM_DIR}/{native_binary.inner_name('structure')}")
        shim = z.read(f"{native_binary.PLATFORM_DIR}/structure.so")
    assert inner == PYTHONFMU_BINARY.read_bytes()
    assert shim != inner
    assert len(names) == len(set(names))


def test_a_guid_of_another_build_is_refused_naming_both(host):
    h = host()
    assert h.instantiate(guid="{00000000-0000-0000-0000-000000000000}") is None
    assert any("{00000000-0000-0000-0000-000000000000}" in e and h.md.guid in e for e in h.errors()), h.log


def test_model_exchange_is_refused(host):
    h = host()
    assert h.instantiate(kind=fmi2ModelExchange) is None
    assert any("Co-Simulation only" in e for e in h.errors()), h.log


def test_a_resource_location_that_is_not_the_fmus_is_refused_naming_it(host, tmp_path):
    h = host()
    assert h.instantiate(resources=tmp_path.as_uri()) is None
    assert any(str(tmp_path / "slavemodule.txt") in e for e in h.errors()), h.log
    assert h.instantiate(resources="http://example.org/resources") is None
    assert any("not a file URI" in e for e in h.errors()), h.log
    odd = host(folder=tmp_path / "a%20b")  # pythonfmu would read "%20" in the path as a space
    assert odd.instantiate() is None
    assert any('its path contains "%20"' in e for e in odd.errors()), odd.log


@pytest.mark.parametrize("spelling", ["percent-encoded", "file:/", "file://localhost/"])
def test_every_spelling_of_a_file_uri_reaches_the_slave(host, tmp_path, spelling):
    """pythonfmu alone strips "file://" and decodes only %20; the shim passes it a plain path."""
    h = host(folder=tmp_path / "unzipped é 100%")
    resources = Path(h.dir) / "resources"
    uri = {"percent-encoded": resources.as_uri(), "file:/": f"file:{resources}",
           "file://localhost/": f"file://localhost{resources}"}[spelling]
    assert h.instantiate(resources=uri) is not None, h.log
    h.initialize()
    assert h.status("fmi2DoStep", 0.0, H, 0) == OK
    assert not h.errors()


def test_a_null_or_foreign_component_is_refused_and_the_host_lives(host):
    h = host()
    assert h.instantiate() is not None
    own = h.c
    foreign = ctypes.create_string_buffer(256)  # readable memory that is no instance of this FMU
    for component in (None, ctypes.addressof(foreign)):
        h.c = component
        assert h.status("fmi2DoStep", 0.0, H, 0) == ERROR
        assert h.status("fmi2SetupExperiment", 0, 0.0, 0.0, 0, 0.0) == ERROR
        h.fmu.fmi2FreeInstance(component)  # ignored
    h.c = own
    h.initialize()
    assert h.status("fmi2DoStep", 0.0, H, 0) == OK


def test_states_not_handed_out_by_this_instance_are_refused(host):
    h = host()
    assert h.instantiate() is not None
    h.initialize()
    saved = fmi2FMUstate()
    assert h.status("fmi2GetFMUstate", ctypes.byref(saved)) == OK
    assert saved.value

    unknown = fmi2FMUstate(saved.value + 16)
    n = ctypes.c_size_t()
    for name, args in (("fmi2SetFMUstate", (unknown,)), ("fmi2SerializedFMUstateSize", (unknown, ctypes.byref(n))),
                       ("fmi2FreeFMUstate", (ctypes.byref(unknown),))):
        mark = len(h.log)
        assert h.status(name, *args) == ERROR
        assert any("is not an FMU state of this instance" in t for s, _, t in h.log[mark:] if s >= ERROR)
    assert h.status("fmi2SetFMUstate", fmi2FMUstate()) == ERROR  # NULL
    assert h.status("fmi2FreeFMUstate", ctypes.byref(fmi2FMUstate())) == OK  # the standard: ignored

    # a serialized state needs the size fmi2SerializedFMUstateSize gave
    assert h.status("fmi2SerializedFMUstateSize", saved, ctypes.byref(n)) == OK and n.value > 0
    small = (ctypes.c_char * (n.value - 1))()
    assert h.status("fmi2SerializeFMUstate", saved, small, n.value - 1) == ERROR
    assert any(f"the state serializes to {n.value}" in e for e in h.errors())

    # fmi2GetFMUstate into a state of ours replaces it: the old pointer is gone
    old = saved.value
    assert h.status("fmi2GetFMUstate", ctypes.byref(saved)) == OK
    assert saved.value != old
    assert h.status("fmi2SetFMUstate", fmi2FMUstate(old)) == ERROR
    assert h.status("fmi2SetFMUstate", saved) == OK

    freed = fmi2FMUstate(saved.value)
    assert h.status("fmi2FreeFMUstate", ctypes.byref(saved)) == OK
    assert saved.value is None  # the pointer is cleared
    assert h.status("fmi2SetFMUstate", freed) == ERROR
    assert h.status("fmi2DoStep", 0.0, H, 0) == OK  # the host and the unit go on


def test_bytes_that_are_no_state_give_no_state(host):
    h = host()
    assert h.instantiate() is not None
    h.initialize()
    state = fmi2FMUstate()
    garbage = (ctypes.c_char * 7).from_buffer_copy(b"garbage")
    assert h.status("fmi2DeSerializeFMUstate", garbage, 7, ctypes.byref(state)) == ERROR
    assert state.value is None  # the shim freed what the slave made of it
    assert h.status("fmi2DeSerializeFMUstate", None, 7, ctypes.byref(state)) == ERROR


def test_a_refused_call_returns_error_and_its_reason_even_with_logging_off(host):
    """pythonfmu drops every message when logging is off, errors included; the shim keeps the slave's
    logging on, so the status rule still sees the error, and passes messages above fmi2OK to the host."""
    h = host()
    assert h.instantiate(logging_on=False) is not None
    assert h.status("fmi2DoStep", 0.0, H, 0) == ERROR  # before initialization
    assert h.errors()
    assert all(status != OK for status, _, _ in h.log)  # fmi2OK messages stay off


@pytest.mark.parametrize("missing", ["python", "libpython"])
def test_a_moved_build_environment_gives_null_and_names_the_missing_path(fmu_checker, structure_fmu, tmp_path, missing):
    moved = tmp_path / "structure.fmu"
    shutil.copyfile(structure_fmu, moved)
    gone = tmp_path / "moved-env" / ("bin/python" if missing == "python" else "lib/libpython3.so.1.0")
    native_binary.install_shim(moved, **{missing: str(gone)})
    with zipfile.ZipFile(moved) as z:
        names = z.namelist()
    assert len(names) == len(set(names))  # installed again over the shim: pythonfmu's binary kept once

    proc = check(fmu_checker, moved, None, 0.001, 0.002)
    text = proc.stdout + proc.stderr
    assert proc.returncode == 1, text  # a checker error exit, not a signal
    assert "Could not instantiate the model" in text, text
    assert any("logStatusError" in line and "fmi2Instantiate" in line and f"missing: {gone}" in line
               for line in text.splitlines()), text


def test_in_a_python_host_a_moved_build_environment_is_not_needed(structure_fmu, tmp_path):
    """A running interpreter (fmpy's) is used as it is: the shim starts none and needs no build paths."""
    moved = tmp_path / "structure.fmu"
    shutil.copyfile(structure_fmu, moved)
    native_binary.install_shim(moved, python=str(tmp_path / "gone" / "bin" / "python"))
    assert_steps(moved)


def test_without_a_c_compiler_build_keeps_pythonfmus_binary_and_says_so(tmp_path, monkeypatch, capsys):
    monkeypatch.setenv("CC", str(tmp_path / "no-such-cc"))
    assert main(["build", str(SCENES / "deploy_rigid.toml"), "--out", str(tmp_path / "fmus")]) == 0
    err = capsys.readouterr().err
    assert f"no C compiler: {tmp_path / 'no-such-cc'}" in err
    assert "runs only in Python hosts" in err
    for unit in ("structure", "aero"):
        fmu = tmp_path / "fmus" / f"{unit}.fmu"
        with zipfile.ZipFile(fmu) as z:
            assert z.read(f"{native_binary.PLATFORM_DIR}/{unit}.so") == PYTHONFMU_BINARY.read_bytes()
            assert f"{native_binary.PLATFORM_DIR}/{native_binary.inner_name(unit)}" not in z.namelist()
    assert_steps(tmp_path / "fmus" / "structure.fmu")   # a working FMU for a Python host


RAISING_SLAVE = '''
from pythonfmu import Fmi2Causality, Fmi2Slave, Real


class Raising(Fmi2Slave):
    author = "tests"
    description = "raises in do_step"

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.x = 1.0
        self.register_variable(Real("x", causality=Fmi2Causality.output))

    def do_step(self, current_time, step_size):
        raise RuntimeError("raised on purpose")
'''


def test_after_a_python_exception_the_instance_is_retired_and_the_host_lives(structure_fmu, tmp_path):
    """pythonfmu 0.7.0 turns an exception into fmi2Fatal and has then released the slave: freeing it again
    crashed hosts later in Python's garbage collector. The shim refuses further calls and does not."""
    import gc
    import sys

    from pythonfmu import FmuBuilder

    script = tmp_path / "raising_slave.py"
    script.write_text(RAISING_SLAVE)
    saved_path = list(sys.path)
    try:
        FmuBuilder.build_FMU(script, dest=tmp_path)
    finally:  # pythonfmu leaves the script's folder on sys.path and the script in sys.modules
        sys.path[:] = saved_path
        sys.modules.pop("raising_slave", None)
    fmu = tmp_path / "Raising.fmu"
    native_binary.install_shim(fmu)
    for _ in range(3):
        h = Host(fmu)
        try:
            assert h.instantiate() is not None, h.log
            h.initialize()
            assert h.status("fmi2DoStep", 0.0, H, 0) == 4  # fmi2Fatal
            assert any("raised on purpose" in text for _, _, text in h.log)
            assert h.status("fmi2DoStep", 0.0, H, 0) == 4
            assert any("cannot be used any more" in text for _, _, text in h.log)
        finally:
            h.close()
        gc.collect()
    assert_steps(structure_fmu)   # the interpreter is sound: a unit still runs
    gc.collect()
