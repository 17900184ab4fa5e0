"""Files the master writes: each one whole or not at all, and each folder written by one process at a time.

- ``write_file(path, write)``: ``write`` fills a temporary name in the target folder (``partial_name``: the
  file's name, this process's id and a random token, so that no two writers, processes or threads, share
  one), which is then renamed to ``path`` (``os.replace``, atomic within one file system). A process killed
  mid-write leaves at most a hidden ``.<name>.<pid>-<token>.partial<suffix>`` file, never a truncated file
  under the final name; ``remove_partials`` deletes those of writers that are gone. Every temporary file
  is in the target folder, so no rename crosses file systems, wherever the system's temporary folder is.
- ``folder_lock(folder, record)``: an advisory lock (``flock``) on ``folder/.wingsim.lock`` (or another lock
  file), which holds the record of its holder (``process_record``: a run id, the process id, the host, the
  command line, the start time) and is removed when released. Taken by a second process, the lock is
  refused (``FolderBusy``, naming the holder) or waited for (``wait=True``, saying whom it waits for). The
  kernel releases a ``flock`` when its holder dies, however it dies (SIGKILL included), so a lock is never
  stale; the lock file a killed holder leaves behind, with its record, is taken by the next process, which
  says it takes the folder over.

Locks are per host (``flock``); a folder shared over a network file system is not locked across machines.
"""
from __future__ import annotations

import contextlib
import datetime
import fcntl
import hashlib
import json
import os
import re
import secrets
import shlex
import socket
import sys
from pathlib import Path
from typing import Callable, Iterator

from fmu_common.errors import SceneError

LOCK_FILE = ".wingsim.lock"
PARTIAL = ".partial"
_PARTIAL_PATTERN = re.compile(r"^\..+\.(\d+)-[0-9a-f]{8}" + re.escape(PARTIAL))


class WriteError(RuntimeError):
    """A file could not be written; the message names the file and the cause."""

    def __init__(self, path: Path, err: OSError):
        self.path, self.cause = Path(path), err
        super().__init__(f"cannot write {path}: {err.strerror or err}")


class FolderBusy(SceneError):
    """Another process holds the folder given with ``option``; the message names that process (its record).
    A SceneError: refused before anything runs (exit 2)."""

    def __init__(self, option: str, folder: Path, holder: dict | None):
        ValueError.__init__(self, f"{option} {str(folder)!r}: busy: {describe(holder)} is writing there; wait "
                                  f"for it to end or give another {option}")
        self.key, self.value, self.holder = option, str(folder), holder
        self.allowed = "a folder no other wingsim process is writing"


def partial_name(path: Path) -> Path:
    """A temporary name for `path` in its folder, unique to this process and call; it keeps `path`'s suffix (a
    writer such as matplotlib's picks the format from it)."""
    path = Path(path)
    return path.with_name(f".{path.name}.{os.getpid()}-{secrets.token_hex(4)}{PARTIAL}{path.suffix}")


def write_file(path: Path, write: Callable[[Path], None]) -> Path:
    """``write(temporary path)``, then rename it to ``path``: ``path`` is either complete or untouched. The
    temporary file is removed if ``write`` fails or is interrupted; WriteError naming ``path`` for an OSError.
    Returns ``path``."""
    path = Path(path)
    tmp = partial_name(path)
    try:
        write(tmp)
        os.replace(tmp, path)
    except BaseException as err:
        with contextlib.suppress(OSError):
            tmp.unlink(missing_ok=True)
        if isinstance(err, OSError):
            raise WriteError(path, err) from err
        raise
    return path


def file_sha256(path: Path) -> str:
    """SHA-256 (hex) of the bytes of the file `path`, read in blocks of 1 MiB."""
    digest = hashlib.sha256()
    with open(path, "rb") as handle:
        for block in iter(lambda: handle.read(1 << 20), b""):
            digest.update(block)
    return digest.hexdigest()


def remove_partials(folder: Path) -> list[Path]:
    """Delete the temporary files (``partial_name``) in `folder` whose writer process is gone (killed while
    writing); returns them."""
    removed = []
    with contextlib.suppress(OSError):
        for entry in Path(folder).iterdir():
            found = _PARTIAL_PATTERN.match(entry.name)
            if found and not _alive(int(found.group(1))):
                with contextlib.suppress(OSError):
                    entry.unlink()
                    removed.append(entry)
    return removed


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:     # another user's process
        return True
    return True


def process_record(**extra) -> dict:
    """Who writes: ``run_id`` (12 random hex digits), ``pid``, ``host``, ``command`` (this process's command
    line) and ``started`` (UTC, ISO 8601), with `extra` fields."""
    program = Path(sys.argv[0]).name if sys.argv and sys.argv[0] else "python"
    program = "python -m orchestrator" if program == "__main__.py" else program
    return {"run_id": secrets.token_hex(6), "pid": os.getpid(), "host": socket.gethostname(),
            "command": " ".join([program, *map(shlex.quote, sys.argv[1:])]),
            "started": datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds"), **extra}


def describe(record: dict | None) -> str:
    """A process record in words: ``run 1a2b... (pid 42 on host, started ..., `wingsim run ...`)``."""
    if not record:
        return "another process (it has not written its record yet)"
    return (f"run {record.get('run_id', '?')} (pid {record.get('pid', '?')} on {record.get('host', '?')}, started "
            f"{record.get('started', '?')}: {record.get('command', '?')})")


@contextlib.contextmanager
def folder_lock(folder: Path, record: dict, lock_file: str = LOCK_FILE, wait: bool = False,
                option: str = "--out", stream=None) -> Iterator[dict | None]:
    """Hold `folder` (created if missing) for this process, writing `record` into its lock file, until the block
    ends. Yields the record a holder killed before it released the lock left behind (and says so on `stream`,
    default stderr), else None.

    Held by another process: FolderBusy naming `option` and the holder, or with `wait` a line on `stream`
    naming the holder, then waiting until it releases the folder. WriteError if the lock file cannot be made.
    """
    stream = stream if stream is not None else sys.stderr
    folder = Path(folder)
    path = folder / lock_file
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError as err:
        raise WriteError(path, err) from err
    fd = _acquire(path, option, folder, wait, stream)
    try:
        stale = _read_record(fd)
        if stale is not None:
            print(f"note: taking over {folder} from {describe(stale)}, which ended without releasing it",
                  file=stream, flush=True)
        try:
            _write_record(fd, record)
        except OSError as err:
            raise WriteError(path, err) from err
        yield stale
    finally:
        with contextlib.suppress(OSError):
            path.unlink()                # while still held: a process waiting on it opens the file anew
        os.close(fd)                     # closing releases the flock


def held(lock: Path) -> bool:
    """True when a live process holds the lock file `lock` (``folder_lock``); False when nobody does, also for
    the file a killed holder left behind (the kernel released its flock) or no file at all. Probing takes the
    lock for an instant: a process starting to take it meanwhile is refused or waits, as for any holder."""
    try:
        fd = os.open(lock, os.O_RDONLY)
    except OSError:
        return False
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except BlockingIOError:
        return True
    finally:
        os.close(fd)
    return False


def _acquire(path: Path, option: str, folder: Path, wait: bool, stream) -> int:
    """An open descriptor of the lock file `path` holding its flock (module docstring); the file may have been
    removed by the holder that released it while this process waited on it: then opened again."""
    waited = False
    while True:
        try:
            fd = os.open(path, os.O_RDWR | os.O_CREAT, 0o644)
        except OSError as err:
            raise WriteError(path, err) from err
        try:
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except BlockingIOError:
                holder = _read_record(fd)
                if not wait:
                    raise FolderBusy(option, folder, holder) from None
                if not waited:
                    print(f"waiting for {describe(holder)}, which holds {folder} ...", file=stream, flush=True)
                    waited = True
                fcntl.flock(fd, fcntl.LOCK_EX)
            if os.fstat(fd).st_ino == os.stat(path).st_ino:
                return fd
        except FileNotFoundError:
            pass                         # removed by its holder as it released it: open it anew
        except BaseException:
            os.close(fd)
            raise
        os.close(fd)


def _read_record(fd: int) -> dict | None:
    """The record in a lock file: None when it is empty; a record in words when it is not JSON."""
    os.lseek(fd, 0, os.SEEK_SET)
    data = b""
    while chunk := os.read(fd, 1 << 16):
        data += chunk
    if not data.strip():
        return None
    try:
        record = json.loads(data)
    except ValueError:
        return {"command": data[:200].decode("utf-8", "replace")}
    return record if isinstance(record, dict) else {"command": str(record)}


def _write_record(fd: int, record: dict) -> None:
    data = (json.dumps(record) + "\n").encode()
    os.ftruncate(fd, 0)
    os.pwrite(fd, data, 0)
