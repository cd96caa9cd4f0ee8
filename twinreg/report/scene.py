"""report.html and its pictures, drawn as SVG without matplotlib (:mod:`.svg`; a small run's fixed costs, issue
51): the top view with placed models, the matches' confidence, the dissimilarity heat map, the dendrogram and each
object's sections against its best model's."""

from __future__ import annotations

import re
import statistics
from collections import Counter, defaultdict
from pathlib import Path

import numpy as np

from .svg import BLUE, GREY, ORANGE, TAB10, Axes, Figure, colour_bar, colour_table, nice_ticks, text

#: the top view's heights above ground (m) from white to black, its grey ramp (256 levels, the lowest first); its
#: longest side (px)
TOP_HEIGHTS = (-0.5, 3.0)
GREY_RAMP = np.linspace(255, 0, 256).round().astype(np.uint8)
TOP_SIDE_PX = 1200


def _height_image(scene_local: np.ndarray, heights: np.ndarray, cell: float):
    lo = scene_local[:, :2].min(0)
    ij = np.floor((scene_local[:, :2] - lo) / cell).astype(np.int64)
    shape = tuple(ij.max(0) + 1)
    flat = np.full(shape[0] * shape[1], -np.inf)
    np.maximum.at(flat, ij[:, 0] * shape[1] + ij[:, 1], heights)
    img = flat.reshape(shape)
    img[~np.isfinite(img)] = np.nan
    return img, lo


def _grey_pixels(img: np.ndarray) -> np.ndarray:
    """(rows, cols, 2) uint8 grey and alpha of a height image (x, y) cells: row 0 the northmost, empty cells
    clear, heights from :data:`TOP_HEIGHTS` white to black."""
    lo, hi = TOP_HEIGHTS
    t = img.T[::-1]
    empty = np.isnan(t)
    level = np.clip((np.where(empty, 0.0, np.clip(t, 0.0, hi)) - lo) / (hi - lo), 0.0, 1.0)
    return np.stack([GREY_RAMP[np.round(level * 255).astype(np.intp)], np.where(empty, 0, 255).astype(np.uint8)], -1)


def _legend(fig: Figure, y: float, x0: float) -> None:
    """The top view's key, one line: a type's colour, the front arrow, the label's suffixes."""
    fig.rect(x0, y - 5, 18, 10, fill=BLUE, stroke=BLUE, opacity=0.45)
    x = x0 + 24
    for glyph, words in (("", "placed object: a colour a type"), ("\u2192", "its front"),
                         ("7", "object 7, a model"), ("7~", "its type's fused shape"),
                         ("7?", "a box (no model, no shape)")):
        if glyph:
            fig.text(x, y, glyph, size=11, bold=True, middle=True)
            x += 8 * len(glyph) + 6
        fig.text(x, y, words, size=10, middle=True)
        x += 6.2 * len(words) + 26


def plot_twin_top(scene_local: np.ndarray, is_ground: np.ndarray, footprints: list[dict], path, title: str,
                  hag: np.ndarray | None = None):
    """topview.svg: the scan as a height-above-ground raster (ground light, the tallest black, empty cells clear)
    with each placed model's footprint (a colour a type), front arrow and label, to scale (metres, equal axes),
    a colour bar and a key."""
    scene_local = np.asarray(scene_local, dtype=np.float64)
    ext = np.maximum(np.ptp(scene_local[:, :2], axis=0), 1.0)
    scale = TOP_SIDE_PX / ext.max()
    w, h = max(400.0, ext[0] * scale), max(300.0, ext[1] * scale)
    left, top, right, bottom = 70.0, 40.0, 100.0, 80.0
    fig = Figure(left + w + right, top + h + bottom)
    heights = np.where(is_ground, 0.0, hag if hag is not None else 1.0)
    cell = max(0.1, float(ext.max()) / 1500)
    img, lo = _height_image(scene_local, heights, cell)
    x1, y1 = lo[0] + img.shape[0] * cell, lo[1] + img.shape[1] * cell
    ax = Axes(fig, (left, top, w, h), (lo[0], x1), (lo[1], y1), equal=True)
    ax.image(_grey_pixels(img), (lo[0], x1, lo[1], y1))
    if footprints:
        colours = [fp["color"] for fp in footprints]
        ax.polygons([fp["corners"] for fp in footprints], colours)
        centre = np.array([fp["centre"] for fp in footprints], dtype=float)
        ax.arrows(centre, np.array([fp["front"] for fp in footprints], dtype=float) - centre, head=6.0)
        ax.labels(centre, [fp["label"] for fp in footprints], size=float(np.clip(scale * 0.25, 7.0, 12.0)))
    ax.frame("x (m, east in the scan's frame)", "y (m, north)", title)
    colour_bar(fig, (left + w + 18, top + 0.1 * h, 12, 0.8 * h), np.repeat(GREY_RAMP[:, None], 3, axis=1),
               *TOP_HEIGHTS, "scan: height above ground (m)", ticks=[0, 1, 2, 3])
    _legend(fig, top + h + 62, left)
    return fig.save(path)


#: the most objects sections.svg draws (a row each; every object's sections are in sections.json and the viewer)
MAX_SECTION_ROWS = 40
#: the sections' scale (px a metre) at most, the longitudinal panel's width (px) at most
SECTION_PX_PER_M, SECTION_PANEL_PX = 40.0, 420.0


def _short(title: str, n: int = 44) -> str:
    """A row's title cut to ``n`` characters (its reason's gist; report.html has the full text).

    >>> _short("obj1: no match (the best model (uaz) leaves 59% of its points unexplained)", 24)
    'obj1: no match (the b...'
    """
    return title if len(title) <= n else title[:n - 3].rstrip() + "..."


def _section_arrays(item: dict, who: str, key: str) -> np.ndarray:
    a = (item.get(who) or {}).get(key)
    return np.asarray(a, dtype=np.float64).reshape(-1, 2) if a is not None and len(a) else np.zeros((0, 2))


def _reach(items: list[dict], key: str, least: float, most: float) -> float:
    """The largest |across| of the rows' sections (m, within [least, most])."""
    far = [np.abs(_section_arrays(it, who, key)[:, 0]).max(initial=0.0) for it in items for who in ("object", "model")]
    return float(np.clip(max(far, default=0.0) + 0.2, least, most))


def plot_object_sections(items: list[dict], path, max_rows: int = MAX_SECTION_ROWS):
    """sections.svg: a row per object, its title on the left, its longitudinal and transverse sections (blue
    squares) with its registered best model's (orange) in two panels, every row at one scale (metres, equal axes;
    a row as tall as its object, 2.5-6 m); at most ``max_rows`` objects (those with a model first), the title
    saying how many of all."""
    total = len(items)
    if total > max_rows:  # a picture that stays a picture: every object's sections are in sections.json
        order = sorted(range(total), key=lambda k: not items[k].get("model"))
        items = [items[k] for k in sorted(order[:max_rows])]
    a, b = _reach(items, "lon", 2.5, 8.0), _reach(items, "tra", 1.0, 4.0)
    s = min(SECTION_PX_PER_M, SECTION_PANEL_PX / (2 * a))
    tops = [float(np.clip(max([_section_arrays(it, w, k)[:, 1].max(initial=0.0) for w in ("object", "model")
                                for k in ("lon", "tra")]) + 0.2, 2.5, 6.0)) for it in items]
    left, gap, head, foot = 270.0, 30.0, 62.0, 50.0
    wl, wt = 2 * a * s, 2 * b * s
    fig = Figure(left + wl + gap + wt + 20, head + sum(t * s + 8 for t in tops) + foot)
    fig.text(10, 18, "each object's sections (blue) and its registered model's (orange), to scale", size=13)
    if total > len(items):
        fig.text(10, 36, f"{len(items)} of {total} objects, those with a model first; all in sections.json",
                 size=11, fill="#555")
    fig.text(left + wl / 2, head - 8, "longitudinal", size=12, anchor="middle")
    fig.text(left + wl + gap + wt / 2, head - 8, "transverse", size=12, anchor="middle")
    y = head
    for it, top in zip(items, tops):
        hp = top * s
        fig.text(left - 10, y + hp / 2, _short(it["title"]), size=10, anchor="end", middle=True)
        for x0, wp, half, key in ((left, wl, a, "lon"), (left + wl + gap, wt, b, "tra")):
            ax = Axes(fig, (x0, y, wp, hp), (-half, half), (-0.1, top - 0.1))
            fig.rect(x0, y, wp, hp, stroke="#bbb")
            ax.points(_section_arrays(it, "object", key), BLUE, size=3.0, opacity=0.85)
            ax.points(_section_arrays(it, "model", key), ORANGE, size=2.0)
        y += hp + 8
    for x0, wp, half, label in ((left, wl, a, "u along heading (m)"), (left + wl + gap, wt, b, "v across (m)")):
        ax = Axes(fig, (x0, y - 8, wp, 0.1), (-half, half), (0, 1))
        ax.frame(label, ticks=True, yticks=[])
    return fig.save(path)


def draw_heatmap(matrix: np.ndarray, labels: list[str], path, title: str = "dissimilarity (cm)"):
    """heatmap.svg: the objects' dissimilarity (cm, blue low, red high), a cell a pair, the values written in
    when there are at most 20 objects."""
    m = np.asarray(matrix, dtype=np.float64) * 100.0
    n = len(labels)
    cell = float(np.clip(600.0 / max(n, 1), 4.0, 30.0))
    left, top = 90.0, 100.0
    fig = Figure(left + n * cell + 110, top + n * cell + 30)
    hi = float(np.nanmax(m)) if n and np.isfinite(m).any() else 1.0
    hi = hi if hi > 0 else 1.0
    table = colour_table()
    fig.image(left, top, n * cell, n * cell, table[np.round(np.clip(np.nan_to_num(m) / hi, 0, 1) * 255).astype(int)])
    fig.rect(left, top, n * cell, n * cell, stroke="#222")
    every = max(1, int(np.ceil(9.0 / cell)))
    size = min(10.0, max(6.0, cell * 0.8))
    for k in range(0, n, every):
        c = left + (k + 0.5) * cell
        fig.text(left - 4, top + (k + 0.5) * cell, labels[k], size=size, anchor="end", middle=True)
        fig.text(c, top - 4, labels[k], size=size, rotate=-90)
    if n <= 20:
        for i in range(n):
            for j in range(n):
                fig.text(left + (j + 0.5) * cell, top + (i + 0.5) * cell, f"{m[i, j]:.1f}", size=min(8.0, cell * 0.3),
                         anchor="middle", middle=True)
    colour_bar(fig, (left + n * cell + 16, top, 12, n * cell), table, 0.0, hi, "RMSE (cm)")
    fig.text(left + n * cell / 2, 18, title, size=13, anchor="middle")
    return fig.save(path)


def draw_dendrogram(linkage: np.ndarray, labels: list[str], threshold: float, path):
    """dendrogram.svg: the objects' hierarchical clustering (heights in cm), the types below the cut in colours,
    the cut dashed."""
    from scipy.cluster.hierarchy import dendrogram

    n = len(labels)
    z = np.array(linkage, dtype=np.float64)
    z[:, 2] *= 100.0  # heights in cm; the other columns are indices and counts
    tree = dendrogram(z, labels=list(labels), color_threshold=threshold * 100.0, no_plot=True)
    step = float(np.clip(700.0 / max(n, 1), 6.0, 24.0))
    left, top, h = 70.0, 40.0, 280.0
    w = n * step
    fig = Figure(left + w + 30, top + h + 90)
    hi = max(float(np.max(z[:, 2])) if len(z) else 1.0, threshold * 100.0) * 1.05
    ax = Axes(fig, (left, top, w, h), (0.0, 10.0 * n), (0.0, hi))
    for xs, ys, c in zip(tree["icoord"], tree["dcoord"], tree["color_list"]):
        colour = TAB10[int(c[1:]) % 10] if c.startswith("C") and c[1:].isdigit() else GREY
        ax.polyline(np.c_[xs, ys], colour, width=1.2)
    ax.polyline([[0.0, threshold * 100.0], [10.0 * n, threshold * 100.0]], GREY, dash="5,4")
    ax.frame(ylabel="dissimilarity (cm)", title=f"hierarchical clustering (cut at {threshold * 100:.1f} cm)",
             xticks=[])
    size = min(10.0, max(5.0, step * 0.8))
    for k, name in enumerate(tree["ivl"]):
        x = left + (k + 0.5) * step
        fig.text(x, top + h + 6, name, size=size, rotate=90)
    return fig.save(path)


def plot_taxonomy(folder: Path, names: list[str], matrix: np.ndarray, linkage: np.ndarray,
                  threshold: float) -> list[Path]:
    """heatmap.svg and dendrogram.svg (known as soon as the objects are clustered)."""
    folder = Path(folder)
    if len(names) < 2:
        return []
    return [draw_heatmap(matrix, names, folder / "heatmap.svg"),
            draw_dendrogram(linkage, names, threshold, folder / "dendrogram.svg")]


def short_reason(reason: str) -> str:
    """A no-match reason's gist (its first clause, models' names left out), for grouping and for table cells.

    >>> short_reason("the best model (uaz_469) fits only 15 cm sunk into the ground (at most 7 cm allowed)")
    'the best model fits only 15 cm sunk into the ground'
    """
    first = re.split(r"[;:]", reason or "no reason given", maxsplit=1)[0]
    first = re.sub(r"\s*\([^)]*\)", "", first).strip()
    return first if len(first) <= 60 else first[:57].rstrip() + "..."


def plot_confidence(twin: dict, path) -> Path:
    """confidence.svg: the matches' confidence (0-1) as a histogram, the objects without a model in its title."""
    conf = [o["match"]["confidence"] for o in twin["objects"] if o["match"] and o["match"].get("confidence") is not None]
    counts, edges = np.histogram(conf, bins=np.linspace(0, 1, 11))
    none = sum(1 for o in twin["objects"] if not o["match"])
    fig = Figure(420, 250)
    ax = Axes(fig, (62, 30, 340, 170), (0.0, 1.0), (0.0, max(1.0, float(counts.max(initial=0)) * 1.08)))
    ax.bars(edges[:-1], np.diff(edges), counts)
    top = nice_ticks(0.0, ax.ylim[1], most=6)
    ax.frame("confidence of the match", "objects", f"{len(conf)} matched, {none} without a model", size=10,
             yticks=top[top == np.round(top)])
    return fig.save(path)


STYLE = ("body{font-family:sans-serif;margin:1.2em 2em;color:#222}h1{font-size:1.4em;margin:.2em 0}"
         "td,th{padding:2px 8px;border-bottom:1px solid #ddd;text-align:left;white-space:nowrap;vertical-align:top}"
         "th{background:#f3f3f3}.lead{max-width:100%;max-height:68vh;border:1px solid #ddd}"
         ".row{display:flex;flex-wrap:wrap;gap:2em;align-items:flex-start;margin:1em 0}"
         "details{display:inline}summary{cursor:pointer}details[open] span{white-space:normal;display:block;"
         "max-width:40em}img.pic{max-width:100%}")


def kinds_table(objects: list[dict]) -> str:
    """The objects by kind (most common first): how many, how many with a model, with a fused shape (their type's,
    or the kind's template), their median kind confidence (none where no object claims it: ``unknown``,
    ``vegetation`` and ``structure`` are no catalogued kind's claim, their confidence 0 no calibrated figure)."""
    by = defaultdict(list)
    for o in objects:
        by[o.get("kind") or "unknown"].append(o)

    def median(v: list) -> str:
        claimed = [o["kind_confidence"] for o in v if o.get("kind_confidence") is not None]
        return f"{statistics.median(claimed):.2f}" if any(c > 0 for c in claimed) else ""

    rows = "".join(
        f"<tr><td>{text(k)}</td><td>{len(v)}</td><td>{sum(1 for o in v if o['match'])}</td>"
        f"<td>{sum(1 for o in v if (o.get('shape') or {}).get('source') in ('fused', 'generic'))}</td><td>"
        + text(median(v)) + "</td></tr>" for k, v in sorted(by.items(), key=lambda kv: -len(kv[1])))
    return ("<table><tr><th>kind</th><th>objects</th><th>with a model</th><th>with a fused shape</th>"
            "<th>median kind confidence</th></tr>"
            f"{rows}</table>")


def _summary_tables(twin: dict) -> str:
    per_model = Counter((o["match"]["name"], o["match"].get("make") or "") for o in twin["objects"] if o["match"])
    why = Counter(short_reason(o.get("reason", "")) for o in twin["objects"] if not o["match"])
    models = "".join(f"<tr><td>{text(n)}</td><td>{text(m)}</td><td>{c}</td></tr>" for (n, m), c in per_model.most_common())
    reasons = "".join(f"<tr><td>{text(r)}</td><td>{c}</td></tr>" for r, c in why.most_common())
    placed = (f"<table><tr><th>model</th><th>make</th><th>objects</th></tr>{models}</table>"
              "<img class='pic' src='confidence.svg' alt='confidence of the matches'>" if per_model else
              "<p>No catalogue model was placed: every object keeps its type, kind and fused shape or box (the "
              "reasons follow, and each object's in the table below).</p>")
    return (kinds_table(twin["objects"]) + placed
            + (f"<table><tr><th>without a model, because</th><th>objects</th></tr>{reasons}</table>" if why else ""))


def _object_row(o: dict) -> str:
    m = o["match"]
    doubt = ", ".join(m.get("ambiguous_with") or []) if m else ""
    if m and m.get("outside_tolerance"):
        doubt += " (outside the size tolerance)"
    if m:
        outcome = text(m["name"])
    else:
        full = o.get("reason", "")
        outcome = f"<details><summary>no model: {text(short_reason(full))}</summary><span>{text(full)}</span></details>"
    cells = [text(o["id"]), text(o["n_points"]),
             text(f"{o['size']['length']:.2f} x {o['size']['width']:.2f} x {o['size']['height']:.2f}"),
             text(o.get("kind") or ""), text(o["cluster"]),
             outcome, text(f"{m['rmse_m'] * 100:.1f} cm" if m else ""),
             text("" if not m or m.get("confidence") is None else f"{m['confidence']:.2f}"), text(doubt),
             text(f"{o['bearing_deg']:.1f}"), text((m.get("runner_up") or {}).get("name", "") if m else "")]
    return "<tr>" + "".join(f"<td>{c}</td>" for c in cells) + "</tr>"


def write_report(folder: Path, twin: dict, top_png_args: dict, section_items: list[dict] | None) -> list[Path]:
    """topview.svg, confidence.svg, sections.svg and report.html (which also shows heatmap.svg and
    dendrogram.svg): the map of the twin over its scan first, then the summary (cars per model, the confidence
    histogram, the objects without a model by reason), a compact table (a no-match reason's gist, the full text on
    demand), the pictures. ``section_items`` None: sections.svg is drawn by another process
    (:func:`plot_object_sections`), the page shows it all the same."""
    folder = Path(folder)
    top = plot_twin_top(path=folder / "topview.svg", **top_png_args)
    conf = plot_confidence(twin, folder / "confidence.svg")
    files = [folder / n for n in ("heatmap.svg", "dendrogram.svg")
             if len(twin["objects"]) >= 2 and twin.get("dissimilarity") is not None]
    files.append(folder / "sections.svg" if section_items is None else
                 plot_object_sections(section_items, folder / "sections.svg"))
    pics = "".join(f"<h2>{text(p.stem)}</h2><img class='pic' src='{text(p.name)}' alt='{text(p.stem)}'>" for p in files)
    matched = sum(1 for o in twin["objects"] if o["match"])
    page = (f"<!doctype html><html><head><meta charset='utf-8'><title>twin of {text(twin['scene'])}</title>"
            f"<style>{STYLE}</style></head><body>"
            f"<h1>Digital twin of {text(twin['scene'])}</h1><p>{len(twin['objects'])} objects, {matched} with a "
            f"model; the twin built in {twin['timing_s']['total']:.2f} s (before this report and the other files "
            "were written: the command's own time is longer).</p>"
            f"<img class='lead' src='topview.svg' alt='the twin over its scan'>"
            f"<div class='row'>{_summary_tables(twin)}</div>"
            "<table><tr><th>object</th><th>points</th><th>size (m)</th><th>kind</th><th>type</th><th>model</th><th>RMSE</th>"
            "<th>confidence</th><th>ambiguous with</th><th>bearing (deg)</th><th>runner-up</th></tr>"
            + "".join(_object_row(o) for o in twin["objects"]) + "</table>" + pics + "</body></html>")
    (folder / "report.html").write_text(page, encoding="utf-8")
    return [top, conf] + files + [folder / "report.html"]
