"""What `--win64` refuses, and how the downloads of its Windows runtime are kept (orchestrator/build/win64.py); the
binaries themselves are run under Wine in tests/fmi/test_win64.py (slow).

- `--win64` without `--standalone`, without the mingw-w64 cross compiler, or when pip cannot download the
  packages is refused with exit 2, naming what is missing, before anything is written;
- the downloads are fetched once and reused while every file is as its manifest records; a file changed, added
  or removed since is detected, and the whole kit is fetched again instead of being used (the fetch itself is
  replaced here by one that writes a small kit: the manifest and its checks are the real ones).
"""
import json
from pathlib import Path

from orchestrator.build import win64
from orchestrator.cli import main
from repository import SCENES

SCENE = SCENES / "deploy_rigid.toml"


def test_win64_without_standalone_is_refused_before_anything_is_written(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    for command in (["build", str(SCENE), "--win64"], ["export", str(SCENE), "--win64"]):
        assert main(command) == 2
        assert "win64 binaries are added to standalone FMUs only: give --standalone too" in capsys.readouterr().err
    assert list(tmp_path.iterdir()) == []


def test_win64_without_the_cross_compiler_is_refused_before_anything_is_written(tmp_path, monkeypatch, capsys):
    monkeypatch.setattr(win64, "COMPILER", "no-such-mingw-gcc")
    monkeypatch.chdir(tmp_path)
    assert main(["build", str(SCENE), "--standalone", "--win64"]) == 2
    assert "win64 binaries cannot be built here: no no-such-mingw-gcc" in capsys.readouterr().err
    assert list(tmp_path.iterdir()) == []


def test_win64_whose_downloads_fail_is_refused_before_anything_is_written(tmp_path, monkeypatch, capsys):
    # pip with no index and no other place to look: the download fails as it does without a network. The cross
    # compiler, whose presence is checked first, need not be installed for this: any program found will do.
    monkeypatch.setattr(win64, "COMPILER", "cc")
    monkeypatch.setenv("PIP_NO_INDEX", "1")
    monkeypatch.setenv("PIP_FIND_LINKS", str(tmp_path / "nothing"))
    monkeypatch.setenv("PIP_CONFIG_FILE", "/dev/null")
    monkeypatch.setenv("WINGSIM_CACHE_DIR", str(tmp_path / "cache"))
    work = tmp_path / "work"
    work.mkdir()
    monkeypatch.chdir(work)
    assert main(["export", str(SCENE), "--standalone", "--win64"]) == 2
    err = capsys.readouterr().err
    assert "win64 binaries cannot be built here: downloading with pip failed" in err, err
    assert list(work.iterdir()) == []
    assert not list((tmp_path / "cache").glob("win64-*")), "a partial download was kept"


def test_the_downloads_are_reused_while_unchanged_and_fetched_again_when_altered(tmp_path, monkeypatch, capsys):
    monkeypatch.setenv("WINGSIM_CACHE_DIR", str(tmp_path))
    fetched = []

    def fetch(spec, folder):
        fetched.append(folder)
        (folder / "embed").mkdir(parents=True)
        (folder / "embed" / "python311.dll").write_bytes(b"MZ the interpreter")
        (folder / "site-packages").mkdir()
        (folder / "site-packages" / "module.py").write_text("x = 1\n")
        win64.write_manifest(folder, spec)

    monkeypatch.setattr(win64, "_fetch", fetch)

    def kit() -> Path:
        win64._checked.clear()       # as a new process would
        return win64.kit().folder

    folder = kit()
    assert len(fetched) == 1 and json.loads((folder / "manifest.json").read_text())["files"]
    assert kit() == folder and len(fetched) == 1, "an unchanged kit is fetched again"
    alterations = [lambda: (folder / "site-packages" / "module.py").write_text("x = 2\n"),
                   lambda: (folder / "site-packages" / "extra.py").write_text("import os\n"),
                   lambda: (folder / "embed" / "python311.dll").unlink()]
    for number, alter in enumerate(alterations, start=2):
        alter()
        assert kit() == folder and len(fetched) == number, "an altered kit was used"
        assert "changed since they were fetched" in capsys.readouterr().err
        assert (folder / "site-packages" / "module.py").read_text() == "x = 1\n"
        assert not (folder / "site-packages" / "extra.py").exists()
