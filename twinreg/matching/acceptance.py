"""Is a registered model really the object? The acceptance test of a match, in units of the scan's noise and
sampling (docs/METHOD.md, "Accepting a match").

Section registration always finds a best model; a box, a skip or a kiosk of car size gets one too. The test looks
at all of the object's points: each point's distance to the placed model's surface (open3d's exact point-to-mesh
distance). A point is explained when it lies within

    tau = accept_sigmas * noise + accept_model_tol + accept_spacing_k * spacing

of the surface: ``noise`` is the scan's range noise (measured on its ground points: 1.4826 x the median absolute
height of the ground points above the ground surface), ``matching.accept_model_tol`` what a CAD model may differ from
the car it stands for (trim, mirrors, wipers, a roof box), and ``spacing`` the object's point spacing (a sparse scan
places the model less exactly). The match is accepted when at most ``matching.accept_max_outliers`` of the points are
not explained.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..raycast import CentredScene
from ..settings import DEFAULT, Settings

#: bounds of the noise estimate (m): a noise-free simulation still leaves the grid's own error; a very rough
#: ground (gravel, grass) must not make every fit acceptable
NOISE_BOUNDS = (0.005, 0.08)


def scene_noise(hag: np.ndarray, is_ground: np.ndarray) -> float:
    """Range noise (m) of a scan: 1.4826 x the median absolute height above the ground surface of its ground points
    (a robust standard deviation), within :data:`NOISE_BOUNDS`.

    >>> rng = np.random.default_rng(0)
    >>> round(scene_noise(rng.normal(0, 0.02, 10000), np.ones(10000, bool)), 3)
    0.02
    """
    h = np.asarray(hag, dtype=np.float64)[np.asarray(is_ground, dtype=bool)]
    if len(h) < 20:
        return NOISE_BOUNDS[1] / 2
    sigma = 1.4826 * float(np.median(np.abs(h - np.median(h))))
    return float(np.clip(sigma, *NOISE_BOUNDS))


@dataclass(frozen=True)
class Verdict:
    """The acceptance test of one placed model: ``tolerance_m`` (tau), the share of points farther than it, the
    median distance (m), and whether the match is accepted."""

    accepted: bool
    tolerance_m: float
    outlier_share: float
    median_m: float
    max_share: float

    def as_dict(self) -> dict:
        return {"accepted": self.accepted, "tolerance_m": round(self.tolerance_m, 4),
                "outlier_share": round(self.outlier_share, 4), "median_distance_m": round(self.median_m, 4)}

    def reason(self, name: str) -> str:
        return (f"the best model ({name}) does not explain the object: {self.outlier_share:.0%} of its points lie "
                f"more than {self.tolerance_m * 100:.1f} cm from the model's surface (at most "
                f"{self.max_share:.0%} allowed)")


def sample_cloud(points: np.ndarray, max_points: int) -> np.ndarray:
    """At most ``max_points`` of (n, 3) points, at a regular stride (deterministic: the same points for the same
    ordered input).

    >>> sample_cloud(np.zeros((3001, 3)), 1500).shape
    (1001, 3)
    """
    n = len(points)
    if n <= max_points:
        return points
    return points[::int(np.ceil(n / max_points))]


class SurfaceIndex:
    """A mesh ready for distance queries in its own frame (built once per model, queried for many objects):
    :class:`twinreg.raycast.CentredScene`."""

    def __init__(self, vertices: np.ndarray, faces: np.ndarray):
        self._scene = CentredScene(vertices, faces)

    def distances(self, points: np.ndarray) -> np.ndarray:
        """Unsigned distance (m) of (n, 3) points, in the mesh's frame, to its surface."""
        return self._scene.distances(points)


def verdict(distances: np.ndarray, noise: float, spacing: float, params: Settings = DEFAULT) -> Verdict:
    """The acceptance test from the points' distances (m) to the placed model's surface."""
    m = params.matching
    tau = m.accept_sigmas * noise + m.accept_model_tol + m.accept_spacing_k * spacing
    d = np.asarray(distances, dtype=np.float64)
    share = float(np.mean(d > tau)) if len(d) else 1.0
    return Verdict(bool(share <= params.matching.accept_max_outliers), float(tau), share,
                   float(np.median(d)) if len(d) else 0.0, params.matching.accept_max_outliers)
