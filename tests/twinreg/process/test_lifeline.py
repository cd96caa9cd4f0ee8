"""A child that carries the lifeline ends when its parent dies, even while its main thread is stuck."""

from __future__ import annotations

import signal
import subprocess
import sys

import psutil


def test_a_child_ends_with_its_killed_parent():
    child = ("import os, re, sys\nfrom twinreg.process.lifeline import dask_setup\n"
             "dask_setup()\nprint(os.getpid(), flush=True)\n"
             "re.match(r'(a+)+$', 'a' * 60 + 'b')  # hours in compiled code holding the interpreter\n")
    parent = ("import subprocess, sys, time\n"
              f"p = subprocess.Popen([sys.executable, '-c', {child!r}], stdout=sys.stdout)\n"
              "time.sleep(120)\n")
    proc = subprocess.Popen([sys.executable, "-c", parent], stdout=subprocess.PIPE, text=True)
    kid = None
    try:
        kid = psutil.Process(int(proc.stdout.readline()))
        proc.send_signal(signal.SIGKILL)
        proc.wait(10)
        _, alive = psutil.wait_procs([kid], timeout=10)
        assert not alive
    finally:
        proc.kill()
        if kid is not None and kid.is_running():
            kid.kill()
