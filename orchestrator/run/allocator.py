"""glibc's allocator thresholds for the processes wingsim owns: the command line, its sweep and study workers, the
benchmarks, and a standalone FMU's worker process (which gets the same values through its environment,
worker_client.c). An ordinary FMU never changes its host's allocator.

The flexible structure's Newton steps make temporary matrices of a few hundred kB. With glibc's defaults, blocks
above the mmap threshold (128 kB at start) get a mapping of their own and free memory above the trim threshold
at the top of the heap goes back to the system, so such a temporary is mapped, faulted in page by page and
unmapped again at every step: about 300 page faults per communication step of deploy_flexible, each dearer in a
process with a second thread (the kernel then interrupts that thread's CPU to unmap). Thresholds above the
temporaries' sizes keep them in the heap, reused step after step: deploy_flexible steps about 20% faster.
"""
from __future__ import annotations

import ctypes
import sys

MMAP_THRESHOLD = 32 * 2**20
"""Bytes: blocks smaller than this come from the heap (glibc's M_MMAP_THRESHOLD; fixed, not adjusted)."""
TRIM_THRESHOLD = 64 * 2**20
"""Bytes of free memory at the top of the heap kept for reuse (glibc's M_TRIM_THRESHOLD)."""
_M_TRIM_THRESHOLD, _M_MMAP_THRESHOLD = -1, -3     # mallopt's parameter numbers (malloc.h)


def tune() -> None:
    """Set the thresholds in this process (glibc's mallopt); nothing on another C library or platform."""
    if not sys.platform.startswith("linux"):
        return
    try:
        mallopt = ctypes.CDLL(None).mallopt
    except (OSError, AttributeError):
        return
    mallopt(_M_MMAP_THRESHOLD, MMAP_THRESHOLD)
    mallopt(_M_TRIM_THRESHOLD, TRIM_THRESHOLD)
