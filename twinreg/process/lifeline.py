"""A child process that ends with its parent: a city run's Dask workers watch the process that started them and
leave when it is gone (killed, crashed), so no worker outlives its command.

The embedded cluster's workers are spawned by the run's process (the nannies live there); they load this module
at start (Dask's ``preload``). The kernel then kills a worker when the thread that started it ends (Linux's
parent-death signal: this works even while the worker is stuck in compiled code that holds the interpreter), and a
thread polls the parent's id twice a second as well (other systems). A parent that died before the worker loaded
this module is Dask's own watch's to see (the worker is not stuck yet). The parent is the process that spawned the
worker, read at start: not an environment variable, which Dask's inherited configuration could carry from another
run.
"""

from __future__ import annotations

import os
import signal
import threading
import time

#: seconds between two looks at the parent
POLL_S = 0.5


def watch_parent(parent: int, poll: float = POLL_S) -> threading.Thread:
    """Start a daemon thread that ends this process (exit status 1, no clean-up: the parent is gone) as soon as
    its parent is no longer ``parent``."""

    def watch():
        while os.getppid() == parent:
            time.sleep(poll)
        os._exit(1)

    t = threading.Thread(target=watch, name="twinreg-lifeline", daemon=True)
    t.start()
    return t


def die_with_parent(sig: int | None = None) -> None:
    """Ask the kernel to send ``sig`` (default SIGKILL) to this process when the thread that started it ends
    (Linux's ``PR_SET_PDEATHSIG``; nothing elsewhere)."""
    try:
        import ctypes

        ctypes.CDLL("libc.so.6", use_errno=True).prctl(1, signal.SIGKILL if sig is None else sig)
    except Exception:  # pragma: no cover - not Linux
        pass


def dask_setup(worker=None) -> None:
    """Dask's preload hook, in each worker process of an embedded cluster: end with the run's process."""
    die_with_parent()
    watch_parent(os.getppid())
