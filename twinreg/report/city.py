"""report.html of a tiled run: a summary that stays readable for thousands of objects (counts per model and per
cell, a map of the city, histograms, and the taxonomy of cluster representatives) instead of the per-scene
report's n x n heat map and per-object sections."""

from __future__ import annotations

import html
from collections import Counter
from pathlib import Path

import numpy as np

import cosco

from ..io.observed import heights
from ..settings import DEFAULT
from .plots import plot_dendrogram, pyplot, save_figure
from .scene import STYLE, kinds_table, short_reason

#: at most this many cluster representatives (the largest clusters) in the report's dendrogram
MAX_REPRESENTATIVES = 30


def plot_city_map(results, objects, outcomes, plan, path):
    """Height above ground of every cell (grey) with the objects: matched (coloured by model), unmatched (red)."""
    plt = pyplot()
    lo = np.min([r.lo for r in results], axis=0)
    hi = np.max([r.hi for r in results], axis=0)
    ext = hi - lo
    scale = 12.0 / max(ext.max(), 1.0)
    fig, ax = plt.subplots(figsize=(max(4.0, ext[0] * scale + 2.5), max(3.0, ext[1] * scale + 1.0)))
    for r in results:
        if r.observed is None:
            continue
        o = r.observed
        ax.imshow(heights(o.code).T, origin="lower", cmap="Greys", vmin=-0.5, vmax=4.0, interpolation="nearest",
                  extent=[o.lo[0], o.hi[0], o.lo[1], o.hi[1]])
    for c in plan.cells.values():
        ax.plot([c.lo[0], c.hi[0], c.hi[0], c.lo[0], c.lo[0]], [c.lo[1], c.lo[1], c.hi[1], c.hi[1], c.lo[1]],
                color="tab:blue", lw=0.4, alpha=0.6)
    xy = np.array([o.shape.centroid[:2] + o.offset[:2] for o in objects]).reshape(-1, 2)
    names = [res.match.name if res.match is not None else None for res in outcomes]
    counts = Counter(n for n in names if n)
    cmap = plt.get_cmap("tab20")
    for k, (name, count) in enumerate(counts.most_common()):
        sel = np.array([n == name for n in names])
        ax.scatter(xy[sel, 0], xy[sel, 1], s=4, color=cmap(k % 20), label=f"{name} ({count})" if k < 20 else None)
    miss = np.array([n is None for n in names])
    if miss.any():
        ax.scatter(xy[miss, 0], xy[miss, 1], s=8, marker="x", color="red", lw=0.6, label=f"no model ({miss.sum()})")
    ax.set_xlim(lo[0], hi[0])
    ax.set_ylim(lo[1], hi[1])
    ax.set_aspect("equal")
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    ax.ticklabel_format(useOffset=False, style="plain")
    ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=6, markerscale=2, frameon=False)
    ax.set_title(f"{len(objects)} objects in {len(results)} cells")
    return save_figure(fig, path, dpi=110)


def plot_histograms(twin: dict, path):
    """Measured length of the objects, RMSE of the matches, share of points the accepted model leaves
    unexplained."""
    plt = pyplot()
    objs = twin["objects"]
    fig, axes = plt.subplots(1, 3, figsize=(11, 3))
    axes[0].hist([o["measured_size"]["length"] for o in objs], bins=40, color="0.4")
    axes[0].set_xlabel("measured length (m)")
    m = [o["match"] for o in objs if o["match"]]
    axes[1].hist([x["rmse_m"] * 100 for x in m], bins=40, color="tab:blue")
    axes[1].set_xlabel("section RMSE of the match (cm)")
    axes[2].hist([x["verification"]["outlier_share"] * 100 for x in m if x.get("verification")], bins=40,
                 color="tab:green")
    axes[2].set_xlabel("points not explained by the model (%)")
    for ax in axes:
        ax.set_ylabel("objects")
    return save_figure(fig, path)


def plot_representatives(objects, outcomes, labels, path, params):
    """The dendrogram of the largest clusters' first objects (the paper's taxonomy at the level of kinds)."""
    sizes = Counter(int(x) for x in labels)
    top = [lab for lab, _ in sizes.most_common(MAX_REPRESENTATIVES)]
    if len(top) < 2:
        return None
    first = {}
    for i, lab in enumerate(labels):
        first.setdefault(int(lab), i)
    reps = [first[lab] for lab in top]
    matrix = cosco.dissimilarity_matrix([objects[i].shape.sections for i in reps], params)
    clusters = cosco.cluster(matrix, params)
    names = [f"{objects[i].id} ({outcomes[i].match.name if outcomes[i].match else 'no model'}, x{sizes[lab]})"
             for i, lab in zip(reps, top)]
    return plot_dendrogram(clusters.linkage, names, clusters.threshold, path)


def write_city_report(folder, twin: dict, results, objects, outcomes, plan, params=None) -> list[Path]:
    """map.png, histograms.png, taxonomy.png and report.html: the map first, then the cars per model and the
    objects without a model by reason, the pictures, the cells."""
    folder = Path(folder)
    labels = [o["cluster"] for o in twin["objects"]]
    pics = [plot_city_map(results, objects, outcomes, plan, folder / "map.png"),
            plot_histograms(twin, folder / "histograms.png")]
    rep = plot_representatives(objects, outcomes, labels, folder / "taxonomy.png", params or DEFAULT)
    if rep is not None:
        pics.append(rep)
    objs = twin["objects"]
    by_model = Counter(o["match"]["name"] if o["match"] else "(no model)" for o in objs)
    rmse = {}
    for o in objs:
        if o["match"]:
            rmse.setdefault(o["match"]["name"], []).append(o["match"]["rmse_m"])
    model_rows = "".join(
        f"<tr><td>{html.escape(name)}</td><td>{n}</td><td>"
        f"{np.median(rmse[name]) * 100:.1f} cm</td></tr>" if name in rmse else
        f"<tr><td>{html.escape(name)}</td><td>{n}</td><td></td></tr>" for name, n in by_model.most_common())
    cell_rows = "".join(
        f"<tr><td>{html.escape(c['name'])}</td><td>{c['n_points']:,}</td><td>{c['n_objects']}</td>"
        f"<td>{c['n_matched']}</td><td>{c['noise_m'] * 100:.1f} cm</td>"
        f"<td>{sum(c['timing_s'].values()):.1f} s</td></tr>" for c in twin["cells"])
    reasons = Counter(short_reason(o.get("reason", "")) for o in objs if not o["match"])
    reason_rows = "".join(f"<tr><td>{html.escape(r)}</td><td>{n}</td></tr>" for r, n in reasons.most_common())
    n_matched = sum(1 for o in objs if o["match"])
    t = twin.get("timing_s", {})
    page = (
        "<!doctype html><html><head><meta charset='utf-8'>"
        f"<title>twin of {html.escape(twin['scene'])}</title><style>{STYLE}</style></head><body>"
        f"<h1>Digital twin of {html.escape(twin['scene'])}</h1>"
        f"<p>{len(objs)} objects, {n_matched} with a model; {twin['n_points']:,} points in "
        f"{twin['grid']['n_cells']} cells of {twin['grid']['cell_m']:g} m"
        + (f"; built in {t['total']:.1f} s" if t.get("total") else "") + ".</p>"
        f"<img class='lead' src='{pics[0].name}' alt='the city map'>"
        "<div class='row'>" + kinds_table(objs) + "<table><tr><th>model</th><th>objects</th><th>median RMSE</th></tr>"
        + model_rows
        + "</table>"
        + (f"<table><tr><th>without a model, because</th><th>objects</th></tr>{reason_rows}</table>"
           if reason_rows else "") + "</div>"
        f"<p>{twin['clustering']['n_clusters']} clusters ({twin['clustering']['method']} taxonomy, "
        f"{twin['clustering']['n_comparisons']:,} comparisons), {twin['matching']['n_trials']:,} registration "
        f"trials; cells with a buffer of {twin['grid']['buffer_m']:g} m.</p>"
        + "".join(f"<h2>{html.escape(p.stem)}</h2><img class='pic' src='{p.name}' alt='{html.escape(p.stem)}'>"
                  for p in pics[1:])
        + "<h2>Cells</h2><table><tr><th>cell</th><th>points</th><th>objects</th><th>matched</th><th>noise</th>"
        "<th>worker time</th></tr>" + cell_rows + "</table></body></html>")
    (folder / "report.html").write_text(page, encoding="utf-8")
    return pics + [folder / "report.html"]
