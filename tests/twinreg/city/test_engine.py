"""The Dask engine: a task that fails once is retried, one that fails twice is reported by name while the others
finish; a tile that breaks some cells leaves the other cells stored, and the next run computes only those."""

from __future__ import annotations

import shutil

import pytest


def test_a_task_failing_twice_is_reported_by_name_while_the_others_finish(tmp_path):
    from twinreg.city.engine import Engine

    marks = str(tmp_path)

    def flaky(job):
        import os

        attempt = len([f for f in os.listdir(marks) if f.startswith(f"{job}-")])
        open(os.path.join(marks, f"{job}-{attempt}"), "w").close()
        if job == 3 or (job == 2 and attempt == 0):
            raise ValueError(f"bad job {job}")
        return job * 10

    got = {}
    with Engine(workers=2) as eng:
        failures = eng.run(flaky, [1, 2, 3, 4, 5], ["j1", "j2", "j3", "j4", "j5"],
                           on_result=lambda name, r: got.__setitem__(name, r))
    assert got == {"j1": 10, "j2": 20, "j4": 40, "j5": 50}
    assert [f.name for f in failures] == ["j3"] and "bad job 3" in failures[0].error
    attempts = sorted(p.name for p in tmp_path.iterdir())
    assert attempts.count("3-0") == 1 and "3-1" in attempts and "2-1" in attempts and "1-1" not in attempts


def test_embedded_workers_start_with_the_allocator_settings():
    """The workers' C library reads MALLOC_* when the process starts: they must be in its environment then."""
    from twinreg.city.engine import Engine
    from twinreg.memory import WORKER_ENV

    def environ(_):
        import os

        return {k: os.environ.get(k) for k in WORKER_ENV}

    with Engine(workers=1) as eng:
        assert eng.map(environ, [0], ["env"]) == [WORKER_ENV]


def test_a_broken_tile_fails_its_cells_only_and_a_rerun_resumes(tmp_path, parametric_catalogue):
    from tests.conftest import CELL
    from twinreg.city.build import build_city_twin
    from twinreg.errors import CityError, SceneReadError
    from twinreg.sim.city import simulate_city

    cat = parametric_catalogue
    rows = sorted(cat.list(), key=lambda r: r.name)
    truth = simulate_city(tmp_path / "copc", [cat.ge_mesh(r) for r in rows], [r.name for r in rows], km2=0.0256,
                          density=25.0, tile=40.0, seed=5, copc=True)  # 4 x 4 tiles: cells far from a tile do not read it
    victim = tmp_path / "copc" / truth["tiles"][3]
    good = victim.read_bytes()
    out = tmp_path / "out"
    # truncated: laspy would read it as empty; refused upfront, naming it, and nothing is written
    victim.write_bytes(good[: len(good) // 2])
    with pytest.raises(SceneReadError, match=f"{victim.name}: a COPC file without its octree hierarchy"):
        build_city_twin([tmp_path / "copc"], cat, None, out, cell=CELL, workers=2)
    assert not out.exists()
    # damaged in the middle: the header and the hierarchy read, some octree nodes do not decompress
    bad = bytearray(good)
    bad[len(bad) * 3 // 10: len(bad) * 6 // 10] = bytes(len(bad) * 6 // 10 - len(bad) * 3 // 10)
    victim.write_bytes(bytes(bad))
    with pytest.raises(CityError, match=r"cells failed twice: c\d+_\d+ \(") as err:
        build_city_twin([tmp_path / "copc"], cat, None, out, cell=CELL, workers=2)
    assert "rerun the same command" in str(err.value)
    stored = list((out / ".cells").glob("*.npz"))
    assert stored and not (out / "twin.json").exists()
    victim.write_bytes(good)
    twin = build_city_twin([tmp_path / "copc"], cat, None, out, cell=CELL, workers=2)
    # the file changed (size, time): only the cells it feeds were computed again
    assert 0 < twin["grid"]["n_cells_reused"] < twin["grid"]["n_cells"]
    assert len(twin["objects"]) == len(truth["cars"])
    shutil.rmtree(out)


def test_the_embedded_cluster_refuses_every_other_process():
    """The scheduler of a city run speaks TLS with this run's temporary credentials: a local process that tries
    plain TCP, TLS without them, or TLS with credentials of its own cannot connect, so it cannot submit work."""
    import subprocess
    import sys
    import textwrap

    from twinreg.city.engine import Engine

    with Engine(workers=1) as eng:
        addr = eng.client.scheduler.address
        assert addr.startswith("tls://127.0.0.1:")
        code = textwrap.dedent(f"""
            from distributed import Client
            from distributed.security import Security
            for addr, sec in (({addr!r}, None), ({addr.replace('tls://', 'tcp://')!r}, None),
                              ({addr!r}, Security.temporary())):
                try:
                    c = Client(addr, timeout="5s", security=sec)
                    print("CONNECTED", c.run(lambda: __import__("os").getpid()))
                except Exception as e:
                    print("REFUSED", type(e).__name__)
            """)
        proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
        lines = proc.stdout.split("\n")
        assert [ln.split()[0] for ln in lines if ln] == ["REFUSED"] * 3, proc.stdout + proc.stderr
        assert eng.map(abs, [-3], ["ok"]) == [3]  # the run's own client still works


def test_workers_leave_when_the_run_is_killed(tmp_path):
    """kill -9 of the process running an embedded cluster while its workers are stuck in compiled code that holds
    the interpreter (as a reader looping over a planted file would be): the worker processes are gone within
    seconds (Dask's own watch of the parent is a thread, which cannot run then)."""
    import signal
    import subprocess
    import sys

    import psutil

    script = ("import time\nfrom twinreg.city.engine import Engine\n"
              "def busy(k):\n"
              "    import re\n"
              "    re.match(r'(a+)+$', 'a' * 60 + 'b')  # hours in compiled code that holds the interpreter\n"
              "with Engine(workers=2) as eng:\n"
              "    futures = [eng.client.submit(busy, k, pure=False) for k in range(2)]\n"
              "    time.sleep(3)\n"
              "    print(eng.n_workers, flush=True)\n"
              "    time.sleep(120)\n")
    proc = subprocess.Popen([sys.executable, "-c", script], stdout=subprocess.PIPE, text=True)
    try:
        assert proc.stdout.readline().strip() == "2"
        children = psutil.Process(proc.pid).children(recursive=True)
        assert len(children) >= 2
        proc.send_signal(signal.SIGKILL)
        proc.wait(10)
        _, alive = psutil.wait_procs(children, timeout=10)
        assert not alive, [p.cmdline()[:3] for p in alive]
    finally:
        proc.kill()


def test_workers_that_cannot_load_a_task_stop_the_run_with_a_clear_error(tmp_path):
    """A task whose module the workers cannot import (a module cycle, another twinreg or a missing package where
    they run) once left its run waiting forever: the worker cannot unpickle it and drops its link to the
    scheduler. The engine asks every worker to load the function by name first and stops at once, saying what."""
    import subprocess
    import sys
    import time

    (tmp_path / "only_here.py").write_text(
        "import os\n"
        "if os.environ.get('ONLY_HERE') != str(os.getpid()):\n"
        "    raise ImportError('only_here: importable in its parent only')\n"
        "def work(job):\n"
        "    return job * 2\n")
    script = ("import os, sys\n"
              f"sys.path.insert(0, {str(tmp_path)!r})\n"
              "from twinreg.city.engine import Engine\n"
              "from twinreg.errors import EngineError\n"
              "if __name__ == '__main__':\n"
              "    os.environ['ONLY_HERE'] = str(os.getpid())\n"
              "    import only_here\n"
              "    with Engine(workers=2) as eng:\n"
              "        assert eng.map(abs, [-3], ['ok']) == [3]\n"
              "        try:\n"
              "            eng.run(only_here.work, [1, 2], ['a', 'b'])\n"
              "        except EngineError as exc:\n"
              "            print(exc)\n")
    path = tmp_path / "run.py"
    path.write_text(script)
    t = time.monotonic()
    res = subprocess.run([sys.executable, str(path)], capture_output=True, text=True, timeout=300)
    assert res.returncode == 0, res.stderr[-2000:]
    assert "cannot load only_here.work (ImportError: only_here: importable in its parent only)" in res.stdout
    assert time.monotonic() - t < 60
