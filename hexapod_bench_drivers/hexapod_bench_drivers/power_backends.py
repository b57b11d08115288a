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

SCPI: ``MEAS:VOLT?`` and ``MEAS:CURR?`` each answered by one line with a number (most bench
supplies: Rigol DP8xx, Keysight E36xx, Korad with SCPI firmware).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, Protocol

import numpy as np

__all__ = [
    'INA219_REGISTERS',
    'INA226_REGISTERS',
    'Ina2xxBackend',
    'PowerBackend',
    'PowerBackendError',
    'PowerSample',
    'ScpiSupplyBackend',
    'SimPowerBackend',
    'ZeroOffset',
    'ros_battery_current',
]


class PowerBackendError(RuntimeError):
    """A power sensor cannot be reached or answers nonsense."""


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
                    'calibration': 0x05, 'manufacturer_id': 0xFE, 'die_id': 0xFF}
INA219_REGISTERS = {'config': 0x00, 'shunt': 0x01, 'bus': 0x02, 'power': 0x03, 'current': 0x04,
                    'calibration': 0x05}
INA226_MANUFACTURER_ID = 0x5449   # 'TI'
INA226_CONFIG = 0x4527            # 16 averages, 1.1 ms conversions, shunt+bus continuous
INA219_CONFIG = 0x399F            # 32 V range, +-320 mV, 12-bit, shunt+bus continuous


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
        Largest expected current [A]; sets the current LSB.
    """

    def __init__(self, bus: Any, *, chip: str = 'ina226', address: int = 0x40,
                 shunt_ohm: float = 0.01, max_current_a: float = 8.0) -> None:
        if chip not in ('ina226', 'ina219'):
            raise ValueError(f'chip: expected ina226 or ina219, got {chip!r}')
        if not (shunt_ohm > 0 and max_current_a > 0):
            raise ValueError(f'shunt_ohm {shunt_ohm} and max_current_a {max_current_a}: '
                             'expected > 0')
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
        self.configure()

    def _write(self, reg: int, value: int) -> None:
        try:
            self.bus.write_i2c_block_data(self.address, reg, [(value >> 8) & 0xFF, value & 0xFF])
        except OSError as err:
            raise PowerBackendError(f'{self.chip} at 0x{self.address:02x}: write of register '
                                    f'0x{reg:02x} failed: {err}') from err

    def _read(self, reg: int, signed: bool = False) -> int:
        try:
            msb, lsb = self.bus.read_i2c_block_data(self.address, reg, 2)
        except (OSError, ValueError) as err:
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
            self._write(INA219_REGISTERS['config'], INA219_CONFIG)
        self._write(INA226_REGISTERS['calibration'], self.calibration)

    def read(self) -> PowerSample:
        raw_bus = self._read(INA226_REGISTERS['bus'])
        if self.chip == 'ina226':
            voltage = raw_bus * 1.25e-3
        else:
            if raw_bus & 0x1:
                raise PowerBackendError('ina219: math overflow flag set (current beyond range)')
            voltage = (raw_bus >> 3) * 4e-3
        current = self._read(INA226_REGISTERS['current'], signed=True) * self.current_lsb_a
        return PowerSample(voltage, current)

    def close(self) -> None:
        close = getattr(self.bus, 'close', None)
        if close is not None:
            close()


class ScpiSupplyBackend:
    """A lab supply answering SCPI ``MEAS:VOLT?`` / ``MEAS:CURR?`` on a serial port.

    Parameters
    ----------
    port : str
        Serial device (or a pty in tests).
    baud_rate : int
    timeout_s : float
        Reply deadline per query [s].
    serial_factory : callable, optional
        ``serial.Serial``-like constructor (tests).
    """

    def __init__(self, port: str, *, baud_rate: int = 9600, timeout_s: float = 0.5,
                 serial_factory: Callable[..., Any] | None = None) -> None:
        import serial

        factory = serial_factory or serial.Serial
        try:
            self.ser = factory(port, baudrate=baud_rate, timeout=timeout_s)
        except (OSError, serial.SerialException) as err:
            raise PowerBackendError(f'SCPI supply on {port!r}: cannot open: {err}') from err
        self.port = port
        self.query_failures = 0

    def query(self, command: str) -> float:
        """Send one query, parse the number in the reply line."""
        self.ser.reset_input_buffer()
        self.ser.write((command + '\n').encode('ascii'))
        line = self.ser.readline().decode('ascii', errors='replace').strip()
        try:
            return float(line.split()[0].rstrip('VAva'))
        except (ValueError, IndexError) as err:
            self.query_failures += 1
            raise PowerBackendError(f'SCPI supply on {self.port!r}: {command} answered '
                                    f'{line!r}, expected a number') from err

    def read(self) -> PowerSample:
        return PowerSample(self.query('MEAS:VOLT?'), self.query('MEAS:CURR?'))

    def close(self) -> None:
        self.ser.close()


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
