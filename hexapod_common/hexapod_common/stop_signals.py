"""SIGINT / SIGTERM noted from a node process's first statements, before rclpy is imported.

A process started in the background by a non-interactive shell (``cmd &`` in a script) starts
with SIGINT ignored (POSIX), and Python keeps that until ``rclpy.init`` installs rclpy's handler
after about a second of imports: a ``kill -INT`` in that second was discarded by the kernel and
the node ran on until killed again (an outside review: ``bag_recorder``, 17 of 17 trials at
0-0.8 s, under load up to 1.2 s). With the default handler it was a ``KeyboardInterrupt``
traceback from inside an import. :func:`catch` replaces both with a handler that only notes
the signal; the program checks :func:`received` when it can stop cleanly.

No ROS import here, so that a program can import this first. A signal that arrives before
that is still discarded by the kernel when SIGINT was ignored: the interpreter's start and the
console script's entry-point lookup (``importlib.metadata``), 0.1-0.2 s here, more under load.
Scripts should stop a background node with ``kill -TERM`` (SIGTERM is never ignored by the
shell, and it kills a process that has not caught it yet).
"""

from __future__ import annotations

import os
import signal
import sys
from typing import Any

__all__ = ['EXIT_CODES', 'STOP_SIGNALS', 'catch', 'catch_if_program', 'caught_program',
           'forget', 'received']

#: exit code of a program stopped by the signal before it did anything (128 + signal number)
EXIT_CODES = {signal.SIGINT: 130, signal.SIGTERM: 143}
STOP_SIGNALS = (signal.SIGINT, signal.SIGTERM)

_received: list[int] = []
_program: list[str] = []


def _note(signum: int, frame: Any) -> None:
    _received.append(signum)


def catch(signals: tuple[int, ...] = STOP_SIGNALS) -> None:
    """Note SIGINT and SIGTERM (also when inherited as ignored) instead of raising or dying.

    Called again once a stop has begun, it also takes the handlers back from rclpy or a node:
    a second Ctrl-C, or ``timeout`` signalling the process and then its group, then no longer
    interrupts the clean-up (it raised ``KeyboardInterrupt`` inside the bag's close: a
    traceback, exit 1 and the last split left hidden; an outside review)."""
    for sig in signals:
        signal.signal(sig, _note)


def catch_if_program(name: str) -> bool:
    """:func:`catch` when this process is the console script ``name`` (``sys.argv[0]``), so
    that importing the module elsewhere (a test, ``hexapod-demo`` recording in-process) keeps
    that process's own Ctrl-C. True if caught."""
    if os.path.basename(sys.argv[0] if sys.argv else '') != name:
        return False
    catch()
    _program.append(name)
    return True


def caught_program() -> str | None:
    """The console script's name when :func:`catch_if_program` caught the signals in this
    process, else None (a test or another program importing the module)."""
    return _program[0] if _program else None


def received() -> int | None:
    """The first stop signal noted since :func:`catch`, or None."""
    return _received[0] if _received else None


def forget() -> None:
    """Forget the signals noted (a run that consumed them is over: called in-process again,
    the next run would have stopped at once; review J5)."""
    _received.clear()
