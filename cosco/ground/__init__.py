"""Ground removal and height above ground (paper 3.1: "background removal").

A grid-based progressive morphological filter (after Zhang et al. 2003) instead of the paper's single RANSAC plane,
so that slopes, kerbs and ramps of real car parks stay ground:

1. the lowest point of every ``cell`` (empty cells take their nearest neighbour's value);
2. grey openings with growing windows; a cell whose surface stands above the opening by more than a threshold that
   grows with the window (``slope`` per metre of window growth, capped) is not ground: car roofs and walls go at
   the window that is wider than them; an opening leaves a planar ramp as it is, so a last strict test against the
   widest opening removes what is left of cars (bumpers, sills) and keeps ramps;
3. the ground surface is the lowest points of the ground cells, with holes (under cars, buildings) filled by
   normalised convolution so it bends smoothly under them; a second pass replaces each ground cell's lowest point
   by the median of the points near the surface (the lowest of noisy points lies a few sigmas too low);
4. every point's height above ground is its z minus the bilinear ground surface under it.

Memory goes by occupied cells, not by the bounding box: the grid is cut into blocks of ``ground.block`` cells and
only blocks holding points are processed, each as a dense window with a halo of ``ground.halo`` cells (more than
the widest opening window and the smoothing reach), of which the block's core is kept. A scan that fits in one
block is processed as one window, exactly as the steps above say; one stray point 30 km away adds one small block,
not a 60,000 x 60,000 grid.
"""

from .blocks import FEW_BLOCKS, estimate_ground, remove_ground
from .surface import Ground, _Grid

__all__ = ["FEW_BLOCKS", "Ground", "estimate_ground", "remove_ground", "_Grid"]
