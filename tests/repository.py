"""Where the repository's files are, for the tests: absolute paths, so that pytest may start in any folder."""
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]   # the repository: scenes/, docs/, README.md, pyproject.toml
SCENES = ROOT / "scenes"
# The FMI Compliance Checker (modelica-tools/FMUComplianceChecker, a static build), where the development
# machines keep it beside the repository; the tests that need it are skipped where it is absent.
FMU_CHECKER = ROOT.parent / "shared" / "tools" / "fmucheck" / "fmuCheck.linux64"
# OpenModelica's OMSimulator (a C++ FMI/SSP host, built from source), kept beside the checker
OMSIMULATOR = ROOT.parent / "shared" / "tools" / "omsimulator"
