"""Where compiled kernels may be cached: only a folder that no one but this user (or root) can write to.

numba's cache holds pickles, and loading a pickle runs code: a cache folder another user could write into (a shared
``XDG_CACHE_HOME`` or ``NUMBA_CACHE_DIR``, ``HOME=/tmp``, a symlink planted on the way) would let them run code as
whoever builds a twin. :func:`cache_folder` takes the folder asked for only when it and every folder above it are
owned by this user or root, not writable by group or others (a root-owned sticky folder such as ``/tmp`` may sit
above it: no one can rename or replace what another user put there), with no symlink of anyone but root on the way,
and writable; the folders it makes are 0700. Otherwise the kernels compile into a private temporary folder of this
process (made 0700 by :func:`tempfile.mkdtemp`, removed at exit), and the reason is said once on stderr.

    >>> import os, tempfile
    >>> base = tempfile.mkdtemp()
    >>> untrusted_reason(os.path.join(base, "twinreg", "numba")) is None
    True
    >>> os.chmod(base, 0o777); untrusted_reason(os.path.join(base, "twinreg", "numba"))[-37:]
    'is writable by other users (mode 777)'
"""

from __future__ import annotations

import os
import stat
import sys
from pathlib import Path

_WRITE_OTHERS = stat.S_IWGRP | stat.S_IWOTH


def _unsafe(current: Path, st: os.stat_result, last: bool) -> str | None:
    """Why one folder on the way to the cache (``last``: the cache itself) lets another user in, or None: the one
    rule both walks apply (:func:`untrusted_reason`, :func:`_untrusted_chain`)."""
    if not stat.S_ISDIR(st.st_mode):
        return f"{current} is not a folder"
    if st.st_uid not in (os.geteuid(), 0):
        return f"{current} belongs to another user (uid {st.st_uid})"
    if st.st_mode & _WRITE_OTHERS and not (st.st_uid == 0 and st.st_mode & stat.S_ISVTX and not last):
        return f"{current} is writable by other users (mode {stat.S_IMODE(st.st_mode):o})"
    return None


def _link_problem(current: Path, st: os.stat_result) -> str | None:
    return (f"{current} is a symlink (the cache folder is taken only without links on the way)"
            if st.st_uid != 0 else None)


def untrusted_reason(folder) -> str | None:
    """Why ``folder`` cannot hold this user's compiled code, or None when it can (made, 0700, where missing)."""
    path = Path(os.path.abspath(os.fspath(folder)))
    me = os.geteuid()
    parts = path.parts
    current = Path(parts[0])
    for i, part in enumerate(parts[1:], start=1):
        current = current / part
        last = i == len(parts) - 1
        try:
            st = os.lstat(current)
        except FileNotFoundError:
            try:
                os.mkdir(current, 0o700)
            except OSError as exc:
                return f"{current} cannot be made ({exc.strerror or exc})"
            st = os.lstat(current)
        except OSError as exc:
            return f"{current} cannot be read ({exc.strerror or exc})"
        if stat.S_ISLNK(st.st_mode):
            target = os.path.realpath(current)
            why = _link_problem(current, st) or (untrusted_reason(target) if last else
                                                 _untrusted_chain(Path(target)))
        else:
            why = _unsafe(current, st, last)
        if why:
            return why
    st = os.stat(path)
    if st.st_uid != me:
        return f"{path} belongs to another user (uid {st.st_uid})"
    if stat.S_IMODE(st.st_mode) & 0o077:
        try:
            os.chmod(path, 0o700)
        except OSError as exc:
            return f"{path} cannot be made private ({exc.strerror or exc})"
    if not os.access(path, os.W_OK | os.X_OK):
        return f"{path} is not writable"
    return None


def _untrusted_chain(target: Path) -> str | None:
    """Why an existing folder a root symlink points to is not safe above the cache (its chain checked alike)."""
    current = Path(target.parts[0])
    for part in target.parts[1:]:
        current = current / part
        try:
            st = os.lstat(current)
        except OSError as exc:
            return f"{current} cannot be read ({exc.strerror or exc})"
        why = _link_problem(current, st) if stat.S_ISLNK(st.st_mode) else _unsafe(current, st, last=False)
        if why:
            return why
    return None


def private_folder() -> Path:
    """A folder of this process's own (0700, removed at exit)."""
    import atexit
    import shutil
    import tempfile

    folder = tempfile.mkdtemp(prefix="twinreg-numba-")
    owner = os.getpid()
    atexit.register(lambda: os.getpid() == owner and shutil.rmtree(folder, ignore_errors=True))
    return Path(folder)


def cache_folder(wanted) -> Path:
    """``wanted`` when it is safe (:func:`untrusted_reason`), else a private folder, the reason said on stderr."""
    why = untrusted_reason(wanted)
    if why is None:
        return Path(os.path.abspath(os.fspath(wanted)))
    sys.stderr.write(f"twinreg: not using the kernel cache {wanted}: {why}; compiling into a private temporary "
                     "folder (set NUMBA_CACHE_DIR to a folder of your own, mode 700)\n")
    return private_folder()


def clear(folder: Path) -> None:
    """Empty a cache folder of ours (a corrupt cache file is dropped, the kernels compiled anew)."""
    import shutil

    for child in Path(folder).iterdir():
        if child.name == ".lock":  # held by this process while it compiles (kernels._one_writer)
            continue
        if child.is_dir() and not child.is_symlink():
            shutil.rmtree(child, ignore_errors=True)
        else:
            child.unlink(missing_ok=True)
