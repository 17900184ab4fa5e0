"""The API reference of wingsim's packages as HTML, made by pdoc from the docstrings:

    .venv/bin/pip install -e '.[docs]'
    .venv/bin/python docs/api_reference.py [--out DIR]

writes DIR/index.html (default build/api/, which git ignores) and one page per module of wingsim (the Python API,
docs/api.md), fmu_common, structure_fmu, aero_fmu and orchestrator with its sub-packages; docstrings are read as
Markdown with Google-style sections (Args:, Returns:; docs/architecture.md, "Docstrings"). No module is
left out: pdoc imports each one (the slave scripts with pythonfmu; orchestrator.build.import_trace, a script
run as `python -I import_trace.py`, only defines functions when imported) but the packages' ``__main__``
(``python -m orchestrator``), which runs the command line when imported and which pdoc never documents.

Exit 1 when the reference is not whole, listing why:
- a module that does not import: pdoc stops at the first (tests/cli/test_importable.py names every one);
- every warning raised while pdoc imports and renders (a module that does not import, a type annotation it
  cannot resolve, ...). pdoc only prints its warnings and exits 0, and it hides those raised during a
  module's import, where it swallows stderr; here they are recorded, whatever their category;
- every module on disk without a page: pdoc walks packages with pkgutil, which passes over a folder without
  ``__init__.py`` in silence.
"""
from __future__ import annotations

import argparse
import shutil
import sys
import time
import traceback
import warnings
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("fmu_common", "structure_fmu", "aero_fmu", "orchestrator", "wingsim")


def modules_on_disk() -> list[str]:
    """Every module of the packages that the reference documents, from their *.py files ("__main__" aside)."""
    names = []
    for package in PACKAGES:
        for path in sorted((ROOT / package).rglob("*.py")):
            parts = path.relative_to(ROOT).with_suffix("").parts
            if parts[-1] == "__main__" or "__pycache__" in parts:
                continue
            names.append(".".join(parts[:-1] if parts[-1] == "__init__" else parts))
    return names


def _where(w: warnings.WarningMessage) -> str:
    """ (the file and line that raised a warning) when it is one of ours; pdoc's own say what they are about."""
    path = Path(w.filename).resolve()
    return f" ({path.relative_to(ROOT)}:{w.lineno})" if path.is_relative_to(ROOT) else ""


def build(out: Path) -> tuple[list[str], list[str]]:
    """Write the reference into `out` (emptied first); returns (the warnings raised, the modules without a page)."""
    import pdoc
    import pdoc.render

    if out.exists():
        shutil.rmtree(out)      # pages of modules since removed or renamed would stay
    pdoc.render.configure(docformat="google", footer_text="wingsim")
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        try:
            pdoc.pdoc(*PACKAGES, output_directory=out)
        except RuntimeError as exc:     # pdoc's "Error importing MODULE", raised from the import's own error
            traceback.print_exception(exc)
            raise SystemExit(f"error: {exc}: {exc.__cause__!r}") from None
    raised = [f"{w.category.__name__}: {w.message}" + _where(w) for w in caught]
    missing = [name for name in modules_on_disk() if not (out / f"{name.replace('.', '/')}.html").is_file()]
    return raised, missing


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description="Write the API reference of wingsim's packages as HTML (pdoc).")
    parser.add_argument("--out", type=Path, default=ROOT / "build" / "api", metavar="DIR",
                        help="output folder, emptied first (default: build/api/ in the repository)")
    args = parser.parse_args(argv)
    out = args.out.resolve()
    if out.exists() and any(out.iterdir()) and not (out / "index.html").is_file():
        print(f"error: --out '{args.out}': a folder that is not an API reference; it would be emptied",
              file=sys.stderr)
        return 2
    sys.path.insert(0, str(ROOT))       # the packages of this checkout, installed or not
    try:
        import pdoc  # noqa: F401
    except ImportError:
        print("error: pdoc is not installed: pip install -e '.[docs]'", file=sys.stderr)
        return 2
    start = time.perf_counter()
    raised, missing = build(out)
    for text in raised:
        print(f"warning: {text}", file=sys.stderr)
    for name in missing:
        print(f"error: {name} has no page (is its folder a package, with __init__.py?)", file=sys.stderr)
    if raised or missing:
        print(f"API reference incomplete: {len(raised)} warnings, {len(missing)} modules without a page",
              file=sys.stderr)
        return 1
    print(f"API reference of {len(modules_on_disk())} modules in {time.perf_counter() - start:.1f} s: "
          f"{out / 'index.html'}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
