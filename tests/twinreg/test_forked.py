"""A call run in a forked child (twinreg/process/helpers.py ``Forked``: a city's JSON formats beside its KMZ,
report and tiles) gives its value; a child that fails, dies or overruns its time is stopped and the call runs in
this process, once, with the same result; no child is left behind."""

from __future__ import annotations

import os
import time
from pathlib import Path

import psutil

from twinreg.process.helpers import Forked


def _write(path: str, text: str, pause: float = 0.0, parent: int = 0) -> int:
    if os.getpid() != parent:  # only the child is slow
        time.sleep(pause)
    Path(path).write_text(f"{text} by {os.getpid()}")
    return os.getpid()


def _fail(path: str) -> int:
    if os.getpid() != int(Path(path).read_text()):
        raise RuntimeError("not in this process")
    return os.getpid()


def _gone(pid: int) -> bool:
    return pid not in {c.pid for c in psutil.Process().children(recursive=True)}


def test_the_child_writes_and_its_value_comes_back(tmp_path):
    f = Forked(_write, str(tmp_path / "a.txt"), "hello")
    child = f.pid
    pid = f.wait(30)
    assert pid == child != os.getpid() and (tmp_path / "a.txt").read_text() == f"hello by {pid}"
    assert _gone(child)


def test_a_failing_dead_or_late_child_is_replaced_by_this_process(tmp_path):
    (tmp_path / "me").write_text(str(os.getpid()))
    assert Forked(_fail, str(tmp_path / "me")).wait(30) == os.getpid()  # failed in the child: run here
    late = Forked(_write, str(tmp_path / "b.txt"), "late", 30.0, os.getpid())
    slow = late.pid
    t = time.monotonic()
    assert late.wait(0.5) == os.getpid() and time.monotonic() - t < 10
    assert (tmp_path / "b.txt").read_text() == f"late by {os.getpid()}" and _gone(slow)
    dead = Forked(_write, str(tmp_path / "c.txt"), "dead", 30.0, os.getpid())
    child = psutil.Process(dead.pid)
    child.kill()
    child.wait(10)
    assert dead.wait(30) == os.getpid() and (tmp_path / "c.txt").read_text() == f"dead by {os.getpid()}"


def _frozen() -> int:
    import gc

    return gc.get_freeze_count()


def test_the_child_leaves_the_inherited_objects_to_the_parent_and_the_parent_unfreezes():
    # the child's collector skips what it inherited (no copy of the shared pages); the parent collects as before
    import gc

    before = gc.get_freeze_count()
    f = Forked(_frozen)
    child = f.pid
    inherited = f.wait(30)
    assert child is not None and inherited > 1000
    assert gc.get_freeze_count() == before == 0
