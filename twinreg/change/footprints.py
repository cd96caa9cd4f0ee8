"""Objects' footprints as oriented rectangles (centre, heading, length, width), sampled on a fixed grid of their
own frame, so that overlaps and what a survey saw under them are array operations over all objects at once."""

from __future__ import annotations

import numpy as np


def corners(centre: np.ndarray, heading: np.ndarray, length: np.ndarray, width: np.ndarray) -> np.ndarray:
    """(n, 4, 2) corners of the rectangles, counter-clockwise from rear right."""
    c, s = np.cos(heading), np.sin(heading)
    u = np.array([-0.5, 0.5, 0.5, -0.5])[None, :] * length[:, None]
    v = np.array([-0.5, -0.5, 0.5, 0.5])[None, :] * width[:, None]
    x = centre[:, 0, None] + u * c[:, None] - v * s[:, None]
    y = centre[:, 1, None] + u * s[:, None] + v * c[:, None]
    return np.stack([x, y], axis=-1)


def record_corners(objs: list[dict]) -> np.ndarray:
    """(n, 4, 2) footprint corners of changes.json's object records (``centroid``, ``heading_rad``, ``size``)."""
    c = np.array([o["centroid"] for o in objs], dtype=np.float64).reshape(-1, 3)
    h = np.array([o["heading_rad"] for o in objs], dtype=np.float64)
    size = np.array([[o["size"]["length"], o["size"]["width"]] for o in objs], dtype=np.float64).reshape(-1, 2)
    return corners(c[:, :2], h, size[:, 0], size[:, 1])


def samples(centre, heading, length, width, nu: int = 12, nv: int = 5, inset: float = 0.0) -> np.ndarray:
    """(n, nu * nv, 2) points on a regular grid inside each rectangle (its edges moved in by ``inset`` metres)."""
    fu = (np.arange(nu) + 0.5) / nu - 0.5
    fv = (np.arange(nv) + 0.5) / nv - 0.5
    gu, gv = np.meshgrid(fu, fv, indexing="ij")
    u = gu.ravel()[None, :] * np.maximum(length - 2 * inset, 0.1)[:, None]
    v = gv.ravel()[None, :] * np.maximum(width - 2 * inset, 0.1)[:, None]
    c, s = np.cos(heading)[:, None], np.sin(heading)[:, None]
    return np.stack([centre[:, 0, None] + u * c - v * s, centre[:, 1, None] + u * s + v * c], axis=-1)


def inside(points: np.ndarray, centre, heading, length, width) -> np.ndarray:
    """(k, m) bool: whether each of the m points of row k lies in rectangle k (points (k, m, 2), one rectangle per
    row)."""
    d = points - centre[:, None, :2]
    c, s = np.cos(heading)[:, None], np.sin(heading)[:, None]
    u = d[..., 0] * c + d[..., 1] * s
    v = -d[..., 0] * s + d[..., 1] * c
    return (np.abs(u) <= length[:, None] / 2) & (np.abs(v) <= width[:, None] / 2)


def overlap(a: tuple, b: tuple) -> np.ndarray:
    """(k,) intersection over union of k pairs of rectangles, each side given as (centre (k, 2), heading (k,),
    length (k,), width (k,)); estimated on a 20 x 8 grid of each rectangle."""
    pa, pb = samples(*a, nu=20, nv=8), samples(*b, nu=20, nv=8)
    area_a, area_b = a[2] * a[3], b[2] * b[3]
    in_b = inside(pa, *b).mean(axis=1) * area_a
    in_a = inside(pb, *a).mean(axis=1) * area_b
    inter = (in_a + in_b) / 2
    return inter / np.maximum(area_a + area_b - inter, 1e-9)


def turn(a: np.ndarray, b: np.ndarray, period: float = 2 * np.pi) -> np.ndarray:
    """The smallest turn (rad, >= 0) from heading a to heading b, with headings equal modulo ``period``."""
    d = np.mod(np.asarray(b) - np.asarray(a), period)
    return np.minimum(d, period - d)


def ring(centre, heading, length, width, grow: float = 0.6, n: int = 24) -> np.ndarray:
    """(k, n, 2) points evenly along each rectangle's outline grown by ``grow`` metres (where a survey should have
    seen the ground or the neighbours around an object it saw whole)."""
    t = (np.arange(n) + 0.5) / n
    big_l, big_w = length + 2 * grow, width + 2 * grow
    perimeter = 2 * (big_l + big_w)
    s = t[None, :] * perimeter[:, None]
    lu, lw = big_l[:, None], big_w[:, None]
    u = np.where(s < lu, s - lu / 2, np.where(s < lu + lw, lu / 2, np.where(s < 2 * lu + lw,
                 lu / 2 - (s - lu - lw), -lu / 2)))
    v = np.where(s < lu, -lw / 2, np.where(s < lu + lw, s - lu - lw / 2, np.where(s < 2 * lu + lw, lw / 2,
                 lw / 2 - (s - 2 * lu - lw))))
    c, sn = np.cos(heading)[:, None], np.sin(heading)[:, None]
    return np.stack([centre[:, 0, None] + u * c - v * sn, centre[:, 1, None] + u * sn + v * c], axis=-1)
