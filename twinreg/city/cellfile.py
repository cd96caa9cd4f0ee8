"""A finished cell's result as data: ``<name>-<key>.npz`` holding its arrays and one JSON document of its
structure (numbers, strings, lists and the names of a fixed set of result classes).

A resumed run reads these files back from ``OUT/.cells``, and OUT may come from someone else (a shared twin keeps
its cells), so the format runs no code when read: arrays are loaded with ``allow_pickle=False``, and the JSON may
name only the classes of :data:`CLASSES` (anything else, or a file that is not such an npz, is refused and the cell
computed again).
"""

from __future__ import annotations

import dataclasses
import json
import zipfile
from pathlib import Path

import numpy as np

from cosco.sections import Frame, ObjectShape, Sections, Size
from cosco.surface import Surface
from cosco.symmetry import Symmetry

from ..errors import CellFileError
from ..io.npz import read_arrays, read_member
from ..io.observed import Raster
from ..io.outdir import atomic_path
from .cells import CellJob, CellObject, CellResult, SavedCell, process_cell

#: the classes a cell file may hold, by the name it gives them
CLASSES = {c.__name__: c for c in (CellResult, CellObject, ObjectShape, Symmetry, Frame, Sections, Size, Surface, Raster)}
#: the largest cell file read back (bytes)
MAX_BYTES = 4 * 1024 ** 3
FORMAT = "twinreg-cell/4"  # 3: shapes carry their surface; 4: and its roughness
#: what reading a damaged or foreign file can raise (each becomes a CellFileError)
_UNREADABLE = (OSError, ValueError, KeyError, TypeError, EOFError, UnicodeDecodeError, AttributeError,
               zipfile.BadZipFile)



def _encode(obj, arrays: dict):
    if isinstance(obj, np.ndarray):
        key = f"a{len(arrays)}"
        arrays[key] = obj
        return {"$array": key}
    if dataclasses.is_dataclass(obj) and not isinstance(obj, type):
        name = type(obj).__name__
        if CLASSES.get(name) is not type(obj):
            raise TypeError(f"a cell result may not hold a {type(obj).__qualname__}")
        return {"$class": name, "fields": {f.name: _encode(getattr(obj, f.name), arrays)
                                           for f in dataclasses.fields(obj)}}
    if isinstance(obj, tuple):
        return {"$tuple": [_encode(v, arrays) for v in obj]}
    if isinstance(obj, list):
        return [_encode(v, arrays) for v in obj]
    if isinstance(obj, dict):
        if not all(isinstance(k, str) for k in obj):
            raise TypeError("a cell result's mappings have string keys")
        return {"$dict": {k: _encode(v, arrays) for k, v in obj.items()}}
    if isinstance(obj, (np.floating, np.integer, np.bool_)):
        return obj.item()
    if obj is None or isinstance(obj, (bool, int, float, str)):
        return obj
    raise TypeError(f"a cell result may not hold a {type(obj).__qualname__}")


def _decode(doc, arrays):
    if isinstance(doc, list):
        return [_decode(v, arrays) for v in doc]
    if not isinstance(doc, dict):
        return doc
    if "$array" in doc:
        return arrays[str(doc["$array"])]
    if "$tuple" in doc:
        return tuple(_decode(v, arrays) for v in doc["$tuple"])
    if "$dict" in doc:
        return {str(k): _decode(v, arrays) for k, v in doc["$dict"].items()}
    cls = CLASSES.get(doc.get("$class"))
    if cls is None:
        raise CellFileError(f"it names a class {str(doc.get('$class'))[:60]!r} a cell result does not hold")
    fields = {f.name for f in dataclasses.fields(cls)}
    given = doc.get("fields", {})
    if not isinstance(given, dict) or not set(given) <= fields:
        raise CellFileError(f"its {cls.__name__} has fields it should not")
    return cls(**{k: _decode(v, arrays) for k, v in given.items()})


def run_cell(job: CellJob, *ready) -> CellResult | SavedCell:
    """:func:`~twinreg.city.cells.process_cell` on a worker; with ``job.result_path``, the cell's file written
    there by the worker itself (through a temporary file: a killed worker leaves none) and only its name, key and
    object count returned (the objects never cross to the main process)."""
    result = process_cell(job, *ready)
    if job.result_path is None:
        return result
    save(result, Path(job.result_path))
    return SavedCell(result.name, result.key, len(result.objects))


def save(result, dst: Path) -> Path:
    """Write ``result`` (a :class:`CellResult`) to ``dst`` through a temporary file."""
    arrays: dict = {}
    doc = {"format": FORMAT, "result": _encode(result, arrays)}
    with atomic_path(dst, ".npz") as tmp:
        with open(tmp, "wb") as fh:
            np.savez(fh, __doc__=np.frombuffer(json.dumps(doc).encode("utf-8"), dtype=np.uint8), **arrays)
    return dst


def _document(path: Path) -> tuple[dict, object]:
    if path.is_symlink() or path.stat().st_size > MAX_BYTES:
        raise CellFileError("it is a link or too large")
    z = np.load(path, allow_pickle=False)
    if not hasattr(z, "files") or "__doc__" not in z.files:
        raise CellFileError("it is not a twinreg cell file")
    doc = json.loads(z["__doc__"].tobytes().decode("utf-8"))
    if not isinstance(doc, dict) or doc.get("format") != FORMAT or not isinstance(doc.get("result"), dict):
        raise CellFileError("it is not a twinreg cell file")
    return doc, z


def identity(path: Path) -> tuple[str, str]:
    """The (cell name, key) a cell file says it holds, reading only its JSON; :class:`CellFileError` if it is not
    a cell file."""
    try:
        doc, z = _document(Path(path))
        z.close()
        fields = doc["result"].get("fields", {})
        if doc["result"].get("$class") != "CellResult":
            raise CellFileError("it does not hold a cell result")
        return str(fields.get("name")), str(fields.get("key"))
    except CellFileError:
        raise
    except _UNREADABLE as exc:
        raise CellFileError(f"it cannot be read ({type(exc).__name__})") from exc


def _cloud_slots(doc: dict) -> list:
    """Each object's ``cloud`` entry in a cell file's document (a mutable dict; None where it holds no array)."""
    objects = doc["result"].get("fields", {}).get("objects", [])
    if not isinstance(objects, list):
        raise CellFileError("its objects are not a list")
    slots = []
    for o in objects:
        fields = o.get("fields") if isinstance(o, dict) else None
        if not isinstance(fields, dict) or o.get("$class") != "CellObject":
            raise CellFileError("it holds an object that is not a cell object")
        slots.append(fields if isinstance(fields.get("cloud"), dict) and "$array" in fields["cloud"] else None)
    return slots


def load(path: Path, clouds: bool = True):
    """The :class:`CellResult` in ``path``; :class:`CellFileError` if the file is not one this program wrote.
    ``clouds=False`` leaves the objects' point samples in the file (``cloud`` None: read them with
    :func:`load_clouds` where they are needed)."""
    path = Path(path)
    try:
        doc, z = _document(path)
        skip = set()
        if not clouds:
            for fields in _cloud_slots(doc):
                if fields is not None:
                    skip.add(str(fields["cloud"]["$array"]))
                    fields["cloud"] = None
        with z:
            if not skip <= set(z.files) - {"__doc__"}:  # the samples left in the file are there to be read
                raise CellFileError("it names point samples it does not hold")
            arrays = read_arrays(z.zip, [k for k in z.files if k != "__doc__" and k not in skip])
        result = _decode(doc["result"], arrays)
    except CellFileError:
        raise
    except _UNREADABLE as exc:
        raise CellFileError(f"it cannot be read ({type(exc).__name__})") from exc
    if not isinstance(result, CellResult):
        raise CellFileError("it does not hold a cell result")
    return result


#: per cell file (path, size, modification time): the array names of its objects' point samples and the zip's
#: entries of those arrays (a worker reads the samples of one file for many batches; its document and directory
#: are parsed once)
_SAMPLE_KEYS: dict = {}


def _sample_keys(path: Path) -> tuple[list, dict]:
    st = path.stat()
    stamp = (str(path), st.st_size, st.st_mtime_ns)
    if stamp not in _SAMPLE_KEYS:
        doc, z = _document(path)
        with z:
            keys = [None if f is None else str(f["cloud"]["$array"]) for f in _cloud_slots(doc)]
            entries = {k: z.zip.getinfo(f"{k}.npy") for k in keys if k is not None and k in z.files and k != "__doc__"}
        if len(_SAMPLE_KEYS) >= 256:
            _SAMPLE_KEYS.clear()
        _SAMPLE_KEYS[stamp] = (keys, entries)
    return _SAMPLE_KEYS[stamp]


def load_clouds(path: Path, indices) -> list:
    """The point samples (``cloud``) of the objects ``indices`` of the cell file ``path``, read alone;
    :class:`CellFileError` if the file is not one this program wrote or has no such objects."""
    path = Path(path)
    try:
        keys, entries = _sample_keys(path)
        wanted = []
        for i in indices:
            key = keys[int(i)] if 0 <= int(i) < len(keys) else None
            if key is None or key not in entries:
                raise CellFileError(f"it has no point sample for object {int(i)}")
            wanted.append(key)
        with open(path, "rb") as fh:
            out = [read_member(fh, entries[k]) for k in wanted]
        if any(a is None for a in out):  # a member this reader leaves to numpy's
            with np.load(path, allow_pickle=False) as z:
                arrays = read_arrays(z.zip, set(wanted))
            out = [a if a is not None else arrays[k].copy() for a, k in zip(out, wanted)]
        return out
    except CellFileError:
        raise
    except _UNREADABLE as exc:
        raise CellFileError(f"it cannot be read ({type(exc).__name__})") from exc
