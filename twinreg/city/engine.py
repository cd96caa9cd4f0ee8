"""The Dask engine of a city run: an embedded ``LocalCluster`` (one single-threaded worker process per core by
default) or an existing cluster given by its scheduler's address.

Tasks go out through a bounded window (at most ``per_worker`` in flight per worker, so the scheduler never holds a
city's worth of results), each is retried once (a worker killed by its memory limit or a crash), and a task that
fails again is reported by name while the others finish. Before a function's first task, every worker is asked to
load it and its job's class by name: a worker that cannot (another twinreg installed there, a package missing, a
module that cannot import) is an :class:`~twinreg.errors.EngineError` saying so, where its task would otherwise
wait forever (a worker that cannot unpickle a task drops its link to the scheduler); an existing cluster with no
worker is one too.

The embedded cluster talks TLS with temporary credentials (``Security.temporary()``: a key and certificate made in
memory for this run, required of both ends), so no other process on the machine can reach its scheduler or
workers and submit work. An existing cluster is reached as its address and the Dask configuration say; its
operator secures it (docs/METHOD.md, "City scale").
"""

from __future__ import annotations

import logging
import os
import socket
import time
from dataclasses import dataclass
from urllib.parse import urlsplit

from cosco import kernels

from .. import KERNEL_MODULES
from ..errors import EngineError

#: memory limit of an embedded worker (bytes); Dask pauses it at 80 % and restarts it at 95 %
WORKER_MEMORY = 4 * 1024 ** 3
#: how long an existing cluster may have no worker before the run stops (s)
WORKERS_WAIT_S = 30.0



@dataclass
class Failure:
    """A task that failed twice: its name and the error's first line."""

    name: str
    error: str


def _reachable(address: str, timeout: float = 5.0) -> None:
    """Raise OSError when nothing listens at a ``tcp://`` or ``tls://`` HOST:PORT address (other forms: Dask's
    own checks)."""
    u = urlsplit(address)
    if u.scheme not in ("tcp", "tls") or not u.hostname or u.port is None:
        return
    with socket.create_connection((u.hostname, u.port), timeout=timeout):
        pass


class Engine:
    """``with Engine(workers=2) as eng: eng.run(fn, jobs, names, on_result)`` (see the module's text)."""

    def __init__(self, workers: int | None = None, scheduler: str | None = None, per_worker: int = 2):
        self.workers = workers
        self.scheduler = scheduler
        self.per_worker = per_worker
        self.cluster = None
        self.client = None
        self.kernels_s = 0.0
        self._loadable: set = set()  # the functions and classes every worker has loaded by name (_check_loadable)

    def __enter__(self) -> "Engine":
        from distributed import Client, LocalCluster
        from distributed.security import Security

        try:
            if self.scheduler:
                _reachable(self.scheduler)  # a refused port is said at once (Dask retries it for 20 s)
                self.client = Client(self.scheduler, timeout="20s")
                try:
                    self.client.wait_for_workers(1, timeout=WORKERS_WAIT_S)
                except TimeoutError as exc:
                    raise EngineError(f"{self.scheduler}: the scheduler has had no worker for {WORKERS_WAIT_S:g} s; "
                                      "start workers (dask worker ADDRESS) with this twinreg installed") from exc
            else:
                n = self.workers or os.cpu_count() or 1
                try:
                    import psutil

                    memory = min(WORKER_MEMORY, int(psutil.virtual_memory().total * 0.8 / n))
                except ImportError:  # pragma: no cover - psutil comes with distributed
                    memory = WORKER_MEMORY
                # the workers keep the memory they free for the next cell (twinreg.memory), set before they start
                import dask

                from ..memory import WORKER_ENV

                environ = {**dask.config.get("distributed.nanny.pre-spawn-environ", {}), **WORKER_ENV,
                           **self._kernels()}
                with dask.config.set({"distributed.nanny.pre-spawn-environ": environ}):
                    self.cluster = LocalCluster(n_workers=n, threads_per_worker=1, processes=True,
                                                memory_limit=memory, dashboard_address=None,
                                                silence_logs=logging.CRITICAL, host="127.0.0.1", scheduler_port=0,
                                                protocol="tls://", security=Security.temporary(),
                                                # the workers leave when this process dies, however it dies
                                                preload=["twinreg.process.lifeline"])
                self.client = Client(self.cluster, security=self.cluster.security)
        except EngineError:
            self.__exit__(None, None, None)
            raise
        except Exception as exc:  # unreachable, refused, a malformed address, no free port...
            self.__exit__(None, None, None)
            where = self.scheduler or "a local cluster"
            first = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
            raise EngineError(f"{where}: cannot start or reach the Dask cluster ({first}); check the address "
                              "(tcp://HOST:PORT) and that the scheduler runs") from exc
        return self

    def _kernels(self) -> dict:
        """The compiled kernels (:mod:`cosco.kernels`) compiled, or loaded from the user's cache, here before the
        workers start (two workers compiling at once may both write one cache file: a known numba crash), and the
        environment that has the workers use them (none where numba is missing)."""
        t = time.perf_counter()
        kernels.enable(*KERNEL_MODULES)
        self.kernels_s = time.perf_counter() - t
        if not kernels.in_use():
            return {}
        return {"TWINREG_JIT": "1", "NUMBA_CACHE_DIR": str(kernels.trusted_cache_dir())}

    def __exit__(self, *exc):
        if self.client is not None:
            self.client.close()
            self.client = None
        if self.cluster is not None:
            self.cluster.close()
            self.cluster = None
        return False

    @property
    def n_workers(self) -> int:
        return max(len(self.client.scheduler_info(n_workers=-1)["workers"]), 1) if self.client else 1

    def _check_loadable(self, fn, job=None) -> None:
        """Every worker loads ``fn`` and ``job``'s class by their names (the standard library's
        ``pkgutil.resolve_name``, which any worker can unpickle), once an engine; an :class:`EngineError` naming
        what a worker could not load. Functions and classes defined inside another (sent by value), in ``__main__``
        or built in are not asked for."""
        import pkgutil

        wanted = []
        for what in (fn, type(job) if job is not None else None):
            module, qual = getattr(what, "__module__", None), getattr(what, "__qualname__", "")
            if module and module not in ("__main__", "builtins") and "<" not in qual:
                wanted.append(f"{module}:{qual}")
        for name in wanted:
            if name in self._loadable:
                continue
            try:
                self.client.run(pkgutil.resolve_name, name)
            except Exception as exc:  # noqa: BLE001 - what the worker raised (ImportError, AttributeError...)
                first = str(exc).splitlines()[0] if str(exc) else ""
                raise EngineError(f"the Dask workers cannot load {name.replace(':', '.')} ({type(exc).__name__}: "
                                  f"{first}); install this twinreg and its packages where the workers run") from exc
            self._loadable.add(name)

    def submit(self, fn, *args, name: str):
        """One task now (retried once), e.g. one whose result later tasks wait for; returns its future."""
        self._check_loadable(fn, args[0] if args else None)
        return self.client.submit(fn, *args, key=f"{fn.__name__}-{name}-{os.getpid()}", retries=1, pure=False)

    def run(self, fn, jobs: list, names: list[str], on_result=None, window: int | None = None,
            deps: dict | None = None) -> list[Failure]:
        """Run ``fn(job, *deps[name])`` for every job, at most ``window`` at a time (default ``per_worker`` per
        worker); ``deps``: futures a job waits for (their results are passed after it). ``on_result(name,
        result)`` is called in this process as each finishes. Returns the failures."""
        from distributed import as_completed

        if jobs:
            self._check_loadable(fn, jobs[0])
        window = window or self.per_worker * self.n_workers
        pending = list(zip(names, jobs))[::-1]
        failures: list[Failure] = []
        futures = {}

        def submit():
            name, job = pending.pop()
            extra = (deps or {}).get(name, ())
            f = self.client.submit(fn, job, *extra, key=f"{fn.__name__}-{name}-{os.getpid()}", retries=1,
                                   pure=False)
            futures[f] = name
            return f

        ac = as_completed([submit() for _ in range(min(window, len(pending)))])
        try:
            for f in ac:
                name = futures.pop(f)
                if f.status == "error":
                    exc = f.exception()
                    failures.append(Failure(name, f"{type(exc).__name__}: {str(exc).splitlines()[0] if str(exc) else ''}"))
                else:
                    result = f.result()
                    if on_result is not None:
                        on_result(name, result)
                f.release()
                if pending:
                    ac.add(submit())
        finally:
            for f in futures:
                f.cancel()
        return failures

    def map(self, fn, jobs: list, names: list[str]) -> list:
        """Results of ``fn(job)`` in order; raises :class:`EngineError` naming a job that failed twice."""
        results = {}
        failures = self.run(fn, jobs, names, on_result=lambda n, r: results.__setitem__(n, r))
        if failures:
            f = failures[0]
            raise EngineError(f"task {f.name} failed twice ({f.error})")
        return [results[n] for n in names]
