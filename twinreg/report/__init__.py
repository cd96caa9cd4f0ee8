"""Every figure and report page: the plotting helpers (:mod:`.plots`), a scene's report (:mod:`.scene`) and a
city's (:mod:`.city`); the helper process that draws them while the twin is written is
:mod:`twinreg.process.helpers`."""
