"""benchmarks/instructions.py: callgrind's totals and the inclusive counts of the FMI calls per FMU, read from
callgrind output files whose counts are known, and its refusals before anything is counted."""
import importlib
import shutil
import subprocess
import sys

import pytest

from repository import ROOT

sys.path.insert(0, str(ROOT / "benchmarks"))
instructions = importlib.import_module("instructions")

# Two FMU binaries that both export fmi2DoStep and fmi2GetReal (compressed names, as callgrind writes them): the
# structure's fmi2DoStep is called twice (inclusive 1000 + 500), the aero's once (inclusive 300, of which 200 in
# a function it calls); fmi2GetReal of the structure once (inclusive 40). Exclusive costs sum to the summary.
SAMPLE = """# callgrind format
version: 1
positions: line
events: Ir
summary: 1900

ob=(1) /usr/lib/libpython3.11.so
fl=(1) ???
fn=(1) ffi_call
0 60
cob=(2) /tmp/a/binaries/linux64/structure_pythonfmu.so
cfn=(2) fmi2DoStep
calls=2 0
0 1500
cob=(3) /tmp/b/binaries/linux64/aero_pythonfmu.so
cfn=(3) fmi2DoStep
calls=1 0
0 300
cob=(2)
cfn=(5) fmi2GetReal
calls=1 0
0 40

ob=(2)
fn=(2)
0 1500
fn=(5)
0 40

ob=(3)
fn=(3)
0 100
cfn=(4) PySlaveInstance::Step(double, double)
calls=1 0
0 200
fn=(4)
0 200
"""


def test_the_total_is_the_summary_line_and_equals_the_sum_of_the_exclusive_costs():
    assert instructions.total_instructions(SAMPLE) == 1900 == 60 + 1500 + 40 + 100 + 200
    older = SAMPLE.replace("summary: 1900", "").replace("events: Ir", "events: Ir Dr") + "totals: 1900 17\n"
    assert instructions.total_instructions(older) == 1900
    with pytest.raises(instructions.CountError, match="no summary"):
        instructions.total_instructions("events: Ir\n")


def test_the_fmi_calls_are_counted_inclusively_and_apart_per_fmu():
    counts = instructions.inclusive_counts(SAMPLE, {"fmi2DoStep", "fmi2GetReal"})
    assert counts == {("fmi2DoStep", "/tmp/a/binaries/linux64/structure_pythonfmu.so"): 1500,
                      ("fmi2DoStep", "/tmp/b/binaries/linux64/aero_pythonfmu.so"): 300,
                      ("fmi2GetReal", "/tmp/a/binaries/linux64/structure_pythonfmu.so"): 40}
    assert instructions.split_by_unit(counts, "fmi2DoStep", ["aero", "structure"]) == {"aero": 300, "structure": 1500}
    with pytest.raises(instructions.CountError, match="of 0 of the units"):
        instructions.split_by_unit(counts, "fmi2DoStep", ["structure"])


@pytest.mark.skipif(shutil.which("valgrind") is None, reason="needs valgrind")
def test_a_real_callgrind_file_reads_to_its_own_sum_of_exclusive_costs(tmp_path):
    out = tmp_path / "callgrind.out"
    subprocess.run(["valgrind", "--tool=callgrind", f"--callgrind-out-file={out}", "true"], check=True,
                   capture_output=True)
    text = out.read_text()
    exclusive, after_calls = 0, False
    for line in text.splitlines():       # a cost line: positions (here one) then Ir; a call's line is inclusive
        if line[:1].isdigit() or line[:1] in "+-*":
            if not after_calls:
                exclusive += int(line.split()[1]) if len(line.split()) > 1 else 0
            after_calls = False
        elif line.startswith("calls="):
            after_calls = True
    assert instructions.total_instructions(text) == exclusive > 0


def test_without_valgrind_it_says_so_and_exits_2(monkeypatch, capsys):
    monkeypatch.setenv("PATH", "")
    assert instructions.main(["--scenes", "deploy_rigid"]) == 2
    assert "valgrind and setarch not found" in capsys.readouterr().err


def test_split_needs_the_fmu_backend_and_a_scene_needs_a_stop_time(capsys):
    with pytest.raises(SystemExit) as raised:
        instructions.main(["--backend", "direct", "--split"])
    assert raised.value.code == 2 and "--split" in capsys.readouterr().err
    if shutil.which("valgrind"):
        with pytest.raises(SystemExit):
            instructions.main(["--scenes", "deploy_flexible_folding"])
        assert "give --stop deploy_flexible_folding=SECONDS" in capsys.readouterr().err
