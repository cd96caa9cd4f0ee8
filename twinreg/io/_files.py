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
