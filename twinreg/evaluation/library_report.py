"""What the catalogue can and cannot do, before any scan: ``twinreg library-report [--density D] [--out DIR]``.

``DIR/library.json`` (schema: docs/schemas/library-report.schema.json) and ``DIR/library.html`` with:

- a gallery: each model's sampled surface seen from the top, the side and the front, its sizes, PCR, sections,
  provenance (file, sha256, unit and axes as resolved) and tags;
- the catalogue's own taxonomy (the paper's section dissimilarity between every pair of models, heat map and
  dendrogram) and its near-duplicates (:mod:`twinreg.catalogue.duplicates`: surface distance under 3 cm);
- confusability at the survey's density: every model placed between two neighbours (other models, 0.4-1.0 m
  apart, which hide part of its sides), at a random heading, scanned ``scans`` times by the simulator's oblique
  passes at that density with 2 cm noise, its points matched against the whole catalogue as build-twin does; the
  confusion matrix, each model's top-1 rate, which models steal it, and the pairs a scan of that density cannot
  tell apart. Each scan is seeded by (seed, model, scan): the same report every time, whatever the number of
  worker processes (``workers``) the models are spread over.
"""

from __future__ import annotations

import html
import json
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np

import cosco

from ..catalogue.duplicates import NEAR_DUPLICATE_M, surface_distance
from ..catalogue.repository import Catalogue
from ..errors import CatalogueError
from ..io.outdir import staged_folder
from ..matching.match import Evidence, ModelCache, match_objects
from ..progress import say
from ..report.plots import pyplot
from ..settings import DEFAULT
from ..sim.accuracy import density_passes
from ..sim.scan import pose_matrix, scan_meshes, transform

#: a pair is "cannot be told apart" when either is taken for the other in at least this share of its scans
CONFUSED_SHARE = 0.2


def _scan_one(folder: str, k: int, density: float, scans: int, seed: int) -> list:
    """The models (names, or None) that ``scans`` simulated scans of model ``k`` were matched to."""
    cat = Catalogue(folder, create=False)
    rows = sorted(cat.list(), key=lambda r: r.id)
    meshes = cat.scan_meshes(rows)
    cache = ModelCache(cat, DEFAULT)
    out = []
    for s in range(scans):
        rng = np.random.default_rng([seed, k, s])
        others = [j for j in range(len(rows)) if j != k]
        left, right = rng.choice(others, 2, replace=len(others) < 2) if others else (k, k)
        placed = []
        heading = rng.uniform(0, 2 * np.pi)
        for j, side in ((left, -1), (k, 0), (right, 1)):
            v, f, g = meshes[j]
            width = np.ptp(v[:, 1])
            gap = rng.uniform(0.4, 1.0)
            offset = 0.0 if side == 0 else side * (np.ptp(meshes[k][0][:, 1]) / 2 + gap + width / 2)
            flip = np.pi if rng.random() < 0.3 else 0.0
            h = heading + flip + rng.normal(0, 0.05) if side else heading
            placed.append((transform(v, pose_matrix(0.0, offset, h)), f, g))
        ground = (np.array([[-6, -8, 0], [6, -8, 0], [6, 8, 0], [-6, 8, 0.0]]), np.array([[0, 1, 2], [0, 2, 3]]))
        sc = scan_meshes(placed + [ground], passes=density_passes(density), noise=0.02,
                         seed=int(rng.integers(1 << 31)))
        pts = sc.points[sc.labels == 1]
        if len(pts) < 20:
            out.append(None)
            continue
        shape = cosco.describe_object(pts, DEFAULT, ground_z=0.0)
        res, _ = match_objects([shape], cat, evidence=Evidence([pts], 0.02), cache=cache)
        out.append(res[0].match.name if res[0].match is not None else None)
    return out


def confusion(catalogue, density: float, scans: int = 10, seed: int = 0, workers: int = 2) -> dict:
    """Confusion of every model at ``density`` (pts/m^2): rows are the scanned models, columns what they were
    matched to (the last column: no model)."""
    rows = sorted(catalogue.list(), key=lambda r: r.id)
    names = [r.name for r in rows]
    args = [(str(catalogue.folder), k, density, scans, seed) for k in range(len(rows))]
    if workers > 1:
        import multiprocessing

        with ProcessPoolExecutor(workers, mp_context=multiprocessing.get_context("spawn")) as pool:
            got = list(pool.map(_scan_one, *zip(*args)))
    else:
        got = [_scan_one(*a) for a in args]
    m = np.zeros((len(rows), len(rows) + 1), dtype=int)
    for k, g in enumerate(got):
        for name in g:
            m[k, names.index(name) if name in names else len(rows)] += 1
    return {"density": density, "scans_per_model": scans, "seed": seed, "names": names, "matrix": m.tolist()}


def taxonomy(catalogue) -> dict:
    """The paper's section dissimilarity between every pair of models, their clusters, and the near-duplicates."""
    rows = sorted(catalogue.list(), key=lambda r: r.id)
    geo = [catalogue.geometry(r, with_mesh=False) for r in rows]
    matrix = cosco.dissimilarity_matrix([g.sections for g in geo], DEFAULT)
    clusters = cosco.cluster(matrix, DEFAULT) if len(rows) > 1 else None
    near = []
    for i in range(len(rows)):
        for j in range(i + 1, len(rows)):
            if np.all(np.abs(geo[i].size - geo[j].size) <= 0.3):
                d = surface_distance(geo[i].points, geo[j].points)
                if d < NEAR_DUPLICATE_M:
                    near.append({"a": rows[i].name, "b": rows[j].name, "surface_distance_m": round(d, 4),
                                 "section_dissimilarity_m": round(float(matrix[i, j]), 4)})
    return {"names": [r.name for r in rows], "dissimilarity_m": np.round(matrix, 4).tolist(),
            "clusters": clusters.labels.tolist() if clusters is not None else [1] * len(rows),
            "linkage": clusters.linkage.tolist() if clusters is not None else [],
            "near_duplicates": near, "near_duplicate_m": NEAR_DUPLICATE_M}


def _pairs_confused(conf: dict) -> list[dict]:
    """Pairs of models one of which is taken for the other in at least CONFUSED_SHARE of its scans."""
    names, m = conf["names"], np.array(conf["matrix"])
    n = m.sum(1)
    out = []
    for i in range(len(names)):
        for j in range(i + 1, len(names)):
            a, b = m[i, j] / max(n[i], 1), m[j, i] / max(n[j], 1)
            if max(a, b) >= CONFUSED_SHARE:
                out.append({"a": names[i], "b": names[j], "a_taken_for_b": round(float(a), 3),
                            "b_taken_for_a": round(float(b), 3),
                            "text": f"{names[i]} and {names[j]}: at {conf['density']:g} pts/m2 a scan of one is taken "
                                    f"for the other {max(a, b):.0%} of the time"})
    return out


def report(catalogue, out, density: float = 20.0, scans: int = 10, seed: int = 0, workers: int = 2,
           progress=None) -> dict:
    """Write library.json, library.html and the pictures to ``out`` (a staged folder: all or nothing)."""
    t0 = time.perf_counter()
    if catalogue.count() == 0:
        raise CatalogueError(f"{catalogue.folder}: the catalogue is empty; add models first")
    rows = sorted(catalogue.list(), key=lambda r: r.id)
    say(progress, "taxonomy")
    tax = taxonomy(catalogue)
    say(progress, f"confusability: {scans} scans of each of {len(rows)} models at {density:g} pts/m2")
    conf = confusion(catalogue, density, scans, seed, workers)
    m = np.array(conf["matrix"])
    names = conf["names"]
    dup_of = {}
    for d in tax["near_duplicates"]:
        dup_of.setdefault(d["a"], []).append(d["b"])
        dup_of.setdefault(d["b"], []).append(d["a"])
    models = []
    for k, r in enumerate(rows):
        n = int(m[k].sum())
        steals = {names[j]: int(m[k, j]) for j in np.argsort(-m[k, :-1]) if j != k and m[k, j] > 0}
        d = r.to_dict()
        models.append({"id": r.id, "name": r.name, "make": r.make, "model": r.model, "body_class": r.body_class,
                       "tags": r.tags, "size": d["size"], "mesh_size": d["mesh_size"], "pcr": d["symmetry"]["pcr"],
                       "provenance": {"file": r.source_name, "sha256": r.sha256, "unit": r.unit,
                                      "unit_source": r.unit_source, "up": r.up_axis, "front": r.front_axis,
                                      "notes": r.notes},
                       "near_duplicates": dup_of.get(r.name, []),
                       "top1": round(float(m[k, k]) / max(n, 1), 3), "no_model": round(float(m[k, -1]) / max(n, 1), 3),
                       "taken_for": steals, "picture": f"models/{r.id}.png"})
    doc = {"catalogue": str(catalogue.folder), "n_models": len(rows), "density": density, "scans_per_model": scans,
           "seed": seed, "models": models, "taxonomy": tax, "confusion": conf,
           "cannot_tell_apart": _pairs_confused(conf)}
    with staged_folder(Path(out), protect=[catalogue.folder], kind="library report") as stage:
        (stage / "models").mkdir()
        say(progress, "pictures")
        for r in rows:
            _model_picture(catalogue, r, stage / "models" / f"{r.id}.png")
        _heatmap(tax, stage / "taxonomy.png")
        _confusion_picture(conf, stage / "confusion.png")
        doc["timing_s"] = round(time.perf_counter() - t0, 2)
        (stage / "library.json").write_text(json.dumps(doc, indent=1), encoding="utf-8")
        (stage / "library.html").write_text(_html(doc), encoding="utf-8")
    return doc


def _model_picture(catalogue, row, path) -> None:
    """Top, side and front views of the model's sampled surface, and its two sections."""
    plt = pyplot()

    g = catalogue.geometry(row, with_mesh=False)
    p = g.points
    fig, axes = plt.subplots(1, 4, figsize=(10, 2.2))
    for ax, (i, j, c, title) in zip(axes, ((0, 1, 2, "top"), (0, 2, 1, "side"), (1, 2, 0, "front"))):
        order = np.argsort(p[:, c]) if title != "front" else np.argsort(-p[:, c])
        ax.scatter(p[order, i], p[order, j], c=p[order, c], s=0.6, cmap="viridis")
        ax.set_aspect("equal")
        ax.set_title(title, fontsize=8)
        ax.tick_params(labelsize=6)
    lon, tra = g.sections.longitudinal, g.sections.transverse
    axes[3].scatter(lon[:, 0], lon[:, 1], s=1.5, c="#36c", label="longitudinal")
    axes[3].scatter(tra[:, 0], tra[:, 1], s=1.5, c="#d33", label="transverse")
    axes[3].set_aspect("equal")
    axes[3].set_title("sections", fontsize=8)
    axes[3].tick_params(labelsize=6)
    fig.suptitle(f"{row.name}: {row.length:.2f} x {row.width:.2f} x {row.height:.2f} m", fontsize=9)
    fig.tight_layout()
    fig.savefig(path, dpi=80)
    plt.close(fig)


def _heatmap(tax: dict, path) -> None:
    plt = pyplot()
    from scipy.cluster.hierarchy import dendrogram

    names, m = tax["names"], np.array(tax["dissimilarity_m"])
    fig, (a1, a2) = plt.subplots(1, 2, figsize=(12, 5))
    im = a1.imshow(m * 100, cmap="magma_r")
    a1.set_xticks(range(len(names)), names, rotation=90, fontsize=6)
    a1.set_yticks(range(len(names)), names, fontsize=6)
    fig.colorbar(im, ax=a1, label="section dissimilarity (cm)")
    if tax["linkage"]:
        dendrogram(np.array(tax["linkage"]), labels=names, ax=a2, leaf_font_size=6, orientation="right")
        a2.axvline(DEFAULT.taxonomy.threshold, color="#888", ls="--", lw=0.8)
    a2.set_xlabel("dissimilarity (m)")
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    plt.close(fig)


def _confusion_picture(conf: dict, path) -> None:
    plt = pyplot()

    names, m = conf["names"], np.array(conf["matrix"], dtype=float)
    share = m / np.maximum(m.sum(1, keepdims=True), 1)
    fig, ax = plt.subplots(figsize=(7, 6))
    im = ax.imshow(share * 100, cmap="Blues", vmin=0, vmax=100)
    ax.set_xticks(range(len(names) + 1), names + ["(no model)"], rotation=90, fontsize=6)
    ax.set_yticks(range(len(names)), names, fontsize=6)
    ax.set_xlabel("matched to")
    ax.set_ylabel("scanned")
    fig.colorbar(im, ax=ax, label="% of the scans")
    ax.set_title(f"{conf['scans_per_model']} scans per model at {conf['density']:g} pts/m2", fontsize=9)
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    plt.close(fig)


def _html(doc: dict) -> str:
    e = html.escape
    cards = []
    for m in doc["models"]:
        p = m["provenance"]
        s = m["size"]
        taken = ", ".join(f"{e(k)} ({v})" for k, v in m["taken_for"].items()) or "none"
        cards.append(
            f"<div class='card' id='model-{m['id']}'><img src='{e(m['picture'])}' alt='{e(m['name'])}'>"
            f"<h3>{e(m['name'])}</h3><p>{e(m['make'] or '')} {e(m['model'] or '')} &middot; {e(m['body_class'] or '')}"
            f" &middot; tags: {e(', '.join(m['tags']) or 'none')}</p>"
            f"<p>{s['length']:.2f} x {s['width']:.2f} x {s['height']:.2f} m, PCR {m['pcr']:.2f}; top-1 at "
            f"{doc['density']:g} pts/m2: <b>{m['top1']:.0%}</b>; taken for: {taken}</p>"
            f"<p class='prov'>{e(p['file'])}, sha256 {e(p['sha256'][:16])}..., unit {e(p['unit'])} "
            f"({e(p['unit_source'])}), up {e(p['up'])}, front {e(p['front'])}</p>"
            + (f"<p class='warn'>near-duplicate of {e(', '.join(m['near_duplicates']))}</p>"
               if m["near_duplicates"] else "") + "</div>")
    dups = "".join(f"<li>{e(d['a'])} and {e(d['b'])}: surfaces {d['surface_distance_m'] * 100:.1f} cm apart</li>"
                   for d in doc["taxonomy"]["near_duplicates"]) or "<li>none</li>"
    pairs = "".join(f"<li>{e(p['text'])}</li>" for p in doc["cannot_tell_apart"]) or "<li>none</li>"
    return ("<!doctype html><html><head><meta charset='utf-8'><title>twinreg library report</title><style>"
            "body{font-family:sans-serif;margin:1.5em;color:#222}.cards{display:flex;flex-wrap:wrap;gap:12px}"
            ".card{border:1px solid #ccc;border-radius:6px;padding:8px;width:560px}.card img{width:100%}"
            ".card h3{margin:4px 0}.card p{margin:3px 0;font-size:13px}.prov{color:#666}.warn{color:#b40}"
            "img.wide{max-width:100%}</style></head><body>"
            f"<h1>Library report: {doc['n_models']} models</h1>"
            f"<p>{e(doc['catalogue'])}; confusability at {doc['density']:g} pts/m2, {doc['scans_per_model']} scans "
            f"per model, seed {doc['seed']}; written in {doc.get('timing_s', 0):.1f} s.</p>"
            f"<h2>Pairs a scan of {doc['density']:g} pts/m2 cannot tell apart</h2><ul id='confused'>{pairs}</ul>"
            f"<h2>Near-duplicates</h2><ul id='duplicates'>{dups}</ul>"
            "<h2>Confusion</h2><img class='wide' src='confusion.png' alt='confusion matrix'>"
            "<h2>Taxonomy</h2><img class='wide' src='taxonomy.png' alt='dissimilarity and dendrogram'>"
            f"<h2>Gallery</h2><div class='cards'>{''.join(cards)}</div></body></html>")
