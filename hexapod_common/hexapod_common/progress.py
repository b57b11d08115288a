"""Progress-bar options shared by the commands (tqdm keyword arguments).

Core module: standard library only. On a terminal a bar refreshes as tqdm does by default;
written to a file or a pipe (``make demo > log``, a CI log) tqdm cannot redraw in place and
every refresh is appended to the log, so there it refreshes at most once a minute (besides its
first and last state). ``--no-progress`` turns it off.
"""

from __future__ import annotations

import sys
from typing import IO, Any

__all__ = ['LOG_REFRESH_S', 'bar_options']

#: seconds between two refreshes of a bar written to a file or pipe
LOG_REFRESH_S = 60.0


def bar_options(disable: bool = False, stream: IO[str] | None = None) -> dict[str, Any]:
    """tqdm keyword arguments for a bar on ``stream`` (default stderr): ``disable`` turns it
    off; a stream that is not a terminal refreshes every :data:`LOG_REFRESH_S` seconds."""
    if disable:
        return {'disable': True}
    out = sys.stderr if stream is None else stream
    if hasattr(out, 'isatty') and out.isatty():
        return {}
    return {'mininterval': LOG_REFRESH_S, 'maxinterval': 10 * LOG_REFRESH_S}
