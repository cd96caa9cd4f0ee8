"""The ASPRS point classes (LAS 1.4 R15, table 17) a classified scan carries, as the kinds read them: a national
scan (AHN, USGS 3DEP, most others) classes its points as ground, vegetation, building, water, bridge; an object
most of whose points the scan classes as vegetation is ``vegetation``, as building or bridge ``structure``.
Classes 0 (never classified) and 1 (unclassified: where AHN puts cars, street furniture and often trees) say
nothing."""

from __future__ import annotations

import numpy as np

NAMES = {2: "ground", 3: "low vegetation", 4: "medium vegetation", 5: "high vegetation", 6: "building",
         9: "water", 17: "bridge deck"}
VEGETATION = (3, 4, 5)
BUILT = (6, 17)


def class_shares(codes: np.ndarray) -> tuple[float, float]:
    """(the share of vegetation, the share of building or bridge) among an object's points' ``codes``.

    >>> class_shares(np.array([1, 5, 5, 6], dtype=np.uint8))
    (0.5, 0.25)
    """
    c = np.asarray(codes)
    if len(c) == 0:
        return 0.0, 0.0
    return round(float(np.isin(c, VEGETATION).mean()), 4), round(float(np.isin(c, BUILT).mean()), 4)


def read_codes(codes: np.ndarray) -> list[int]:
    """The classes the kinds read (:data:`NAMES`) that ``codes`` hold, ascending.

    >>> read_codes(np.array([1, 2, 2, 6, 26], dtype=np.uint8))
    [2, 6]
    """
    present = np.flatnonzero(np.bincount(np.asarray(codes, dtype=np.int64), minlength=256))
    return [int(c) for c in present if int(c) in NAMES]


def used_codes(codes: np.ndarray | None) -> dict:
    """{code: name} of the classes the kinds read that a scan's ``codes`` hold (json keys: strings).

    >>> used_codes(np.array([1, 2, 6, 6, 26], dtype=np.uint8))
    {'2': 'ground', '6': 'building'}
    """
    if codes is None:
        return {}
    return {str(c): NAMES[c] for c in read_codes(codes)}


def classes_doc(codes: np.ndarray | None, on: bool = True, reason: str | None = None) -> dict:
    """twin.json's ``scan_classes``: whether the kinds read the scan's classes, and which (CONTRACT).

    >>> classes_doc(np.array([1, 2, 6], dtype=np.uint8))
    {'used': True, 'codes': {'2': 'ground', '6': 'building'}}
    >>> classes_doc(None)["used"], classes_doc(np.array([2, 6], dtype=np.uint8), on=False)["reason"][:8]
    (False, 'turned o')
    """
    if reason is not None:
        return {"used": False, "reason": reason}
    if codes is None:
        return {"used": False, "reason": "the scan's points carry no ASPRS class (every point 0 or 1, or a format "
                                         "without classes)"}
    if not on:
        return {"used": False, "reason": "turned off (--no-scan-classes)", "codes": used_codes(codes)}
    return {"used": True, "codes": used_codes(codes)}
