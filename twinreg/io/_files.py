"""The checks every reader makes before opening a file."""

from __future__ import annotations

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


def read_json_doc(path, max_bytes: int, error, fix: str):
    """The JSON document of a file from someone else: its size checked before it is read (more than
    ``max_bytes`` is refused unread), its nesting bounded by the parser's recursion limit; ``error`` raised with one
    line naming the file, what was wrong and ``fix`` otherwise."""
    import json

    path = Path(path)
    size = path.stat().st_size
    if size > max_bytes:
        raise error(f"{path}: {size / 1024 ** 2:,.0f} MB, larger than any such file twinreg writes "
                    f"({max_bytes >> 20} MB at most); {fix}")
    try:
        return json.loads(path.read_bytes().decode("utf-8"))
    except RecursionError as exc:
        raise error(f"{path}: nested deeper than any such file twinreg writes; {fix}") from exc
    except (ValueError, UnicodeDecodeError) as exc:
        raise error(f"{path}: not valid JSON ({type(exc).__name__}); {fix}") from exc
