"""When to try reopening a failed serial port again: 0.5 s after the failure, then doubling up
to 8 s after each failed attempt, and what a failed port raises. Shared by the force sensor and
the SCPI supply. No ROS."""

from __future__ import annotations

from collections.abc import Callable

__all__ = ['ReopenBackoff', 'serial_port_errors']


def serial_port_errors() -> tuple[type[BaseException], ...]:
    """What a serial port that failed (unplugged) raises: OSError, pyserial's
    SerialException, and the termios.error (errno EIO) its reset_input_buffer() / tcflush
    raises on a vanished device, which is not an OSError (POSIX only)."""
    import serial

    try:
        import termios
    except ImportError:             # not POSIX
        return (OSError, serial.SerialException)
    return (OSError, serial.SerialException, termios.error)


class ReopenBackoff:
    """Reopen schedule of one port; ``clock`` gives monotonic seconds."""

    FIRST_S = 0.5
    MAX_S = 8.0

    def __init__(self, clock: Callable[[], float]) -> None:
        self._clock = clock
        self.delay_s = 0.0
        self._next = 0.0

    def port_failed(self) -> None:
        """The port just failed: the first attempt comes ``FIRST_S`` later."""
        self.delay_s = self.FIRST_S
        self._next = self._clock() + self.delay_s

    def attempt_failed(self) -> None:
        """A reopen attempt failed: wait twice as long (at most ``MAX_S``)."""
        self.delay_s = min(self.MAX_S, 2 * self.delay_s)
        self._next = self._clock() + self.delay_s

    def due(self) -> bool:
        """Whether an attempt may be made now."""
        return self._clock() >= self._next
