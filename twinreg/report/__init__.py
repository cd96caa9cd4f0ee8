"""Every figure and report page: the plotting helpers (:mod:`.plots`, matplotlib, for the pictures drawn on
request), SVG written directly (:mod:`.svg`, a scene's report: no import to pay), a scene's report (:mod:`.scene`)
and a city's (:mod:`.city`); the helper process that draws them while the twin is written is
:mod:`twinreg.process.helpers`."""
