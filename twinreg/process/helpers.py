"""A helper process that draws the report's pictures while the main process matches and writes the twin.

The helper is forked at the start of a run (it starts at once with this process's imports), warms matplotlib up,
then runs the drawing calls it is sent. It is a speed-up only: every wait on it has a time limit, on every path,
and it is stopped with :class:`multiprocessing.Process`'s public ``terminate``/``kill``; when it is unavailable,
stuck or failed, the caller draws in its own process. The helper also dies with its parent (Linux
``PR_SET_PDEATHSIG``), so a killed run leaves no orphan.
"""

from __future__ import annotations

import gc
import os
import signal
import time

from ..errors import HelperError
from .lifeline import die_with_parent

#: seconds the main process waits for the helper's pictures before drawing them itself
HELPER_TIMEOUT_S = 30.0


def _die_with_parent() -> None:
    die_with_parent(signal.SIGTERM)


def _end(proc, first: float, grace: float) -> None:
    """Wait ``first`` seconds for a helper process to leave, then terminate it, then kill it (``grace`` each)."""
    proc.join(first)
    if proc.is_alive():
        proc.terminate()
        proc.join(grace)
    if proc.is_alive():
        proc.kill()
        proc.join(grace)


def _serve(conn) -> None:
    _die_with_parent()
    while True:
        try:
            task = conn.recv()
        except (EOFError, OSError):
            return
        if task is None:
            return
        key, fn, args = task
        try:
            conn.send((key, True, fn(*args)))
        except BaseException as exc:  # reported to the caller, who draws in-process instead
            try:
                conn.send((key, False, f"{type(exc).__name__}: {exc}"))
            except Exception:
                return



class Painter:
    """One forked helper process running drawing calls in order.

    >>> p = Painter.start()
    >>> k = p.submit(sum, [1, 2, 3]) if p else None
    >>> (p.result(k, timeout=10) if p else 6), (p.stop() if p else None)
    (6, None)
    """

    def __init__(self, proc, conn):
        self._proc, self._conn = proc, conn
        self._next = 0
        self._done: dict[int, tuple[bool, object]] = {}

    @classmethod
    def start(cls, warm=None) -> "Painter | None":
        """A started helper (``warm`` is sent first), or None with TWINREG_NO_HELPER=1 or where fork is missing."""
        if os.environ.get("TWINREG_NO_HELPER"):
            return None
        try:
            import multiprocessing

            ctx = multiprocessing.get_context("fork")
            conn, child = ctx.Pipe()
            proc = ctx.Process(target=_serve, args=(child,), daemon=True, name="twinreg-painter")
            proc.start()
            child.close()
        except (OSError, ValueError):  # pragma: no cover - no fork on this platform
            return None
        painter = cls(proc, conn)
        if warm is not None:
            painter.submit(warm)
        return painter

    def submit(self, fn, *args) -> int:
        """Send a call (a module-level function and picklable arguments); returns its key."""
        key = self._next
        self._next += 1
        try:
            self._conn.send((key, fn, args))
        except Exception as exc:  # a closed pipe, or a call that does not pickle (nothing was sent)
            self._done[key] = (False, f"cannot send to the helper ({exc})")
        return key

    def result(self, key: int, timeout: float = HELPER_TIMEOUT_S):
        """The return value of call ``key``; :class:`HelperError` when it failed, or after ``timeout`` seconds."""
        deadline = time.monotonic() + timeout
        while key not in self._done:
            left = deadline - time.monotonic()
            if left <= 0:
                raise HelperError(f"the helper did not answer within {timeout:g} s")
            try:
                if not self._conn.poll(min(left, 0.5)):
                    if not self._proc.is_alive():
                        raise HelperError("the helper process is gone")
                    continue
                k, ok, value = self._conn.recv()
            except (EOFError, OSError) as exc:
                raise HelperError(f"the helper process is gone ({exc})") from exc
            self._done[k] = (ok, value)
        ok, value = self._done.pop(key)
        if not ok:
            raise HelperError(str(value))
        return value

    def stop(self, grace: float = 1.0) -> None:
        """Stop the helper: ask it to leave, then terminate, then kill; each wait at most ``grace`` seconds."""
        try:
            self._conn.send(None)
        except (OSError, ValueError):
            pass
        _end(self._proc, grace, grace)
        self._conn.close()

    @property
    def pid(self) -> int | None:
        return self._proc.pid


class Pending:
    """``fn(*args)`` sent to ``helper`` (a :class:`Painter`, or None to run it here): :meth:`wait` gives its value,
    computed here when the helper is missing, stuck or failed (the helper is then stopped)."""

    def __init__(self, helper: Painter | None, fn, *args):
        self.helper, self.fn, self.args = helper, fn, args
        self.key = helper.submit(fn, *args) if helper is not None else None

    def wait(self, timeout: float = HELPER_TIMEOUT_S):
        if self.helper is not None:
            try:
                return self.helper.result(self.key, timeout=timeout)
            except HelperError:
                self.helper.stop()
        return self.fn(*self.args)


def _run_once(conn, fn, args) -> None:
    _die_with_parent()
    try:
        value = fn(*args)
    except BaseException as exc:  # reported to the caller, who runs the call itself instead
        try:
            conn.send((False, f"{type(exc).__name__}: {exc}"))
        except Exception:
            pass
        return
    conn.send((True, value))


class Forked:
    """``fn(*args)`` run in a child forked now, its arguments inherited rather than sent (a city's records are
    tens of megabytes), beside this process's own work. :meth:`wait` gives its value; when the child is missing,
    failed, died or has not finished within the time given, it is stopped first (only one process writes a file)
    and the call runs here. Fork only after the run's Dask client and cluster are closed, and pass no open
    database connection: the child uses what it is given, nothing else.

    >>> f = Forked(sum, [1, 2, 3])
    >>> f.wait(10)
    6
    """

    def __init__(self, fn, *args):
        self.fn, self.args = fn, args
        self._proc = self._conn = None
        self.ran_apart = False  # whether wait's value came from the child (else it was computed here)
        if os.environ.get("TWINREG_NO_HELPER"):
            return
        try:
            import multiprocessing

            ctx = multiprocessing.get_context("fork")
            self._conn, child = ctx.Pipe(duplex=False)
            self._proc = ctx.Process(target=_run_once, args=(child, fn, args), daemon=True, name="twinreg-writer")
            # the collector in the child would write to every inherited object's header, copying the pages the
            # two processes share; frozen, it leaves them alone
            gc.freeze()
            try:
                self._proc.start()
            finally:
                gc.unfreeze()
            child.close()
        except (OSError, ValueError):  # pragma: no cover - no fork on this platform
            self._proc = None

    def wait(self, timeout: float = HELPER_TIMEOUT_S):
        if self._proc is not None:
            try:
                if self._conn.poll(timeout):
                    ok, value = self._conn.recv()
                    if ok:
                        self.stop()
                        self.ran_apart = True
                        return value
            except (EOFError, OSError):  # the child died without a word
                pass
            self.stop()
        return self.fn(*self.args)

    @property
    def pid(self) -> int | None:
        """The child's process id (None when the call runs here)."""
        return self._proc.pid if self._proc is not None else None

    def stop(self, grace: float = 1.0) -> None:
        """Stop the child (if still running): terminate, then kill; each wait at most ``grace`` seconds."""
        if self._proc is None:
            return
        _end(self._proc, 0.05, grace)
        self._conn.close()
        self._proc = None


def apart(costs, head_start: float = 0.0, slower: float = 1.0) -> list[int]:
    """Which of the jobs of ``costs`` (their expected work) a second process takes so that both hold about equal
    work: the largest first, each to the lighter half (this one's on a tie); ``head_start``: the work this process
    has before any of them (an import the other inherits); ``slower``: how much longer a job takes the other
    process (one without this one's compiled kernels). The indices, in order.

    >>> apart([5, 4, 3, 2]), apart([5, 4, 3, 2], head_start=4), apart([5, 4, 3, 2], slower=2.0)
    ([1, 2], [0, 2], [1])
    """
    mine, theirs, out = float(head_start), 0.0, []
    for k in sorted(range(len(costs)), key=lambda k: -costs[k]):
        if mine <= theirs:
            mine += costs[k]
        else:
            theirs += costs[k] * slower
            out.append(k)
    return sorted(out)
