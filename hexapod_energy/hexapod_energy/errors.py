"""Typed exceptions of :mod:`hexapod_energy`.

Every error names the bad input and what was expected.  All derive from
:class:`EnergyError`, so callers can catch the package's errors in one clause.
"""

from __future__ import annotations

__all__ = [
    'BagContentError',
    'EnergyError',
    'FitError',
    'InvalidInputError',
    'NotFittedError',
]


class EnergyError(Exception):
    """Base class of the package's exceptions."""


class InvalidInputError(EnergyError, ValueError):
    """An argument has the wrong shape, sign or range."""


class NotFittedError(EnergyError, RuntimeError):
    """A fitted attribute was read before ``fit`` was called."""


class FitError(EnergyError, RuntimeError):
    """A fit could not be carried out (too few points, singular system)."""


class BagContentError(EnergyError, ValueError):
    """A bag lacks a topic or field the analysis needs."""
