"""Supply voltage and current: simulated, INA219/INA226 over Linux I2C, SCPI lab supply. No ROS.

Every backend returns :class:`PowerSample` with ``current_a`` **positive when the robot draws
current** (the physical direction through a high-side shunt, and what a lab supply reports).
``sensor_msgs/BatteryState`` wants the opposite (negative while discharging): convert with
:func:`ros_battery_current` at the node, in one place.

INA226 / INA219 (Texas Instruments): registers are 16 bit, **big-endian on the wire** (SMBus
word reads are little-endian, so this code reads two-byte blocks, MSB first). Calibration per the
datasheets: ``current_lsb = max_current_a / 2**15``;
INA226 ``CAL = 0.00512 / (current_lsb * shunt_ohm)``, Current = Shunt * CAL / 2048,
bus voltage 1.25 mV/bit; INA219 ``CAL = 0.04096 / (current_lsb * shunt_ohm)``,
Current = Shunt * CAL / 4096, bus voltage register bits 15..3 at 4 mV/bit.

Range checks (a clipped or wrapped current is never returned as valid): ``max_current_a *
shunt_ohm`` above the chip's shunt range (INA226 81.92 mV, INA219 320 mV at PGA /8) is refused at
start; a shunt ADC at full scale, the INA226 MathOvf flag (Mask/Enable bit 2) or the INA219 OVF
bit make :meth:`Ina2xxBackend.read` raise :class:`PowerBackendError` (the sample is dropped).
A chip reset (brown-out, hot-plug: Calibration back to 0, so Current reads 0) is detected by
reading Calibration back every ``cal_check_every`` reads, after an I/O error and whenever
Current reads exactly 0 with the bus voltage up; Config and Calibration are then rewritten and
that read raises (dropped) with the reason.

SCPI: ``MEAS:VOLT?`` and ``MEAS:CURR?`` each answered by one line with a number (most bench
supplies: Rigol DP8xx, Keysight E36xx, Korad with SCPI firmware). Supplies answer in order, so a
reply that misses the deadline would be taken for the answer to the next query: after any failed
query the backend resynchronises before the next read (``*IDN?`` sent, every line up to its
non-numeric reply discarded; or the line quiet for ``resync_s``) and a pair is only returned from
two queries answered in sync. The overrange codes ``9.9E37`` / ``9.91E37`` (SCPI NaN) and
non-finite replies are refused. A port that fails (unplugged) raises :class:`PowerPortLost`
once and is reopened at the next reads with a backoff (0.5 s doubling up to 8 s). ``port`` may
be a pyserial URL such as ``socket://host:5025`` (LAN SCPI).
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, Protocol

import numpy as np

from hexapod_bench_drivers.reopen import ReopenBackoff, serial_port_errors


__all__ = [
    'FailureLog',
    'INA219_REGISTERS',
    'INA226_REGISTERS',
    'Ina2xxBackend',
    'PowerBackend',
    'PowerBackendError',
    'PowerPortLost',
    'PowerSensorReset',
    'PowerSample',
    'ScpiSupplyBackend',
    'SimPowerBackend',
    'ZeroOffset',
    'ros_battery_current',
]


class PowerBackendError(RuntimeError):
    """A power sensor cannot be reached or answers nonsense."""


class PowerPortLost(PowerBackendError):
    """The port of the sensor failed (unplugged); the backend reopens it with a backoff."""


class PowerSensorReset(PowerBackendError):
    """The sensor lost its configuration (chip reset); the backend rewrote it."""


@dataclass(frozen=True)
class PowerSample:
    """voltage_v [V] at the robot; current_a [A], positive when the robot draws current."""

    voltage_v: float
    current_a: float

    @property
    def power_w(self) -> float:
        return self.voltage_v * self.current_a


class PowerBackend(Protocol):
    def read(self) -> PowerSample: ...

    def close(self) -> None: ...


def ros_battery_current(draw_current_a: float) -> float:
    """Drawn current (positive = discharging) -> BatteryState.current (negative = discharging)."""
    return -float(draw_current_a)


class SimPowerBackend:
    """A supply with a given voltage and current draw, plus optional Gaussian noise.

    Parameters
    ----------
    voltage_v, current_a : float or callable() -> float
        Constant, or a function called at every read.
    noise_a : float
        Standard deviation of the current noise [A].
    internal_resistance_ohm : float
        Voltage sag per ampere [ohm].
    seed : int
    """

    def __init__(self, voltage_v: float | Callable[[], float] = 11.9,
                 current_a: float | Callable[[], float] = 1.0, *, noise_a: float = 0.0,
                 internal_resistance_ohm: float = 0.0, seed: int = 0) -> None:
        self._v = voltage_v
        self._i = current_a
        self.noise_a = float(noise_a)
        self.internal_resistance_ohm = float(internal_resistance_ohm)
        self._rng = np.random.default_rng(seed)

    def read(self) -> PowerSample:
        i = float(self._i() if callable(self._i) else self._i)
        v = float(self._v() if callable(self._v) else self._v) - self.internal_resistance_ohm * i
        if self.noise_a > 0:
            i += float(self._rng.normal(0.0, self.noise_a))
        return PowerSample(v, i)

    def close(self) -> None:
        pass


INA226_REGISTERS = {'config': 0x00, 'shunt': 0x01, 'bus': 0x02, 'power': 0x03, 'current': 0x04,
                    'calibration': 0x05, 'mask_enable': 0x06, 'manufacturer_id': 0xFE,
                    'die_id': 0xFF}
INA219_REGISTERS = {'config': 0x00, 'shunt': 0x01, 'bus': 0x02, 'power': 0x03, 'current': 0x04,
                    'calibration': 0x05}
INA226_MANUFACTURER_ID = 0x5449   # 'TI'
INA226_CONFIG = 0x4527            # 16 averages, 1.1 ms conversions, shunt+bus continuous
INA219_CONFIG = 0x399F            # 32 V range, +-320 mV, 12-bit, shunt+bus continuous
INA226_MATH_OVF = 0x0004          # Mask/Enable bit 2: current/power arithmetic overflowed
# Shunt ADC full scale: raw code at the clamp, volts per LSB.
INA_SHUNT_FULL_SCALE = {'ina226': (32767, 2.5e-6), 'ina219': (32000, 10e-6)}
INA_CONVERSION_S = {'ina226': 0.0352, 'ina219': 0.0011}   # one result with the configs above


class Ina2xxBackend:
    """INA226 or INA219 current/voltage monitor on an SMBus (``smbus2.SMBus`` or a fake).

    Parameters
    ----------
    bus : object with ``read_i2c_block_data(addr, reg, n)`` and ``write_i2c_block_data``
        An open ``smbus2.SMBus(i2c_bus_number)``.
    chip : str
        ``'ina226'`` or ``'ina219'``.
    address : int
        7-bit I2C address (0x40 default).
    shunt_ohm : float
        Shunt resistance [ohm].
    max_current_a : float
        Largest expected current [A]; sets the current LSB. ``max_current_a * shunt_ohm`` must
        fit the shunt range (INA226 81.92 mV, INA219 320 mV), else ValueError.
    cal_check_every : int
        Read the Calibration register back every that many reads (chip reset detection).
    clock : callable() -> float, optional
        Monotonic seconds (tests); reads within one conversion after a reconfiguration are
        dropped.

    Attributes
    ----------
    resets : int
        Chip resets detected (Config and Calibration rewritten).
    """

    def __init__(self, bus: Any, *, chip: str = 'ina226', address: int = 0x40,
                 shunt_ohm: float = 0.01, max_current_a: float = 8.0, cal_check_every: int = 50,
                 clock: Callable[[], float] | None = None) -> None:
        if chip not in ('ina226', 'ina219'):
            raise ValueError(f'chip: expected ina226 or ina219, got {chip!r}')
        if not (shunt_ohm > 0 and max_current_a > 0):
            raise ValueError(f'shunt_ohm {shunt_ohm} and max_current_a {max_current_a}: '
                             'expected > 0')
        full_code, shunt_lsb_v = INA_SHUNT_FULL_SCALE[chip]
        full_scale_v = full_code * shunt_lsb_v
        if max_current_a * shunt_ohm > full_scale_v * 1.001:
            raise ValueError(
                f'max_current_a {max_current_a} A x shunt_ohm {shunt_ohm} ohm = '
                f'{max_current_a * shunt_ohm * 1e3:.1f} mV exceeds the {chip} shunt range '
                f'{full_scale_v * 1e3:.2f} mV: this shunt measures at most '
                f'{full_scale_v / shunt_ohm:.3f} A (check shunt_ohm against the board: many '
                'breakouts carry 0.1 ohm "R100"; or lower max_current_a)')
        self.bus = bus
        self.chip = chip
        self.address = int(address)
        self.shunt_ohm = float(shunt_ohm)
        self.current_lsb_a = float(max_current_a) / 2**15
        scale = 0.00512 if chip == 'ina226' else 0.04096
        self.calibration = int(math.floor(scale / (self.current_lsb_a * self.shunt_ohm)))
        if not 0 < self.calibration < 0x8000:
            raise ValueError(f'calibration {self.calibration} out of range for shunt '
                             f'{shunt_ohm} ohm and max current {max_current_a} A')
        # The LSB the chip applies with the calibration it holds (rounded down; INA219 bit 0
        # reads 0), exact rather than max_current_a / 2**15.
        held = self.calibration & (0xFFFF if chip == 'ina226' else 0xFFFE)
        self.current_lsb_a = scale / (held * self.shunt_ohm)
        self.max_current_a = float(max_current_a)
        self.cal_check_every = max(1, int(cal_check_every))
        self._clock = clock or time.monotonic
        self._reads = 0
        self._check_cal = False
        self._settle_until = -math.inf
        self.resets = 0
        self.configure()

    def _write(self, reg: int, value: int) -> None:
        try:
            self.bus.write_i2c_block_data(self.address, reg, [(value >> 8) & 0xFF, value & 0xFF])
        except OSError as err:
            self._check_cal = True
            raise PowerBackendError(f'{self.chip} at 0x{self.address:02x}: write of register '
                                    f'0x{reg:02x} failed: {err}') from err

    def _read(self, reg: int, signed: bool = False) -> int:
        try:
            msb, lsb = self.bus.read_i2c_block_data(self.address, reg, 2)
        except (OSError, ValueError) as err:
            self._check_cal = True     # a NACK is what a power-cycling chip gives
            raise PowerBackendError(f'{self.chip} at 0x{self.address:02x}: read of register '
                                    f'0x{reg:02x} failed: {err}') from err
        value = (msb << 8) | lsb
        return value - 0x10000 if signed and value & 0x8000 else value

    def configure(self) -> None:
        """Check the chip (INA226 manufacturer ID), write configuration and calibration."""
        if self.chip == 'ina226':
            found = self._read(INA226_REGISTERS['manufacturer_id'])
            if found != INA226_MANUFACTURER_ID:
                raise PowerBackendError(
                    f'ina226 at 0x{self.address:02x}: manufacturer ID 0x{found:04x}, expected '
                    f'0x{INA226_MANUFACTURER_ID:04x} (wrong address or not an INA226?)')
            self._write(INA226_REGISTERS['config'], INA226_CONFIG)
        else:
            # an INA226 driven as an INA219 read its registers with the INA219's scales,
            # accepted (an outside review). It answers its manufacturer ID where an INA219 has
            # no register, and it holds bit 0 of the calibration, which an INA219 reads as 0
            # (FS0, read only). Both must say INA226: an INA219 (or an emulator of one) that
            # answers anything at 0xFE is kept when it drops the bit.
            try:
                found = self._read(INA226_REGISTERS['manufacturer_id'])
            except PowerBackendError:
                found = None
            if found == INA226_MANUFACTURER_ID:
                self._write(INA226_REGISTERS['calibration'], self.calibration | 1)
                if self._read(INA226_REGISTERS['calibration']) & 1:
                    raise PowerBackendError(
                        f'ina219 chosen, but the chip at 0x{self.address:02x} answers the INA226 '
                        f'manufacturer ID 0x{found:04x} and holds bit 0 of its calibration '
                        '(an INA219 reads it 0): it is an INA226 (backend ina226)')
            self._check_cal = False
            self._write(INA219_REGISTERS['config'], INA219_CONFIG)
        self._write(INA226_REGISTERS['calibration'], self.calibration)

    def _calibration_lost(self) -> int | None:
        """The Calibration register's value if it no longer holds what was written, else None."""
        found = self._read(INA226_REGISTERS['calibration'])
        # INA219: bit 0 (FS0) is read only and reads 0.
        mask = 0xFFFF if self.chip == 'ina226' else 0xFFFE
        return None if found & mask == self.calibration & mask else found

    def read(self) -> PowerSample:
        """One sample; raises PowerBackendError (sample dropped) rather than return a current
        that is clipped, wrapped or computed with a lost calibration."""
        where = f'{self.chip} at 0x{self.address:02x}'
        self._reads += 1
        if self._check_cal or self._reads % self.cal_check_every == 0:
            self._verify_calibration(where)
        raw_bus = self._read(INA226_REGISTERS['bus'])
        if self.chip == 'ina226':
            voltage = raw_bus * 1.25e-3
        else:
            if raw_bus & 0x1:
                raise PowerBackendError('ina219: math overflow flag set (current beyond range)')
            voltage = (raw_bus >> 3) * 4e-3
        raw_shunt = self._read(INA226_REGISTERS['shunt'], signed=True)
        raw_current = self._read(INA226_REGISTERS['current'], signed=True)
        full_code, shunt_lsb_v = INA_SHUNT_FULL_SCALE[self.chip]
        if abs(raw_shunt) >= full_code:
            raise PowerBackendError(
                f'{where}: shunt voltage at full scale ({raw_shunt * shunt_lsb_v * 1e3:+.2f} mV):'
                f' current beyond {full_code * shunt_lsb_v / self.shunt_ohm:.3f} A, sample '
                'dropped')
        if self.chip == 'ina226':
            mask = self._read(INA226_REGISTERS['mask_enable'])
            if mask & INA226_MATH_OVF:
                raise PowerBackendError(
                    f'{where}: math overflow flag (MathOvf) set: current beyond '
                    f'max_current_a {self.max_current_a:g} A, sample dropped')
        if raw_current == 0 and (voltage > 0.5 or raw_shunt != 0):
            self._verify_calibration(where)
        if self._clock() < self._settle_until:
            raise PowerBackendError(f'{where}: reconfigured, waiting one conversion')
        return PowerSample(voltage, raw_current * self.current_lsb_a)

    def _verify_calibration(self, where: str) -> None:
        found = self._calibration_lost()
        self._check_cal = False
        if found is None:
            return
        self.configure()
        self.resets += 1
        # Current holds 0 until the next conversion with the new calibration.
        self._settle_until = self._clock() + INA_CONVERSION_S[self.chip]
        raise PowerSensorReset(
            f'{where}: calibration register reads 0x{found:04x}, expected '
            f'0x{self.calibration:04x}: the chip was reset (brown-out, loose connector?); '
            'configuration and calibration rewritten, sample dropped')

    def close(self) -> None:
        close = getattr(self.bus, 'close', None)
        if close is not None:
            close()


SCPI_OVERRANGE = 9.9e37           # 9.9E37 overflow, 9.91E37 "not a number" (SCPI-99)


def _scpi_number(line: str) -> float:
    """The number in a reply line (``12.003``, ``+1.20030E+01``, ``12.003V``, ``12.003 V``)."""
    return float(line.split()[0].rstrip('VAva'))


class ScpiSupplyBackend:
    """A lab supply answering SCPI ``MEAS:VOLT?`` / ``MEAS:CURR?`` on a serial port.

    Parameters
    ----------
    port : str
        Serial device (or a pty in tests), or a pyserial URL (``socket://host:5025``).
    baud_rate : int
    timeout_s : float
        Reply deadline per query [s].
    resync_s : float, optional
        How long a resynchronisation may take [s] (default ``max(2, 4 * timeout_s)``).
    serial_factory : callable, optional
        ``serial.Serial``-like constructor (tests); default ``serial.serial_for_url``.
    clock : callable() -> float, optional
        Monotonic seconds (tests).

    Attributes
    ----------
    query_failures, resyncs, reconnects : int
    lost : str or None
        Why the port is closed, while it is (reopened by the next reads, with a backoff).
    """

    def __init__(self, port: str, *, baud_rate: int = 9600, timeout_s: float = 0.5,
                 resync_s: float | None = None,
                 serial_factory: Callable[..., Any] | None = None,
                 clock: Callable[[], float] | None = None) -> None:
        import serial

        self._factory = serial_factory or serial.serial_for_url
        self._port_errors = serial_port_errors()
        self.port = port
        self.baud_rate = int(baud_rate)
        self.timeout_s = float(timeout_s)
        self.resync_s = float(resync_s) if resync_s is not None else max(2.0, 4 * timeout_s)
        self._clock = clock or time.monotonic
        self.ser = self._open()
        self.query_failures = 0
        self.resyncs = 0
        self.reconnects = 0
        self.in_sync = True
        self.lost: str | None = None
        self._backoff = ReopenBackoff(self._clock)

    def _open(self) -> Any:
        try:
            return self._factory(self.port, baudrate=self.baud_rate, timeout=self.timeout_s)
        except self._port_errors as err:
            raise PowerBackendError(f'SCPI supply on {self.port!r}: cannot open: {err}') from err

    def _port_failed(self, err: BaseException) -> PowerPortLost:
        """Close the failed port; the next reads reopen it (0.5 s backoff, doubling to 8 s)."""
        try:
            self.ser.close()
        except self._port_errors:
            pass
        self.ser = None
        self.in_sync = False
        self.lost = f'{type(err).__name__}: {err}'
        self._backoff.port_failed()
        return PowerPortLost(f'SCPI supply on {self.port!r}: port failed ({self.lost}); '
                             'reopening it with a backoff')

    def _reopen(self) -> None:
        if not self._backoff.due():
            raise PowerPortLost(f'SCPI supply on {self.port!r}: port lost ({self.lost})')
        try:
            self.ser = self._open()
        except PowerBackendError as err:
            self._backoff.attempt_failed()
            raise PowerPortLost(f'{err}; next attempt in {self._backoff.delay_s:g} s') from err
        self.lost = None
        self.reconnects += 1

    def _send(self, command: str, *, clear: bool = True) -> None:
        try:
            if clear:
                self.ser.reset_input_buffer()
            self.ser.write((command + '\n').encode('ascii'))
        except self._port_errors as err:
            raise self._port_failed(err) from err

    def _readline(self) -> bytes:
        try:
            return self.ser.readline()
        except self._port_errors as err:
            raise self._port_failed(err) from err

    def query(self, command: str) -> float:
        """Send one query, parse the number in the reply line.

        A reply missing its deadline, an incomplete or unreadable one marks the line out of
        sync (its late reply may still come): :meth:`read` resynchronises before the next pair.
        """
        self._send(command)
        raw = self._readline()
        line = raw.decode('ascii', errors='replace').strip()
        try:
            if not raw.endswith(b'\n'):
                raise ValueError('no complete reply line before the deadline')
            value = _scpi_number(line)
        except (ValueError, IndexError) as err:
            self.query_failures += 1
            self.in_sync = False
            late = '' if raw.endswith(b'\n') else f' within {self.timeout_s:g} s'
            raise PowerBackendError(f'SCPI supply on {self.port!r}: {command} answered '
                                    f'{line!r}{late}, expected a number') from err
        if not math.isfinite(value) or abs(value) >= SCPI_OVERRANGE:
            self.query_failures += 1
            raise PowerBackendError(f'SCPI supply on {self.port!r}: {command} answered '
                                    f'{line!r}: overrange / not a number, sample dropped')
        return value

    def resync(self) -> None:
        """Discard every reply still due: send ``*IDN?`` and read up to its (non-numeric)
        reply; supplies answer in order, so a late reply to an earlier query comes before it.
        A supply that does not answer ``*IDN?`` counts as in sync once the line has been quiet
        for ``timeout_s`` after ``resync_s``."""
        self.resyncs += 1
        deadline = self._clock() + self.resync_s
        self._send('*IDN?')
        while True:
            raw = self._readline()
            if raw.endswith(b'\n'):
                try:
                    _scpi_number(raw.decode('ascii', errors='replace').strip())
                except (ValueError, IndexError):
                    self.in_sync = True         # the *IDN? answer (or an error text): in step
                    return
            elif not raw and self._clock() >= deadline:
                self.in_sync = True             # quiet for timeout_s: nothing more is due
                return
            if self._clock() >= deadline + 2 * self.timeout_s:
                raise PowerBackendError(f'SCPI supply on {self.port!r}: replies still arriving '
                                        f'{self.resync_s:g} s after a late one; resynchronising')

    def read(self) -> PowerSample:
        """Voltage and current, from two queries answered in step (never a stale reply)."""
        if self.ser is None:
            self._reopen()
        if not self.in_sync:
            self.resync()
        voltage = self.query('MEAS:VOLT?')
        return PowerSample(voltage, self.query('MEAS:CURR?'))

    def close(self) -> None:
        if self.ser is not None:
            self.ser.close()


class FailureLog:
    """What to log for a run of failures: the first at once, then at most one summary per
    ``period_s`` (count and latest reason), and one line when it recovers. No ROS.

    ``failed(now, reason)`` and ``succeeded(now)`` return the line to log, or None.
    """

    def __init__(self, period_s: float = 5.0) -> None:
        self.period_s = float(period_s)
        self.total = 0
        self.run = 0            # failures since the last success
        self.last_reason = ''
        self._last_logged = -math.inf
        self._since_logged = 0

    def failed(self, now: float, reason: str) -> str | None:
        self.total += 1
        self.run += 1
        self._since_logged += 1
        self.last_reason = reason
        if self.run == 1:
            self._last_logged, self._since_logged = now, 0
            return reason
        if now - self._last_logged >= self.period_s:
            n, self._last_logged, self._since_logged = self._since_logged, now, 0
            return f'{n} more failures in the last {self.period_s:g} s; latest: {reason}'
        return None

    def succeeded(self, now: float) -> str | None:
        if self.run == 0:
            return None
        line = f'recovered after {self.run} failures'
        self.run, self._since_logged = 0, 0
        return line


class ZeroOffset:
    """Zero-current offset: average the current with the robot unpowered, subtract it after.

    ``fit(currents_a) -> self`` sets ``offset_a_`` (mean) and ``noise_a_`` (standard deviation).
    """

    def __init__(self, *, min_samples: int = 10) -> None:
        self.min_samples = int(min_samples)

    def fit(self, currents_a: Any) -> ZeroOffset:
        x = np.asarray(currents_a, dtype=float).ravel()
        if x.size < self.min_samples or not np.all(np.isfinite(x)):
            raise ValueError(f'currents_a: expected >= {self.min_samples} finite samples, '
                             f'got {x.size}')
        self.offset_a_ = float(np.mean(x))
        self.noise_a_ = float(np.std(x, ddof=1)) if x.size > 1 else 0.0
        return self

    def apply(self, sample: PowerSample) -> PowerSample:
        if not hasattr(self, 'offset_a_'):
            raise RuntimeError('ZeroOffset is not fitted: call fit() with zero-load currents')
        return PowerSample(sample.voltage_v, sample.current_a - self.offset_a_)
