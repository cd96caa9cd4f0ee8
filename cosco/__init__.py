"""COSCO: Clustering Of Symmetric Cross-sections of Objects (Xue et al. 2020).

Numpy in, numpy out: no database, no CLI. Lengths in metres, angles in radians counter-clockwise from +X.
"""

from .arrays import voxel_downsample
from .cluster import Clustering, cluster
from .dissimilarity import (
    Registration,
    SectionPair,
    dissimilarity,
    dissimilarity_matrix,
    polished,
    register_sections,
)
from .footprint import Rectangle, min_area_rectangle
from .frames import axis_difference
from .params import DEFAULT, CoscoParams
from .sections import Frame, ObjectShape, Sections, Size, describe_object
from .symmetry import Symmetry, detect_symmetry

__all__ = [
    "DEFAULT", "Clustering", "CoscoParams", "Frame", "ObjectShape", "Rectangle", "Registration", "SectionPair",
    "Sections", "Size", "Symmetry", "axis_difference", "cluster", "describe_object", "detect_symmetry",
    "dissimilarity", "dissimilarity_matrix", "min_area_rectangle", "polished", "register_sections", "voxel_downsample",
]
