"""Compiled kernels: one registry, one way to choose.

A kernel is a plain Python function in numba's subset, written in the module that owns the work, beside its numpy
reference, and registered with :func:`kernel`. :func:`fast` gives its compiled version where the kernels are in use,
else None: the caller then runs the reference, which stays the definition (and the answer where numba is missing or
``TWINREG_NO_NUMBA`` is set). A kernel's registration names the function that chooses (its ``entry``) and a small
input for it (its ``example``): :func:`warm` compiles every kernel by calling the entries on their examples, and one
test (tests/cosco/test_kernels.py) runs each entry both ways and asks for the same answer. Helpers that kernels call
are registered with ``helper=True`` (compiled inside the kernels that call them).

Compiled code is cached (``cache=True``) in the user's cache folder (``$XDG_CACHE_HOME/twinreg/numba``, else
``~/.cache/twinreg/numba``; ``NUMBA_CACHE_DIR`` wins when set), never beside the installed code, and only when no
other user can write to it (:mod:`cosco._cache`: a cache file is a pickle, and loading it runs code); otherwise in a
private temporary folder. :func:`enable` compiles them all once (a fresh install's first run, a few seconds; then a
read of the cache, about half a second, numba's import): the city engine calls it before its Dask workers start, so
that no two workers write one cache at once, and a scene's run when it holds many objects; a sweep's run starts that
loading on a thread as soon as its points are read (:func:`preload`), and :func:`enable` then waits for it.
Importing this module imports neither numba nor any kernel: a command that does not enable them starts as fast and
gives the same answers, from the references.

    >>> cache_dir().parts[-2:]
    ('twinreg', 'numba')
"""

from __future__ import annotations

import contextlib
import importlib
import os
import sys
import threading
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

#: numba's options for every kernel: cached, no GIL held, IEEE arithmetic (the references' bits), numpy's errors
OPTIONS = {"cache": True, "nogil": True, "fastmath": False, "error_model": "numpy"}

_STATE: dict = {}
#: per thread: whether this thread is the one :func:`preload` started (the kernels are in use there alone)
_LOCAL = threading.local()


@dataclass(frozen=True)
class Kernel:
    """A registered kernel: its Python source ``fn``; the module's function ``entry`` that chooses it or its
    reference, with ``example(rng)`` giving that function's arguments; ``helper`` for one that kernels call."""

    fn: Callable
    entry: str | None = None
    example: str | None = None
    helper: bool = False
    tolerance: float = 0.0

    @property
    def name(self) -> str:
        return f"{self.fn.__module__}.{self.fn.__name__}"

    def entry_and_example(self) -> tuple[Callable, Callable]:
        module = sys.modules[self.fn.__module__]
        entry = module
        for part in self.entry.split("."):  # a function, or a class's method ("Class.method")
            entry = getattr(entry, part)
        return entry, getattr(module, self.example)


_KERNELS: dict[str, Kernel] = {}
_JITABLE: set = set()  # the helpers made callable from compiled code (once a process: numba's registry is global)


def kernel(entry: str | None = None, example: str | None = None, helper: bool = False, tolerance: float = 0.0):
    """Register the decorated function as a kernel (the function itself is returned unchanged): ``entry`` and
    ``example`` name, in its module, the function that chooses it and the one giving that function's arguments
    from a ``numpy.random.Generator``; ``helper`` a function that kernels call (it may have an entry too);
    ``tolerance`` the largest difference from the reference's numbers (0: the same bits)."""
    if bool(entry) != bool(example) or not (helper or entry):
        raise ValueError("a kernel names its entry and its example")

    def register(fn):
        k = Kernel(fn, entry, example, helper, tolerance)
        _KERNELS[k.name] = k
        if helper and _STATE.get("numba") is not None:
            _jitable(fn)
        return fn

    return register


def kernels() -> list[Kernel]:
    """The registered kernels of the modules imported so far that have an entry (helpers alone left out), by name."""
    return sorted((k for k in _KERNELS.values() if k.entry), key=lambda k: k.name)


def flag(name: str) -> bool:
    """Whether the environment variable ``name`` says yes (set, and not ``0``, ``false``, ``no``, ``off`` or empty).

    >>> os.environ["TWINREG_X"] = "0"; flag("TWINREG_X"), flag("TWINREG_Y")
    (False, False)
    """
    return _yes(os.environ.get(name, ""))


def _yes(text: str) -> bool:
    """Whether a switch's value says yes: set, and not ``0``, ``false``, ``no``, ``off`` or empty."""
    return text.strip().lower() not in ("", "0", "false", "no", "off")


def cache_dir() -> Path:
    """The folder asked for the compiled kernels: ``NUMBA_CACHE_DIR``, else the user's cache folder (used only when
    it is the user's own: :func:`trusted_cache_dir`)."""
    if os.environ.get("NUMBA_CACHE_DIR"):
        return Path(os.environ["NUMBA_CACHE_DIR"])
    base = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(base) / "twinreg" / "numba"


def trusted_cache_dir() -> Path:
    """The folder the kernels are cached in: :func:`cache_dir` when no one but this user can write to it or to a
    folder above it, else a private temporary folder (:mod:`cosco._cache`); decided once a process."""
    if "cache" not in _STATE:
        from ._cache import cache_folder

        _STATE["cache"] = cache_folder(cache_dir())
    return _STATE["cache"]


def in_use() -> bool:
    """Whether the compiled kernels answer in this process: after :func:`enable`, or when ``TWINREG_JIT`` says yes
    (a parent that enabled them sets it for the workers it starts); never inside :func:`reference_only`, where
    numba is missing or when ``TWINREG_NO_NUMBA`` says yes (``TWINREG_NO_NUMBA=0`` does not). Asked before every
    kernel call (a city asks it millions of times): the two variables are read as :func:`_said` reads them."""
    if _STATE.get("reference_only") or _said("TWINREG_NO_NUMBA"):
        return False
    if not (_STATE.get("enabled") or getattr(_LOCAL, "preloading", False) or _said("TWINREG_JIT")):
        return False
    return _numba() is not None


#: per variable: its key in the environment's own store; per raw value: what :func:`flag` makes of it
_ENV_KEYS: dict = {}
_SAYS: dict = {}


def _said(name: str) -> bool:
    """:func:`flag` read from the environment's store (``os.environ._data``, which ``os.environ`` itself keeps up to
    date) without the mapping's encoding of the name and decoding of the value at each call; ``flag`` itself where
    there is no such store."""
    data = getattr(os.environ, "_data", None)
    if not isinstance(data, dict):
        return flag(name)
    key = _ENV_KEYS.get(name)
    if key is None:
        key = _ENV_KEYS[name] = os.environ.encodekey(name)
    raw = data.get(key)
    if raw is None:
        return False
    says = _SAYS.get(raw)
    if says is None:
        says = _SAYS[raw] = _yes(os.environ.decodevalue(raw))
    return says


def _numba():
    """numba, imported once with its cache pointed at the trusted folder (None where it is not installed)."""
    if "numba" not in _STATE:
        folder = str(trusted_cache_dir())
        os.environ["NUMBA_CACHE_DIR"] = folder  # numba reads it at import; its config is set below as well
        try:
            import numba
        except ImportError:  # numba is not installed: the numpy references
            _STATE["numba"] = None
            return None
        numba.config.CACHE_DIR = folder  # read when each kernel is compiled: never the package's __pycache__
        _STATE["numba"] = numba
        for k in list(_KERNELS.values()):
            if k.helper:
                _jitable(k.fn)
    return _STATE["numba"]


def _jitable(fn) -> None:
    """Let compiled kernels call the helper ``fn`` (it stays a Python function)."""
    if fn in _JITABLE:
        return
    _JITABLE.add(fn)
    from numba.extending import register_jitable

    register_jitable(fastmath=OPTIONS["fastmath"], error_model=OPTIONS["error_model"])(fn)


def fast(fn: Callable):
    """The compiled ``fn`` (a registered kernel) where the kernels are in use, else None: the one way a caller
    chooses between a kernel and its reference."""
    if not in_use():
        return None
    got = _STATE.get("compiled", {}).get(fn)
    if got is not None:  # loaded before (a warm that drops a cache empties the table)
        return got
    name = f"{fn.__module__}.{fn.__name__}"
    if name not in _KERNELS:
        raise KeyError(f"{name} is not a registered kernel")
    if name in _STATE.get("later", ()) and name not in _STATE.setdefault("warmed", set()):
        if _STATE.get("warming"):  # asked for by an entry being warmed: it loads under that warm's lock
            _STATE["warmed"].add(name)
        else:  # left for later by enable(): loaded now as enable would have (a cache it cannot read dropped)
            warm(only=name)
    compiled = _STATE.setdefault("compiled", {})  # (after a warm: a dropped cache empties it)
    if fn not in compiled:
        compiled[fn] = _numba().njit(**OPTIONS)(fn)
    return compiled[fn]


@contextlib.contextmanager
def reference_only():
    """Inside, every caller takes the numpy reference (tests of the reference path; the agreement test)."""
    before = _STATE.get("reference_only", False)
    _STATE["reference_only"] = True
    try:
        yield
    finally:
        _STATE["reference_only"] = before


def enable(*modules: str, later: tuple = ()) -> float:
    """Use the compiled kernels in this process, compiling them first (or loading them from the cache), those of
    ``modules`` (imported here) too; seconds taken. Call it in one process before starting workers (and give them
    ``TWINREG_JIT=1``), so that no two of them write one cache at once. A small run does not call it: importing
    numba alone takes longer than its kernels save on a car park (docs/PERFORMANCE.md). ``later``: the names (or
    their prefixes) of kernels the caller will not call from here on, not loaded now (a scene's ground and
    components, found before): :func:`fast` loads one on its first call all the same."""
    _import_kernels(modules)
    waited = settle()  # a preload's thread done (what it loaded is not loaded again)
    _STATE["enabled"] = True
    return waited + warm(later)


def _import_kernels(modules) -> None:
    import pkgutil

    here = sys.modules[__package__]
    for name in [m.name for m in pkgutil.walk_packages(here.__path__, f"{__package__}.")] + list(modules):
        importlib.import_module(name)


def preload(*modules: str, later: tuple = ()) -> bool:
    """Start loading the kernels :func:`enable` would load, on a thread of its own, while this one goes on with the
    references: a sweep reads its points and finds its ground (numpy's work, much of it without the GIL) while numba
    loads. Only that thread uses them; :func:`enable` waits for it, then uses them everywhere, from the same point
    of the run as without a preload (the same answers). Call :func:`settle` before forking where :func:`enable` may
    not be called. Whether a thread was started (not where numba is off or missing, or already enabled)."""
    if "preload" in _STATE or _STATE.get("enabled") or _STATE.get("reference_only") or flag("TWINREG_NO_NUMBA"):
        return False
    _import_kernels(modules)  # here: the thread imports only numba

    def load() -> None:
        _LOCAL.preloading = True
        try:
            warm(later)
        except BaseException as exc:  # noqa: BLE001 - enable() then warms what is missing in its own thread
            _STATE["preload_error"] = f"{type(exc).__name__}: {exc}"
        finally:
            _LOCAL.preloading = False

    thread = threading.Thread(target=load, name="twinreg-kernels", daemon=True)
    _STATE["preload"] = thread
    thread.start()
    return True


def settle() -> float:
    """Wait for a :func:`preload`'s thread, if one runs (before a fork: a child must not inherit numba's locks
    held by a thread it does not have); seconds waited."""
    thread = _STATE.pop("preload", None)
    if thread is None:
        return 0.0
    t = time.perf_counter()
    thread.join()
    return time.perf_counter() - t


def _warm_all(later: tuple = (), only: str | None = None) -> None:
    """Every registered kernel not warmed yet in this process (or the one named ``only``) called through its entry
    on its example (once for kernels that share an entry and an example: the one call runs them all), but those
    whose names start with one of ``later``: :func:`fast` warms such a kernel on its first call."""
    import numpy as np

    warmed = _STATE.setdefault("warmed", set())
    for k in kernels():
        if k.name in warmed or (only is not None and k.name != only):
            continue
        if only is None and later and k.name.startswith(tuple(later)):
            _STATE.setdefault("later", set()).add(k.name)
            continue
        key = (k.fn.__module__, k.entry, k.example)
        warmed.update(j.name for j in kernels() if (j.fn.__module__, j.entry, j.example) == key)
        entry, example = k.entry_and_example()
        entry(*example(np.random.default_rng(0)))


def warm(later: tuple = (), only: str | None = None) -> float:
    """Compile (or load from the cache) every registered kernel, when they are in use, by calling each one's entry
    on its example; seconds taken. A kernel already warmed in this process is not called again (a second
    :func:`enable` warms only the kernels of modules imported since). A cache file that cannot be read (a corrupt
    or foreign index: numba's unpickling fails) is dropped with the rest of the cache folder, and the kernels
    compiled anew."""
    t = time.perf_counter()
    if in_use():
        with _one_writer(trusted_cache_dir()), _warming():
            try:
                _warm_all(later, only)
            except Exception as exc:  # noqa: BLE001 - numba raises what unpickling raised (UnpicklingError...)
                from ._cache import clear

                folder = trusted_cache_dir()
                sys.stderr.write(f"twinreg: the kernel cache {folder} could not be read ({type(exc).__name__}); "
                                 "compiling anew\n")
                clear(folder)
                _STATE.pop("compiled", None)
                _STATE.pop("warmed", None)
                _warm_all(later, only)
    return time.perf_counter() - t


@contextlib.contextmanager
def _warming():
    """Marks this process as warming kernels (a kernel an entry asks for meanwhile loads under the same lock)."""
    _STATE["warming"] = _STATE.get("warming", 0) + 1
    try:
        yield
    finally:
        _STATE["warming"] -= 1


@contextlib.contextmanager
def _one_writer(folder: Path):
    """Held while this process compiles or loads the kernels: two runs started at once on a fresh cache (two
    scenes, a scene beside a city) would both write its files, a known numba crash; the second waits for the
    first, then loads what it wrote. An advisory lock on ``folder/.lock``; none where it cannot be taken."""
    try:
        import fcntl

        fh = open(os.path.join(folder, ".lock"), "a")
    except (ImportError, OSError):
        yield
        return
    try:
        try:
            fcntl.flock(fh, fcntl.LOCK_EX)
        except OSError:
            pass
        yield
    finally:
        fh.close()  # releases the lock
