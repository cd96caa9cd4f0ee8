"""open3d, imported without its plotly drawing functions until one is called.

open3d's package import also imports ``open3d.visualization.draw_plotly``, which imports dash and plotly: about
half of open3d's import time (0.45 of 0.85 s here), for three drawing functions twinreg never calls. :func:`load`
first puts a stand-in for that one module in ``sys.modules``. Every name asked of the stand-in is a function that
imports the real module and calls its namesake, so nothing is lost: a script that draws with
``open3d.visualization.draw_plotly`` after twinreg loaded open3d gets the real drawing, only later.
"""

from __future__ import annotations

import importlib
import os
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


#: this process's native threads once open3d was imported here (None: not imported by :func:`load`)
_THREADS_AT_IMPORT: list = []


def _threads() -> int | None:
    """This process's native threads (Linux), or None where they cannot be counted."""
    try:
        return len(os.listdir("/proc/self/task"))
    except OSError:
        return None


def load():
    """The open3d module (imported on the first call, with the stand-in for its plotly drawing)."""
    first = "open3d" not in sys.modules
    if first and DRAWING not in sys.modules:
        sys.modules[DRAWING] = _stand_in()
    import open3d

    if first:
        _THREADS_AT_IMPORT.append(_threads())
    return open3d


def fork_safe() -> bool:
    """Whether a child forked now may use open3d: it is not loaded, or it was loaded by :func:`load` and has started
    no thread since (a forked child inherits none of its thread pools' workers, and would wait for them)."""
    if "open3d" not in sys.modules:
        return True
    now = _threads()
    return bool(_THREADS_AT_IMPORT) and now is not None and _THREADS_AT_IMPORT[0] is not None \
        and now <= _THREADS_AT_IMPORT[0]
