"""Typed exceptions of hexapod_common: bags, parameters and message types."""

from __future__ import annotations

__all__ = [
    'BagError',
    'BagExistsError',
    'BagNotFoundError',
    'BagReadError',
    'HexapodError',
    'ParameterError',
    'UnknownTypeError',
]


class HexapodError(Exception):
    """Base exception of the project's shared layer."""


class ParameterError(HexapodError, ValueError):
    """A node parameter is missing, of the wrong type or out of range."""


class BagError(HexapodError):
    """A bag cannot be opened, read or written."""


class BagNotFoundError(BagError, FileNotFoundError):
    """The bag path does not exist."""


class BagExistsError(BagError, FileExistsError):
    """Refusing to overwrite an existing bag."""


class BagReadError(BagError):
    """The path exists but is not a readable rosbag2 bag (not a bag, truncated, corrupt)."""


class UnknownTypeError(HexapodError, LookupError):
    """A message type is not known to the typestore or to the ROS installation."""
