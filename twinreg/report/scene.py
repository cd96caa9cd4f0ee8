"""report.html and its PNGs: the top view with placed models, the dissimilarity heat map, the dendrogram and each
object's sections against its best model's."""

from __future__ import annotations

import html
import io
import re
import statistics
from collections import Counter, defaultdict
from pathlib import Path

import numpy as np

from .plots import plot_dendrogram, plot_heatmap, pyplot, save_figure


def warm_up() -> bool:
    """Import matplotlib and draw a first tiny figure (font set-up): run in the helper process at the start."""
    plt = pyplot()
    fig, ax = plt.subplots(figsize=(1, 1))
    ax.text(0.5, 0.5, r"warm $\sim$")  # mathtext too: the top view's legend uses it
    fig.savefig(io.BytesIO(), format="png")
    plt.close(fig)
    return True


def _height_image(scene_local: np.ndarray, heights: np.ndarray, cell: float):
    lo = scene_local[:, :2].min(0)
    ij = np.floor((scene_local[:, :2] - lo) / cell).astype(np.int64)
    shape = tuple(ij.max(0) + 1)
    img = np.full(shape, np.nan)
    flat = np.full(shape[0] * shape[1], -np.inf)
    np.maximum.at(flat, ij[:, 0] * shape[1] + ij[:, 1], heights)
    img = flat.reshape(shape)
    img[~np.isfinite(img)] = np.nan
    return img, lo


def plot_twin_top(scene_local: np.ndarray, is_ground: np.ndarray, footprints: list[dict], path, title: str,
                  hag: np.ndarray | None = None):
    """Top view: the scan as a height-above-ground image (a raster, fast at any size) with each placed model's
    footprint, front arrow and label. The footprints and arrows are one collection each (a sweep's hundred objects
    as a hundred patches and arrows took a second to draw), and the figure is drawn once: its margins are fixed,
    not measured by a first drawing (``bbox_inches="tight"`` or a layout engine)."""
    from matplotlib.cm import ScalarMappable
    from matplotlib.collections import PolyCollection
    from matplotlib.colors import Normalize
    from matplotlib.lines import Line2D
    from matplotlib.patches import Patch

    plt = pyplot()
    ext = np.ptp(scene_local[:, :2], axis=0)
    scale = 14.0 / max(ext.max(), 1.0)
    w, h = max(4, ext[0] * scale + 1), max(3, ext[1] * scale + 1)  # the map (inches)
    fw, fh = w + 1.6, h + 1.1  # and fixed margins: the axes' labels and the bar, the title and the legend
    fig = plt.figure(figsize=(fw, fh))
    ax = fig.add_axes((0.75 / fw, 0.8 / fh, w / fw, h / fh))
    cax = fig.add_axes(((w + 0.85) / fw, (0.8 + 0.1 * h) / fh, 0.12 / fw, 0.8 * h / fh))
    heights = np.where(is_ground, 0.0, hag if hag is not None else 1.0)
    cell = max(0.1, float(ext.max()) / 1500)
    img, lo = _height_image(scene_local, heights, cell)
    # coloured here (a 256-colour table, empty cells clear): matplotlib then only places the pixels, without
    # normalising and colour-mapping a float image of millions of cells
    norm = Normalize(vmin=-0.5, vmax=3.0)
    table = (plt.get_cmap("Greys")(np.linspace(0.0, 1.0, 256)) * 255).round().astype(np.uint8)
    empty = np.isnan(img.T)
    level = np.round(np.clip((np.where(empty, 0.0, np.clip(img.T, 0, 3)) - norm.vmin) / (norm.vmax - norm.vmin), 0, 1)
                     * 255).astype(np.uint8)
    rgba = table[level]
    rgba[empty, 3] = 0
    ax.imshow(rgba, origin="lower", extent=[lo[0], lo[0] + img.shape[0] * cell, lo[1], lo[1] + img.shape[1] * cell],
              interpolation="nearest")
    shown = ScalarMappable(norm=norm, cmap="Greys")
    if footprints:
        colours = np.array([fp["color"] for fp in footprints], dtype=float)[:, :3]
        ax.add_collection(PolyCollection([np.asarray(fp["corners"]) for fp in footprints],
                                         facecolors=np.c_[colours, np.full(len(colours), 0.45)],
                                         edgecolors=colours, linewidths=1), autolim=False)
        centre = np.array([fp["centre"] for fp in footprints], dtype=float)
        front = np.array([fp["front"] for fp in footprints], dtype=float) - centre
        ax.quiver(centre[:, 0], centre[:, 1], front[:, 0], front[:, 1], angles="xy", scale_units="xy", scale=1,
                  width=0.001, headwidth=6, headlength=7, headaxislength=6, color="black")
        for fp in footprints:
            ax.text(fp["centre"][0], fp["centre"][1], fp["label"], fontsize=5, ha="center", va="center")
    ax.set_aspect("equal")
    ax.set_title(title)
    ax.set_xlabel("x (m, east in the scan's frame)")
    ax.set_ylabel("y (m, north)")
    handles = [Patch(color="tab:blue", alpha=0.45, label="placed object: a colour a type"),
               Line2D([], [], color="black", marker=r"$\rightarrow$", lw=0, markersize=9, label="its front"),
               Line2D([], [], lw=0, marker="$7$", color="black", label="7: object 7, a model"),
               Line2D([], [], lw=0, marker="$\\sim$", color="black", label="7~: its type's fused shape"),
               Line2D([], [], lw=0, marker="$?$", color="black", label="7?: a box (no model, no shape)")]
    fig.legend(handles=handles, loc="lower center", ncol=5, fontsize=7, frameon=False)
    bar = fig.colorbar(shown, cax=cax, ticks=[0, 1, 2, 3])
    bar.set_label("scan: height above ground (m)", fontsize=7)
    bar.ax.tick_params(labelsize=6)
    return save_figure(fig, path, tight=False, dpi=100)


#: the most objects sections.png draws (a row each; every object's sections are in sections.json and the viewer)
MAX_SECTION_ROWS = 40


def _short(title: str, n: int = 44) -> str:
    """A row's title cut to ``n`` characters (its reason's gist; report.html has the full text).

    >>> _short("obj1: no match (the best model (uaz) leaves 59% of its points unexplained)", 24)
    'obj1: no match (the b...'
    """
    return title if len(title) <= n else title[:n - 3].rstrip() + "..."


def plot_object_sections(items: list[dict], path, max_rows: int = MAX_SECTION_ROWS):
    """Each object's sections (blue squares) with its registered best model's (orange dots), stacked in two
    panels: longitudinal (left) and transverse (right), one row of 2.5 m per object, its title beside the row;
    at most ``max_rows`` objects (those with a model first), the title saying how many of all."""
    plt = pyplot()
    total = len(items)
    if total > max_rows:  # a picture that stays a picture: 1000 x 36,000 px helps no one
        order = sorted(range(total), key=lambda k: not items[k].get("model"))
        items = [items[k] for k in sorted(order[:max_rows])]
    n = max(1, len(items))
    fig, (ax_l, ax_t) = plt.subplots(1, 2, figsize=(11, 1.2 + 0.9 * n), gridspec_kw={"width_ratios": [2.4, 1.0]})
    step = 2.5
    for ax, key in ((ax_l, "lon"), (ax_t, "tra")):
        for who, style in (("object", dict(s=4, marker="s", color="tab:blue")),
                           ("model", dict(s=2, color="tab:orange"))):
            parts = [np.asarray(it.get(who, {}).get(key)) + [0.0, -k * step] for k, it in enumerate(items)
                     if it.get(who, {}).get(key) is not None and len(it[who][key])]
            if parts:
                p = np.vstack(parts)
                ax.scatter(p[:, 0], p[:, 1], linewidths=0, **style)
    # each row's title as the left panel's tick label, outside the panes
    ax_l.set_yticks([-k * step + 1.0 for k in range(len(items))], [_short(it["title"]) for it in items], fontsize=6)
    ax_l.tick_params(axis="y", length=0)
    ax_t.set_yticks([])
    for ax, xl in ((ax_l, "u along heading (m)"), (ax_t, "v across (m)")):
        ax.set_aspect("equal")
        ax.set_xlabel(xl)
    ax_l.set_xlim(-3.7, 3.2)
    ax_t.set_xticks([-1, 0, 1])
    shown = f" ({len(items)} of {total} objects, those with a model first; all in sections.json)" \
        if total > len(items) else ""
    ax_l.set_title(f"longitudinal sections (blue: object, orange: registered model){shown}", fontsize=8)
    ax_t.set_title("transverse sections", fontsize=8)
    return save_figure(fig, path, tight=True, dpi=100)


def plot_taxonomy(folder: Path, names: list[str], matrix: np.ndarray, linkage: np.ndarray,
                  threshold: float) -> list[Path]:
    """heatmap.png and dendrogram.png (known as soon as the objects are clustered)."""
    folder = Path(folder)
    if len(names) < 2:
        return []
    return [plot_heatmap(matrix, names, folder / "heatmap.png"),
            plot_dendrogram(linkage, names, threshold, folder / "dendrogram.png")]


def short_reason(reason: str) -> str:
    """A no-match reason's gist (its first clause, models' names left out), for grouping and for table cells.

    >>> short_reason("the best model (uaz_469) fits only 15 cm sunk into the ground (at most 7 cm allowed)")
    'the best model fits only 15 cm sunk into the ground'
    """
    first = re.split(r"[;:]", reason or "no reason given", maxsplit=1)[0]
    first = re.sub(r"\s*\([^)]*\)", "", first).strip()
    return first if len(first) <= 60 else first[:57].rstrip() + "..."


def plot_confidence(twin: dict, path) -> Path:
    """The matches' confidence (0-1) as a histogram, the objects without a model beside it."""
    plt = pyplot()
    conf = [o["match"]["confidence"] for o in twin["objects"] if o["match"] and o["match"].get("confidence") is not None]
    fig, ax = plt.subplots(figsize=(4.2, 2.4))
    ax.hist(conf, bins=np.linspace(0, 1, 11), color="#2c7fb8", edgecolor="white")
    none = sum(1 for o in twin["objects"] if not o["match"])
    ax.set_xlabel("confidence of the match")
    ax.set_ylabel("objects")
    ax.set_title(f"{len(conf)} matched, {none} without a model", fontsize=9)
    return save_figure(fig, path, dpi=100)


STYLE = ("body{font-family:sans-serif;margin:1.2em 2em;color:#222}h1{font-size:1.4em;margin:.2em 0}"
         "td,th{padding:2px 8px;border-bottom:1px solid #ddd;text-align:left;white-space:nowrap;vertical-align:top}"
         "th{background:#f3f3f3}.lead{max-width:100%;max-height:68vh;border:1px solid #ddd}"
         ".row{display:flex;flex-wrap:wrap;gap:2em;align-items:flex-start;margin:1em 0}"
         "details{display:inline}summary{cursor:pointer}details[open] span{white-space:normal;display:block;"
         "max-width:40em}img.pic{max-width:100%}")


def text(x) -> str:
    """Anything as HTML text (quotes escaped too: also safe inside an attribute)."""
    return html.escape(str(x), quote=True)


def kinds_table(objects: list[dict]) -> str:
    """The objects by kind (most common first): how many, how many with a model, with a fused shape (their type's,
    or the kind's template), their median kind confidence."""
    by = defaultdict(list)
    for o in objects:
        by[o.get("kind") or "unknown"].append(o)
    rows = "".join(
        f"<tr><td>{text(k)}</td><td>{len(v)}</td><td>{sum(1 for o in v if o['match'])}</td>"
        f"<td>{sum(1 for o in v if (o.get('shape') or {}).get('source') in ('fused', 'generic'))}</td><td>"
        + text("" if not [o for o in v if o.get("kind_confidence") is not None] else
               f"{statistics.median(o['kind_confidence'] for o in v if o.get('kind_confidence') is not None):.2f}")
        + "</td></tr>" for k, v in sorted(by.items(), key=lambda kv: -len(kv[1])))
    return ("<table><tr><th>kind</th><th>objects</th><th>with a model</th><th>with a fused shape</th>"
            "<th>median kind confidence</th></tr>"
            f"{rows}</table>")


def _summary_tables(twin: dict) -> str:
    per_model = Counter((o["match"]["name"], o["match"].get("make") or "") for o in twin["objects"] if o["match"])
    why = Counter(short_reason(o.get("reason", "")) for o in twin["objects"] if not o["match"])
    models = "".join(f"<tr><td>{text(n)}</td><td>{text(m)}</td><td>{c}</td></tr>" for (n, m), c in per_model.most_common())
    reasons = "".join(f"<tr><td>{text(r)}</td><td>{c}</td></tr>" for r, c in why.most_common())
    return (kinds_table(twin["objects"]) + f"<table><tr><th>model</th><th>make</th><th>objects</th></tr>{models}</table>"
            f"<img class='pic' src='confidence.png' alt='confidence of the matches'>"
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
    """topview.png, confidence.png, sections.png and report.html (which also shows heatmap.png and
    dendrogram.png): the map of the twin over its scan first, then the summary (cars per model, the confidence
    histogram, the objects without a model by reason), a compact table (a no-match reason's gist, the full text on
    demand), the pictures. ``section_items`` None: sections.png is drawn by another process
    (:func:`plot_object_sections`), the page shows it all the same."""
    folder = Path(folder)
    top = plot_twin_top(path=folder / "topview.png", **top_png_args)
    conf = plot_confidence(twin, folder / "confidence.png")
    files = [folder / n for n in ("heatmap.png", "dendrogram.png")
             if len(twin["objects"]) >= 2 and twin.get("dissimilarity") is not None]
    files.append(folder / "sections.png" if section_items is None else
                 plot_object_sections(section_items, folder / "sections.png"))
    pics = "".join(f"<h2>{text(p.stem)}</h2><img class='pic' src='{text(p.name)}' alt='{text(p.stem)}'>" for p in files)
    matched = sum(1 for o in twin["objects"] if o["match"])
    page = (f"<!doctype html><html><head><meta charset='utf-8'><title>twin of {text(twin['scene'])}</title>"
            f"<style>{STYLE}</style></head><body>"
            f"<h1>Digital twin of {text(twin['scene'])}</h1><p>{len(twin['objects'])} objects, {matched} with a "
            f"model; the twin built in {twin['timing_s']['total']:.2f} s (before this report and the other files "
            "were written: the command's own time is longer).</p>"
            f"<img class='lead' src='topview.png' alt='the twin over its scan'>"
            f"<div class='row'>{_summary_tables(twin)}</div>"
            "<table><tr><th>object</th><th>points</th><th>size (m)</th><th>kind</th><th>type</th><th>model</th><th>RMSE</th>"
            "<th>confidence</th><th>ambiguous with</th><th>bearing (deg)</th><th>runner-up</th></tr>"
            + "".join(_object_row(o) for o in twin["objects"]) + "</table>" + pics + "</body></html>")
    (folder / "report.html").write_text(page, encoding="utf-8")
    return [top, conf] + files + [folder / "report.html"]
