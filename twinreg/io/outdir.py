"""Output folders that are safe to write: files go through a temporary name, folders are replaced as a whole, and
only a folder this program wrote is ever replaced.

``staged_folder(OUT)`` refuses an OUT that is not missing, not empty and not marked as twinreg's (a marker file,
:data:`MARKER`, lists what twinreg wrote there; a folder holding anything else is refused, so a user's files are
never deleted), and an OUT that holds one of the run's inputs or the catalogue. Everything is written into a
staging folder beside OUT, which then takes OUT's place. The swap is journalled (``.OUT.swap`` beside it): a run
killed between the two renames is finished (or rolled back) by the next run that writes to OUT, so OUT is never
lost.
"""

from __future__ import annotations

import contextlib
import datetime
import errno
import fcntl
import json
import os
import shutil
import tempfile
from pathlib import Path

from ..errors import ExportError

#: the file marking a folder as written by twinreg, with the list of what it wrote there
MARKER = ".twinreg-output.json"
#: files under this folder of OUT are a tiled run's finished cells (twinreg's, kept to resume; see city/resume.py)
WORK_PREFIX = ".cells/"
#: what a marked folder holds (the marker's ``kind``), and the command that writes it
KINDS = {"twin": "build-twin", "comparison": "compare", "detection": "detect --out", "demo": "demo",
         "library report": "library-report", "city": "simulate-city",
         "street": "simulate-street"}


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


def _inside(path: Path, folder: Path) -> bool:
    try:
        path.resolve().relative_to(folder.resolve())
        return True
    except ValueError:
        return False


def _listing(folder: Path) -> list[str]:
    """Every file under ``folder`` (relative paths, sorted): what is not a folder, links to folders not followed
    (as ``Path.rglob`` lists them, a tenth of its time on a city's 12,000 files)."""
    out = []
    for root, _, files in os.walk(folder):
        rel = os.path.relpath(root, folder)
        out.extend(files if rel == "." else (os.path.join(rel, n) for n in files))
    return sorted(out)


#: what SQLite keeps beside a database while it is open (or after a reader that could not remove them)
SQLITE_SIDECARS = ("-wal", "-shm", "-journal")


def _sidecar(entry: str, listed: set) -> bool:
    """True when ``entry`` is SQLite's file beside a database twinreg wrote (a catalogue in OUT opened since).

    >>> _sidecar("library/catalogue.sqlite-shm", {"library/catalogue.sqlite"}), _sidecar("x.pdf-wal", set())
    (True, False)
    """
    return any(entry.endswith(s) and entry[:-len(s)] in listed for s in SQLITE_SIDECARS)


def marked_kind(folder, marker: dict | None = None) -> str | None:
    """What a folder twinreg wrote holds (:data:`KINDS`): its marker's ``kind``, else (a marker written before
    kinds were recorded) guessed from its files; None when unknown."""
    folder = Path(folder)
    kind = (marker or {}).get("kind")
    if isinstance(kind, str) and kind in KINDS:
        return kind
    for name, guess in (("twin.json", "twin"), ("changes.json", "comparison"), ("truth.json", "city")):
        if (folder / name).is_file():
            return guess
    return None


def check_replaceable(target, protect=(), kind: str | None = None) -> Path:
    """Raise :class:`ExportError` unless ``target`` may be replaced: missing, an empty folder, or a folder
    twinreg wrote (its marker lists every file in it) holding what this command writes (``kind``, one of
    :data:`KINDS`; a twin is never replaced by a comparison, nor the reverse), neither holding nor lying inside any
    of the ``protect`` paths (inputs, the catalogue). A symbolic link is judged by the folder it points to."""
    target = real_target(target)
    for p in protect:
        if p is not None and _inside(Path(p), target):
            raise ExportError(f"{target}: the output folder holds {p}, which this run reads; choose another --out "
                              "(an output folder is replaced as a whole)")
        if p is not None and Path(p).is_dir() and _inside(target, Path(p)):
            raise ExportError(f"{target}: the output folder lies inside {p}, which this run reads; choose an --out "
                              "outside it")
    if not target.exists() and not target.is_symlink():
        return target
    if not target.is_dir():
        raise ExportError(f"{target}: exists and is not a folder; choose another --out")
    entries = _listing(target)
    if not entries:
        return target
    marker = target / MARKER
    if not marker.is_file():
        shown = ", ".join(entries[:3]) + (", ..." if len(entries) > 3 else "")
        raise ExportError(f"{target}: the folder holds files twinreg did not write ({shown}); choose a new or empty "
                          "--out folder (an output folder is replaced as a whole)")
    try:
        doc = json.loads(marker.read_text(encoding="utf-8"))
        listed = set(doc["files"])
    except (OSError, ValueError, KeyError, TypeError) as exc:
        raise ExportError(f"{marker}: not a readable twinreg marker ({exc}); choose another --out") from exc
    held = marked_kind(target, doc if isinstance(doc, dict) else None)
    if kind is not None and held is not None and held != kind:
        raise ExportError(f"{target}: holds a {held} (written by twinreg {KINDS[held]}), which this command does not "
                          f"replace with a {kind}; choose another --out")
    foreign = [e for e in entries if e != MARKER and e not in listed and not e.startswith(WORK_PREFIX)
               and not _sidecar(e, listed)]
    if foreign:
        shown = ", ".join(foreign[:3]) + (", ..." if len(foreign) > 3 else "")
        raise ExportError(f"{target}: holds files twinreg did not write ({shown}); move them out or choose another "
                          "--out (an output folder is replaced as a whole)")
    return target


def real_target(target) -> Path:
    """OUT itself, or the folder it links to when OUT is a symbolic link (the link stays and sees the new twin).

    >>> real_target("exports/x") == Path("exports/x")
    True
    """
    target = Path(target)
    return Path(os.path.realpath(target)) if target.is_symlink() else target


#: errors of a full, read-only or over-quota disk: said with the folder and the fix, not as a bare errno
DISK_ERRORS = (errno.ENOSPC, errno.EDQUOT, errno.EROFS, errno.EACCES, errno.EPERM, errno.EFBIG)


def disk_error(target: Path, exc: OSError) -> ExportError:
    """The one-line error of a failed write into ``target``."""
    where = f" ({exc.filename})" if getattr(exc, "filename", None) else ""
    return ExportError(f"{target}: cannot write the output: {exc.strerror or exc}{where}; free space on its disk "
                       "or choose another --out (nothing was changed)")


def _journal(target: Path) -> Path:
    return target.parent / f".{target.name}.swap"


@contextlib.contextmanager
def _parent_lock(target: Path):
    """An exclusive lock on OUT's parent folder while a swap or a recovery runs (no file is left behind)."""
    fd = os.open(target.parent, os.O_RDONLY)
    try:
        fcntl.flock(fd, fcntl.LOCK_EX)
        yield
    finally:
        fcntl.flock(fd, fcntl.LOCK_UN)
        os.close(fd)


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True


def recover(target) -> str | None:
    """Finish or roll back a swap of ``target`` that a killed run left half-done, and remove staging folders of
    dead runs. Returns what was done ("finished", "rolled back", "cleaned") or None."""
    target = Path(target)
    if not target.parent.is_dir():
        return None
    done = None
    with _parent_lock(target):
        journal = _journal(target)
        if journal.exists():
            try:
                info = json.loads(journal.read_text(encoding="utf-8"))
                stage = target.parent / info["stage"]
                old = target.parent / info["old"]
            except (OSError, ValueError, KeyError, TypeError):
                stage = old = None
            if stage is not None:
                if not target.exists() and stage.exists():
                    os.replace(stage, target)  # the stage was complete when the journal was written
                    done = "finished"
                elif not target.exists() and old.exists():
                    os.replace(old, target)
                    done = "rolled back"
                elif stage.exists():
                    shutil.rmtree(stage, ignore_errors=True)
                    done = "rolled back"
                else:
                    done = "finished"
                if old.exists():
                    shutil.rmtree(old, ignore_errors=True)
            journal.unlink(missing_ok=True)
        # the staging folders of killed runs beside it, whatever folder they were for (.NAME.tmp-PID-...)
        for p in target.parent.glob(".*.tmp-*"):
            pid = p.name.rsplit(".tmp-", 1)[-1].split("-")[0]
            if p.is_dir() and not p.is_symlink() and pid.isdigit() and not _alive(int(pid)) \
                    and not _journal(target.parent / p.name[1:].rsplit(".tmp-", 1)[0]).exists():
                shutil.rmtree(p, ignore_errors=True)
                done = done or "cleaned"
    return done


def _drop_temporaries(stage: Path) -> None:
    """Remove temporary files a killed helper process left in the stage (``.tmp-*``, never published)."""
    for p in stage.rglob(".tmp-*"):
        if p.is_file():
            p.unlink(missing_ok=True)


def claim(target, protect=(), kind: str = "twin") -> Path:
    """Make ``target`` a folder marked as twinreg's (creating it when missing), after :func:`check_replaceable`:
    a long run can then keep work in it (``.cells/``) before its results replace it as a whole."""
    target = real_target(target)
    recover(target)
    check_replaceable(target, protect, kind)
    try:
        target.mkdir(parents=True, exist_ok=True)
        marker = target / MARKER
        if not marker.exists():
            with atomic_path(marker, ".json") as tmp:
                Path(tmp).write_text(json.dumps({"tool": "twinreg", "kind": kind, "files": []}), encoding="utf-8")
    except OSError as exc:
        raise ExportError(f"{target}: cannot write here ({exc.strerror}); choose another --out") from exc
    return target


@contextlib.contextmanager
def staged_folder(target, protect=(), kind: str | None = None):
    """Yield a staging folder; on success it replaces ``target`` as a whole, on failure it is deleted and
    ``target`` is left as it was. ``target`` must pass :func:`check_replaceable` (``protect``: paths the run
    reads, such as its inputs and the catalogue, which OUT may neither hold nor lie in; ``kind``: what the folder
    holds, :data:`KINDS`, recorded in its marker). A symbolic link as OUT: the folder it points to is replaced, the
    link kept."""
    target = real_target(target)
    try:
        target.parent.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise ExportError(f"{target}: cannot write here ({exc.strerror}); choose another --out") from exc
    recover(target)
    check_replaceable(target, protect, kind)
    try:
        stage = Path(tempfile.mkdtemp(dir=target.parent, prefix=f".{target.name}.tmp-{os.getpid()}-"))
        os.chmod(stage, 0o777 & ~_umask())
    except OSError as exc:
        raise ExportError(f"{target}: cannot write here ({exc.strerror}); choose another --out") from exc
    try:
        yield stage
        _drop_temporaries(stage)
        marker = {"tool": "twinreg", "files": _listing(stage)} | ({"kind": kind} if kind else {})
        (stage / MARKER).write_text(json.dumps(marker, indent=1), encoding="utf-8")
    except BaseException as exc:
        shutil.rmtree(stage, ignore_errors=True)
        if isinstance(exc, OSError) and exc.errno in DISK_ERRORS:
            raise disk_error(target, exc) from exc
        raise
    old = target.parent / f".{target.name}.old-{os.getpid()}"
    try:
        with _parent_lock(target):
            check_replaceable(target, protect, kind)  # another run may have written it meanwhile
            journal = _journal(target)
            with atomic_path(journal, ".swap") as tmp:
                Path(tmp).write_text(json.dumps({"stage": stage.name, "old": old.name}), encoding="utf-8")
            if target.exists():
                os.replace(target, old)
            os.replace(stage, target)
            journal.unlink()
    except BaseException as exc:  # roll back: the old folder returns, the stage goes
        if not target.exists() and old.exists():
            os.replace(old, target)
        _journal(target).unlink(missing_ok=True)
        shutil.rmtree(stage, ignore_errors=True)
        if isinstance(exc, OSError):
            raise ExportError(f"{target}: cannot replace the folder ({exc.strerror})") from exc
        raise
    shutil.rmtree(old, ignore_errors=True)


def _lock_file(target: Path) -> Path:
    return target.parent / f".{target.name}.lock"


@contextlib.contextmanager
def locked(target, command: str):
    """Hold OUT for the whole of a run: a second run writing the same OUT is refused at once with one line naming
    the running one (its process id, command and start). The lock is the kernel's (``flock`` on ``.OUT.lock``
    beside OUT): a killed run's lock goes with it, and the file is removed when the run ends."""
    target = real_target(target)
    try:
        target.parent.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise ExportError(f"{target}: cannot write here ({exc.strerror}); choose another --out") from exc
    path = _lock_file(target)
    while True:
        try:
            fd = os.open(path, os.O_RDWR | os.O_CREAT, 0o644)
        except OSError as exc:
            raise ExportError(f"{target}: cannot write here ({exc.strerror}); choose another --out") from exc
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            try:
                held = json.loads(os.read(fd, 4096).decode("utf-8"))
                who = (f"process {int(held['pid'])}, twinreg {str(held['command'])[:40]}, started "
                       f"{str(held['started'])[:19]}")
            except (OSError, ValueError, KeyError, TypeError):
                who = "another process"
            os.close(fd)
            raise ExportError(f"{target}: another twinreg run is writing this folder ({who}); wait for it to end or "
                              "choose another --out") from None
        try:
            same = os.fstat(fd).st_ino == os.stat(path).st_ino
        except FileNotFoundError:
            same = False
        if same:
            break
        os.close(fd)  # the file was removed by the run that held it: lock the new one
    try:
        os.ftruncate(fd, 0)
        os.write(fd, json.dumps({"pid": os.getpid(), "command": command,
                                 "started": datetime.datetime.now().isoformat(timespec="seconds")}).encode())
        yield target
    finally:
        try:
            os.unlink(path)
        except OSError:
            pass
        os.close(fd)
