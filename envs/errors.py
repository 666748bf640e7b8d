"""One exception type for user mistakes, so the CLI can print one line and exit 2."""
from __future__ import annotations


class BenchError(ValueError):
    """A user-facing error: bad config, layout, map file, scenario or results folder.

    The message names what is wrong and where; the CLI prints it on one line and exits 2.
    """
