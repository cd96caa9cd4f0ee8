"""A fused type promoted into the catalogue (``add-model --from-twin OUT --type T --name N [--category K]``): the
type's shape (``OUT/shapes/type_<T>.ply``, written by build-twin) measured and stored as any mesh model, with its
provenance in its tags (the twin's folder, the type, its members). The twin is someone else's data: twin.json is
read with its size checked, the shape's file is found by the type's number alone (no path read from the twin), and
must be a file inside the twin's folder."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..catalogue.categories import check_category, size_range
from ..catalogue.names import printable
from ..errors import CatalogueError
from ..io._files import file_of, twin_doc


def fused_entry(folder: Path, type_: int) -> tuple[dict, Path, dict]:
    """The twin's ``shapes`` entry of type ``type_``, its shape's file and twin.json's document; a
    :class:`CatalogueError` naming the twin and the fix when the twin has no such fused type."""
    folder = Path(folder)
    doc_path, doc = twin_doc(folder, CatalogueError, "--from-twin")
    shapes = doc.get("shapes") if isinstance(doc, dict) else None
    entries = [s for s in shapes if isinstance(s, dict) and s.get("type") == type_] if isinstance(shapes, list) else []
    if not entries:
        have = sorted(s.get("type") for s in shapes if isinstance(s, dict) and isinstance(s.get("type"), int)) \
            if isinstance(shapes, list) else []
        raise CatalogueError(f"{doc_path}: no fused shape of type {type_}; its fused types: "
                             f"{', '.join(map(str, have[:30])) or 'none'} (build-twin fuses the types without a model)")
    path = folder / "shapes" / f"type_{type_}.ply"
    if not file_of(folder, path):
        raise CatalogueError(f"{path}: missing or not a file of the twin; rerun build-twin")
    return entries[0], path, doc


def contradiction(catalogue, doc: dict, type_: int, kind: str) -> str | None:
    """Why the members of type ``type_`` (twin.json's ``doc``) are not of ``kind``, or None: fewer than half of them
    fit the kind's sizes, as the catalogue's references of the kind measure them (the kinds decision's
    :func:`~twinreg.recognition.kinds.fits_size`), or, when it holds none, the kind's plausible longest extent."""
    from ..recognition.kinds import References, fits_size

    objs = doc.get("objects") if isinstance(doc.get("objects"), list) else []
    sizes = []
    for o in objs:
        size = o.get("size") if isinstance(o, dict) and o.get("type") == type_ else None
        if isinstance(size, dict) and all(isinstance(size.get(k), (int, float)) for k in ("length", "width", "height")):
            sizes.append([float(size["length"]), float(size["width"]), float(size["height"])])
    if not sizes:
        return None
    sizes = np.asarray(sizes)
    refs = References.of_catalogue(catalogue)
    if refs.ranges and kind in refs.ranges:
        lo, hi = refs.ranges[kind]
        fit = np.array([fits_size(s, lo, hi) for s in sizes])
        span = f"its references measure {lo[0]:.1f}-{hi[0]:.1f} m long, {lo[2]:.1f}-{hi[2]:.1f} m tall"
    else:
        small, large, _ = size_range(kind)
        fit = (sizes.max(axis=1) >= small) & (sizes.max(axis=1) <= large)
        span = f"a {kind} is {small:g}-{large:g} m at its longest"
    if fit.mean() >= 0.5:
        return None
    return (f"type {type_}'s {len(sizes)} members measure {sizes[:, 0].min():.1f}-{sizes[:, 0].max():.1f} m long, "
            f"{sizes[:, 2].min():.1f}-{sizes[:, 2].max():.1f} m tall; {int(fit.sum())} fit a {kind} ({span})")


def promote(catalogue, folder: Path, type_: int, name: str, category: str | None = None, force: bool = False):
    """Add type ``type_`` of the twin in ``folder`` to ``catalogue`` as model ``name`` of ``category`` (default:
    the type's kind); refused when the type's members contradict the kind (:func:`contradiction`) unless
    ``force``. Returns the catalogue row."""
    if not isinstance(type_, int) or type_ < 1:
        raise CatalogueError(f"--type {type_}: give a type number (twin.json's objects carry theirs)")
    catalogue.check_free_name(name)  # before the twin is read or its shape measured
    entry, path, doc = fused_entry(Path(folder), type_)
    kind = category if category is not None else entry.get("kind")
    if not isinstance(kind, str) or kind == "unknown":
        raise CatalogueError(f"type {type_} of {folder} is of no known kind; give --category")
    kind = check_category(kind)
    why = None if force else contradiction(catalogue, doc, type_, kind)
    if why:
        raise CatalogueError(f"{Path(folder) / 'twin.json'}: {why}; check --category, or pass --force to add it anyway")
    members = entry.get("members") if isinstance(entry.get("members"), list) else []
    tags = ["fused", f"twin:{printable(Path(folder).resolve().name)[:80]}", f"type:{type_}",
            f"members:{len(members)}"]
    return catalogue.add(path, name=name, category=kind, unit="m", up="+z", front="+x", tags=tags)
