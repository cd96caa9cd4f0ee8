"""Every figure and report page: the plotting helpers (:mod:`.plots`), a scene's report (:mod:`.scene`), a city's
(:mod:`.city`), and the helper process that draws while the twin is written (:mod:`.painter`)."""
