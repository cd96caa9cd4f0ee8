"""Sorting integer keys fast: the stages group millions of points by a cell or label key.

``np.sort`` of int64 runs on the CPU's vector units (several times faster than ``argsort`` and 20-30x faster than
``lexsort`` on 5M keys), so a key packed with what else the sort must carry (the point's position, or a value
quantised to an integer) is sorted by value and unpacked, whenever the two fit in 63 bits together.
"""

from __future__ import annotations

import numpy as np

from .kernels import fast, kernel


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
    are exact to half of it); a range too wide for that falls back to a two-key sort. Where the kernels are in use
    and the keys are few enough to count, :func:`_group_medians_fast` gives the same medians.

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
    top = int(keys.max())
    packs = int(keys.min()) >= 0 and _bits(top) + vb <= 63
    compiled = fast(_group_medians_fast)
    if packs and compiled is not None and top < 4 * len(keys) + (1 << 20):  # keys a counting sort can hold
        return compiled(keys, values, lo, float(resolution), top + 1)
    if packs:
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


@kernel(entry="group_medians", example="_medians_example")
def _group_medians_fast(keys, values, lo, resolution, n_keys):
    """:func:`group_medians`' packed sort compiled: the values quantised as it does, the keys counted into their
    groups (``n_keys`` > every key), each group's two middle values found by sorting the group alone."""
    n = keys.shape[0]
    counts = np.zeros(n_keys + 1, dtype=np.int64)
    for p in range(n):
        counts[keys[p] + 1] += 1
    distinct = 0
    for k in range(n_keys):
        if counts[k + 1] > 0:
            distinct += 1
        counts[k + 1] += counts[k]
    fill = counts[:-1].copy()
    q = np.empty(n, dtype=np.int64)
    for p in range(n):
        q[fill[keys[p]]] = np.int64(np.rint((values[p] - lo) / resolution))
        fill[keys[p]] += 1
    out_keys = np.empty(distinct, dtype=np.int64)
    out = np.empty(distinct)
    g = 0
    for k in range(n_keys):
        a, b = counts[k], counts[k + 1]
        if b > a:
            group = np.sort(q[a:b])
            m = b - a
            out_keys[g] = k
            out[g] = 0.5 * ((group[(m - 1) // 2] * resolution + lo) + (group[m // 2] * resolution + lo))
            g += 1
    return out_keys, out


def _medians_example(rng) -> tuple:
    """Cells' heights, some cells empty, one of a single point (the registry's example for :func:`group_medians`)."""
    keys = rng.integers(0, 400, 5000) * 3
    return np.r_[keys, 1201], np.r_[rng.normal(1.5, 0.3, 5000), 9.0]
