"""Sorting integer keys fast: the stages group millions of points by a cell or label key.

``np.sort`` of int64 runs on the CPU's vector units (several times faster than ``argsort`` and 20-30x faster than
``lexsort`` on 5M keys), so a key packed with what else the sort must carry (the point's position, or a value
quantised to an integer) is sorted by value and unpacked, whenever the two fit in 63 bits together.
"""

from __future__ import annotations

import numpy as np


def _bits(n: int) -> int:
    return max(int(n).bit_length(), 1)


def stable_argsort(keys) -> np.ndarray:
    """The permutation that sorts non-negative integer ``keys`` (n,), equal keys in their original order (as
    ``np.argsort(keys, kind="stable")``), from one sort of the keys packed with their positions.

    >>> stable_argsort(np.array([3, 1, 3, 0, 1])).tolist()
    [3, 1, 4, 0, 2]
    """
    keys = np.asarray(keys)
    n = len(keys)
    if n == 0:
        return np.zeros(0, dtype=np.int64)
    top = int(keys.max())
    b = _bits(n)
    if int(keys.min()) < 0 or _bits(top) + b > 63:
        return np.argsort(keys, kind="stable")
    packed = keys.astype(np.int64) << b
    packed |= np.arange(n, dtype=np.int64)
    packed.sort()
    packed &= (1 << b) - 1
    return packed


def group_by_key(keys) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Groups of equal non-negative integer ``keys`` (n,): ``(order, distinct keys, starts)``, where ``order`` is
    :func:`stable_argsort` and the group of ``distinct[k]`` is ``order[starts[k]:starts[k + 1]]``.

    >>> order, distinct, starts = group_by_key(np.array([3, 1, 3, 0, 1]))
    >>> order.tolist(), distinct.tolist(), starts.tolist()
    ([3, 1, 4, 0, 2], [0, 1, 3], [0, 1, 3])
    """
    keys = np.asarray(keys)
    order = stable_argsort(keys)
    if not len(order):
        return order, np.zeros(0, dtype=np.int64), np.zeros(0, dtype=np.int64)
    ordered = keys[order]
    starts = np.flatnonzero(np.r_[True, ordered[1:] != ordered[:-1]])
    return order, ordered[starts].astype(np.int64), starts


def group_medians(keys, values, resolution: float = 1e-6) -> tuple[np.ndarray, np.ndarray]:
    """The distinct non-negative integer ``keys`` (sorted) and the median of ``values`` (float) in each group: the
    mean of the two middle values for an even count. Values are sorted as integers of ``resolution`` (their medians
    are exact to half of it); a range too wide for that falls back to a two-key sort.

    >>> k, m = group_medians(np.array([5, 2, 5, 5, 2]), np.array([1.0, 4.0, 3.0, 2.0, 6.0]))
    >>> k.tolist(), np.round(m, 6).tolist()
    ([2, 5], [5.0, 2.0])
    """
    keys = np.asarray(keys, dtype=np.int64)
    values = np.asarray(values, dtype=np.float64)
    if len(keys) == 0:
        return np.zeros(0, dtype=np.int64), np.zeros(0)
    lo = float(values.min())
    span = int(np.ceil((float(values.max()) - lo) / resolution)) + 1
    vb = _bits(span)
    if int(keys.min()) >= 0 and _bits(int(keys.max())) + vb <= 63:
        q = values - lo
        q /= resolution
        packed = keys << vb
        packed |= np.rint(q, out=q).astype(np.int64)
        del q
        packed.sort()
        k = packed >> vb
        v = (packed & ((1 << vb) - 1)) * resolution + lo
    else:
        order = np.lexsort((values, keys))
        k, v = keys[order], values[order]
    starts = np.flatnonzero(np.r_[True, k[1:] != k[:-1]])
    ends = np.r_[starts[1:], len(k)]
    return k[starts], 0.5 * (v[(starts + ends - 1) // 2] + v[(starts + ends) // 2])
