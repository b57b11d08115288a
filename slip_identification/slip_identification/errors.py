"""Typed exceptions of the SLIP identification package."""

from __future__ import annotations

__all__ = [
    'SlipError',
    'SlipDataError',
    'StanceRejectedError',
    'NotFittedError',
    'MissingTopicError',
]


class SlipError(Exception):
    """Base class of every error raised by :mod:`slip_identification`."""


class SlipDataError(SlipError, ValueError):
    """Input data that cannot be analysed (wrong shape, NaN, too short, non-uniform)."""


class StanceRejectedError(SlipDataError):
    """One stance that cannot be fitted; ``reason`` is a short machine-readable tag.

    Parameters
    ----------
    reason : str
        Tag counted in the output (``too_short``, ``nan``, ``mocap_gap``, ...).
    message : str
        Human-readable explanation naming the bad input.
    """

    def __init__(self, reason: str, message: str) -> None:
        super().__init__(f'{reason}: {message}')
        self.reason = reason


class NotFittedError(SlipError, RuntimeError):
    """A fitted attribute was read before ``fit`` was called."""


class MissingTopicError(SlipDataError):
    """A bag lacks a topic the analysis needs."""
