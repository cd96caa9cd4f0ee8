"""open3d, imported without its plotly drawing functions until one is called.

open3d's package import also imports ``open3d.visualization.draw_plotly``, which imports dash and plotly: about
half of open3d's import time (0.45 of 0.85 s here), for three drawing functions twinreg never calls. :func:`load`
first puts a stand-in for that one module in ``sys.modules``. Every name asked of the stand-in is a function that
imports the real module and calls its namesake, so nothing is lost: a script that draws with
``open3d.visualization.draw_plotly`` after twinreg loaded open3d gets the real drawing, only later.
"""

from __future__ import annotations

import importlib
import sys
import types

#: the open3d module whose import pulls in dash and plotly
DRAWING = "open3d.visualization.draw_plotly"


def _deferred(name: str):
    def call(*args, **kwargs):
        module = sys.modules.get(DRAWING)
        if getattr(module, "twinreg_stand_in", False):
            del sys.modules[DRAWING]
        return getattr(importlib.import_module(DRAWING), name)(*args, **kwargs)

    call.__name__ = call.__qualname__ = name
    return call


def _stand_in() -> types.ModuleType:
    module = types.ModuleType(DRAWING, "Stands in for open3d's plotly drawing until a function of it is called.")
    module.twinreg_stand_in = True

    def __getattr__(name: str):
        if name.startswith("__"):
            raise AttributeError(name)
        return _deferred(name)

    module.__getattr__ = __getattr__
    return module


def load():
    """The open3d module (imported on the first call, with the stand-in for its plotly drawing)."""
    if "open3d" not in sys.modules and DRAWING not in sys.modules:
        sys.modules[DRAWING] = _stand_in()
    import open3d

    return open3d
