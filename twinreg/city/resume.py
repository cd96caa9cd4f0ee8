"""Resuming a city run: each finished cell's result is kept under the output folder (``OUT/.cells/``), named by
the cell and a hash of what it was computed from (the tiles that feed it, the grid, the parameters and the
program's version). A rerun reuses the results whose hash still matches and computes only the others; a result
file is written under a temporary name and renamed, so a killed run never leaves half of one.

The results are data, not code (:mod:`twinreg.city.cellfile`: arrays and JSON, read with no pickle): an OUT from
someone else is safe to resume into, and a file that is not a cell result this program wrote is ignored and its
cell computed again.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import shutil
from pathlib import Path

from . import cellfile

#: the work folder inside OUT, kept with the twin (a rerun with the same inputs reuses it)
WORK = ".cells"


#: the groups a cell reads whole (ground, segmentation, symmetry and headings, levels, sections) and the values it
#: reads from others (the number of each object's points kept for the acceptance test, whether the objects' class
#: shares are read from the scan's ASPRS classes): a cell's key hashes
#: these alone, so that matching's, kinds', fusion's and change's settings (``--min-confidence``, ``--tol``...)
#: reuse every finished cell. A test runs cells with recording settings and checks that nothing else is read.
CELL_GROUPS = ("ground", "segment", "joins", "symmetry", "levels", "sections", "surface")
CELL_VALUES = (("matching", "accept_max_points"), ("open_world", "scan_classes"))


def cell_params(params) -> dict:
    """The settings a cell reads (:data:`CELL_GROUPS`, :data:`CELL_VALUES`), by ``group.name``.

    >>> from twinreg.settings import DEFAULT
    >>> p = cell_params(DEFAULT); "ground.cell" in p, "min_confidence" in p, "matching.size_tol" in p
    (True, False, False)
    """
    out = {f"{g}.{f.name}": getattr(getattr(params, g), f.name)
           for g in CELL_GROUPS for f in dataclasses.fields(getattr(params, g))}
    out.update({f"{g}.{n}": getattr(getattr(params, g), n) for g, n in CELL_VALUES})
    return out


def cell_key(cell_name: str, sources: list, grid, params, version: str, offset=(0.0, 0.0, 0.0)) -> str:
    """The hash of what a cell's result depends on: its tiles, the grid, the parameters it reads
    (:func:`cell_params`), the program's version and the run's frame."""
    text = json.dumps([cell_name, sorted(s.key() for s in sources), grid.size, grid.buffer, grid.margin,
                       repr(sorted(cell_params(params).items())), version, [float(v) for v in offset]])
    return hashlib.sha256(text.encode()).hexdigest()[:16]


class CellStore:
    """The finished cells of a run under ``OUT/.cells`` (see the module's text)."""

    def __init__(self, out):
        self.folder = Path(out) / WORK

    def path(self, name: str, key: str) -> Path:
        return self.folder / f"{name}-{key}.npz"

    def has(self, name: str, key: str, labels: bool = False) -> bool:
        """True when a readable result of this cell and key is kept with its scan tiles (and its labelled points,
        when ``labels``; an unreadable or foreign file is deleted: the cell is then computed again)."""
        p = self.path(name, key)
        if not p.is_file():
            return False
        try:
            ok = cellfile.identity(p) == (name, key)
        except cellfile.CellFileError:
            ok = False
        if not ok:
            p.unlink(missing_ok=True)
        if labels and not self.labels_path(name, key).is_file():
            return False
        return ok and (self.scan_folder() / f"{name}-{key}").is_dir()  # its scan tiles too

    def save(self, result) -> Path:
        return cellfile.save(result, self.path(result.name, result.key))

    def load(self, name: str, key: str, clouds: bool = True):
        """The cell's result (``clouds=False``: its objects' point samples left in the file)."""
        return cellfile.load(self.path(name, key), clouds=clouds)

    def split_folder(self, key: str) -> Path:
        return self.folder / "split" / key

    def scan_folder(self) -> Path:
        """Where the workers write the cells' scan tiles (one folder a cell and key)."""
        return self.folder / "scan"

    def labels_path(self, name: str, key: str) -> Path:
        """A cell's labelled points for the classified scan (:mod:`twinreg.city.classified`)."""
        return self.folder / "labels" / f"{name}-{key}.npz"

    def clear(self) -> None:
        """Forget every stored result (``--restart``)."""
        shutil.rmtree(self.folder, ignore_errors=True)

    def prune(self, keep: set[tuple[str, str]]) -> None:
        """Remove the splits, temporary files and results (and scan tiles) of cells other than ``keep`` ((name, key)
        pairs)."""
        if not self.folder.is_dir():
            return
        shutil.rmtree(self.folder / "split", ignore_errors=True)
        wanted = {self.path(n, k).name for n, k in keep}
        kept = {"scan": {f"{n}-{k}" for n, k in keep}, "labels": {f"{n}-{k}.npz" for n, k in keep}}
        for sub, names in kept.items():
            if (self.folder / sub).is_dir():
                for p in (self.folder / sub).iterdir():
                    if p.name not in names:
                        shutil.rmtree(p, ignore_errors=True) if p.is_dir() else p.unlink(missing_ok=True)
        for p in self.folder.iterdir():
            if p.is_dir() and p.name not in kept:
                shutil.rmtree(p, ignore_errors=True)
            elif p.is_file() and p.name not in wanted:
                p.unlink(missing_ok=True)
