"""Twin exports: twin.ply (placed meshes), twin.kmz (KML + COLLADA for Google Earth), report (PNGs + HTML)."""
