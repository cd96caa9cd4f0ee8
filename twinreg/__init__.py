"""twinreg: a digital-twin registration workbench built on COSCO (see README.md and docs/METHOD.md).

The public API (imported on first use, so the command line starts fast); the ``twinreg`` command is a thin
layer over it.
"""

__version__ = "0.1.0"

_API = {
    "Catalogue": "twinreg.catalogue.repository",
    "TwinregError": "twinreg.errors",
    "build_twin": "twinreg.pipeline",
    "detect_file": "twinreg.detect",
    "georef_from_options": "twinreg.geo.georef",
    "load_mesh": "twinreg.io.meshes",
    "read_points": "twinreg.io.points",
}

#: twinreg's modules that hold compiled kernels (:mod:`cosco.kernels` imports cosco's own): imported and warmed
#: by ``kernels.enable(*KERNEL_MODULES)`` (tests/cosco/test_kernels.py checks that none is missing)
KERNEL_MODULES = ("twinreg.export.cityjson", "twinreg.export.scan_tiles", "twinreg.export.tiles3d",
                  "twinreg.matching.refine", "twinreg.shapes.fuse")

__all__ = sorted(_API) + ["__version__"]


def __getattr__(name):
    if name in _API:
        import importlib

        return getattr(importlib.import_module(_API[name]), name)
    raise AttributeError(f"module 'twinreg' has no attribute {name!r}")
