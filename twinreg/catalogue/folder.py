"""``import-models DIR [--manifest CSV]``: every mesh of a folder added in turn; a bad file is reported and skipped,
the rest go in, each with its near-duplicates named. A manifest (docs/CONTRACT.md) says per file its name, category,
scale, make, model, unit, up and front; it is someone else's data: read whole and checked before any file is added
(its size, its columns, every value, every file inside the folder), so that a bad manifest changes nothing."""

from __future__ import annotations

import csv
import io
import math
from dataclasses import dataclass, field
from pathlib import Path

from ..errors import CatalogueError, TwinregError
from ..io.meshes import MESH_SUFFIXES
from .categories import check_category
from .duplicates import near_duplicate_report
from .names import check_name, check_text, preferred_stem, printable


@dataclass
class FolderImport:
    """What an import of a folder did: the rows added (with their near-duplicates), the files skipped (with the
    error), the warnings."""

    added: list = field(default_factory=list)
    duplicates: list = field(default_factory=list)
    skipped: list = field(default_factory=list)
    warnings: list = field(default_factory=list)
    left_out: list = field(default_factory=list)

    def as_dict(self) -> dict:
        return {"added": [r.to_dict() | {"near_duplicates": d} for r, d in zip(self.added, self.duplicates)],
                "skipped": self.skipped, "warnings": self.warnings, "left_out": self.left_out}


def mesh_files(folder, also=()) -> list[Path]:
    """The mesh files under ``folder`` (recursively, sorted) and the files ``also`` (a manifest's, scanned objects
    among them); :class:`CatalogueError` if none or not a folder."""
    folder = Path(folder)
    if not folder.is_dir():
        raise CatalogueError(f"{folder}: not a folder")
    files = sorted({p for p in folder.rglob("*") if p.is_file() and p.suffix.lower() in MESH_SUFFIXES} | set(also))
    if not files:
        raise CatalogueError(f"{folder}: no mesh files ({', '.join(sorted(MESH_SUFFIXES))})")
    return files


#: a manifest's columns (``file`` required)
MANIFEST_COLUMNS = ("file", "name", "category", "scale", "make", "model", "unit", "up", "front")
#: the largest manifest read (bytes) and the most rows
MAX_MANIFEST_BYTES = 4 << 20
MAX_MANIFEST_ROWS = 20_000
_UNITS = ("auto", "m", "cm", "mm", "in", "ft")
_UPS = ("auto", "+x", "-x", "+y", "-y", "+z", "-z")
_FRONTS = ("auto", "+x", "-x", "+y", "-y")


def read_manifest(path, folder) -> dict[Path, dict]:
    """The manifest's rows by file (resolved inside ``folder``), each a dict of the options it sets (empty cells
    left out); :class:`CatalogueError` naming the manifest, its line and the fix for anything wrong."""
    path, folder = Path(path), Path(folder)
    reader, header = _manifest_reader(path)
    root = folder.resolve()
    rows: dict[Path, dict] = {}
    seen: set = set()  # the listed files, resolved (two spellings of one file are one file)
    for line, cells in enumerate(reader, start=2):
        if not any(c.strip() for c in cells):
            continue
        if line > MAX_MANIFEST_ROWS + 1:
            raise CatalogueError(f"{path}: more than {MAX_MANIFEST_ROWS:,} rows")
        if len(cells) > len(header):
            raise CatalogueError(f"{path}, line {line}: {len(cells)} cells for {len(header)} columns")
        row = {h: c.strip() for h, c in zip(header, cells) if c.strip()}
        where = f"{path}, line {line}: "
        target = _manifest_file(where, row.pop("file", ""), folder, root, seen)
        try:
            _check_manifest_values(row)
        except ValueError as exc:
            raise CatalogueError(f"{where}scale {printable(row.get('scale'))[:20]!r} is not a factor between 0.0001 "
                                 "and 10000") from exc
        except CatalogueError as exc:
            raise CatalogueError(f"{where}{exc}") from exc
        rows[target] = row
    if not rows:
        raise CatalogueError(f"{path}: no rows under its header")
    return rows


def _manifest_reader(path: Path):
    """A CSV reader of the manifest's rows and its header (lower case), after its size, encoding and columns are
    checked."""
    if not path.is_file():
        raise CatalogueError(f"{path}: no such manifest; give a CSV with a header row ({','.join(MANIFEST_COLUMNS)})")
    if path.stat().st_size > MAX_MANIFEST_BYTES:
        raise CatalogueError(f"{path}: larger than {MAX_MANIFEST_BYTES >> 20} MB; a manifest holds a line a model")
    try:
        text = path.read_bytes().decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        raise CatalogueError(f"{path}: not UTF-8 text; save the manifest as UTF-8 CSV") from exc
    reader = csv.reader(io.StringIO(text))
    header = [h.strip().lower() for h in next(reader, [])]
    unknown = [h for h in header if h not in MANIFEST_COLUMNS]
    if "file" not in header or unknown or len(set(header)) != len(header):
        what = (f"unknown column(s) {printable(', '.join(unknown))[:120]}" if unknown else
                "no 'file' column" if "file" not in header else "a column twice")
        raise CatalogueError(f"{path}: {what}; the header row names some of {','.join(MANIFEST_COLUMNS)} "
                             "(file required)")
    return reader, header


def _manifest_file(where: str, rel: str, folder: Path, root: Path, seen: set) -> Path:
    """The file a row lists: a path inside ``folder`` (no absolute path, no ``..``, no link out), present, and not
    listed before (``seen``, resolved)."""
    target = folder / rel
    if (not rel or Path(rel).is_absolute() or ".." in Path(rel).parts or target.is_symlink()
            or root not in target.resolve().parents):
        raise CatalogueError(f"{where}file {printable(rel)[:100]!r} is not a path inside {folder}; give it "
                             "relative to the folder")
    if not target.is_file():
        raise CatalogueError(f"{where}{printable(rel)[:100]} is not in {folder}; fix the manifest's file column")
    if target.resolve() in seen:
        raise CatalogueError(f"{where}{printable(rel)[:100]} is listed twice")
    seen.add(target.resolve())
    return target


def _check_manifest_values(row: dict) -> None:
    """A row's values checked (names and texts as everywhere, the category known, a scale in 1e-4..1e4, unit, up and
    front among their choices), the category, scale and axes normalised in place."""
    if "name" in row:
        check_name(row["name"])
    for key in ("make", "model"):
        check_text(row.get(key), key)
    if "category" in row:
        row["category"] = check_category(row["category"])
    if "scale" in row:
        row["scale"] = float(row["scale"])
        if not (math.isfinite(row["scale"]) and 1e-4 <= row["scale"] <= 1e4):
            raise ValueError
    for key, allowed in (("unit", _UNITS), ("up", _UPS), ("front", _FRONTS)):
        if key in row:
            row[key] = row[key].lower()
            if row[key] not in allowed:
                raise CatalogueError(f"{key} {printable(row[key])[:20]!r} is not one of {', '.join(allowed)}")


def import_folder(catalogue, files, unit: str = "auto", up: str = "auto", progress=None, manifest=None,
                  category: str | None = None, scale: float = 1.0, root=None) -> FolderImport:
    """Add each of ``files`` (found under ``root``); ``manifest`` (from :func:`read_manifest`) sets a listed file's
    options, ``unit``, ``up``, ``category`` and ``scale`` are the others' (and an empty cell's). A file without a
    name takes its folder's when its own is generic or it is its folder's only model file
    (:func:`~twinreg.catalogue.names.preferred_stem`). ``progress(event, path, text)`` is called with "start" and
    "done" around each file, and "warning" or "skipped" with the line to show."""
    result = FolderImport()
    say = progress or (lambda *a: None)
    listed = {p.resolve(): row for p, row in (manifest or {}).items()}
    # a file the manifest does not list, beside one it does, is a part of that model (a Gazebo model's bench.dae
    # beside its base_link.dae), not a model: left out and said
    parts_of = {p.parent for p in listed}
    kept = []
    for path in files:
        if listed and path.resolve() not in listed and path.resolve().parent in parts_of:
            result.left_out.append(str(path))
            say("done", path, "")
        else:
            kept.append(path)
    if result.left_out:
        say("warning", None, f"left out {len(result.left_out)} file(s) the manifest does not list beside a model "
                             f"it lists (parts of it): {', '.join(Path(p).name for p in result.left_out[:10])}")
    files = kept
    per_folder: dict = {}
    for path in files:
        per_folder[path.parent] = per_folder.get(path.parent, 0) + 1
    for path in files:
        say("start", path, "")
        row = listed.get(path.resolve(), {})
        options = {"unit": unit, "up": up, "category": category, "scale": scale} | row
        if "name" not in options:
            options["name_hint"] = preferred_stem(path, root, sole=per_folder[path.parent] == 1)
        try:
            row = catalogue.add(path, **options)
        except TwinregError as exc:
            result.skipped.append({"file": str(path), "error": str(exc)})
            say("skipped", path, f"skipped: {exc}")
        else:
            near, warning = near_duplicate_report(catalogue, row)
            result.added.append(row)
            result.duplicates.append(near)
            if warning:
                result.warnings.append(warning)
                say("warning", path, warning)
        say("done", path, "")
    return result
