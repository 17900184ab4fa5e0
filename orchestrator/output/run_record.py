"""``run.json``: which run wrote a results folder, and whether it finished writing it.

``start_record`` writes it before the run, with ``complete`` false: the writer's record
(``orchestrator.files.process_record``: ``run_id``, ``pid``, ``host``, ``command``, ``started``), the
``overrides`` (``--set`` items) and any fields the caller adds (a sweep adds ``sweep``). ``finish_record``
rewrites it last, once every other file is written, with ``complete`` true, ``finished`` (UTC) and ``files``:
the SHA-256 of each file the run wrote ({path from the folder: hex digest}). ``complete_record`` reads it back and
checks those digests: a folder whose run was killed, or whose files were changed or truncated since, is not complete.
"""
from __future__ import annotations

import datetime
import json
from pathlib import Path
from typing import Iterable

from orchestrator.files import file_sha256, write_file

RUN_RECORD = "run.json"


def start_record(out_dir: Path, holder: dict, overrides: Iterable[str], **extra) -> dict:
    """Write ``out_dir/run.json`` for the run `holder` (a process record) with its `overrides` and `extra`
    fields, ``complete`` false; returns the record. WriteError naming the file."""
    record = {**holder, "overrides": list(overrides), **extra, "complete": False}
    _write(Path(out_dir), record)
    return record


def finish_record(out_dir: Path, record: dict, files: Iterable[Path]) -> dict:
    """Rewrite ``out_dir/run.json`` as `record`, complete, with the SHA-256 of each of `files` (the files the run
    wrote, in `out_dir` or below it, named by their path from it: ``vtk/structure.pvd``); the last file a run
    writes. Returns the record. WriteError naming the file."""
    def name(f: Path) -> str:
        return f.relative_to(out_dir).as_posix() if f.is_relative_to(out_dir) else f.name

    out_dir = Path(out_dir)
    done = {**record, "complete": True,
            "finished": datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds"),
            "files": {name(f): file_sha256(f) for f in sorted(set(map(Path, files)))}}
    _write(Path(out_dir), done)
    return done


def complete_record(out_dir: Path) -> dict | None:
    """The record of ``out_dir/run.json`` if its run finished writing the folder and every file it lists still
    has the digest it had then; else None (no record, a run killed before the end, a file missing or changed)."""
    try:
        record = json.loads((Path(out_dir) / RUN_RECORD).read_text())
        if not (isinstance(record, dict) and record.get("complete") is True and isinstance(record.get("files"), dict)):
            return None
        for name, digest in record["files"].items():
            if file_sha256(Path(out_dir) / name) != digest:
                return None
    except (OSError, ValueError):
        return None
    return record


def _write(out_dir: Path, record: dict) -> None:
    text = json.dumps(record, indent=2) + "\n"
    write_file(out_dir / RUN_RECORD, lambda tmp: tmp.write_text(text))
