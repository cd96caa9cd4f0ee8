"""Where the twin is on Earth: CRS and georeferencing (:mod:`.georef`) and the one local east-north-up frame of the
3D formats (:mod:`.earth`)."""
