"""What the catalogue lacks, read from real twins: ``twinreg coverage OUT/twin.json ...``.

The objects of the twins that got no model, or one outside the size window, are grouped by their measured size
(cells of ``LENGTH_BIN`` x ``WIDTH_BIN`` metres); each group is reported with its size range and the catalogue model
nearest to it, and a group with no model in the matcher's size window is a size the catalogue is missing. The
window is the one the twin was matched with (its ``matching.tol_m`` and ``tol_spacing_k``, the defaults of
:class:`twinreg.settings.Settings` otherwise): a model may be ``tol`` smaller and ``tol`` plus ``tol_spacing_k``
point spacings larger in length and width (the spacing estimated from each object's points over its footprint).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..errors import SceneReadError
from ..io._files import MAX_TWIN_BYTES, read_json_doc
from ..report.plots import pyplot, save_figure
from ..settings import DEFAULT

LENGTH_BIN = 0.5
WIDTH_BIN = 0.3


def read_objects(paths) -> list[dict]:
    """Every object of the twin.json files (each with its ``twin`` path)."""
    out = []
    for p in paths:
        p = Path(p)
        if not p.is_file():
            raise SceneReadError(f"{p}: no such file; give OUT/twin.json of a folder build-twin wrote")
        doc = read_json_doc(p, MAX_TWIN_BYTES, SceneReadError, "give OUT/twin.json of a folder build-twin wrote")
        try:
            objs = doc["objects"]
            if not isinstance(objs, list):
                raise TypeError("its objects are not a list")
            m = doc.get("matching", {})
            window = (float(m.get("tol_m", DEFAULT.matching.size_tol)),
                      float(m.get("tol_spacing_k", DEFAULT.matching.size_spacing_k)))
        except (OSError, ValueError, KeyError, TypeError, AttributeError) as exc:
            raise SceneReadError(f"{p}: not a twin.json written by build-twin ({exc}); give OUT/twin.json") from exc
        out += [o | {"twin": str(p), "window": window} for o in objs]
    return out


def coverage(objects: list[dict], models: np.ndarray, names: list[str], kinds: list[str] | None = None) -> dict:
    """Groups of the objects with no model (or one outside the window) by kind and measured size, each with the
    nearest catalogue model of its kind (of any kind when it has none or is unknown). ``models``: (m, 3) L, W, H
    of the catalogue's models, ``names`` and ``kinds`` (categories; None: all cars) theirs. A twin written
    before kinds counts its objects as cars."""
    kinds = ["car"] * len(names) if kinds is None else list(kinds)
    lacking = [o for o in objects if not o.get("match") or o["match"].get("outside_tolerance")]
    sizes = np.array([[o["measured_size"]["length"], o["measured_size"]["width"], o["measured_size"]["height"]]
                      for o in lacking]).reshape(-1, 3)
    groups = {}
    for o, s in zip(lacking, sizes):
        kind = str(o.get("kind") or "car")
        groups.setdefault((kind, int(s[0] // LENGTH_BIN), int(s[1] // WIDTH_BIN)), []).append((o, s))
    out = []
    per_kind: dict = {}
    for o in objects:
        k = str(o.get("kind") or "car")
        entry = per_kind.setdefault(k, {"n_objects": 0, "n_lacking": 0})
        entry["n_objects"] += 1
        entry["n_lacking"] += int(not o.get("match") or bool(o["match"].get("outside_tolerance")))
    for (kind, _, _), members in sorted(groups.items(), key=lambda kv: (-len(kv[1]), kv[0])):
        s = np.array([m[1] for m in members])
        lo, hi = s.min(0), s.max(0)
        tol, grow = window_of([m[0] for m in members])
        centre = (lo + hi) / 2
        g = {"kind": kind, "n_objects": len(members), "window_m": {"smaller": round(tol, 3), "larger": round(tol + grow, 3)}, "length_m": [round(lo[0], 2), round(hi[0], 2)],
             "width_m": [round(lo[1], 2), round(hi[1], 2)], "height_m": [round(lo[2], 2), round(hi[2], 2)],
             "n_no_model": sum(1 for m in members if not m[0].get("match")), "objects": [m[0]["id"] for m in members]}
        same = np.array([k == kind for k in kinds], dtype=bool)
        pool = np.flatnonzero(same) if same.any() else np.arange(len(names))
        if len(pool):
            # how far each model's size lies outside the group's range (0 inside), in metres summed
            larger = np.array([tol + grow, tol + grow, tol])
            gap = np.maximum(np.maximum(lo - tol - models[pool], models[pool] - hi - larger), 0).sum(1)
            k = int(pool[np.argmin(np.abs(models[pool] - centre).sum(1))])
            g["nearest_model"] = {"name": names[k], "kind": kinds[k],
                                  "size_gap_m": [round(v, 2) for v in models[k] - centre]}
            g["models_within_tol"] = int((gap == 0).sum())
        g["text"] = _text(g)
        out.append(g)
    return {"n_objects": len(objects), "n_lacking": len(lacking), "per_kind": per_kind, "groups": out}


def window_of(objects: list[dict]) -> tuple[float, float]:
    """(tol, grow) m of the matcher's size window for these objects: the twin's tolerance, and its spacing factor
    times the objects' median point spacing (estimated as sqrt(footprint / points); 0 when a record has no point
    count)."""
    windows = np.array([o.get("window", (DEFAULT.matching.size_tol, DEFAULT.matching.size_spacing_k)) for o in objects])
    tol, k = (float(v) for v in np.median(windows, axis=0))
    spacing = np.median([np.sqrt(o["measured_size"]["length"] * o["measured_size"]["width"] / o["n_points"])
                         if o.get("n_points") else 0.0 for o in objects])  # unknown: the plain tolerance
    return tol, k * float(spacing)


def _text(g: dict) -> str:
    """One line for a group, e.g. "14 cars 3.2-3.6 m long, 1.5-1.7 m wide: no model in the size window ..."."""
    kind = g.get("kind", "car")
    what = (f"{g['n_objects']} {'object' if kind == 'unknown' else kind}{'s' if g['n_objects'] != 1 else ''} "
            f"{g['length_m'][0]:.1f}-{g['length_m'][1]:.1f} m long, {g['width_m'][0]:.1f}-{g['width_m'][1]:.1f} m wide")
    if g.get("models_within_tol") == 0:
        near = g["nearest_model"]
        gap = near["size_gap_m"]
        w = g["window_m"]
        return (f"{what}: no model in the size window ({w['smaller']:.2f} m smaller to {w['larger']:.2f} m larger; "
                f"nearest: {near['name']}, {gap[0]:+.2f} m in length, {gap[1]:+.2f} m in width, {gap[2]:+.2f} m in "
                "height)")
    if "models_within_tol" in g:
        return f"{what}: {g['models_within_tol']} model(s) near in size, none accepted on its fit"
    return what


def plot(objects: list[dict], models: np.ndarray, names: list[str], path) -> Path:
    """Object sizes (length x width; got a model or not) over the catalogue's models."""
    plt = pyplot()

    tol, grow = window_of(objects) if objects else (DEFAULT.matching.size_tol, 0.0)
    fig, ax = plt.subplots(figsize=(7, 4.6))
    lw = np.array([[o["measured_size"]["length"], o["measured_size"]["width"]] for o in objects]).reshape(-1, 2)
    ok = np.array([bool(o.get("match")) and not o["match"].get("outside_tolerance") for o in objects], dtype=bool)
    for mask, colour, label in ((ok, "#2a7", "given a model"), (~ok, "#d33", "no model / outside the window")):
        ax.scatter(lw[mask, 0], lw[mask, 1], s=10, c=colour, alpha=0.6, label=f"{label} ({int(mask.sum())})")
    if len(models):
        for (length, width, _), name in zip(models, names):
            # the objects this model would be tried for: from (tol + grow) shorter to tol longer than the model
            ax.add_patch(plt.Rectangle((length - tol - grow, width - tol - grow), 2 * tol + grow, 2 * tol + grow,
                                       fill=False, ec="#36c", lw=0.6))
            ax.annotate(name, (length, width), fontsize=6, color="#36c", ha="center")
        ax.scatter(models[:, 0], models[:, 1], marker="s", s=18, c="#36c",
                   label=f"catalogue models (size window: {tol:.2f} m, {tol + grow:.2f} m towards smaller objects)")
    ax.set(xlabel="length (m)", ylabel="width (m)")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7, loc="upper left")
    return save_figure(fig, path, dpi=100)
