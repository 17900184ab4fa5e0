"""The import trace of a standalone FMU's build sees only the unit's requirements in site-packages
(orchestrator/build/import_trace.py, `runtime.required_packages`): a package that merely happens to be installed
(charset_normalizer, which numpy.f2py imports when it finds it) is not importable there, so the runtime never
depends on it and the win64 runtime, made of the requirements' wheels alone, has everything the trace found."""
import subprocess
import sys
from pathlib import Path

from orchestrator.build import import_trace
from orchestrator.build.runtime import required_packages

TRACE = Path(import_trace.__file__)


def test_only_the_requirements_of_site_packages_are_importable(tmp_path):
    site = tmp_path / "site-packages"
    site.mkdir()
    (site / "required_probe.py").write_text("VALUE = 1\n")
    (site / "optional_probe.py").write_text("VALUE = 2\n")
    script = (f"import sys; sys.path.insert(0, {str(site)!r}); sys.path.insert(0, {str(TRACE.parent)!r})\n"
              "from import_trace import OnlyRequired\n"
              "sys.meta_path.insert(0, OnlyRequired(['required_probe']))\n"
              "import required_probe, json, email.mime.text\n"
              "try:\n    import optional_probe\nexcept ModuleNotFoundError as err:\n    print('refused:', err)\n"
              "print(required_probe.VALUE)\n")
    out = subprocess.run([sys.executable, "-I", "-c", script], capture_output=True, text=True, timeout=60)
    assert out.returncode == 0, out.stderr
    assert "refused: No module named 'optional_probe' (not among the unit's requirements)" in out.stdout
    assert out.stdout.strip().endswith("1")       # a required package and the standard library import as ever


def test_the_required_packages_are_the_requirements_and_what_they_require(tmp_path):
    # scipy requires numpy; pythonfmu is every unit's; nothing else installed here (matplotlib, the test tools)
    (tmp_path / "requirements.txt").write_text("scipy==0\n")
    packages = set(required_packages(tmp_path))
    assert {"scipy", "numpy", "pythonfmu"} <= packages
    assert not packages & {"matplotlib", "pytest", "charset_normalizer", "requests", "threadpoolctl"}
