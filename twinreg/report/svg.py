"""Pictures as SVG, written without matplotlib: a scene's report draws its five pictures with these few parts in
tens of milliseconds, where matplotlib took about two CPU-seconds and half a second to import (issue 51: a small
run's fixed costs). A :class:`Figure` holds SVG elements in pixels; an :class:`Axes` maps data units onto a box of
it (ticks at 1-2-5 steps, equal scales on request) and draws points, lines, polygons, arrows, labels and raster
images (PNG, written here from a uint8 array with zlib). Every text is escaped: a model's or a scan's name from
someone else is shown, never interpreted. Colours are ``#rrggbb`` strings or RGB triples in 0-1."""

from __future__ import annotations

import base64
import html
import struct
import zlib
from pathlib import Path

import numpy as np

from ..export.twin_ply import PALETTE
from ..io.outdir import atomic_path

#: the exports' palette of types (matplotlib's tab10), as SVG colours
TAB10 = tuple(f"#{r:02x}{g:02x}{b:02x}" for r, g, b in PALETTE.tolist())
BLUE, ORANGE, GREY = TAB10[0], TAB10[1], "#888888"
#: coolwarm's anchors (matplotlib's diverging map: blue, light grey, red), interpolated linearly
COOLWARM = ((0.0, (59, 76, 192)), (0.25, (141, 176, 254)), (0.5, (221, 221, 221)), (0.75, (244, 154, 123)),
            (1.0, (180, 4, 38)))
FONT = "font-family='DejaVu Sans,Arial,sans-serif'"


def text(s) -> str:
    """Anything as XML text (quotes escaped too: also safe inside an attribute)."""
    return html.escape(str(s), quote=True)


def hex_colour(c) -> str:
    """A colour as ``#rrggbb``: a string is kept, an RGB(A) triple in 0-1 converted.

    >>> hex_colour((1.0, 0.5, 0.0)), hex_colour("#123456")
    ('#ff8000', '#123456')
    """
    if isinstance(c, str):
        return c
    r, g, b = (int(round(min(max(float(v), 0.0), 1.0) * 255)) for v in tuple(c)[:3])
    return f"#{r:02x}{g:02x}{b:02x}"


def colour_table(anchors=COOLWARM, n: int = 256) -> np.ndarray:
    """(n, 3) uint8: a colour map from its anchors ((position 0-1, (r, g, b)), ...), linear between them."""
    pos = np.array([a[0] for a in anchors])
    rgb = np.array([a[1] for a in anchors], dtype=np.float64)
    t = np.linspace(0.0, 1.0, n)
    return np.stack([np.interp(t, pos, rgb[:, c]) for c in range(3)], axis=1).round().astype(np.uint8)


def png(pixels: np.ndarray, level: int = 6) -> bytes:
    """A PNG of ``pixels``: (h, w) grey, (h, w, 2) grey and alpha, (h, w, 3) RGB or (h, w, 4) RGBA, uint8, row 0
    at the top.

    >>> png(np.zeros((2, 3), np.uint8))[:8] == b"\\x89PNG\\r\\n\\x1a\\n"
    True
    """
    a = np.ascontiguousarray(pixels, dtype=np.uint8)
    if a.ndim == 2:
        a = a[:, :, None]
    h, w, c = a.shape
    kind = {1: 0, 2: 4, 3: 2, 4: 6}[c]
    raw = np.concatenate([np.zeros((h, 1), np.uint8), a.reshape(h, w * c)], axis=1).tobytes()

    def chunk(tag: bytes, data: bytes) -> bytes:
        return struct.pack(">I", len(data)) + tag + data + struct.pack(">I", zlib.crc32(tag + data) & 0xFFFFFFFF)

    return (b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", w, h, 8, kind, 0, 0, 0))
            + chunk(b"IDAT", zlib.compress(raw, level)) + chunk(b"IEND", b""))


def nice_ticks(lo: float, hi: float, most: int = 8) -> np.ndarray:
    """Tick values at a 1-2-5 step covering [lo, hi] with at most ``most`` of them.

    >>> nice_ticks(0.0, 1.0).tolist()
    [0.0, 0.2, 0.4, 0.6, 0.8, 1.0]
    >>> nice_ticks(31.5, 172.0).tolist()
    [40.0, 60.0, 80.0, 100.0, 120.0, 140.0, 160.0]
    """
    span = max(hi - lo, 1e-9)
    mag = 10.0 ** np.floor(np.log10(span / max(most, 1)))
    step = next(m * mag for m in (1, 2, 5, 10, 20, 50, 100)
                if np.floor(hi / (m * mag) + 1e-9) - np.ceil(lo / (m * mag) - 1e-9) + 1 <= most)
    first = np.ceil(lo / step - 1e-9) * step
    ticks = np.arange(first, hi + step * 1e-6, step)
    return np.round(ticks, 10) + 0.0


def _label(v: float) -> str:
    return f"{v:g}" if abs(v) >= 1e-9 else "0"


def _num(a) -> np.ndarray:
    return np.round(np.asarray(a, dtype=np.float64), 1)


def _image(x, y, w, h, pixels: np.ndarray, smooth: bool = False) -> str:
    """An ``<image>`` element of the raster ``pixels`` (a PNG inline) over the pixel box."""
    data = base64.b64encode(png(pixels)).decode("ascii")
    look = "" if smooth else " style='image-rendering:pixelated' image-rendering='optimizeSpeed'"
    return (f"<image x='{x:.1f}' y='{y:.1f}' width='{w:.1f}' height='{h:.1f}' preserveAspectRatio='none'{look} "
            f"href='data:image/png;base64,{data}'/>")


class Figure:
    """An SVG picture of ``width`` x ``height`` pixels (a white background), its elements in drawing order."""

    def __init__(self, width: float, height: float):
        self.width, self.height = float(width), float(height)
        self.parts: list[str] = []
        self._clips = 0

    def add(self, element: str) -> None:
        self.parts.append(element)

    def clip(self, x: float, y: float, w: float, h: float) -> str:
        """A new clip path of this rectangle; its id."""
        self._clips += 1
        cid = f"c{self._clips}"
        self.add(f"<clipPath id='{cid}'><rect x='{x:.1f}' y='{y:.1f}' width='{w:.1f}' height='{h:.1f}'/></clipPath>")
        return cid

    def text(self, x: float, y: float, s, size: float = 11, anchor: str = "start", rotate: float | None = None,
             fill: str = "#222", bold: bool = False, middle: bool = False) -> None:
        turn = f" transform='rotate({rotate:g} {x:.1f} {y:.1f})'" if rotate else ""
        weight = " font-weight='bold'" if bold else ""
        base = " dominant-baseline='central'" if middle else ""
        self.add(f"<text x='{x:.1f}' y='{y:.1f}' font-size='{size:g}' text-anchor='{anchor}' fill='{fill}'"
                 f"{weight}{base}{turn}>{text(s)}</text>")

    def rect(self, x, y, w, h, fill="none", stroke="none", opacity: float = 1.0, width: float = 1.0) -> None:
        self.add(f"<rect x='{x:.1f}' y='{y:.1f}' width='{w:.1f}' height='{h:.1f}' fill='{hex_colour(fill)}' "
                 f"stroke='{hex_colour(stroke)}' stroke-width='{width:g}' fill-opacity='{opacity:g}'/>")

    def line(self, x0, y0, x1, y1, stroke="#222", width: float = 1.0, dash: str | None = None) -> None:
        d = f" stroke-dasharray='{dash}'" if dash else ""
        self.add(f"<line x1='{x0:.1f}' y1='{y0:.1f}' x2='{x1:.1f}' y2='{y1:.1f}' stroke='{hex_colour(stroke)}' "
                 f"stroke-width='{width:g}'{d}/>")

    def image(self, x, y, w, h, pixels: np.ndarray, smooth: bool = False) -> None:
        """A raster (see :func:`png`) stretched over the box, its pixels kept sharp unless ``smooth``."""
        self.add(_image(x, y, w, h, pixels, smooth))

    def to_string(self) -> str:
        return (f"<svg xmlns='http://www.w3.org/2000/svg' width='{self.width:.0f}' height='{self.height:.0f}' "
                f"viewBox='0 0 {self.width:.0f} {self.height:.0f}' {FONT}>"
                f"<rect width='100%' height='100%' fill='white'/>" + "".join(self.parts) + "</svg>")

    def save(self, path) -> Path:
        """Write the picture to ``path`` atomically (a reader never sees half of it)."""
        path = Path(path)
        with atomic_path(path) as tmp:
            tmp.write_text(self.to_string(), encoding="utf-8")
        return path


class Axes:
    """Data coordinates ``xlim`` x ``ylim`` drawn into the pixel box (x, y, w, h) of ``fig`` (y up); ``equal``:
    one metre is as long across as up, the limits widened around their centre to fill the box."""

    def __init__(self, fig: Figure, box, xlim, ylim, equal: bool = False):
        self.fig = fig
        self.x, self.y, self.w, self.h = (float(v) for v in box)
        (x0, x1), (y0, y1) = (tuple(map(float, xlim)), tuple(map(float, ylim)))
        x1, y1 = max(x1, x0 + 1e-9), max(y1, y0 + 1e-9)
        if equal:
            per = max((x1 - x0) / self.w, (y1 - y0) / self.h)
            cx, cy = (x0 + x1) / 2, (y0 + y1) / 2
            x0, x1 = cx - per * self.w / 2, cx + per * self.w / 2
            y0, y1 = cy - per * self.h / 2, cy + per * self.h / 2
        self.xlim, self.ylim = (x0, x1), (y0, y1)
        self._clip = fig.clip(self.x, self.y, self.w, self.h)

    def px(self, x) -> np.ndarray:
        return self.x + (np.asarray(x, dtype=np.float64) - self.xlim[0]) / (self.xlim[1] - self.xlim[0]) * self.w

    def py(self, y) -> np.ndarray:
        return self.y + self.h - (np.asarray(y, dtype=np.float64) - self.ylim[0]) / (self.ylim[1] - self.ylim[0]) \
            * self.h

    def _in(self, body: str) -> None:
        self.fig.add(f"<g clip-path='url(#{self._clip})'>{body}</g>")

    def frame(self, xlabel: str = "", ylabel: str = "", title: str = "", ticks: bool = True, size: float = 11,
              xticks=None, yticks=None) -> None:
        """The box, its ticks and their values (1-2-5 steps unless given), the axis labels and the title."""
        f = self.fig
        f.rect(self.x, self.y, self.w, self.h, stroke="#222")
        if ticks:
            xt = nice_ticks(*self.xlim, most=max(3, int(self.w // 70))) if xticks is None else np.asarray(xticks)
            yt = nice_ticks(*self.ylim, most=max(3, int(self.h // 45))) if yticks is None else np.asarray(yticks)
            for v in xt[(xt >= self.xlim[0] - 1e-9) & (xt <= self.xlim[1] + 1e-9)]:
                p = float(self.px(v))
                f.line(p, self.y + self.h, p, self.y + self.h + 4)
                f.text(p, self.y + self.h + 6 + size * 0.8, _label(v), size=size * 0.9, anchor="middle")
            for v in yt[(yt >= self.ylim[0] - 1e-9) & (yt <= self.ylim[1] + 1e-9)]:
                p = float(self.py(v))
                f.line(self.x - 4, p, self.x, p)
                f.text(self.x - 6, p, _label(v), size=size * 0.9, anchor="end", middle=True)
        if xlabel:
            f.text(self.x + self.w / 2, self.y + self.h + 12 + 2 * size, xlabel, size=size, anchor="middle")
        if ylabel:
            f.text(self.x - 16 - 2.6 * size, self.y + self.h / 2, ylabel, size=size, anchor="middle", rotate=-90)
        if title:
            f.text(self.x + self.w / 2, self.y - 8, title, size=size * 1.15, anchor="middle")

    def points(self, xy, colour=BLUE, size: float = 2.0, opacity: float = 1.0) -> None:
        """Small squares of ``size`` pixels at the (n, 2) data points, as one path."""
        xy = np.asarray(xy, dtype=np.float64).reshape(-1, 2)
        if not len(xy):
            return
        px = np.round(np.c_[self.px(xy[:, 0]), self.py(xy[:, 1])] - size / 2, 1)
        px = np.unique(px, axis=0)  # a square drawn twice adds nothing
        s = f"{size:g}"
        d = "".join(f"M{a:g} {b:g}h{s}v{s}h-{s}z" for a, b in px.tolist())
        self._in(f"<path d='{d}' fill='{hex_colour(colour)}' fill-opacity='{opacity:g}'/>")

    def polyline(self, xy, colour="#222", width: float = 1.0, dash: str | None = None) -> None:
        xy = np.asarray(xy, dtype=np.float64).reshape(-1, 2)
        if len(xy) < 2:
            return
        pts = " ".join(f"{a:g},{b:g}" for a, b in np.c_[_num(self.px(xy[:, 0])), _num(self.py(xy[:, 1]))].tolist())
        d = f" stroke-dasharray='{dash}'" if dash else ""
        self._in(f"<polyline points='{pts}' fill='none' stroke='{hex_colour(colour)}' stroke-width='{width:g}'{d}/>")

    def segments(self, starts, ends, colours, width: float = 1.0) -> None:
        """Straight lines from each of ``starts`` to ``ends`` ((n, 2) each), a colour each (a list of n)."""
        a, b = np.asarray(starts, dtype=np.float64), np.asarray(ends, dtype=np.float64)
        x0, y0, x1, y1 = (_num(v).tolist() for v in (self.px(a[:, 0]), self.py(a[:, 1]), self.px(b[:, 0]),
                                                       self.py(b[:, 1])))
        self._in("".join(f"<line x1='{p:g}' y1='{q:g}' x2='{r:g}' y2='{s:g}' stroke='{hex_colour(c)}' "
                         f"stroke-width='{width:g}'/>" for p, q, r, s, c in zip(x0, y0, x1, y1, colours)))

    def polygons(self, rings: list, fills: list, opacity: float = 0.45, width: float = 1.0) -> None:
        """Closed polygons ((k, 2) data points each), filled with ``fills`` (one colour each) at ``opacity`` and
        outlined in the same colour."""
        out = []
        for ring, c in zip(rings, fills):
            r = np.asarray(ring, dtype=np.float64).reshape(-1, 2)
            pts = " ".join(f"{a:g},{b:g}" for a, b in np.c_[_num(self.px(r[:, 0])), _num(self.py(r[:, 1]))].tolist())
            c = hex_colour(c)
            out.append(f"<polygon points='{pts}' fill='{c}' fill-opacity='{opacity:g}' stroke='{c}' "
                       f"stroke-width='{width:g}'/>")
        self._in("".join(out))

    def arrows(self, starts, vectors, colour="#000", width: float = 1.0, head: float = 6.0) -> None:
        """Arrows from ``starts`` along ``vectors`` ((n, 2) data units), their heads ``head`` pixels long."""
        a = np.asarray(starts, dtype=np.float64).reshape(-1, 2)
        if not len(a):
            return
        b = a + np.asarray(vectors, dtype=np.float64).reshape(-1, 2)
        p0 = np.c_[self.px(a[:, 0]), self.py(a[:, 1])]
        p1 = np.c_[self.px(b[:, 0]), self.py(b[:, 1])]
        d = p1 - p0
        u = d / np.maximum(np.linalg.norm(d, axis=1, keepdims=True), 1e-9)
        n = np.c_[-u[:, 1], u[:, 0]]
        left, right = p1 - head * u + 0.45 * head * n, p1 - head * u - 0.45 * head * n
        body = "".join(f"M{q[0]:.1f} {q[1]:.1f}L{r[0]:.1f} {r[1]:.1f}" for q, r in zip(p0, p1 - 0.8 * head * u))
        heads = "".join(f"M{r[0]:.1f} {r[1]:.1f}L{s[0]:.1f} {s[1]:.1f}L{t[0]:.1f} {t[1]:.1f}z"
                        for r, s, t in zip(p1, left, right))
        c = hex_colour(colour)
        self._in(f"<path d='{body}' stroke='{c}' stroke-width='{width:g}' fill='none'/><path d='{heads}' fill='{c}'/>")

    def labels(self, xy, strings, size: float = 7.0, colour: str = "#000") -> None:
        """A short text centred on each of the (n, 2) data points."""
        xy = np.asarray(xy, dtype=np.float64).reshape(-1, 2)
        xs, ys = _num(self.px(xy[:, 0])).tolist(), _num(self.py(xy[:, 1])).tolist()
        self._in("".join(f"<text x='{x:g}' y='{y:g}' font-size='{size:g}' text-anchor='middle' "
                         f"dominant-baseline='central' fill='{colour}'>{text(s)}</text>"
                         for x, y, s in zip(xs, ys, strings)))

    def image(self, pixels: np.ndarray, extent) -> None:
        """A raster (row 0 at the top) over the data box ``extent`` = (x0, x1, y0, y1)."""
        x0, x1, y0, y1 = extent
        px0, px1 = float(self.px(x0)), float(self.px(x1))
        py0, py1 = float(self.py(y1)), float(self.py(y0))
        self._in(_image(px0, py0, px1 - px0, py1 - py0, pixels))

    def bars(self, lefts, widths, heights, colour="#2c7fb8") -> None:
        lefts, widths, heights = (np.asarray(v, dtype=np.float64) for v in (lefts, widths, heights))
        out = []
        for l, w, h in zip(lefts, widths, heights):
            if h <= 0:
                continue
            x0, x1, y0, y1 = float(self.px(l)), float(self.px(l + w)), float(self.py(h)), float(self.py(0.0))
            out.append(f"<rect x='{x0:.1f}' y='{y0:.1f}' width='{x1 - x0:.1f}' height='{y1 - y0:.1f}' "
                       f"fill='{hex_colour(colour)}' stroke='white'/>")
        self._in("".join(out))


def colour_bar(fig: Figure, box, table: np.ndarray, lo: float, hi: float, label: str, ticks=None,
               size: float = 9) -> None:
    """A vertical colour bar of ``table`` ((n, 3) or (n, 4) uint8, low values first) in the pixel box, its ticks
    labelled from ``lo`` to ``hi``."""
    x, y, w, h = box
    strip = np.asarray(table)[::-1][:, None, :]
    fig.image(x, y, w, h, strip, smooth=True)
    fig.rect(x, y, w, h, stroke="#222")
    for v in (nice_ticks(lo, hi, most=6) if ticks is None else ticks):
        if lo - 1e-9 <= v <= hi + 1e-9:
            p = y + h - (v - lo) / (hi - lo) * h
            fig.line(x + w, p, x + w + 3, p)
            fig.text(x + w + 5, p, _label(v), size=size, middle=True)
    fig.text(x + w + 14 + 2 * size, y + h / 2, label, size=size, anchor="middle", rotate=90)
