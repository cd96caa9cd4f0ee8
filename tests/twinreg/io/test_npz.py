"""An npz's arrays read from the mapped file (twinreg/io/npz.py) are numpy's, array for array: dtype, shape,
order, bytes, writable; members numpy's reader must read (compressed, other headers, objects) go to it, and an
object array is refused as numpy refuses it."""

from __future__ import annotations

import numpy as np
import pytest

from twinreg.io.npz import read_arrays


def _arrays():
    rng = np.random.default_rng(3)
    return {"f8": rng.normal(size=(7, 3)), "fortran": np.asfortranarray(rng.normal(size=(4, 5))),
            "scalar": np.array(2.5), "empty": np.zeros((0, 3)), "flags": rng.random(9) > 0.5,
            "ints": rng.integers(-5, 5, size=(2, 3, 4)).astype(np.int32), "bytes": np.arange(10, dtype=np.uint8),
            "big_endian": np.arange(6, dtype=">f4"), "f4": rng.normal(size=5).astype(np.float32),
            "text": np.array(["a", "bc"]), "complex": np.array([1 + 2j])}


@pytest.mark.parametrize("compressed", [False, True])
def test_every_array_comes_back_as_numpy_reads_it(tmp_path, compressed, monkeypatch):
    import twinreg.io.npz as npz

    path = tmp_path / "a.npz"
    (np.savez_compressed if compressed else np.savez)(path, **_arrays())
    by_numpy = []
    numpy_read = npz._numpy_read
    monkeypatch.setattr(npz, "_numpy_read", lambda zf, info: by_numpy.append(info.filename) or numpy_read(zf, info))
    with np.load(path, allow_pickle=False) as z:
        ref = {k: z[k] for k in z.files}
        got = read_arrays(z.zip, z.files)
    assert set(got) == set(ref)
    # numpy reads what is compressed, and the strings and complex numbers; the plain arrays are read here
    assert sorted(by_numpy) == (sorted(f"{k}.npy" for k in ref) if compressed else ["complex.npy", "text.npy"])
    for k, a in ref.items():
        b = got[k]
        assert b.dtype == a.dtype and b.shape == a.shape and b.tobytes(order="A") == a.tobytes(order="A"), k
        assert b.flags.f_contiguous == a.flags.f_contiguous and b.flags.writeable, k
        assert np.array_equal(a, b), k
    with np.load(path) as z, pytest.raises(KeyError):
        read_arrays(z.zip, ["missing"])


def test_an_object_array_is_refused_and_never_unpickled(tmp_path):
    path = tmp_path / "o.npz"
    np.savez(path, good=np.ones(3), bad=np.array([{"x": 1}], dtype=object))
    with np.load(path, allow_pickle=False) as z:
        assert np.array_equal(read_arrays(z.zip, ["good"])["good"], np.ones(3))
        with pytest.raises(ValueError):
            read_arrays(z.zip, ["bad"])


def test_damaged_members_go_to_numpy_which_refuses_them(tmp_path):
    """A member whose bytes fail their CRC, and one whose header promises more data than the zip holds, are left
    to numpy's reader, which refuses both (nothing is read past a member's end)."""
    import io
    import zipfile

    path = tmp_path / "s.npz"
    np.savez(path, a=np.arange(100.0))
    data = bytearray(path.read_bytes())
    at = data.find(b"'shape': (100,)")
    data[at:at + 15] = b"'shape': (900,)"
    path.write_bytes(bytes(data))
    with np.load(path, allow_pickle=False) as z, pytest.raises(zipfile.BadZipFile):
        read_arrays(z.zip, ["a"])
    npy = io.BytesIO()
    np.save(npy, np.arange(100.0))
    long = npy.getvalue().replace(b"'shape': (100,)", b"'shape': (900,)")
    with zipfile.ZipFile(path, "w") as out:
        out.writestr("a.npy", long)
    with np.load(path, allow_pickle=False) as z, pytest.raises(ValueError):
        read_arrays(z.zip, ["a"])
