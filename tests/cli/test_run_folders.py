"""Results kept per variant: the folder each `wingsim run` writes without --out, `wingsim results` listing them,
`wingsim clean` removing them (and nothing else)."""
import hashlib
import json
import os
import re

import orchestrator.output.plots

from orchestrator.cli import main
from orchestrator.clean import clean
from orchestrator.files import folder_lock, process_record
from orchestrator.output.run_record import start_record
from orchestrator.output.run_folders import MAX_LABEL, run_folder, variant_label

SHORT = ["--set", "time.stop=0.004"]
README_VARIANTS = [[], ["flow.speed=20"], ["aero.model=uvlm-free"], ["aero.model=none"],
                   ["structure.fidelity=strain-based"]]
"""The five `wingsim run scenes/deploy_flexible.toml` commands of the README, by their --set items."""
WINDOWS_FORBIDDEN = set('<>:"/\\|?*')


def sets(overrides):
    return [arg for item in overrides for arg in ("--set", item)]


def test_the_readmes_five_deploy_flexible_variants_leave_five_folders_listed_then_cleaned(tmp_path, capsys,
                                                                                          monkeypatch):
    monkeypatch.chdir(tmp_path)
    # the folders are the point
    monkeypatch.setattr(orchestrator.output.plots, "write_plots", lambda result, out, workers=1: [])
    for overrides in README_VARIANTS:
        assert main(["run", "deploy_flexible", *SHORT, *sets(overrides), "--backend", "direct"]) == 0
    capsys.readouterr()
    scene_folder = tmp_path / "results" / "deploy_flexible"
    expected = {"time.stop=0.004" + "".join(f",{o}" for o in overrides) for overrides in README_VARIANTS}
    assert {p.name for p in scene_folder.iterdir()} == expected
    for overrides in README_VARIANTS:   # each folder holds its own run: the resolved scene has its overrides
        summary = json.loads((scene_folder / variant_label(["time.stop=0.004", *overrides]) / "summary.json")
                             .read_text())
        assert summary["status"] == "ok" and summary["scene"]["time"]["stop"] == 0.004
        for item in overrides:
            key, value = item.split("=")
            section, leaf = key.split(".")
            given = summary["scene"][section][leaf]
            assert given == (float(value) if isinstance(given, float) else value)

    assert main(["results", "deploy_flexible"]) == 0
    listed = capsys.readouterr().out.splitlines()
    assert len(listed) == 5
    for overrides in README_VARIANTS:
        label = variant_label(["time.stop=0.004", *overrides])
        line = next(x for x in listed if x.startswith(f"deploy_flexible/{label}:"))
        assert ": ok; t_sim_s 0.004," in line
        assert line.endswith("; " + " ".join(f"--set {o}" for o in ["time.stop=0.004", *overrides]))
    assert "CL_final" not in next(x for x in listed if "aero.model=none" in x)   # no aero unit, no lift

    assert main(["clean", "deploy_flexible", "--results", "--dry-run"]) == 0
    assert capsys.readouterr().out == f"would remove {os.path.join('results', 'deploy_flexible')}\n"
    assert len(list(scene_folder.iterdir())) == 5
    assert main(["clean", "deploy_flexible", "--results"]) == 0
    assert not scene_folder.exists() and (tmp_path / "results").is_dir()
    assert main(["results"]) == 0 and "no runs in results" in capsys.readouterr().err


def test_the_scene_as_written_keeps_its_own_folder():
    assert run_folder("results", "deploy_rigid", []).as_posix() == "results/deploy_rigid"
    assert run_folder("results", "deploy_rigid", ["flow.speed=8"]).as_posix() == "results/deploy_rigid/flow.speed=8"


def test_unsafe_characters_become_underscores_and_keep_variants_apart():
    label = variant_label(['probes.0.name="a/b"', "flow.speed=10"])
    assert not WINDOWS_FORBIDDEN & set(label) and " " not in label
    assert re.fullmatch(r'probes\.0\.name=_a_b_,flow\.speed=10~[0-9a-f]{8}', label)
    digest = hashlib.sha256('probes.0.name="a/b"\nflow.speed=10'.encode()).hexdigest()[:8]
    assert label.endswith(f"~{digest}")
    # two overrides that sanitize alike still get two folders
    assert variant_label(["aero.model=a b"]) != variant_label(["aero.model=a:b"])
    assert variant_label([".hidden=1"]).startswith("_") and variant_label(["-x=1"]).startswith("_")


def test_long_labels_are_cut_with_a_digest_of_the_whole_overrides():
    many = [f"structure.bodies.{i}.section.density={1000 + i}" for i in range(10)]
    label = variant_label(many)
    assert len(label) <= MAX_LABEL and label.startswith(many[0])
    assert label.endswith("~" + hashlib.sha256("\n".join(many).encode()).hexdigest()[:8])
    assert variant_label(many[:9] + ["structure.bodies.9.section.density=1"]) != label


def test_clean_removes_only_inside_its_folders_and_keeps_a_folder_in_use(tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    outside = tmp_path / "precious"
    outside.mkdir()
    (outside / "data.txt").write_text("keep")
    for name in ("deploy_rigid", "deploy_rigid-0123456789ab", "deploy_rigid-standalone", "deploy_rigid_two"):
        (tmp_path / "fmus" / name).mkdir(parents=True)
    (tmp_path / "fmus" / "link").symlink_to(outside, target_is_directory=True)
    (tmp_path / "results" / "busy").mkdir(parents=True)
    (tmp_path / "results" / "idle").mkdir()

    done = clean([tmp_path / "fmus"], "deploy_rigid")
    assert sorted(p.name for p in done.removed) == ["deploy_rigid", "deploy_rigid-0123456789ab",
                                                    "deploy_rigid-standalone"]
    assert sorted(p.name for p in (tmp_path / "fmus").iterdir()) == ["deploy_rigid_two", "link"]

    with folder_lock(tmp_path / "results" / "busy", process_record()):
        assert main(["clean", "--fmus", "--results"]) == 0
    captured = capsys.readouterr()
    assert f"kept {os.path.join('results', 'busy')}: a running wingsim process holds it" in captured.err
    assert sorted(p.name for p in (tmp_path / "results").iterdir()) == ["busy"]
    assert list((tmp_path / "fmus").iterdir()) == []   # the link removed as a link ...
    assert (outside / "data.txt").read_text() == "keep"   # ... its target untouched


def test_clean_without_a_choice_is_refused(tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "results" / "x").mkdir(parents=True)
    assert main(["clean"]) == 2
    assert "--fmus/--results/--export" in capsys.readouterr().err
    assert (tmp_path / "results" / "x").is_dir()


def test_a_run_not_finished_is_listed_as_running_while_held_else_incomplete(tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    folder = tmp_path / "results" / "deploy_rigid" / "flow.speed=8"
    holder = process_record()
    with folder_lock(folder, holder):
        start_record(folder, holder, ["flow.speed=8"])
        assert main(["results"]) == 0
        assert capsys.readouterr().out == "deploy_rigid/flow.speed=8: running; --set flow.speed=8\n"
    assert main(["results", "deploy_rigid"]) == 0   # the holder gone without finishing: killed
    assert capsys.readouterr().out == "deploy_rigid/flow.speed=8: incomplete; --set flow.speed=8\n"
