"""The third-party packages a unit needs, checked before it imports any of them.

Inside an ordinary FMU (which runs in a Python it finds on the target: the host's, or the build environment's,
or the one $WINGSIM_PYTHON names, docs/fmu.md), the slave script imports this module first. When the FMU's
`resources/requirements.txt` (written by the build: the distributions its sources import, pinned to the
versions it was built with; `pythonfmu deploy FMU` installs them) names a package that Python cannot import,
the import raises one ImportError naming every missing package and the interpreter, instead of failing on the
first one. Outside an FMU (the direct backend, the installed wingsim) there is no such file and nothing is
checked: the installer brought the packages.
"""
from __future__ import annotations

import importlib.util
import re
import sys
from pathlib import Path

REQUIREMENTS = "requirements.txt"


def missing_packages(requirements: Path) -> list[str]:
    """The distributions named in `requirements` that cannot be imported.

    Their import name is the distribution's with '-' as '_'.

    Args:
        requirements: a requirements file (pip's format, one per line).
    """
    names = [re.split(r"[\s=<>!~;\[]", line.strip(), maxsplit=1)[0]
             for line in requirements.read_text(encoding="utf-8").splitlines()
             if line.strip() and not line.lstrip().startswith("#")]
    return [name for name in names if importlib.util.find_spec(name.replace("-", "_")) is None]


def _check() -> None:
    requirements = Path(__file__).resolve().parent.parent / REQUIREMENTS   # fmu_common/ sits in resources/
    if not requirements.is_file():
        return
    missing = missing_packages(requirements)
    if missing:
        version = ".".join(map(str, sys.version_info[:3]))
        raise ImportError(
            f"this wingsim unit needs {', '.join(missing)}, which the Python it runs in cannot import "
            f"({sys.executable or 'an embedded interpreter'}, Python {version}): install them there (pip install "
            f"-r {requirements}, or pythonfmu deploy on the FMU), give a host without Python another environment "
            "with WINGSIM_PYTHON=/path/to/python, or use a standalone FMU (wingsim build --standalone), which "
            "carries its own Python")


_check()
