"""One progress protocol for every long-running function: ``progress(stage, done, total)``, a callable given by the
caller (the command line's :class:`~twinreg.cli._common.RunProgress.update`), called with ``done`` and ``total``
None for a stage that starts (a message) and with counts as counted work advances. :func:`say` calls it when given.
"""

from __future__ import annotations


def say(progress, stage: str, done: int | None = None, total: int | None = None) -> None:
    """``progress(stage, done, total)`` when there is a ``progress``.

    >>> say(lambda *a: print(a), "sections of 3 objects")
    ('sections of 3 objects', None, None)
    """
    if progress:
        progress(stage, done, total)
