"""Treadmill normal force: ASCII lines from a load-cell microcontroller, and their calibration.

Line format (one sample per line, ASCII, ``\\n`` or ``\\r\\n`` terminated)::

    <t_ms>,<raw>

``t_ms`` is the microcontroller's uptime in milliseconds (unsigned integer) and ``raw`` the
load-cell amplifier reading (signed integer counts, e.g. an HX711's 24-bit value). Lines that
start with ``#`` are comments (banners, tare messages) and are ignored. Anything else (missing
field, non-numbers, non-ASCII bytes, a line longer than 64 bytes) is **malformed**: counted and
skipped, never raised.

Calibration (as on the authors' MiMiC-Ant bench, whose single load cell sits under the treadmill
so that its reading depends on where the foot presses): a linear regression of the known force on
``[1, raw, tip_x_m, tip_y_m]``, fitted from calibration weights placed at several tip positions,
``force_n = c0 + c1 * raw + c2 * tip_x_m + c3 * tip_y_m``. No ROS here.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

__all__ = [
    'ForceCalibration',
    'ForceLineParser',
    'ForceReading',
    'SerialForceSource',
]

MAX_LINE_BYTES = 64


@dataclass(frozen=True)
class ForceReading:
    """One sample: microcontroller time [s] and raw load-cell counts."""

    t_mcu_s: float
    raw: int


class ForceLineParser:
    """Incremental parser: feed byte chunks, get complete readings; counts what it skips.

    Attributes
    ----------
    lines_ok, malformed, comments : int
    """

    def __init__(self) -> None:
        self._buf = bytearray()
        self.lines_ok = 0
        self.malformed = 0
        self.comments = 0
        self._overflow = False

    def feed(self, chunk: bytes) -> list[ForceReading]:
        out: list[ForceReading] = []
        self._buf += chunk
        while True:
            nl = self._buf.find(b'\n')
            if nl < 0:
                if len(self._buf) > MAX_LINE_BYTES:
                    # A runaway line: drop what we have and the rest of it up to the next \n.
                    self._buf.clear()
                    if not self._overflow:
                        self.malformed += 1
                    self._overflow = True
                return out
            line = bytes(self._buf[:nl])
            del self._buf[:nl + 1]
            if self._overflow:
                self._overflow = False
                continue
            reading = self._parse(line)
            if reading is not None:
                out.append(reading)

    def _parse(self, line: bytes) -> ForceReading | None:
        text = line.rstrip(b'\r')
        if not text.strip():
            return None
        if text.lstrip().startswith(b'#'):
            self.comments += 1
            return None
        try:
            if len(text) > MAX_LINE_BYTES:
                raise ValueError('line too long')
            t_text, raw_text = text.decode('ascii').split(',')
            t_ms, raw = int(t_text), int(raw_text)
            if t_ms < 0:
                raise ValueError('negative time')
        except (ValueError, UnicodeDecodeError):
            self.malformed += 1
            return None
        self.lines_ok += 1
        return ForceReading(t_ms / 1000.0, raw)


class SerialForceSource:
    """Non-blocking reader of a serial port feeding a ForceLineParser.

    Parameters
    ----------
    port : str
        Serial device (or a pty in tests).
    baud_rate : int
    serial_factory : callable, optional
        ``serial.Serial``-like constructor (tests).
    """

    def __init__(self, port: str, *, baud_rate: int = 115200,
                 serial_factory: Callable[..., Any] | None = None) -> None:
        import serial

        factory = serial_factory or serial.Serial
        self.ser = factory(port, baudrate=baud_rate, timeout=0)
        self.parser = ForceLineParser()

    def poll(self) -> list[ForceReading]:
        """Readings from every complete line received since the last call."""
        waiting = self.ser.in_waiting
        if not waiting:
            return []
        return self.parser.feed(self.ser.read(waiting))

    def close(self) -> None:
        self.ser.close()


class ForceCalibration:
    """Force [N] = c0 + c1 * raw + c2 * tip_x_m + c3 * tip_y_m, by least squares.

    ``fit(raw, tip_x_m, tip_y_m, force_n) -> self`` sets ``coef_`` (4,), ``coef_stderr_`` (4,)
    and ``residual_std_n_``. Or build a fitted one from known coefficients with
    :meth:`from_coefficients`.
    """

    def fit(self, raw: Any, tip_x_m: Any, tip_y_m: Any, force_n: Any) -> ForceCalibration:
        """Fit on N calibration samples; all arrays of shape (N,), N >= 5."""
        design = self._design(raw, tip_x_m, tip_y_m)
        y = np.asarray(force_n, dtype=float).ravel()
        if design.shape[0] != y.size or y.size < 5:
            raise ValueError(f'force_n: expected as many samples as raw ({design.shape[0]}), '
                             f'at least 5; got {y.size}')
        if np.linalg.matrix_rank(design) < 4:
            raise ValueError('calibration samples: raw, tip_x_m and tip_y_m must each vary '
                             '(place the weights at several tip positions)')
        coef, *_ = np.linalg.lstsq(design, y, rcond=None)
        resid = y - design @ coef
        dof = max(1, y.size - 4)
        sigma2 = float(resid @ resid) / dof
        cov = sigma2 * np.linalg.inv(design.T @ design)
        self.coef_ = coef
        self.coef_stderr_ = np.sqrt(np.diag(cov))
        self.residual_std_n_ = float(np.sqrt(sigma2))
        return self

    @classmethod
    def from_coefficients(cls, coef: Any) -> ForceCalibration:
        c = np.asarray(coef, dtype=float).ravel()
        if c.size != 4:
            raise ValueError(f'coef: expected 4 values [c0, c1, c2, c3], got {c.size}')
        cal = cls()
        cal.coef_ = c
        cal.coef_stderr_ = np.full(4, np.nan)
        cal.residual_std_n_ = float('nan')
        return cal

    @staticmethod
    def _design(raw: Any, tip_x_m: Any, tip_y_m: Any) -> np.ndarray:
        r = np.asarray(raw, dtype=float).ravel()
        x = np.broadcast_to(np.asarray(tip_x_m, dtype=float), r.shape)
        y = np.broadcast_to(np.asarray(tip_y_m, dtype=float), r.shape)
        return np.column_stack([np.ones_like(r), r, x, y])

    def predict(self, raw: Any, tip_x_m: Any = 0.0, tip_y_m: Any = 0.0) -> np.ndarray:
        """Force [N], shape of ``raw``."""
        if not hasattr(self, 'coef_'):
            raise RuntimeError('ForceCalibration is not fitted: call fit() or '
                               'from_coefficients()')
        shape = np.shape(raw)
        return (self._design(raw, tip_x_m, tip_y_m) @ self.coef_).reshape(shape)
