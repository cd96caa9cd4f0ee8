"""How the processes that crunch point clouds allocate memory.

Every stage allocates arrays of a few hundred MB and frees them a moment later. glibc hands out any block above
32 MB with ``mmap`` and gives it back with ``munmap`` (Dask's nanny even asks it to trim the heap at 64 kB), so the
next array of the same size is faulted in and zeroed page by page again. On the VMs twinreg is measured on a page
first touched costs about 1-2 ms per MB, several times the arithmetic done on it: a city cell spent a quarter of its
time in page faults. Keeping the freed blocks in the process (one heap, no mmap, no trimming) reuses warm pages;
the process's resident memory then stays at its high-water mark, which is what the memory limits count anyway.

:data:`WORKER_ENV` is given to the worker processes a run starts (read by glibc when the process starts);
:func:`keep_freed_memory` does the same from inside a running process (the CLI's main thread). A worker gives
the memory back with :func:`release_freed_memory` once a cell is done, so that two workers' high-water marks do
not add up between their cells. All are no-ops where the C library is not glibc.
"""

from __future__ import annotations

import ctypes
import ctypes.util
import sys

#: glibc's environment tunables: one arena (the worker's task thread allocates from the main heap, which can grow
#: by brk without limit), no mmap'd blocks, no trimming of the heap's top, and the heap grown 64 MB at a time
WORKER_ENV = {
    "MALLOC_ARENA_MAX": "1",
    "MALLOC_MMAP_MAX_": "0",
    "MALLOC_TRIM_THRESHOLD_": str(1 << 40),
    "MALLOC_TOP_PAD_": str(64 << 20),
}

# mallopt parameters (malloc.h)
_M_TRIM_THRESHOLD, _M_TOP_PAD, _M_MMAP_MAX = -1, -2, -4
_done = False


def _libc():
    if not sys.platform.startswith("linux"):
        return None
    try:
        return ctypes.CDLL(ctypes.util.find_library("c") or "libc.so.6")
    except OSError:
        return None


def release_freed_memory() -> None:
    """Return the memory this process has freed to the system (glibc's ``malloc_trim``)."""
    trim = getattr(_libc(), "malloc_trim", None)
    if trim is not None:
        trim.argtypes, trim.restype = [ctypes.c_size_t], ctypes.c_int
        trim(0)


def keep_freed_memory() -> bool:
    """Ask glibc to keep freed memory for reuse in this process (see the module's text); True when it did.

    Only the main heap is affected: call it from the main thread (threads started later share the main heap only
    when the process started with :data:`WORKER_ENV`).
    """
    global _done
    if _done:
        return True
    mallopt = getattr(_libc(), "mallopt", None)
    if mallopt is None:  # not Linux, or a C library without mallopt: nothing to tune
        return False
    mallopt.argtypes, mallopt.restype = [ctypes.c_int, ctypes.c_int], ctypes.c_int
    ok = all(mallopt(p, v) == 1 for p, v in ((_M_MMAP_MAX, 0), (_M_TRIM_THRESHOLD, 2**31 - 1),
                                             (_M_TOP_PAD, 64 << 20)))
    _done = ok
    return ok
