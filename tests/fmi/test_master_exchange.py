"""What the master does per communication step (orchestrator.run.master, recording, units, fmu_port): the samples it
records from the units' output vectors are those the units' own monitors give, row by row; the two backends record
the same run bit for bit; an explicit coupling reads each unit once per step; a unit terminated refuses calls
instead of calling into a freed instance; the series' preallocated rows grow without changing a sample."""
import numpy as np
import pytest

from aero_fmu.aero_slave import AeroSlave
from orchestrator.run import units as real_units
from orchestrator.run.coupling import AeroInputs, make_scheme
from orchestrator.run.master import new_series, recorded_rows, run_scene
from orchestrator.run.port import UnitError
from orchestrator.run.recording import Recorder
from orchestrator.run.timeseries import PROBE_ROWS, TimeSeries
from orchestrator.scene.columns import AERO_COLUMNS, hinge_moment_column
from orchestrator.scene.load import load_scene
from repository import SCENES
from structure_fmu.structure_slave import StructureSlave

STOP = ["time.stop=0.01"]


def _reference_row(series: TimeSeries, t: float, structure, aero) -> None:
    """Append the sample at t as the series' own `append` files the units' `monitors()` dictionaries: the path
    the recorder's index gathers replace."""
    m, a = structure.monitors(), aero.monitors()
    rates = {key: np.array([m[key][p] for p in series.probe_names]) if key in m else None for key in PROBE_ROWS}
    loads = {name: a[name] for name in AERO_COLUMNS}
    loads.update({hinge_moment_column(h): a["hinge_moments"].get(h, np.nan) for h in series.hinge_names})
    series.append(t, rates["probe_positions"], m["fold_angles_deg"], m["energy"], m["constraint_residual"],
                  kinetic_energy=m["kinetic_energy"], external_work=m["external_work"], aero=loads,
                  strains=m["strains"], joints=m["joints"], velocities=rates["probe_velocities"],
                  accelerations=rates["probe_accelerations"])


def test_the_recorded_samples_are_the_units_monitors_row_by_row():
    scene = load_scene(SCENES / "deploy_rigid.toml", STOP)
    reads = recorded_rows(scene)
    structure = real_units.make_unit("structure", scene, "direct", None, reads=reads["structure"],
                                     monitors_with_outputs=True)
    aero = real_units.make_unit("aero", scene, "direct", None, reads=reads["aero"], monitors_with_outputs=True)
    try:
        fast, reference = new_series(scene), new_series(scene)
        recorder = Recorder(fast, structure, aero)
        scheme = make_scheme(scene, structure, aero, AeroInputs.empty())
        scheme.start()
        recorder.record(0.0)
        _reference_row(reference, 0.0, structure, aero)
        h = scene["coupling"]["step"]
        for k in range(5):
            scheme.advance(k * h, (k + 1) * h)
            recorder.record((k + 1) * h)
            _reference_row(reference, (k + 1) * h, structure, aero)
        assert fast.columns == reference.columns
        table = fast.table()
        assert np.isfinite(table).all()           # every column of the shipped scene is recorded
        assert np.array_equal(table, reference.table())
        assert recorder.latch_times() == structure.monitors()["latch_times"]
    finally:
        structure.terminate()
        aero.terminate()


@pytest.mark.parametrize("name", ["deploy_rigid", "spin_up"])
def test_both_backends_record_the_same_run_bit_for_bit(name, built_fmus):
    scene = load_scene(SCENES / f"{name}.toml", STOP)
    folder = built_fmus(name)                       # the shipped build runs a shorter time.stop
    runs = {backend: run_scene(scene, backend=backend, fmu_dir=folder) for backend in ("fmu", "direct")}
    fmu, direct = runs["fmu"], runs["direct"]
    assert fmu.status == direct.status == "ok", (fmu.message, direct.message)
    assert len(fmu.series) == round(0.01 / scene["coupling"]["step"]) + 1
    assert np.array_equal(fmu.series.table(), direct.series.table(), equal_nan=True)
    assert fmu.latch_times == direct.latch_times
    assert np.array_equal(fmu.structure_coordinates.e, direct.structure_coordinates.e)
    if fmu.aero_inputs is not None:
        assert np.array_equal(fmu.aero_inputs.e, direct.aero_inputs.e)
        assert np.array_equal(fmu.aero_inputs.de, direct.aero_inputs.de)


def test_an_explicit_coupling_reads_each_unit_once_per_step(monkeypatch):
    reads = {StructureSlave: 0, AeroSlave: 0}
    for cls in reads:
        original = cls.get_real

        def counted(self, vrs, cls=cls, original=original):
            reads[cls] += 1
            return original(self, vrs)
        monkeypatch.setattr(cls, "get_real", counted)
    scene = load_scene(SCENES / "deploy_rigid.toml", STOP)
    steps = round(0.01 / scene["coupling"]["step"])

    class Counting:
        UnitError = real_units.UnitError

        @staticmethod
        def make_unit(**kwargs):
            unit = real_units.make_unit(**kwargs)
            reads[StructureSlave] = reads[AeroSlave] = 0    # the reads of construction are not the steps'
            return unit

    result = run_scene(scene, backend="direct", units=Counting)
    assert result.status == "ok", result.message
    # the exchange at t = 0 and each step: the output blocks and every recorded output in one read per unit
    assert reads == {StructureSlave: steps + 1, AeroSlave: steps + 1}


def test_a_terminated_unit_refuses_calls_instead_of_calling_the_freed_instance(built_fmus):
    scene = load_scene(SCENES / "deploy_rigid.toml", STOP)
    unit = real_units.make_unit("structure", scene, "fmu", built_fmus("deploy_rigid"))
    e, de = unit.get_outputs()
    unit.terminate()
    with pytest.raises(UnitError, match="fmi2DoStep after the unit was terminated"):
        unit.do_step(0.0, scene["coupling"]["step"])
    with pytest.raises(UnitError, match="fmi2SetReal after the unit was terminated"):
        unit.set_inputs(np.zeros(unit.n))
    with pytest.raises(UnitError, match="fmi2GetReal after the unit was terminated"):
        unit.monitor_values()


def test_the_series_grows_past_its_preallocated_rows_keeping_every_sample():
    rng = np.random.default_rng(3)
    m = 3 * 64 + 5                                  # past the first block, twice
    time, positions, folds = np.arange(m) * 1e-3, rng.normal(size=(m, 2, 3)), rng.normal(size=(m, 1))
    energy, residual = rng.normal(size=m), rng.normal(size=m)
    grown = TimeSeries(["a", "b"], ["fold"])
    for k in range(m):
        grown.append(time[k], positions[k], {"fold": folds[k, 0]}, energy[k], residual[k])
    whole = TimeSeries.from_arrays(["a", "b"], ["fold"], time, positions, folds, energy, residual)
    assert len(grown) == m and np.array_equal(grown.table(), whole.table(), equal_nan=True)
    whole.append(1.0, positions[0], {}, 0.0, 0.0)   # a series made whole grows too
    assert len(whole) == m + 1 and np.isnan(whole.fold_angles_deg[-1]).all()
