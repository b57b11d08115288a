"""The output folder of an analysis command, checked before the analysis runs. No ROS.

``energy``, ``slip`` and ``residuals`` used to find an ``--out`` that is a regular file, or a
folder they cannot write, only when writing their results after the whole analysis (minutes
on real bags), with a bare ``[Errno 17] File exists``.

Each command owns the files :data:`OUTPUTS` names in its folder: it sets an earlier run's
aside while it runs, removes them when it finishes and puts them back when it does not
(:func:`replacing_outputs`), writes its figures, and its JSON result last
(:func:`write_text_atomic`), so that a folder never pairs one run's JSON with another run's
figures, and an interrupted run leaves no result that looks complete (outside review C).
``hexapod-analyze report`` assigns figures to results by the same patterns.
"""

from __future__ import annotations

import os
import tempfile
from contextlib import contextmanager
from fnmatch import fnmatchcase
from collections.abc import Iterator
from pathlib import Path

from .errors import HexapodError

__all__ = ['OUTPUTS', 'OutputDirError', 'creatable_problem', 'owned_by', 'prepare_out_dir',
           'remove_outputs', 'replacing_outputs', 'write_text_atomic']

#: result JSON -> the figures (file-name patterns) the command writing it may put beside it
OUTPUTS: dict[str, tuple[str, ...]] = {
    'energy.json': ('four_quadrant_*.png', 'four_quadrant_*.svg') + tuple(
        f'{name}.{ext}' for name in ('gait_type_comparison', 'power_map', 'prediction',
                                     'where_the_watts_go', 'power_in_over_time',
                                     'measured_runs', 'bench_surfaces')
        for ext in ('png', 'svg')),
    'slip.json': tuple(f'{name}.{ext}' for name in ('fig7_*', 'fig8_*', 'fig9_*',
                                                    'slip_fit_*') for ext in ('png', 'svg')),
    'residuals.json': ('residual_*.png',),
}


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


def owned_by(result: str, name: str) -> bool:
    """Whether a file called ``name`` is one of the figures :data:`OUTPUTS` gives ``result``
    (e.g. ``'slip.json'``)."""
    return any(fnmatchcase(name, pattern) for pattern in OUTPUTS.get(result, ()))


def remove_outputs(out: str | os.PathLike[str], result: str) -> None:
    """Remove from ``out`` the result JSON ``result`` and every figure it owns
    (:data:`OUTPUTS`): what an earlier run of the command left there."""
    folder = Path(out)
    if not folder.is_dir():
        return
    (folder / result).unlink(missing_ok=True)
    for pattern in OUTPUTS.get(result, ()):
        for path in folder.glob(pattern):
            if path.is_file():
                path.unlink(missing_ok=True)


@contextmanager
def replacing_outputs(out: str | os.PathLike[str], result: str,
                      keep: tuple[type[BaseException], ...] = ()) -> Iterator[None]:
    """Run the block as a run of the command writing ``result`` into ``out``: an earlier
    run's result and figures (:data:`OUTPUTS`) are set aside in a hidden folder beside them
    first; when the block finishes they are removed, and when it does not (a refused bag,
    Ctrl-C) what it wrote is removed and the earlier result put back. An exception of a type
    in ``keep`` is a result of its own (a refused fit that wrote its sessions): it replaces
    the earlier one. (A first version removed the earlier result before any bag was read: a
    re-run refused for a missing topic left an empty folder, an outside review.)"""
    import shutil

    folder = Path(out)
    aside: Path | None = None
    if folder.is_dir():
        owned = [folder / result] + [p for pattern in OUTPUTS.get(result, ())
                                     for p in folder.glob(pattern)]
        owned = [p for p in owned if p.is_file()]
        if owned:
            aside = Path(tempfile.mkdtemp(prefix=f'.{result}.earlier.', dir=folder))
            for p in owned:
                os.replace(p, aside / p.name)
    try:
        yield
    except BaseException as err:
        if not isinstance(err, keep):
            remove_outputs(folder, result)
            if aside is not None:
                for p in aside.iterdir():
                    os.replace(p, folder / p.name)
        raise
    finally:
        if aside is not None:
            shutil.rmtree(aside, ignore_errors=True)


def write_text_atomic(path: str | os.PathLike[str], text: str) -> None:
    """Write ``text`` to ``path`` through a temporary file in the same folder renamed over
    it: a reader (or a run cut short) sees the old file or the whole new one, never half.
    The file gets the permissions a plain write would (the umask's, not ``mkstemp``'s 0600)."""
    target = Path(path)
    for _ in range(100):
        tmp = target.with_name(f'.{target.name}.{os.getpid()}.{os.urandom(4).hex()}.tmp')
        try:
            fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o666)
            break
        except FileExistsError:
            continue
    else:  # pragma: no cover - 100 random names taken
        raise FileExistsError(f'no free temporary name beside {target}')
    try:
        with os.fdopen(fd, 'w', encoding='utf-8') as f:
            f.write(text)
        os.replace(tmp, target)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise
