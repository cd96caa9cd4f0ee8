"""The arrays of an open npz file, read quickly and as data.

numpy's reader opens each member through :mod:`zipfile` and parses each array's header with ``ast.literal_eval``:
about 150 microseconds an array, 5 s for the 39,000 arrays of a 100M-point city's cell files. ``np.savez`` stores
its members uncompressed, each a .npy file whose header numpy writes in one fixed form; such members are read
here straight into their arrays' buffers, their CRCs checked, their headers matched by a strict pattern and every
size checked against the zip's directory. Any other member (compressed, a header in another form, an object
array) goes to numpy's own reader with ``allow_pickle=False``: either way a file runs no code and gives the arrays
numpy would.
"""

from __future__ import annotations

import math
import re
import struct
import zipfile
import zlib

import numpy as np

#: the header numpy writes for a plain array (bool, integers, floats): descr, fortran_order, shape, then padding
_HEADER = re.compile(rb"\{'descr': '([<>|][biuf][1248])', 'fortran_order': (False|True), "
                     rb"'shape': \(((?:\d+, )*(?:\d+,?)?)\), \} *\n")


def read_arrays(zf: zipfile.ZipFile, names) -> dict:
    """``{name: array}`` of the npz members ``name + ".npy"`` of ``zf`` (an open npz: ``np.load(...).zip``);
    a KeyError for a name the file does not hold."""
    infos = {name: zf.getinfo(f"{name}.npy") for name in names}
    out = {}
    for name, info in infos.items():
        a = read_member(zf.fp, info)
        out[name] = a if a is not None else _numpy_read(zf, info)
    return out


def _numpy_read(zf: zipfile.ZipFile, info: zipfile.ZipInfo) -> np.ndarray:
    with zf.open(info) as fh:
        return np.lib.format.read_array(fh, allow_pickle=False)


def read_member(fh, info: zipfile.ZipInfo) -> np.ndarray | None:
    """The array of the npz member ``info`` (from the zip's directory) read from the open file ``fh`` into its own
    buffer, or None where numpy's reader should read it (its CRC checked as zipfile checks it: a damaged member is
    numpy's to refuse)."""
    if info.compress_type != zipfile.ZIP_STORED or info.flag_bits & 0x1 or info.compress_size != info.file_size:
        return None
    try:
        fh.seek(info.header_offset)
        local = fh.read(30)
        if len(local) != 30 or local[:4] != b"PK\x03\x04":
            return None
        name_len, extra_len = struct.unpack("<HH", local[26:30])
        fh.seek(info.header_offset + 30 + name_len + extra_len)
        buf = bytearray(info.file_size)
        if fh.readinto(buf) != len(buf) or zlib.crc32(buf) != info.CRC:
            return None
    except (AttributeError, OSError, ValueError):  # not a seekable file
        return None
    if buf[:6] != b"\x93NUMPY":
        return None
    if buf[6] == 1:
        (size,), head = struct.unpack("<H", buf[8:10]), 10
    elif buf[6] in (2, 3):
        (size,), head = struct.unpack("<I", buf[8:12]), 12
    else:
        return None
    m = _HEADER.fullmatch(buf, head, head + size)
    if m is None:
        return None
    dtype = np.dtype(m.group(1).decode("ascii"))
    shape = tuple(int(x) for x in m.group(3).replace(b" ", b"").split(b",") if x)
    count = math.prod(shape)
    if head + size + count * dtype.itemsize != len(buf):
        return None
    a = np.frombuffer(buf, dtype=dtype, count=count, offset=head + size)
    return a.reshape(shape[::-1]).T if m.group(2) == b"True" else a.reshape(shape)


def member_shapes(zf: zipfile.ZipFile, max_members: int = 4096) -> dict:
    """``{name: (dtype, shape)}`` of every ``.npy`` member of an open npz, read from the members' headers alone
    (the first bytes of each, decompressed no further), so that a caller can sum what the arrays would take
    before reading any. A member that is not a plain ``.npy`` array, a file of more than ``max_members``
    members, or a header numpy cannot parse raises ``ValueError``."""
    infos = zf.infolist()
    if len(infos) > max_members:
        raise ValueError(f"it holds {len(infos)} members (at most {max_members})")
    out = {}
    for info in infos:
        if not info.filename.endswith(".npy"):
            raise ValueError(f"its member {info.filename[:60]!r} is not an array")
        with zf.open(info) as fh:
            version = np.lib.format.read_magic(fh)
            if version == (1, 0):
                shape, fortran, dtype = np.lib.format.read_array_header_1_0(fh)
            elif version in ((2, 0), (3, 0)):
                shape, fortran, dtype = np.lib.format.read_array_header_2_0(fh)
            else:
                raise ValueError(f"its member {info.filename[:60]!r} has an unknown array version")
        if dtype.hasobject:
            raise ValueError(f"its member {info.filename[:60]!r} holds Python objects")
        out[info.filename[:-4]] = (dtype, tuple(int(s) for s in shape))
    return out


def nbytes(shapes: dict) -> int:
    """What the arrays of :func:`member_shapes` take in memory (bytes).

    >>> nbytes({"a": (np.dtype("f8"), (10, 3)), "b": (np.dtype("u1"), (4,))})
    244
    """
    return sum(math.prod(shape) * dtype.itemsize for dtype, shape in shapes.values())
