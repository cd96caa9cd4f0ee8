"""``twinreg view``: the offline 3D viewer of a twin folder, served on 127.0.0.1 (:mod:`.server`)."""

from .server import serve, vendor_folder

__all__ = ["serve", "vendor_folder"]
