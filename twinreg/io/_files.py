"""The checks every reader makes before opening a file."""

from __future__ import annotations

import json
from pathlib import Path


def checked_input(path, suffixes, kind: str, formats: str, error) -> tuple[Path, str]:
    """``(path, lower-case suffix)`` of an existing, non-empty file of a supported format, or ``error`` raised
    with one line naming the file and what to do."""
    path = Path(path)
    if path.is_dir():
        raise error(f"{path}: is a folder; pass one {kind} file ({formats})")
    if not path.is_file():
        raise error(f"{path}: no such file")
    suffix = path.suffix.lower()
    if suffix not in suffixes:
        raise error(f"{path}: unsupported {kind} format '{suffix}'; use {formats}")
    if path.stat().st_size == 0:
        raise error(f"{path}: the file is empty")
    return path, suffix


#: the largest twin.json read from someone else (a 47,040-car survey's is about 140 MB)
MAX_TWIN_BYTES = 256 << 20
#: the most objects and arrays a JSON document from someone else may hold (a twin of 47,040 cars holds about 2M;
#: 4M empty objects are about 300 MB once parsed)
MAX_JSON_CONTAINERS = 4_000_000
#: the most values (an upper bound: commas, objects and arrays counted) it may hold (a 47,040-car twin: about 8M)
MAX_JSON_VALUES = 24_000_000


def read_json_doc(path, max_bytes: int, error, fix: str, max_containers: int = MAX_JSON_CONTAINERS,
                  max_values: int = MAX_JSON_VALUES):
    """The JSON document of a file from someone else: its size checked before it is read (more than
    ``max_bytes`` is refused unread), its objects and arrays and its values counted before it is parsed (more
    than ``max_containers`` or ``max_values`` are refused: parsed, a 100 MB file of empty objects takes 3 GB), its
    nesting bounded by the parser's recursion limit; ``error`` raised with one line naming the file, what was
    wrong and ``fix`` otherwise."""
    path = Path(path)
    size = path.stat().st_size
    if size > max_bytes:
        raise error(f"{path}: {size / 1024 ** 2:,.0f} MB, larger than any such file twinreg writes "
                    f"({max_bytes >> 20} MB at most); {fix}")
    raw = path.read_bytes()
    containers = raw.count(b"{") + raw.count(b"[")
    values = containers + raw.count(b",")
    if containers > max_containers or values > max_values:
        raise error(f"{path}: holds about {containers:,} objects and arrays and {values:,} values, more than any "
                    f"such file twinreg writes ({max_containers:,} and {max_values:,} at most); {fix}")
    try:
        return json.loads(raw.decode("utf-8"))
    except RecursionError as exc:
        raise error(f"{path}: nested deeper than any such file twinreg writes; {fix}") from exc
    except (ValueError, UnicodeDecodeError) as exc:
        raise error(f"{path}: not valid JSON ({type(exc).__name__}); {fix}") from exc


def twin_doc(folder, error, command: str) -> tuple[Path, object]:
    """(``folder``/twin.json, its document) of a folder someone says build-twin wrote (:func:`read_json_doc`,
    at most :data:`MAX_TWIN_BYTES`); ``error`` raised with one line naming ``command`` when there is none."""
    doc_path = Path(folder) / "twin.json"
    if not doc_path.is_file():
        raise error(f"{folder}: no twin.json; {command} takes a folder build-twin wrote")
    return doc_path, read_json_doc(doc_path, MAX_TWIN_BYTES, error, "give a folder build-twin wrote")


def file_of(folder, path: Path) -> bool:
    """Whether ``path`` is a regular file inside ``folder``: no symlink, nothing that resolves out of it (a
    stranger's twin names no file elsewhere)."""
    return not path.is_symlink() and path.is_file() and Path(folder).resolve() in path.resolve().parents
