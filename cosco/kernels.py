"""Compiled kernels for the loops a city spends its time in, each beside its numpy reference (which stays the
definition, and the answer where numba is missing or ``TWINREG_NO_NUMBA`` is set).

The kernels (:mod:`cosco._jit`) are numba functions compiled with ``cache=True``; the cache lives in the user's cache
folder (``$XDG_CACHE_HOME/twinreg/numba``, else ``~/.cache/twinreg/numba``; ``NUMBA_CACHE_DIR`` wins when set), never
beside the installed code, and only when no other user can write to it (:mod:`cosco._cache`: a cache file is a
pickle, and loading it runs code); otherwise in a private temporary folder. :func:`enable` compiles them all once (a fresh install's first run, a few seconds; then a
read of the cache, about half a second, numba's import): the city engine calls it before its Dask workers start, so
that no two workers write one cache at once, and a scene's run when it holds many objects. Importing this module
imports neither numba nor the kernels: a command that does not match starts as fast as before, and a run that does
not enable them gives the same answers from the references.

    >>> cache_dir().parts[-2:]
    ('twinreg', 'numba')
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

_STATE: dict = {}


def flag(name: str) -> bool:
    """Whether the environment variable ``name`` says yes (set, and not ``0``, ``false``, ``no``, ``off`` or empty).

    >>> os.environ["TWINREG_X"] = "0"; flag("TWINREG_X"), flag("TWINREG_Y")
    (False, False)
    """
    return os.environ.get(name, "").strip().lower() not in ("", "0", "false", "no", "off")


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


def jit():
    """The compiled kernels' module, or None: the numpy references answer. None until :func:`enable` was called in
    this process or ``TWINREG_JIT`` says yes (a parent that enabled them sets it for the workers it starts), and
    always where numba is missing or ``TWINREG_NO_NUMBA`` says yes (``TWINREG_NO_NUMBA=0`` does not)."""
    if "jit" not in _STATE:
        if not (_STATE.get("enabled") or flag("TWINREG_JIT")) or flag("TWINREG_NO_NUMBA"):
            return None
        folder = str(trusted_cache_dir())
        os.environ["NUMBA_CACHE_DIR"] = folder  # numba reads it at import; its config is set below as well
        try:
            import numba
        except ImportError:  # numba is not installed: the numpy references
            _STATE["jit"] = None
            return None
        numba.config.CACHE_DIR = folder  # read when each kernel is decorated: never the package's __pycache__
        from . import _jit as mod

        _STATE["jit"] = mod
    return _STATE["jit"]


def enable() -> float:
    """Use the compiled kernels in this process, compiling them first (or loading them from the cache); seconds
    taken. Call it in one process before starting workers (and give them ``TWINREG_JIT=1``), so that no two of them
    write one cache at once. A small run does not call it: importing numba alone takes longer than its kernels save
    on a car park (docs/PERFORMANCE.md)."""
    _STATE["enabled"] = True
    return warm()


def warm() -> float:
    """Compile (or load from the cache) every kernel, when they are in use (:func:`jit`); seconds taken. A cache
    file that cannot be read (a corrupt or foreign index: numba's unpickling fails) is dropped with the rest of the
    cache folder, and the kernels compiled anew."""
    import time

    t = time.perf_counter()
    mod = jit()
    if mod is not None:
        try:
            mod.warm()
        except Exception as exc:  # noqa: BLE001 - numba raises what unpickling raised (UnpicklingError, EOFError...)
            import sys

            from ._cache import clear

            folder = trusted_cache_dir()
            sys.stderr.write(f"twinreg: the kernel cache {folder} could not be read ({type(exc).__name__}); "
                             "compiling anew\n")
            clear(folder)
            mod.warm()
    return time.perf_counter() - t


# ---------------------------------------------------------------- the registrations' distance-field look-ups


def section_sums(a, b, r: int, du, tz, cap: float, one_way: bool, n_du: int):
    """The compiled :func:`cosco.dissimilarity._sq_sums` on the distance fields (every look-up of one rotation in
    one call, no (candidates x probes) index arrays; its numpy reference is that function's own loop over
    :meth:`~cosco.dissimilarity.DistanceField.nearest_shifted`), or None where numba is not in use."""
    mod = jit()
    if mod is None:
        return None
    fields = [a.fields["lon"], a.fields["tra"], b.fields["lon"], b.fields["tra"]]
    cell = fields[0].cell
    if any(f.cell != cell for f in fields):  # (the caps are checked by the caller, _sq_sums)
        return None
    return mod.section_sums(a.probes["lon"], a.probes["tra"], b.probes["lon"], b.probes["tra"],
                            *[f.values for f in fields], *[f.origin for f in fields],
                            *[np.asarray(f.start, dtype=np.int64) for f in fields], float(cell), int(r),
                            np.ascontiguousarray(du, dtype=np.float64), np.ascontiguousarray(tz, dtype=np.float64),
                            float(np.float32(cap)), bool(one_way), int(n_du))


# ---------------------------------------------------------------- the symmetry search's mirror correspondences


def mirror_distances_numpy(tree, points, phi, rho, bound) -> np.ndarray:
    """(n,) each of ``points`` (n, 3) mirrored in the vertical plane (phi, rho), its distance to the nearest point
    of ``tree`` (a cKDTree), at most ``bound``: the numpy reference."""
    d, _ = mirror_nearest_numpy(tree, points, phi, rho, bound)
    return np.minimum(d, bound)


class MirrorIndex:
    """The compiled :func:`mirror_distances_numpy` for one object's points (a grid of ``bound`` m voxels, the
    voxels along z of a plan cell contiguous, built once, asked for many planes). :meth:`of` gives None where numba
    is missing or the grid would be large (more than ``max_cells`` voxels): the caller keeps its KD-tree."""

    def __init__(self, mod, points: np.ndarray, targets: np.ndarray, bound: float):
        self.mod, self.points, self.bound = mod, points, float(bound)
        self.grid, self.order, self.starts, self.lo, self.shape = mod.grid_build(targets, self.bound)

    @classmethod
    def of(cls, points: np.ndarray, bound: float, targets: np.ndarray | None = None,
           max_cells: int = 4_000_000) -> "MirrorIndex | None":
        """``points`` are mirrored, their nearest among ``targets`` (default: the points themselves) found."""
        mod = jit()
        pts = np.ascontiguousarray(points, dtype=np.float64)
        tgt = pts if targets is None else np.ascontiguousarray(targets, dtype=np.float64)
        if mod is None or len(pts) == 0 or len(tgt) == 0 or not bound > 0:
            return None
        extent = np.ptp(tgt, axis=0) / bound + 1
        if float(np.prod(extent)) > max_cells:
            return None
        return cls(mod, pts, tgt, bound)

    def distances(self, phi: float, rho: float) -> np.ndarray:
        d, _ = self.nearest(self.points, phi, rho, self.bound)
        d[~np.isfinite(d)] = self.bound
        return d

    def nearest(self, points: np.ndarray, phi: float, rho: float, bound: float) -> tuple[np.ndarray, np.ndarray]:
        """Each of ``points`` mirrored in (phi, rho): the distance to its nearest target nearer than ``bound`` (at
        most the index's) and that target's row; inf and the target count where none is (a KD-tree's bounded
        query, :func:`mirror_nearest_numpy`)."""
        if bound > self.bound:
            raise ValueError(f"a mirror index of {self.bound} m asked for neighbours up to {bound} m")
        return self.mod.mirror_nearest(np.ascontiguousarray(points, dtype=np.float64), float(phi), float(rho),
                                       self.grid, self.order, self.starts, self.lo, self.shape, self.bound,
                                       float(bound))


def mirror_nearest_numpy(tree, points, phi, rho, bound) -> tuple[np.ndarray, np.ndarray]:
    """The numpy reference of :meth:`MirrorIndex.nearest`: a KD-tree's bounded query of the mirrored points."""
    from .frames import reflect

    return tree.query(reflect(points, phi, rho), k=1, distance_upper_bound=bound)


# ---------------------------------------------------------------- the levels of symmetry's shares of mapped points


def near_share_numpy(tree, points, bound: float) -> float:
    """The share of (n, 3) ``points`` with a point of ``tree`` (a cKDTree) nearer than ``bound``: the numpy
    reference of :meth:`NearIndex.share`."""
    d, _ = tree.query(points, distance_upper_bound=bound)
    return float(np.isfinite(d).mean())


class NearIndex:
    """The compiled :func:`near_share_numpy` for one set of targets (a voxel grid of ``bound`` m, built once, asked
    for many moved copies of an object). :meth:`of` gives None where numba is missing or the grid would be large."""

    def __init__(self, mod, targets: np.ndarray, bound: float):
        self.mod, self.bound = mod, float(bound)
        self.grid, _, self.starts, self.lo, self.shape = mod.grid_build(targets, self.bound)

    @classmethod
    def of(cls, targets: np.ndarray, bound: float, max_cells: int = 4_000_000) -> "NearIndex | None":
        mod = jit()
        tgt = np.ascontiguousarray(targets, dtype=np.float64)
        if mod is None or len(tgt) == 0 or not bound > 0:
            return None
        if float(np.prod(np.ptp(tgt, axis=0) / bound + 1)) > max_cells:
            return None
        return cls(mod, tgt, bound)

    def share(self, points: np.ndarray) -> float:
        return float(self.mod.share_near(np.ascontiguousarray(points, dtype=np.float64), self.grid, self.starts,
                                         self.lo, self.shape, self.bound, self.bound))


# ---------------------------------------------------------------- the verification's bounded nearest neighbours


class BoundedTree:
    """A cKDTree of (n, 3) points whose bounded queries (``distance_upper_bound`` given, ``k=1``) are answered by
    a compiled voxel grid of that bound (built at the first such query, kept for queries up to that bound): the
    same answers. Other queries, and every query where numba is not in use or the grid would be large, go to the
    KD-tree itself (built when first needed)."""

    def __init__(self, points: np.ndarray, max_cells: int = 4_000_000):
        self.data = np.ascontiguousarray(points, dtype=np.float64)
        self.max_cells = max_cells
        self._tree = None
        self._grid = None
        self._bound = None

    @property
    def tree(self):
        if self._tree is None:
            from scipy.spatial import cKDTree

            self._tree = cKDTree(self.data)
        return self._tree

    def query(self, points, k: int = 1, distance_upper_bound: float = np.inf):
        bound = float(distance_upper_bound)
        mod = jit()
        if mod is None or k != 1 or not np.isfinite(bound) or not bound > 0 or len(self.data) == 0:
            return self.tree.query(points, k=k, distance_upper_bound=distance_upper_bound)
        if self._grid is None and self._bound is None:
            self._bound = bound
            if float(np.prod(np.ptp(self.data, axis=0) / bound + 1)) <= self.max_cells:
                self._grid = mod.grid_build(self.data, bound)
        if self._grid is None or bound > self._bound:
            return self.tree.query(points, k=k, distance_upper_bound=distance_upper_bound)
        grid, order, starts, lo, shape = self._grid
        return mod.nearest_within(np.ascontiguousarray(points, dtype=np.float64), grid, order, starts, lo, shape,
                                  self._bound, bound)
