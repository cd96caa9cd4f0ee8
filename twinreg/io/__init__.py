"""File formats: meshes (OBJ, PLY, STL, OFF, GLB/glTF, DAE) and point sets (PLY, PCD, LAS, LAZ, XYZ, KITTI)."""

from .meshes import LoadedMesh, load_mesh
from .points import read_points

__all__ = ["LoadedMesh", "load_mesh", "read_points"]
