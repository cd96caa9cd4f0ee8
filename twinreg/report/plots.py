"""Pictures: a model's or object's cross-sections, the dissimilarity heat map and the dendrogram (matplotlib,
written to PNG through a temporary file and a rename)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..io.outdir import atomic_path


def pyplot():
    """matplotlib's pyplot on the file-only Agg backend (no display needed): every figure of twinreg comes from
    here."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def save_figure(fig, path, tight: bool = True, dpi: int = 110) -> Path:
    """Write a figure to ``path`` atomically; the figure is closed."""
    path = Path(path)
    try:
        with atomic_path(path, path.suffix or ".png") as tmp:
            fig.savefig(tmp, dpi=dpi, bbox_inches="tight" if tight else None)
    finally:
        pyplot().close(fig)
    return path


def _section_axes(ax, pts, res, title, xlabel, color="tab:blue", label=None):
    if len(pts):
        ax.scatter(pts[:, 0], pts[:, 1], s=12, marker="s", color=color, label=label, alpha=0.8)
    ax.set_title(title)
    ax.set_xlabel(xlabel)
    ax.set_ylabel("z above ground (m)")
    ax.set_aspect("equal")
    ax.grid(alpha=0.3)


def plot_sections(sections, title: str, path, other=None, other_label: str | None = None, points=None):
    """Longitudinal and transverse sections (and optionally another object's, registered, in orange; and a top
    view of ``points`` (n, 3) in the object frame)."""
    plt = pyplot()
    ncols = 3 if points is not None else 2
    fig, axes = plt.subplots(1, ncols, figsize=(5.5 * ncols, 3.6),
                             gridspec_kw={"width_ratios": [2.2, 1.2] + ([2.2] if points is not None else [])})
    _section_axes(axes[0], sections.longitudinal, sections.res, "longitudinal section", "u along heading (m)",
                  label=title)
    _section_axes(axes[1], sections.transverse, sections.res, "transverse section", "v across (m)")
    if other is not None:
        _section_axes(axes[0], other.longitudinal, other.res, "longitudinal section", "u along heading (m)",
                      color="tab:orange", label=other_label)
        _section_axes(axes[1], other.transverse, other.res, "transverse section", "v across (m)", color="tab:orange")
        axes[0].legend(loc="lower center", fontsize=8)
    if points is not None:
        ax = axes[2]
        sc = ax.scatter(points[:, 0], points[:, 1], c=points[:, 2], s=2, cmap="viridis")
        ax.set_aspect("equal")
        ax.set_title("top view (colour: height)")
        ax.set_xlabel("u (m)")
        ax.set_ylabel("v (m)")
        fig.colorbar(sc, ax=ax, shrink=0.8)
    fig.suptitle(title)
    return save_figure(fig, path)


def plot_model(geometry, info: dict, path):
    """A catalogue model: its sections and the top view of its sampled points."""
    size = info["size"]
    title = (f"{info['name']} ({info.get('make') or '?'} {info.get('model') or ''}): "
             f"{size['length']:.2f} x {size['width']:.2f} x {size['height']:.2f} m")
    return plot_sections(geometry.sections, title, path, points=geometry.points)


def plot_heatmap(matrix: np.ndarray, labels: list[str], path, title: str = "dissimilarity (cm)"):
    plt = pyplot()
    n = len(labels)
    fig, ax = plt.subplots(figsize=(1.0 + 0.55 * n, 0.8 + 0.5 * n))
    im = ax.imshow(np.asarray(matrix) * 100.0, cmap="coolwarm")
    ax.set_xticks(range(n), labels, rotation=90)
    ax.set_yticks(range(n), labels)
    if n <= 20:
        for i in range(n):
            for j in range(n):
                ax.text(j, i, f"{matrix[i][j] * 100:.1f}", ha="center", va="center", fontsize=7)
    fig.colorbar(im, ax=ax, label="RMSE (cm)")
    ax.set_title(title)
    return save_figure(fig, path)


def plot_dendrogram(linkage: np.ndarray, labels: list[str], threshold: float, path):
    from scipy.cluster.hierarchy import dendrogram

    plt = pyplot()
    fig, ax = plt.subplots(figsize=(max(5, 0.5 * len(labels) + 2), 4))
    if len(labels) >= 2:
        z = np.array(linkage, dtype=np.float64)
        z[:, 2] *= 100.0  # heights in cm; the other columns are indices and counts
        dendrogram(z, labels=labels, color_threshold=threshold * 100.0, ax=ax)
        ax.axhline(threshold * 100.0, color="grey", ls="--", lw=1)
    ax.set_ylabel("dissimilarity (cm)")
    ax.set_title(f"hierarchical clustering (cut at {threshold * 100:.1f} cm)")
    return save_figure(fig, path)
