"""Typed exceptions of :mod:`hexapod_gait`.

Every exception names the bad input and what was expected.
"""

from __future__ import annotations

__all__ = [
    'HexapodGaitError',
    'InvalidGaitError',
    'InfeasibleGaitError',
    'UnreachableError',
]


class HexapodGaitError(Exception):
    """Base class of every error raised by :mod:`hexapod_gait`."""


class InvalidGaitError(HexapodGaitError, ValueError):
    """A gait description is malformed (unknown name, bad duty factor, odd leg count...)."""


class InfeasibleGaitError(HexapodGaitError, ValueError):
    """A well-formed gait violates the actuator limits (swing, stance or step frequency)."""


class UnreachableError(HexapodGaitError, ValueError):
    """A leg-tip target lies outside the leg's workspace or outside its joint limits."""
