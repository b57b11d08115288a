"""The output folder of an analysis command, checked before the analysis runs. No ROS.

``energy``, ``slip`` and ``residuals`` used to find an ``--out`` that is a regular file, or a
folder they cannot write, only when writing their results after the whole analysis (minutes
on real bags), with a bare ``[Errno 17] File exists``.
"""

from __future__ import annotations

import os
import tempfile
from pathlib import Path

from .errors import HexapodError

__all__ = ['OutputDirError', 'creatable_problem', 'prepare_out_dir']


class OutputDirError(HexapodError, ValueError):
    """The output folder cannot be used (a file by that name, no permission)."""


def prepare_out_dir(out: str | os.PathLike[str], flag: str = '--out') -> Path:
    """Create ``out`` (and its parents) if needed and check that a file can be written in
    it; raises :class:`OutputDirError` naming ``flag`` otherwise."""
    path = Path(out)
    if path.exists() and not path.is_dir():
        raise OutputDirError(f'{flag} {out} is a file, not a folder')
    try:
        path.mkdir(parents=True, exist_ok=True)
    except OSError as err:
        raise OutputDirError(f'{flag} {out}: cannot create the folder '
                             f'({err.strerror or err})') from err
    try:
        fd, probe = tempfile.mkstemp(prefix='.write-test-', dir=path)
        os.close(fd)
        os.unlink(probe)
    except OSError as err:
        raise OutputDirError(f'{flag} {out}: cannot write in the folder '
                             f'({err.strerror or err})') from err
    return path


def creatable_problem(out: str | os.PathLike[str], flag: str = '--out') -> str | None:
    """Why a new folder ``out`` could not be created (its nearest existing ancestor is not
    a folder, or a folder cannot be made in it), else None; nothing is left behind. For
    commands that create a new bag or results folder (``hexapod-sim``, ``bag_recorder``,
    ``hexapod-demo``), which check whether ``out`` may already exist themselves."""
    parent = Path(out).absolute().parent
    while not parent.exists() and parent != parent.parent:
        parent = parent.parent   # the writer creates the missing folders
    if not parent.is_dir():
        return f'{flag} {out}: {parent} is a file, not a folder'
    try:
        os.rmdir(tempfile.mkdtemp(prefix='.write-test-', dir=parent))
    except OSError as err:
        return f'{flag} {out}: cannot create a folder in {parent} ({err.strerror or err})'
    return None
