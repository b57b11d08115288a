"""A node logger that names the topics a node really reads.

A live node's messages come from core code that knows the contract's topic names
(``/battery_state``, ``/joint_states``, ``/gait/phase``, ``/mocap/body``, ``/odom``): with
``--ros-args -r battery_state:=/lab/power`` or a namespace, "no /battery_state for 5 s" named a
topic the node was not reading. :class:`RenamingLogger` wraps the node's logger and writes, in
every message, the names the node's subscriptions resolved those topics to.

rclpy's logger keys its filters (``once``, ``throttle_duration_sec``) and its "one severity per
call site" rule on the caller's file and line, found by skipping rclpy's own logging files;
this module is added to that list (``rclpy.impl.rcutils_logger._internal_callers``, which rclpy
keeps for third parties), so the call sites are still the node's.
"""

from __future__ import annotations

import os
import re
from collections.abc import Mapping
from typing import Any

__all__ = ['RenamingLogger', 'topic_renames']


def _register_as_internal_caller() -> None:
    from rclpy.impl import rcutils_logger

    here = os.path.realpath(__file__)
    if here not in rcutils_logger._internal_callers:
        rcutils_logger._internal_callers.append(here)


def topic_renames(subscriptions: Mapping[str, Any]) -> dict[str, str]:
    """``{contract name: resolved name}`` for the subscriptions (contract name without its
    leading slash, e.g. ``'battery_state'``) whose resolved topic differs from ``/name``."""
    out = {}
    for name, sub in subscriptions.items():
        resolved = getattr(sub, 'topic_name', None)
        if isinstance(resolved, str) and resolved and resolved != '/' + name.strip('/'):
            out[name.strip('/')] = resolved
    return out


class RenamingLogger:
    """``logger`` with each contract topic name in a message replaced by its resolved name
    (``renames``, from :func:`topic_renames`; updated with :meth:`set_renames`). Other
    attributes are the logger's."""

    def __init__(self, logger: Any, renames: Mapping[str, str] | None = None) -> None:
        _register_as_internal_caller()
        self._logger = logger
        self._pattern: re.Pattern[str] | None = None
        self._renames: dict[str, str] = {}
        self.set_renames(renames or {})

    def set_renames(self, renames: Mapping[str, str]) -> None:
        self._renames = {k.strip('/'): v for k, v in renames.items()}
        if not self._renames:
            self._pattern = None
            return
        names = sorted(self._renames, key=len, reverse=True)
        # a whole topic name, with or without its leading slash, not part of a longer name
        self._pattern = re.compile(r'(?<![\w/])/?(' + '|'.join(map(re.escape, names))
                                   + r')(?![\w/])')

    def rename(self, message: Any) -> Any:
        """``message`` with the contract names replaced (non-strings unchanged)."""
        if self._pattern is None or not isinstance(message, str):
            return message
        return self._pattern.sub(lambda m: self._renames[m.group(1)], message)

    def debug(self, message: Any, **kwargs: Any) -> Any:
        return self._logger.debug(self.rename(message), **kwargs)

    def info(self, message: Any, **kwargs: Any) -> Any:
        return self._logger.info(self.rename(message), **kwargs)

    def warning(self, message: Any, **kwargs: Any) -> Any:
        return self._logger.warning(self.rename(message), **kwargs)

    def warn(self, message: Any, **kwargs: Any) -> Any:
        return self._logger.warning(self.rename(message), **kwargs)

    def error(self, message: Any, **kwargs: Any) -> Any:
        return self._logger.error(self.rename(message), **kwargs)

    def fatal(self, message: Any, **kwargs: Any) -> Any:
        return self._logger.fatal(self.rename(message), **kwargs)

    def log(self, message: Any, severity: Any, **kwargs: Any) -> Any:
        return self._logger.log(self.rename(message), severity, **kwargs)

    def __getattr__(self, name: str) -> Any:
        return getattr(self._logger, name)
