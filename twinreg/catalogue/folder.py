"""``import-models DIR``: every mesh of a folder added in turn; a bad file is reported and skipped, the rest go in,
each with its near-duplicates named."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

from ..errors import CatalogueError, TwinregError
from ..io.meshes import MESH_SUFFIXES
from .duplicates import near_duplicate_report


@dataclass
class FolderImport:
    """What an import of a folder did: the rows added (with their near-duplicates), the files skipped (with the
    error), the warnings."""

    added: list = field(default_factory=list)
    duplicates: list = field(default_factory=list)
    skipped: list = field(default_factory=list)
    warnings: list = field(default_factory=list)

    def as_dict(self) -> dict:
        return {"added": [r.to_dict() | {"near_duplicates": d} for r, d in zip(self.added, self.duplicates)],
                "skipped": self.skipped, "warnings": self.warnings}


def mesh_files(folder) -> list[Path]:
    """The mesh files under ``folder`` (recursively, sorted); :class:`CatalogueError` if none or not a folder."""
    folder = Path(folder)
    if not folder.is_dir():
        raise CatalogueError(f"{folder}: not a folder")
    files = sorted(p for p in folder.rglob("*") if p.is_file() and p.suffix.lower() in MESH_SUFFIXES)
    if not files:
        raise CatalogueError(f"{folder}: no mesh files ({', '.join(sorted(MESH_SUFFIXES))})")
    return files


def import_folder(catalogue, files, unit: str = "auto", up: str = "auto", progress=None) -> FolderImport:
    """Add each of ``files``; ``progress(event, path, text)`` is called with "start" and "done" around each file,
    and "warning" or "skipped" with the line to show."""
    result = FolderImport()
    say = progress or (lambda *a: None)
    for path in files:
        say("start", path, "")
        try:
            row = catalogue.add(path, unit=unit, up=up)
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
