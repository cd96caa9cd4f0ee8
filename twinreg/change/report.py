"""changes.html, a report a parking manager can read: for each epoch and the next, a map of the later scan with
every change drawn where it is in its status colour (the earlier footprint dashed, the later one filled, an arrow
for a moved car, red tint where the later survey has no returns), the counts, the occupancy of each epoch, and
the moved and replaced cars with their displacement. Every text from the twins is escaped."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..io import observed
from ..report.plots import pyplot, save_figure
from ..report.scene import text
from .footprints import record_corners

COLOURS = {"same": "#7f8c8d", "moved": "#e67e22", "replaced": "#8e44ad", "left": "#c0392b", "arrived": "#27ae60",
           "unobserved": "#b0b7bf"}
#: the map's background is drawn at most this many pixels across
MAP_PIXELS = 1000


def _background(record: observed.Record, lo, hi):
    pixel = max(observed.PIXEL, float(np.max(hi - lo)) / MAP_PIXELS)
    xs = np.arange(lo[0] + pixel / 2, hi[0], pixel)
    ys = np.arange(lo[1] + pixel / 2, hi[1], pixel)
    gx, gy = np.meshgrid(xs, ys, indexing="ij")
    code, _ = record.lookup(np.column_stack([gx.ravel(), gy.ravel()]))
    return observed.heights(code).reshape(len(xs), len(ys)), code.reshape(len(xs), len(ys)) == observed.NONE


def plot_step(doc: dict, epochs, k: int, path: Path) -> Path:
    """The map of the changes from epoch ``k`` to ``k + 1`` (coordinates of epoch ``k``)."""
    from matplotlib.collections import PolyCollection

    plt = pyplot()
    a, b = epochs[k], epochs[k + 1]
    shift = np.asarray(doc["alignment"][k]["shift"])
    lo = np.maximum(a.record.bounds()[0], b.record.bounds()[0] - shift[:2])
    hi = np.minimum(a.record.bounds()[1], b.record.bounds()[1] - shift[:2])
    ext = hi - lo
    scale = 11.0 / max(float(ext.max()), 1.0)
    fig, ax = plt.subplots(figsize=(max(4.0, ext[0] * scale + 2.8), max(3.0, ext[1] * scale + 1.2)))
    top, empty = _background(b.record, lo + shift[:2], hi + shift[:2])
    extent = [lo[0], hi[0], lo[1], hi[1]]
    ax.imshow(top.T, origin="lower", cmap="Greys", vmin=-0.5, vmax=4.0, interpolation="nearest", extent=extent)
    tint = np.where(empty, 1.0, np.nan)
    ax.imshow(tint.T, origin="lower", cmap="Reds", vmin=0, vmax=2.5, alpha=0.35, interpolation="nearest",
              extent=extent)
    steps = [c for c in doc["changes"] if c["from"] == k]
    for status, colour in COLOURS.items():
        sel = [c for c in steps if c["status"] == status]
        before = [c["before"] for c in sel if c["before"] is not None]
        after = [dict(c["after"], centroid=list(np.asarray(c["after"]["centroid"]) - shift)) for c in sel
                 if c["after"] is not None]
        if before:
            ax.add_collection(PolyCollection(record_corners(before), facecolors="none", edgecolors=colour,
                                             linewidths=0.9, linestyles="--"))
        if after:
            ax.add_collection(PolyCollection(record_corners(after), facecolors=colour, edgecolors=colour, alpha=0.55,
                                             linewidths=0.6))
        ax.plot([], [], color=colour, lw=6, alpha=0.7, label=f"{status} ({len(sel)})")
        if status == "moved" and sel:  # one arrow per moved car, drawn as one artist
            p = np.array([c["before"]["centroid"][:2] for c in sel])
            q = np.array([c["after"]["centroid"][:2] for c in sel]) - shift[:2]
            ax.quiver(p[:, 0], p[:, 1], q[:, 0] - p[:, 0], q[:, 1] - p[:, 1], angles="xy", scale_units="xy",
                      scale=1.0, width=0.002, color="black")
    ax.plot([], [], color="#f4b6b0", lw=6, label="no returns later")
    ax.set_xlim(lo[0], hi[0])
    ax.set_ylim(lo[1], hi[1])
    ax.set_aspect("equal")
    ax.ticklabel_format(useOffset=False, style="plain")
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    ax.set_title(f"{a.date or 'epoch %d' % k} -> {b.date or 'epoch %d' % (k + 1)}: dashed before, filled after")
    ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=8, frameon=False)
    return save_figure(fig, path, dpi=110)


def plot_occupancy(doc: dict, path: Path) -> Path:
    plt = pyplot()
    rows = doc["occupancy"]["epochs"]
    fig, ax = plt.subplots(figsize=(max(3.5, 1.1 * len(rows) + 1.5), 2.8))
    labels = [r["date"] or f"epoch {r['epoch']}" for r in rows]
    ax.bar(labels, [r["n_in_common_area"] for r in rows], color="#2c7fb8")
    ax.set_ylabel("cars where every survey saw")
    ax.set_title(f"occupancy ({doc['occupancy']['common_area_m2']:,.0f} m2 seen by all)")
    return save_figure(fig, path, dpi=110)


def _table(head: list[str], rows: list[list]) -> str:
    out = ["<table><tr>" + "".join(f"<th>{text(h)}</th>" for h in head) + "</tr>"]
    out += ["<tr>" + "".join(f"<td>{text(v)}</td>" for v in r) + "</tr>" for r in rows]
    return "\n".join(out) + "</table>"


def _moved_rows(doc: dict, epochs) -> list[list]:
    rows = []
    for c in doc["changes"]:
        if c["status"] in ("moved", "replaced"):
            rows.append([f"{epochs[c['from']].date or c['from']} -> {epochs[c['to']].date or c['to']}", c["status"],
                         f"{c['before']['id']} ({c['before']['model'] or 'no model'})",
                         f"{c['after']['id']} ({c['after']['model'] or 'no model'})",
                         f"{c['displacement_m']:.2f}", f"{np.degrees(c['turn_rad']):.1f}", f"{c['confidence']:.2f}"])
    return rows


STYLE = """body{font-family:sans-serif;margin:1.5em;max-width:1200px;color:#222}table{border-collapse:collapse;
margin:.5em 0 1.2em}td,th{border:1px solid #ccc;padding:2px 8px;text-align:left;white-space:nowrap}
th{background:#f2f2f2}img{max-width:100%;border:1px solid #ddd}.note{color:#555;font-size:.9em}"""


def write_report(stage: Path, doc: dict, epochs) -> None:
    """changes.html and its PNGs (changes_K.png for each step, occupancy.png) in ``stage``."""
    parts = [f"<!doctype html><html><head><meta charset='utf-8'><title>twinreg: changes</title>"
             f"<style>{STYLE}</style></head><body><h1>What changed: {len(epochs)} surveys</h1>"]
    parts.append(_table(["epoch", "date", "twin", "objects", "point spacing (m)"],
                        [[k, e["date"] or "(none)", Path(e["twin"]).name, e["n_objects"], e["spacing_m"]]
                         for k, e in enumerate(doc["epochs"])]))
    for k, s in enumerate(doc["summary"]):
        plot_step(doc, epochs, k, stage / f"changes_{k}.png")
        al = doc["alignment"][k]
        shift = ", ".join(f"{v * 100:+.1f}" for v in al["shift"])
        parts.append(f"<h2>{text(epochs[k].date or k)} to {text(epochs[k + 1].date or k + 1)}</h2>")
        parts.append(f"<img src='changes_{k}.png' alt='map of the changes'>")
        parts.append(_table(["same", "moved", "replaced", "left", "arrived", "unobserved"],
                            [[s[c] for c in ("same", "moved", "replaced", "left", "arrived", "unobserved")]]))
        parts.append(f"<p class='note'>The later survey is offset by {text(shift)} cm (x, y, z) from the earlier one, "
                     f"estimated from {al['n_pairs']} vehicles that stayed (residual "
                     f"{text('-' if al['rms_m'] is None else round(al['rms_m'] * 100, 1))} cm) and "
                     f"{al['n_ground']:,} ground pixels; positions are compared after removing it. "
                     f"{text(al.get('note', ''))}</p>")
    plot_occupancy(doc, stage / "occupancy.png")
    parts.append("<h2>Occupancy</h2><img src='occupancy.png' alt='occupancy per epoch'>")
    parts.append(_table(["epoch", "date", "objects", "in the area every survey saw", "per hectare"],
                        [[r["epoch"], r["date"] or "(none)", r["n_objects"], r["n_in_common_area"], r["per_hectare"]]
                         for r in doc["occupancy"]["epochs"]]))
    moved = _moved_rows(doc, epochs)
    parts.append(f"<h2>Moved and replaced ({len(moved)})</h2>")
    parts.append(_table(["when", "status", "before", "after", "displacement (m)", "turn (deg)", "confidence"], moved))
    stays = [t["days"] for t in doc["tracks"] if t["days"] is not None and len(t["epochs"]) > 1]
    parts.append(f"<h2>Vehicles</h2><p>{len(doc['tracks'])} vehicles seen; {len(stays)} seen in more than one "
                 f"survey" + (f", for {np.median(stays):.0f} days (median)" if stays else "") + ".</p>")
    parts.append("<p class='note'>Statuses: same, moved (the same vehicle re-parked), replaced (another vehicle in "
                 "its footprint), left (the later survey saw the ground there), arrived, unobserved (a survey has no "
                 "returns there: never counted as left or arrived). changes.json holds every object's record and "
                 "reason; changes.geojson the footprints for a GIS.</p></body></html>")
    (stage / "changes.html").write_text("\n".join(parts), encoding="utf-8")
