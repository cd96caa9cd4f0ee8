"""The compiled kernels' cache holds pickles, and loading a pickle runs code: a cache another user could write into
is never read (a payload planted there does not run, through the real command line), a corrupt one is dropped and
compiled anew, a read-only one never sends numba to write beside the installed code."""

from __future__ import annotations

import os
import pickle
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("numba")

import cosco
from tests.conftest import write_las

TWINREG = str(Path(sys.executable).with_name("twinreg"))
ENABLE = "import cosco.kernels as k; k.enable(); print(k.trusted_cache_dir())"


class _Payload:
    """Unpickled, it creates its marker file: what a planted cache index would do."""

    def __init__(self, marker: Path):
        self.marker = str(marker)

    def __reduce__(self):
        return (open, (self.marker, "w"))


def _env(cache_home: Path) -> dict:
    env = {k: v for k, v in os.environ.items() if k not in ("NUMBA_CACHE_DIR", "TWINREG_JIT", "TWINREG_NO_NUMBA")}
    return env | {"XDG_CACHE_HOME": str(cache_home)}


CHOSEN = "import cosco.kernels as k; print(k.trusted_cache_dir())"  # the folder taken, nothing compiled
#: one kernel compiled (or loaded from the cache) through its entry, as a run calls it: what the cache folder decides
#: holds for every kernel alike, in seconds rather than the minute of compiling them all
ONE = ("import os; os.environ['TWINREG_JIT'] = '1'; import numpy as np, cosco.kernels as k, cosco.footprint as f; "
       "f.min_area_rectangle(*f._example(np.random.default_rng(0))); print(k.trusted_cache_dir(), k.in_use())")


@pytest.fixture(scope="module")
def compiled(tmp_path_factory) -> Path:
    """A cache compiled for real once (its ``twinreg/numba`` folder under a base of mode 700)."""
    base = tmp_path_factory.mktemp("compiled")
    os.chmod(base, 0o700)
    out = subprocess.run([sys.executable, "-c", ENABLE], env=_env(base), capture_output=True, text=True, check=True)
    folder = Path(out.stdout.strip())
    assert folder == base / "twinreg" / "numba" and any(folder.rglob("*.nbi"))
    return folder


def _copy(compiled: Path, base: Path) -> Path:
    """The compiled cache copied under ``base`` (mode 700), as if compiled there; its folder."""
    base.mkdir(mode=0o700)
    (base / "twinreg").mkdir(mode=0o700)
    shutil.copytree(compiled, base / "twinreg" / "numba")
    return base / "twinreg" / "numba"


def _plant(folder: Path, marker: Path) -> int:
    """Every index file of the cache replaced by a payload; how many."""
    files = list(folder.rglob("*.nbi"))
    for f in files:
        f.write_bytes(pickle.dumps(_Payload(marker)))
    return len(files)


@pytest.fixture(scope="module")
def tiny_tile(tmp_path_factory) -> Path:
    """One LAZ tile of a car-sized block on flat ground (RD New)."""
    rng = np.random.default_rng(0)
    pts = np.vstack([rng.uniform([0, 0, 0], [60, 60, 0.05], (20000, 3)),
                     rng.uniform([20, 20, 0], [24.2, 21.8, 1.5], (3000, 3))]) + [155000, 463000, 0]
    tile = tmp_path_factory.mktemp("tiny_city") / "a.laz"
    write_las(tile, pts, crs="EPSG:28992")
    return tile


def _build(scan: Path, library: Path, out: Path, env: dict) -> subprocess.CompletedProcess:
    """build-twin with the kernels on (``TWINREG_JIT=1``: a scene's run compiles, or loads, those it calls; a
    city's engine loads them all through the same :func:`cosco.kernels.trusted_cache_dir` before its workers
    start, a minute of compiling here when the cache is refused)."""
    return subprocess.run([TWINREG, "--library", str(library), "build-twin", str(scan), "--out", str(out)],
                          env=env | {"TWINREG_JIT": "1"}, capture_output=True, text=True, timeout=600)


def test_a_planted_cache_runs_no_code_in_a_build(tmp_path, tiny_tile, parametric_catalogue, compiled):
    base = tmp_path / "cache"
    folder = _copy(compiled, base)
    marker = tmp_path / "payload-ran"
    assert _plant(folder, marker) > 10
    os.chmod(base, 0o777)  # any local user could have written the payload
    res = _build(tiny_tile, parametric_catalogue.folder, tmp_path / "out", _env(base))
    assert res.returncode == 0, res.stderr
    assert not marker.exists()
    assert "not using the kernel cache" in res.stderr and "writable by other users (mode 777)" in res.stderr
    assert (tmp_path / "out" / "twin.json").is_file()
    # the control: the same planted files in a folder that is the user's own are read (so the test can fail); one
    # kernel's index is enough to run the payload
    os.chmod(base, 0o700)
    subprocess.run([sys.executable, "-c", ONE], env=_env(base), capture_output=True, text=True)
    assert marker.exists()


def test_a_corrupt_cache_is_dropped_and_compiled_anew(tmp_path, compiled):
    base = tmp_path / "cache"
    folder = _copy(compiled, base)
    for f in list(folder.rglob("*.nbi"))[:3]:
        f.write_bytes(b"\x00garbage")
    res = subprocess.run([sys.executable, "-c", ENABLE], env=_env(base), capture_output=True, text=True)
    assert res.returncode == 0, res.stderr
    assert "could not be read" in res.stderr and "compiling anew" in res.stderr
    assert not any(f.read_bytes().startswith(b"\x00garbage") for f in folder.rglob("*.nbi"))  # dropped


@pytest.mark.skipif(os.geteuid() != 0, reason="making a folder of another user needs root")
def test_a_folder_of_another_user_or_behind_a_link_is_not_used(tmp_path, compiled):
    base = tmp_path / "cache"
    folder = _copy(compiled, base)
    marker = tmp_path / "payload-ran"
    _plant(folder, marker)
    for path in [folder, *folder.rglob("*")]:
        os.chown(path, 65534, 65534)  # nobody's folder, mode 700: not writable by us, but theirs
    out = subprocess.run([sys.executable, "-c", CHOSEN], env=_env(base), capture_output=True, text=True, check=True)
    assert Path(out.stdout.strip()) != folder and "belongs to another user (uid 65534)" in out.stderr
    assert not marker.exists()
    # ~/.cache/twinreg/numba a symlink to a folder another user can write to
    shared = tmp_path / "shared"
    shutil.copytree(folder, shared)
    os.chmod(shared, 0o777)
    home = tmp_path / "home"
    (home / "twinreg").mkdir(parents=True, mode=0o700)
    os.chmod(home, 0o700)
    (home / "twinreg" / "numba").symlink_to(shared)
    out = subprocess.run([sys.executable, "-c", CHOSEN], env=_env(home), capture_output=True, text=True, check=True)
    assert Path(out.stdout.strip()) != home / "twinreg" / "numba" and "not using the kernel cache" in out.stderr
    assert not marker.exists()


def test_a_read_only_cache_never_writes_beside_the_code(tmp_path):
    """A cache folder that cannot be made: the kernels are still compiled, for the process alone, and nothing is
    written beside the code (one kernel compiled: numba's cache folder is one setting for them all)."""
    base = tmp_path / "cache"
    base.mkdir(mode=0o700)
    (base / "twinreg").mkdir(mode=0o500)
    package = Path(cosco.__file__).parent
    before = set(package.rglob("*.nbi"))
    out = subprocess.run([sys.executable, "-c", ONE], env=_env(base), capture_output=True, text=True, check=True)
    where, used = out.stdout.split()
    assert not Path(where).is_relative_to(package) and used == "True"
    assert set(package.rglob("*.nbi")) == before


def test_the_switches_read_their_values():
    """TWINREG_NO_NUMBA=0 leaves numba on, TWINREG_JIT=0 does not turn it on."""
    code = "import cosco.kernels as k; print(k.in_use())"
    env = {k: v for k, v in os.environ.items() if k not in ("TWINREG_JIT", "TWINREG_NO_NUMBA")}
    for extra, want in (({"TWINREG_JIT": "0"}, "False"), ({"TWINREG_JIT": "1", "TWINREG_NO_NUMBA": "0"}, "True"),
                        ({"TWINREG_JIT": "yes", "TWINREG_NO_NUMBA": "1"}, "False")):
        out = subprocess.run([sys.executable, "-c", code], env=env | extra, capture_output=True, text=True, check=True)
        assert out.stdout.strip() == want, extra


def test_a_second_run_waits_for_the_one_compiling(tmp_path, compiled):
    """Two runs on one cache: while one holds it (compiling or loading), the other waits, then loads what it
    wrote (two numba processes writing one cache at once is a known crash)."""
    import fcntl
    import time

    base = tmp_path / "cache"
    folder = _copy(compiled, base)
    t = time.monotonic()
    subprocess.run([sys.executable, "-c", ENABLE], env=_env(base), capture_output=True, text=True, check=True)
    alone = time.monotonic() - t  # loading the compiled kernels with no one else there
    with open(folder / ".lock", "a") as held:
        fcntl.flock(held, fcntl.LOCK_EX)  # another run compiling
        waiting = subprocess.Popen([sys.executable, "-c", ENABLE], env=_env(base), stdout=subprocess.PIPE,
                                   stderr=subprocess.PIPE, text=True)
        try:
            time.sleep(max(3 * alone, 5.0))
            assert waiting.poll() is None  # still waiting for the lock
        finally:
            fcntl.flock(held, fcntl.LOCK_UN)
    out, err = waiting.communicate(timeout=120)
    assert waiting.returncode == 0, err
    assert Path(out.strip()) == folder and "compiling anew" not in err
