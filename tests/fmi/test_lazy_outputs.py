"""Outputs computed when read (fmu_common.fmi_slave): every output of every shipped scene's units, read through
fmi2GetReal at a few steps, equals what the solver API gives when all of it is evaluated at that step by another
path (`StructureSolver.sensor_outputs`' one product for all sensors, `monitors()`, `AeroSolver.outputs()`); a
restored FMU state never answers a value computed at another time; an output no one reads is never computed, one
read is computed once per step; and the master asks the units only for what the scene's `record` table asks for.
"""
import json

import numpy as np
import pytest
from pythonfmu import Real

from aero_fmu.aero_slave import AeroSlave
from fmu_common.errors import SceneError
from fmu_common.fmi_slave import SCENE_RESOURCE
from fmu_common.interface import fmi_name
from orchestrator.run.master import has_aero, run_scene
from orchestrator.scene.load import load_scene
from repository import SCENES
from structure_fmu.interface import LATCH_PENDING
from structure_fmu.solver import StructureSolver
from structure_fmu.structure_slave import StructureSlave

SHIPPED = sorted(path.stem for path in SCENES.glob("*.toml"))
STEPS = 3


def _slave(cls, scene, folder):
    """A slave of `cls` for `scene`, initialized at FMI start time 0."""
    folder.mkdir(exist_ok=True)
    (folder / SCENE_RESOURCE).write_text(json.dumps(scene), encoding="utf-8")
    slave = cls(instance_name=cls.model_name, resources=str(folder))
    slave.setup_experiment(0.0)
    slave.enter_initialization_mode()
    slave.exit_initialization_mode()
    return slave


def _outputs(slave) -> dict[str, int]:
    """{name: value reference} of the slave's Real outputs."""
    return {v.name: vr for vr, v in slave.vars.items() if v.causality.name == "output" and isinstance(v, Real)}


def _blocks(name: str, values) -> dict[str, float]:
    return {f"{name}[{k}]": float(v) for k, v in enumerate(values, start=1)}


def eager_structure(solver: StructureSolver) -> dict[str, float]:
    """Every output of the structure unit by its FMI name, all evaluated now through the solver API."""
    monitors = solver.monitors()
    out = {**_blocks("e", solver.e), **_blocks("de", solver.de),
           **{name: float(monitors[name]) for name in ("energy", "kinetic_energy", "constraint_residual",
                                                        "external_work")}}
    for hinge, angle in solver.fold_angles_deg().items():
        out[f"fold_angle_{hinge}"] = angle
        out[f"latch_time_{hinge}"] = monitors["latch_times"].get(hinge, LATCH_PENDING)    # FMI start time 0
    out.update(zip(solver.sensors.output_names(), solver.sensor_outputs().tolist()))
    out.update(solver.joint_monitors())
    return {fmi_name(name): value for name, value in out.items()}


def eager_aero(solver) -> dict[str, float]:
    """Every output of the aero unit by its FMI name, all evaluated now through the solver API."""
    out = {**_blocks("Q", solver.Q), **{name: float(v) for name, v in solver.outputs().items()},
           **{f"hinge_moment_{h}": m for h, m in solver.hinge_moments().items()}}
    return {fmi_name(name): value for name, value in out.items()}


def assert_reads(slave, expected: dict[str, float], what: str) -> None:
    """Every output of `slave` read through fmi2GetReal (first the last one alone, then all at once) equals
    `expected`: bit for bit, or within 1e-12 relative where the eager path sums in another order."""
    outputs = _outputs(slave)
    assert set(outputs) == set(expected), what
    last = list(outputs)[-1]
    first = slave.get_real([outputs[last]])
    got = dict(zip(outputs, slave.get_real(list(outputs.values()))))
    assert first == [got[last]], what
    assert not [m for m in slave.log_queue if m.status.value >= 3], (what, [m.msg for m in slave.log_queue])
    for name, value in got.items():
        assert value == pytest.approx(expected[name], rel=1e-12, abs=1e-14), f"{what}: {name}"


@pytest.mark.parametrize("name", SHIPPED)
def test_every_output_read_is_what_the_solver_gives_evaluated_all_at_once(name, tmp_path):
    scene = load_scene(SCENES / f"{name}.toml")
    h = scene["coupling"]["step"]
    structure = _slave(StructureSlave, scene, tmp_path / "structure")
    aero = _slave(AeroSlave, scene, tmp_path / "aero") if has_aero(scene) else None
    vr_s = _outputs(structure)
    n = structure.n
    names = {v.name: vr for vr, v in aero.vars.items()} if aero else {}
    e_in = [names[f"{block}[{k}]"] for block in ("e", "de") for k in range(1, n + 1)] if aero else []
    for k in range(STEPS + 1):
        assert_reads(structure, eager_structure(structure._solver), f"{name}, structure, step {k}")
        if aero is not None:
            assert_reads(aero, eager_aero(aero._solver), f"{name}, aero, step {k}")
        if k == STEPS:
            break
        assert structure.do_step(k * h, h), [m.msg for m in structure.log_queue]
        if aero is not None:
            e = structure.get_real([vr_s[f"e[{i}]"] for i in range(1, n + 1)])
            de = structure.get_real([vr_s[f"de[{i}]"] for i in range(1, n + 1)])
            aero.set_real(e_in, e + de)
            assert aero.do_step(k * h, h), [m.msg for m in aero.log_queue]


@pytest.mark.parametrize("read_before_saving", [False, True])
def test_a_restored_state_answers_the_outputs_of_its_own_time(read_before_saving, tmp_path):
    scene = load_scene(SCENES / "deploy_flexible.toml")
    h = scene["coupling"]["step"]
    slave = _slave(StructureSlave, scene, tmp_path)
    outputs = list(_outputs(slave).values())
    for k in range(2):
        slave.do_step(k * h, h)
    at_2h = eager_structure(slave._solver)
    if read_before_saving:
        slave.get_real(outputs)
    saved = slave._fmu_state_from_bytes(slave._fmu_state_to_bytes(slave._get_fmu_state()))
    state = slave._get_fmu_state()
    slave.do_step(2 * h, h)
    later = slave.get_real(outputs)                 # the unit now holds the values at 3h
    assert later != [at_2h[name] for name in _outputs(slave)]
    for restored in (state, saved):
        slave._set_fmu_state(restored)
        assert_reads(slave, at_2h, "restored at 2h")
        slave.do_step(2 * h, h)                     # and on from there as before
        assert slave.get_real(outputs) == later


def test_an_output_is_computed_only_when_read_and_once_per_step(tmp_path, monkeypatch):
    scene = load_scene(SCENES / "deploy_flexible.toml", ["aero.model=none"])
    h = scene["coupling"]["step"]
    calls = []
    solve = StructureSolver.probe_accelerations
    monkeypatch.setattr(StructureSolver, "probe_accelerations", lambda self: calls.append(self.time) or solve(self))
    slave = _slave(StructureSlave, scene, tmp_path)
    vr = _outputs(slave)
    positions = [vr["tip_x"], vr["tip_y"], vr["tip_z"], vr["energy"], vr["strain_20mm"]]
    accelerations = [vr["tip_ax"], vr["tip_ay"], vr["tip_az"]]
    calls.clear()                                   # the layout's start values at construction
    slave.do_step(0.0, h)
    slave.get_real(positions)
    assert calls == []                              # no acceleration solved for the positions, energy, strain
    first = slave.get_real(accelerations)
    assert slave.get_real(accelerations[:1]) == first[:1] and slave.get_real(accelerations) == first
    assert calls == [pytest.approx(h)]              # once in the step, however often read
    slave.do_step(h, h)
    slave.do_step(2 * h, h)                         # a step nobody reads costs no solve
    slave.get_real(accelerations)
    assert calls == [pytest.approx(h), pytest.approx(3 * h)]


def test_the_run_records_only_what_the_record_table_asks_for_and_the_units_compute_nothing_else(monkeypatch):
    stop = ["time.stop=0.02"]
    full = run_scene(load_scene(SCENES / "deploy_rigid.toml", stop), backend="direct")

    computed = []
    for query in ("probe_accelerations", "potential_energy"):
        original = getattr(StructureSolver, query)
        monkeypatch.setattr(StructureSolver, query,
                            lambda self, f=original, q=query: computed.append((q, self.time)) or f(self))
    lean = run_scene(load_scene(SCENES / "deploy_rigid.toml",
                                stop + ["record.probes=velocity", "record.monitors=constraints"]), backend="direct")
    assert full.status == lean.status == "ok", (full.message, lean.message)
    assert {t for _, t in computed} == {0.0}   # only the start values the unit's layout declares, at construction
    assert full.series.columns == lean.series.columns           # columns are kept, not renamed or dropped
    table, lean_table = full.series.table(), lean.series.table()
    skipped = [c for c in full.series.columns
               if c.endswith(("_ax", "_ay", "_az")) or c in ("energy", "kinetic_energy", "external_work")]
    assert len(skipped) == 3 * len(full.series.probe_names) + 3
    for j, column in enumerate(full.series.columns):
        if column in skipped:
            assert np.isnan(lean_table[:, j]).all() and np.isfinite(table[:, j]).all(), column
        else:          # reading less changes nothing else: the same run, bit for bit
            assert np.array_equal(lean_table[:, j], table[:, j], equal_nan=True), column


@pytest.mark.parametrize("key, value", [("record.probes", "jerk"), ("record.monitors", "energy")])
def test_a_record_value_not_declared_is_refused_naming_the_key(key, value):
    with pytest.raises(SceneError, match=key.replace(".", r"\.")):
        load_scene(SCENES / "deploy_rigid.toml", [f"{key}={value!r}".replace("'", '"')])


def test_an_implicit_coupling_computes_the_recorded_outputs_of_its_accepted_iterates_only(monkeypatch):
    computed = []
    solve = StructureSolver.probe_accelerations
    monkeypatch.setattr(StructureSolver, "probe_accelerations", lambda self: computed.append(self.time) or solve(self))
    scene = load_scene(SCENES / "deploy_rigid.toml", ["time.stop=0.01", "coupling.algorithm=implicit"])
    result = run_scene(scene, backend="direct")
    assert result.status == "ok", result.message
    iterations = result.series.column("coupling_iterations")[1:]
    steps = len(iterations)
    assert iterations.sum() > steps                   # steps repeated: the structure stepped more often than recorded
    after_start = [t for t in computed if t > 0]
    assert after_start == pytest.approx(scene["coupling"]["step"] * np.arange(1, steps + 1))   # once per record


def test_an_output_whose_computation_fails_reads_nan_with_the_reason_at_every_read(tmp_path, monkeypatch):
    scene = load_scene(SCENES / "deploy_flexible.toml", ["aero.model=none"])
    slave = _slave(StructureSlave, scene, tmp_path)
    vr = _outputs(slave)

    def singular(self):
        raise np.linalg.LinAlgError("singular matrix")

    monkeypatch.setattr(StructureSolver, "probe_accelerations", singular)
    assert slave.do_step(0.0, scene["coupling"]["step"])
    for _ in range(2):
        slave.log_queue.clear()
        values = slave.get_real([vr["tip_x"], vr["tip_ax"]])
        assert np.isfinite(values[0]) and np.isnan(values[1])
        errors = [m.msg for m in slave.log_queue if m.status.value >= 3]
        assert len(errors) == 1 and "bending_100mm_ax .. tip_az: LinAlgError: singular matrix" in errors[0], errors
