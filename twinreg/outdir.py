"""Output folders that are replaced only as a whole: everything is written into a staging folder beside the
target, which then takes the target's place (the old one is removed only after the swap)."""

from __future__ import annotations

import contextlib
import os
import shutil
import tempfile
from pathlib import Path

from .errors import ExportError


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


def publish(tmp, dst) -> None:
    """Give a temporary file (made private by mkstemp) the usual permissions, then rename it into place."""
    os.chmod(tmp, 0o666 & ~_umask())
    os.replace(tmp, dst)


@contextlib.contextmanager
def atomic_path(dst, suffix: str | None = None):
    """Yield a temporary path beside ``dst``; when the block ends without error the file takes ``dst``'s place
    (a reader never sees half a file), otherwise it is deleted."""
    dst = Path(dst)
    dst.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=dst.parent, prefix=".tmp-", suffix=suffix if suffix is not None else dst.suffix)
    os.close(fd)
    try:
        yield Path(tmp)
        publish(tmp, dst)
    finally:
        if os.path.exists(tmp):
            os.unlink(tmp)


@contextlib.contextmanager
def staged_folder(target):
    """Yield a staging folder; on success it replaces ``target`` atomically, on failure it is deleted and
    ``target`` is left as it was."""
    target = Path(target)
    try:
        target.parent.mkdir(parents=True, exist_ok=True)
        stage = Path(tempfile.mkdtemp(dir=target.parent, prefix=f".{target.name}.tmp-"))
        os.chmod(stage, 0o777 & ~_umask())
    except OSError as exc:
        raise ExportError(f"{target}: cannot write here ({exc.strerror}); choose another --out") from exc
    try:
        yield stage
    except BaseException:
        shutil.rmtree(stage, ignore_errors=True)
        raise
    old = None
    try:
        if target.exists():
            old = target.parent / f".{target.name}.old-{os.getpid()}"
            os.replace(target, old)
        os.replace(stage, target)
    except OSError as exc:
        shutil.rmtree(stage, ignore_errors=True)
        if old is not None and not target.exists():
            os.replace(old, target)
        raise ExportError(f"{target}: cannot replace the folder ({exc.strerror})") from exc
    if old is not None:
        shutil.rmtree(old, ignore_errors=True)
