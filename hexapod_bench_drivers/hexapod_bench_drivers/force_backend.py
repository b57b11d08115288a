"""Treadmill normal force: ASCII lines from a load-cell microcontroller, and their calibration.

Line format (one sample per line, ASCII, ``\\n`` or ``\\r\\n`` terminated)::

    <t_ms>,<raw>

``t_ms`` is the microcontroller's uptime in milliseconds (unsigned integer) and ``raw`` the
load-cell amplifier reading (signed integer counts, e.g. an HX711's 24-bit value). Lines that
start with ``#`` are comments (banners, tare messages) and are ignored. Anything else (missing
field, non-numbers, non-ASCII bytes, a line longer than 64 bytes) is **malformed**: counted and
skipped, never raised; :class:`MalformedWatch` turns a run of them with no valid line into a
warning naming the last line seen and the expected format. A raw value at the HX711 limits
(8388607 / -8388608, 24-bit two's complement) is a saturated amplifier: ``ForceReading.saturated``.

:class:`SerialForceSource` reopens a port that fails (unplugged) with a backoff (0.5 s doubling
to 8 s). :class:`McuClockMap` maps the microcontroller time onto the receiving clock (offset by a
running minimum over ``window_s``; an MCU reset or a garbled time restarts it) so that samples
received in a USB burst keep their spacing.

Calibration (as on the authors' MiMiC-Ant bench, whose single load cell sits under the treadmill
so that its reading depends on where the foot presses): a linear regression of the known force on
``[1, raw, tip_x_m, tip_y_m]``, fitted from calibration weights placed at several tip positions,
``force_n = c0 + c1 * raw + c2 * tip_x_m + c3 * tip_y_m``. No ROS here.
"""

from __future__ import annotations

import math
import time
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from hexapod_bench_drivers.reopen import ReopenBackoff, serial_port_errors


__all__ = [
    'ForceCalibration',
    'ForceLineParser',
    'ForceReading',
    'MalformedWatch',
    'McuClockMap',
    'SerialForceSource',
]

MAX_LINE_BYTES = 64
HX711_MAX_RAW = 0x7FFFFF
HX711_MIN_RAW = -0x800000
EXPECTED_FORMAT = "'<t_ms>,<raw>' (two integers, e.g. '1000,-12345'), '#' comments"


@dataclass(frozen=True)
class ForceReading:
    """One sample: microcontroller time [s] and raw load-cell counts."""

    t_mcu_s: float
    raw: int

    @property
    def saturated(self) -> bool:
        """The HX711 output at its limit: the load is beyond the range, the value is clipped."""
        return self.raw >= HX711_MAX_RAW or self.raw <= HX711_MIN_RAW


class ForceLineParser:
    """Incremental parser: feed byte chunks, get complete readings; counts what it skips.

    Attributes
    ----------
    lines_ok, malformed, comments : int
    last_malformed : bytes
        The latest malformed line (its first 40 bytes).
    """

    def __init__(self) -> None:
        self._buf = bytearray()
        self.lines_ok = 0
        self.malformed = 0
        self.comments = 0
        self.last_malformed = b''
        self._overflow = False

    def clear(self) -> None:
        """Forget a partial line (the port was reopened)."""
        self._buf.clear()
        self._overflow = False

    def feed(self, chunk: bytes) -> list[ForceReading]:
        out: list[ForceReading] = []
        self._buf += chunk
        while True:
            nl = self._buf.find(b'\n')
            if nl < 0:
                if len(self._buf) > MAX_LINE_BYTES:
                    # A runaway line: drop what we have and the rest of it up to the next \n.
                    if not self._overflow:
                        self.malformed += 1
                        self.last_malformed = bytes(self._buf[:40])
                    self._buf.clear()
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
            self.last_malformed = text[:40]
            return None
        self.lines_ok += 1
        return ForceReading(t_ms / 1000.0, raw)


class MalformedWatch:
    """Warn when ``threshold`` malformed lines came with no valid one, then at most every
    ``period_s`` while more keep coming. ``check(now, parser)`` returns the warning text or
    None. No ROS."""

    def __init__(self, threshold: int = 10, period_s: float = 10.0) -> None:
        self.threshold = int(threshold)
        self.period_s = float(period_s)
        self._ok0 = 0
        self._bad0 = 0
        self._last_warn = -math.inf
        self._bad_warned = -1

    def check(self, now: float, parser: ForceLineParser) -> str | None:
        if parser.lines_ok != self._ok0:        # a valid line since: a new count starts
            self._ok0, self._bad0 = parser.lines_ok, parser.malformed
            self._last_warn = -math.inf
            return None
        bad = parser.malformed - self._bad0
        if (bad < self.threshold or now - self._last_warn < self.period_s
                or parser.malformed == self._bad_warned):
            return None
        self._last_warn, self._bad_warned = now, parser.malformed
        return (f'{bad} malformed lines and no valid one ({parser.malformed} malformed in '
                f'all); last seen: {parser.last_malformed!r}; expected {EXPECTED_FORMAT}')


class McuClockMap:
    """Microcontroller time -> receiving clock: ``stamp(t_mcu_s, t_recv_s)``.

    The offset ``t_recv - t_mcu`` is the transmission delay plus a constant; its minimum over
    the last ``window_s`` of MCU time is the least-delayed sample, so ``t_mcu + min offset``
    keeps the MCU spacing of samples received in bursts and follows a slow clock drift. When a
    less-delayed sample lowers the minimum (the first lines read late at start-up), the applied
    offset slews down to it at 0.1 s/s (stamps may lead the reception meanwhile): stamps never
    go back. A sample whose offset differs from the minimum by more than
    ``jump_s`` (an MCU reset, a garbled time) is stamped at reception; ``restart_after`` such
    samples in a row restart the map.
    """

    def __init__(self, window_s: float = 10.0, jump_s: float = 1.0,
                 restart_after: int = 3) -> None:
        self.window_s = float(window_s)
        self.jump_s = float(jump_s)
        self.restart_after = int(restart_after)
        self._mins: deque[tuple[float, float]] = deque()   # (t_mcu, offset), offsets increasing
        self._jumps = 0
        self.restarts = 0
        self.slew = 0.1                  # s of offset correction per s of MCU time
        self._used: float | None = None  # the offset applied (slews down to the minimum)
        self._used_t = 0.0
        self._last_stamp = -math.inf

    def stamp(self, t_mcu_s: float, t_recv_s: float) -> float:
        return self.stamp_batch([t_mcu_s], t_recv_s)[0]

    def stamp_batch(self, t_mcu_s: Any, t_recv_s: float) -> list[float]:
        """Stamps of samples received together (one read): the map is updated with all of
        them first, so the first of a burst is not stamped with its larger delay."""
        restarts = self.restarts
        prev_used = self._used
        ok, epochs = [], []
        for t in t_mcu_s:
            ok.append(self._update(float(t), t_recv_s))
            epochs.append(self.restarts)
        if not self._mins:
            return [t_recv_s for _ in ok]
        base, newest = self._mins[0][1], self._mins[-1][0]
        if self._used is None or self.restarts != restarts or base >= self._used:
            self._used = base
        else:
            # A less-delayed sample lowered the minimum: slew to it (stamps never step back).
            step = self.slew * max(0.0, newest - self._used_t)
            self._used = max(base, self._used - step)
        self._used_t = newest
        out = []
        for t, good, epoch in zip(t_mcu_s, ok, epochs):
            if not good:
                stamp = t_recv_s
            elif epoch != self.restarts:
                # read before a reset or a wrap inside this same batch: its own clock's offset
                # (the new one put it the whole uptime late, and held every later stamp
                # there: a second review)
                stamp = float(t) + prev_used if prev_used is not None else t_recv_s
            else:
                stamp = float(t) + self._used
            # never more than jump_s after its reception (the start-up slew may lead it a
            # little), never before the previous stamp
            stamp = max(min(stamp, t_recv_s + self.jump_s), self._last_stamp)
            self._last_stamp = stamp
            out.append(stamp)
        return out

    def _update(self, t_mcu_s: float, t_recv_s: float) -> bool:
        offset = t_recv_s - t_mcu_s
        if self._mins:
            base = self._mins[0][1]
            newest = self._mins[-1][0]
            if abs(offset - base) > self.jump_s or t_mcu_s < newest - self.jump_s:
                self._jumps += 1
                if self._jumps < self.restart_after:
                    return False
                self._mins.clear()
                self.restarts += 1
        self._jumps = 0
        while self._mins and self._mins[-1][1] >= offset:
            self._mins.pop()
        self._mins.append((t_mcu_s, offset))
        while self._mins[0][0] < t_mcu_s - self.window_s:
            self._mins.popleft()
        return True


class SerialForceSource:
    """Non-blocking reader of a serial port feeding a ForceLineParser.

    A port that fails is closed and reopened by later polls with a backoff (0.5 s, doubling up
    to 8 s); ``poll`` never raises for it.

    Parameters
    ----------
    port : str
        Serial device (or a pty in tests).
    baud_rate : int
    serial_factory : callable, optional
        ``serial.Serial``-like constructor (tests).
    clock : callable() -> float, optional
        Monotonic seconds (tests).

    Attributes
    ----------
    lost : str or None
        Why the port is closed, while it is.
    reconnects, failed_opens : int
    """

    def __init__(self, port: str, *, baud_rate: int = 115200,
                 serial_factory: Callable[..., Any] | None = None,
                 clock: Callable[[], float] | None = None) -> None:
        import serial

        self._factory = serial_factory or serial.Serial
        self._port_errors = serial_port_errors()
        self.port = port
        self.baud_rate = int(baud_rate)
        self._clock = clock or time.monotonic
        self.ser: Any = self._open()
        self.parser = ForceLineParser()
        self.lost: str | None = None
        self.reconnects = 0
        self.failed_opens = 0
        self._backoff = ReopenBackoff(self._clock)

    def _open(self) -> Any:
        ser = self._factory(self.port, baudrate=self.baud_rate, timeout=0)
        flush = getattr(ser, 'reset_input_buffer', None)
        if flush is not None:
            flush()        # lines queued before the open are stale: their stamps would be wrong
        return ser

    def poll(self) -> list[ForceReading]:
        """Readings from every complete line received since the last call."""
        if self.ser is None and not self._reopen():
            return []
        try:
            waiting = self.ser.in_waiting
            if not waiting:
                return []
            chunk = self.ser.read(waiting)
        except self._port_errors as err:
            self._failed(err)
            return []
        return self.parser.feed(chunk)

    def _failed(self, err: BaseException) -> None:
        try:
            self.ser.close()
        except self._port_errors:
            pass
        self.ser = None
        self.lost = f'{type(err).__name__}: {err}'
        self.parser.clear()
        self._backoff.port_failed()

    def _reopen(self) -> bool:
        if not self._backoff.due():
            return False
        try:
            self.ser = self._open()
        except self._port_errors:
            self.failed_opens += 1
            self._backoff.attempt_failed()
            return False
        self.lost = None
        self.reconnects += 1
        return True

    def close(self) -> None:
        if self.ser is not None:
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
