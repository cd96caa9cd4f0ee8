"""A fused type promoted into the catalogue (``add-model --from-twin OUT --type T --name N [--category K]``): the
type's shape (``OUT/shapes/type_<T>.ply``, written by build-twin) measured and stored as any mesh model, with its
provenance in its tags (the twin's folder, the type, its members). The twin is someone else's data: twin.json is
read with its size checked, the shape's file is found by the type's number alone (no path read from the twin), and
must be a file inside the twin's folder."""

from __future__ import annotations

from pathlib import Path

from ..catalogue.categories import check_category
from ..catalogue.names import printable
from ..errors import CatalogueError
from ..io._files import MAX_TWIN_BYTES as MAX_TWIN_JSON
from ..io._files import read_json_doc


def fused_entry(folder: Path, type_: int) -> tuple[dict, Path]:
    """The twin's ``shapes`` entry of type ``type_`` and its shape's file; a :class:`CatalogueError` naming the
    twin and the fix when the twin has no such fused type."""
    folder = Path(folder)
    doc_path = folder / "twin.json"
    if not doc_path.is_file():
        raise CatalogueError(f"{folder}: no twin.json; --from-twin takes a folder build-twin wrote")
    doc = read_json_doc(doc_path, MAX_TWIN_JSON, CatalogueError, "give a folder build-twin wrote")
    shapes = doc.get("shapes") if isinstance(doc, dict) else None
    entries = [s for s in shapes if isinstance(s, dict) and s.get("type") == type_] if isinstance(shapes, list) else []
    if not entries:
        have = sorted(s.get("type") for s in shapes if isinstance(s, dict) and isinstance(s.get("type"), int)) \
            if isinstance(shapes, list) else []
        raise CatalogueError(f"{doc_path}: no fused shape of type {type_}; its fused types: "
                             f"{', '.join(map(str, have[:30])) or 'none'} (build-twin fuses the types without a model)")
    path = folder / "shapes" / f"type_{type_}.ply"
    if path.is_symlink() or not path.is_file() or folder.resolve() not in path.resolve().parents:
        raise CatalogueError(f"{path}: missing or not a file of the twin; rerun build-twin")
    return entries[0], path


def promote(catalogue, folder: Path, type_: int, name: str, category: str | None = None):
    """Add type ``type_`` of the twin in ``folder`` to ``catalogue`` as model ``name`` of ``category`` (default:
    the type's kind). Returns the catalogue row."""
    if not isinstance(type_, int) or type_ < 1:
        raise CatalogueError(f"--type {type_}: give a type number (twin.json's objects carry theirs)")
    catalogue.check_free_name(name)  # before the twin is read or its shape measured
    entry, path = fused_entry(Path(folder), type_)
    kind = category if category is not None else entry.get("kind")
    if not isinstance(kind, str) or kind == "unknown":
        raise CatalogueError(f"type {type_} of {folder} is of no known kind; give --category")
    kind = check_category(kind)
    members = entry.get("members") if isinstance(entry.get("members"), list) else []
    tags = ["fused", f"twin:{printable(Path(folder).resolve().name)[:80]}", f"type:{type_}",
            f"members:{len(members)}"]
    return catalogue.add(path, name=name, category=kind, unit="m", up="+z", front="+x", tags=tags)
