"""Dynamixel control tables as data: addresses, sizes, unit conversions, error bits.

Four models are described, from the ROBOTIS e-Manual:

=========  ========  ============  =============================================
model      protocol  model number  notes
=========  ========  ============  =============================================
AX-12A     1.0       12            1024 ticks over 300 deg, 0.111 rpm, 1.5 N m
AX-18A     1.0       18            1024 ticks over 300 deg, 0.111 rpm, 1.8 N m
XL430-W250 2.0       1060          4096 ticks over 360 deg, 0.229 rpm, 1.5 N m
XM430-W350 2.0       1020          as XL430, Present Current (2.69 mA) at 126
=========  ========  ============  =============================================

Conventions: positions are radians about the servo's centre tick (512 or 2048), counter-clockwise
positive as the servo counts. Protocol 1.0 speed and load carry their direction in bit 10
(set = clockwise = negative); Protocol 2.0 values are two's-complement. ``load`` is a signed
fraction of the maximum (stall) torque. Pure data and arithmetic: no SDK, no ROS.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from types import MappingProxyType

__all__ = [
    'ControlTableError',
    'AX12A',
    'AX18A',
    'MODELS_BY_NUMBER',
    'MODELS_BY_NAME',
    'P1_ERROR_BITS',
    'P2_HARDWARE_ERROR_BITS',
    'P2_STATUS_ERRORS',
    'ControlTable',
    'PresentState',
    'Register',
    'XL430',
    'XM430',
    'ERROR_INPUT_VOLTAGE',
    'ERROR_OVERHEATING',
    'ERROR_OVERLOAD',
    'decode_error_flags',
    'table_for_model',
]

RPM_TO_RAD_S = 2.0 * math.pi / 60.0


class ControlTableError(ValueError):
    """Unknown model, unknown register, or a value that does not fit its register."""

#: Protocol 1.0 status-packet error byte (bit -> meaning).
P1_ERROR_BITS: Mapping[int, str] = MappingProxyType({
    0: 'input_voltage', 1: 'angle_limit', 2: 'overheating', 3: 'range', 4: 'checksum',
    5: 'overload', 6: 'instruction',
})
#: Protocol 2.0 Hardware Error Status register (address 70; bit -> meaning).
P2_HARDWARE_ERROR_BITS: Mapping[int, str] = MappingProxyType({
    0: 'input_voltage', 2: 'overheating', 3: 'motor_encoder', 4: 'electrical_shock',
    5: 'overload',
})
#: Protocol 2.0 status-packet error field, low 7 bits (bit 7 is the hardware alert flag).
P2_STATUS_ERRORS: Mapping[int, str] = MappingProxyType({
    0x01: 'result_fail', 0x02: 'instruction_error', 0x03: 'crc_error', 0x04: 'data_range_error',
    0x05: 'data_length_error', 0x06: 'data_limit_error', 0x07: 'access_error',
})

# The three flags the issue cares about sit on the same bits in both protocols' hardware flags
# (P1 status error byte, P2 Hardware Error Status), so /servo_status `error` reads the same.
ERROR_INPUT_VOLTAGE = 1 << 0
ERROR_OVERHEATING = 1 << 2
ERROR_OVERLOAD = 1 << 5


@dataclass(frozen=True)
class Register:
    """One control-table item.

    Attributes
    ----------
    address, size : int
        Byte address and width (1, 2 or 4), little endian.
    writable : bool
        False for read-only items.
    signed : bool
        Two's-complement (Protocol 2.0 velocity, load, current).
    default : int
        Power-on value used by the emulator.
    """

    address: int
    size: int
    writable: bool = False
    signed: bool = False
    default: int = 0


def _p1_registers(model_number: int, temperature_limit_c: int) -> dict[str, Register]:
    r = Register
    return {
        'model_number': r(0, 2, default=model_number),
        'firmware_version': r(2, 1, default=24),
        'id': r(3, 1, True, default=1),
        'baud_rate': r(4, 1, True, default=1),
        'return_delay_time': r(5, 1, True, default=0),
        'cw_angle_limit': r(6, 2, True, default=0),
        'ccw_angle_limit': r(8, 2, True, default=1023),
        'temperature_limit': r(11, 1, True, default=temperature_limit_c),
        'min_voltage_limit': r(12, 1, True, default=60),
        'max_voltage_limit': r(13, 1, True, default=140),
        'max_torque': r(14, 2, True, default=1023),
        'status_return_level': r(16, 1, True, default=2),
        'alarm_led': r(17, 1, True, default=36),
        'shutdown': r(18, 1, True, default=36),
        'torque_enable': r(24, 1, True),
        'led': r(25, 1, True),
        'cw_compliance_margin': r(26, 1, True, default=1),
        'ccw_compliance_margin': r(27, 1, True, default=1),
        'cw_compliance_slope': r(28, 1, True, default=32),
        'ccw_compliance_slope': r(29, 1, True, default=32),
        'goal_position': r(30, 2, True, default=512),
        'moving_speed': r(32, 2, True),
        'torque_limit': r(34, 2, True, default=1023),
        'present_position': r(36, 2, default=512),
        'present_speed': r(38, 2),
        'present_load': r(40, 2),
        'present_voltage': r(42, 1, default=120),
        'present_temperature': r(43, 1, default=26),
        'registered': r(44, 1),
        'moving': r(46, 1),
        'lock': r(47, 1, True),
        'punch': r(48, 2, True, default=32),
    }


def _p2_registers(model_number: int, temperature_limit_c: int,
                  current_sensing: bool) -> dict[str, Register]:
    r = Register
    regs = {
        'model_number': r(0, 2, default=model_number),
        'model_information': r(2, 4),
        'firmware_version': r(6, 1, default=46),
        'id': r(7, 1, True, default=1),
        'baud_rate': r(8, 1, True, default=3),
        'return_delay_time': r(9, 1, True, default=0),
        'drive_mode': r(10, 1, True),
        'operating_mode': r(11, 1, True, default=3),
        'homing_offset': r(20, 4, True, True),
        'temperature_limit': r(31, 1, True, default=temperature_limit_c),
        'max_voltage_limit': r(32, 2, True, default=140),
        'min_voltage_limit': r(34, 2, True, default=60),
        'pwm_limit': r(36, 2, True, default=885),
        'velocity_limit': r(44, 4, True, default=265),
        'max_position_limit': r(48, 4, True, default=4095),
        'min_position_limit': r(52, 4, True, default=0),
        'shutdown': r(63, 1, True, default=52),
        'torque_enable': r(64, 1, True),
        'led': r(65, 1, True),
        'status_return_level': r(68, 1, True, default=2),
        'registered_instruction': r(69, 1),
        'hardware_error_status': r(70, 1),
        'position_p_gain': r(84, 2, True, default=640),
        'goal_pwm': r(100, 2, True, True, default=885),
        'goal_velocity': r(104, 4, True, True),
        'profile_acceleration': r(108, 4, True),
        'profile_velocity': r(112, 4, True),
        'goal_position': r(116, 4, True, True, default=2048),
        'realtime_tick': r(120, 2),
        'moving': r(122, 1),
        'moving_status': r(123, 1),
        'present_pwm': r(124, 2, signed=True),
        'present_velocity': r(128, 4, signed=True),
        'present_position': r(132, 4, signed=True, default=2048),
        'velocity_trajectory': r(136, 4, signed=True),
        'position_trajectory': r(140, 4, signed=True),
        'present_input_voltage': r(144, 2, default=120),
        'present_temperature': r(146, 1, default=26),
    }
    if current_sensing:
        regs['current_limit'] = r(38, 2, True, default=1193)
        regs['goal_current'] = r(102, 2, True, True)
        regs['present_current'] = r(126, 2, signed=True)
    else:
        regs['present_load'] = r(126, 2, signed=True)
    return regs


@dataclass(frozen=True)
class PresentState:
    """One servo's present values in SI units, decoded from its read block.

    Attributes
    ----------
    position_rad, velocity_rad_s : float
        Servo frame, about the centre tick, counter-clockwise positive.
    load_fraction : float
        Signed fraction of stall torque (from Present Load, or Present Current / stall current).
    voltage_v, temperature_c : float
        Supply voltage [V] and internal temperature [degC].
    """

    position_rad: float
    velocity_rad_s: float
    load_fraction: float
    voltage_v: float
    temperature_c: float


@dataclass(frozen=True)
class ControlTable:
    """A Dynamixel model: its registers and the conversions between raw units and SI.

    Attributes
    ----------
    model_name : str
    model_number : int
        What PING (2.0) or address 0 (1.0) reports.
    protocol : int
        1 or 2.
    registers : Mapping[str, Register]
    ticks_per_rev_span : int
        Number of position ticks over ``position_span_rad`` (1024 or 4096).
    position_span_rad : float
        Angle covered by the tick range (300 deg or 360 deg).
    center_tick : int
        Tick of 0 rad (512 or 2048).
    velocity_unit_rpm : float
        One speed unit [rpm] (0.111 or 0.229).
    stall_torque_nm, stall_current_a : float
        At 12 V; effort estimate = load fraction * stall torque.
    no_load_speed_rad_s : float
        At 12 V.
    """

    model_name: str
    model_number: int
    protocol: int
    registers: Mapping[str, Register]
    ticks_per_span: int
    position_span_rad: float
    center_tick: int
    velocity_unit_rpm: float
    stall_torque_nm: float
    stall_current_a: float
    no_load_speed_rad_s: float
    current_unit_a: float = 0.0
    read_names: tuple[str, ...] = field(default=())

    # --- registers -------------------------------------------------------------------------
    def reg(self, name: str) -> Register:
        """The register called ``name``; ControlTableError names the model when absent."""
        try:
            return self.registers[name]
        except KeyError:
            raise ControlTableError(
                f'{self.model_name} has no register {name!r}; '
                f'expected one of {sorted(self.registers)}') from None

    @property
    def memory_size(self) -> int:
        """Bytes needed to hold every register."""
        return max(r.address + r.size for r in self.registers.values())

    @property
    def read_block(self) -> tuple[int, int]:
        """(start address, length) of one read covering position, speed, load, voltage, temp."""
        regs = [self.reg(n) for n in self.read_names]
        start = min(r.address for r in regs)
        end = max(r.address + r.size for r in regs)
        return start, end - start

    @property
    def goal_block(self) -> tuple[int, int]:
        """(start address, length) of one write of moving speed and goal position together."""
        regs = [self.reg('goal_position'), self.reg(self.speed_limit_register)]
        start = min(r.address for r in regs)
        end = max(r.address + r.size for r in regs)
        return start, end - start

    @property
    def speed_limit_register(self) -> str:
        """Moving Speed (1.0) or Profile Velocity (2.0): 0 means as fast as possible."""
        return 'moving_speed' if self.protocol == 1 else 'profile_velocity'

    def encode(self, name: str, value: int) -> bytes:
        """Little-endian bytes of ``value`` for register ``name`` (range checked)."""
        reg = self.reg(name)
        lo = -(1 << (8 * reg.size - 1)) if reg.signed else 0
        hi = (1 << (8 * reg.size - (1 if reg.signed else 0))) - 1
        if not lo <= int(value) <= hi:
            raise ControlTableError(
                f'{self.model_name} {name}: value {value} outside [{lo}, {hi}]')
        return int(value).to_bytes(reg.size, 'little', signed=reg.signed)

    def decode(self, name: str, data: bytes | bytearray | list[int], start: int = 0) -> int:
        """Integer value of register ``name`` from ``data`` that begins at address ``start``."""
        reg = self.reg(name)
        off = reg.address - start
        if off < 0 or off + reg.size > len(data):
            raise ControlTableError(
                f'{self.model_name} {name} at {reg.address}+{reg.size} not inside data starting '
                f'at {start} of {len(data)} bytes')
        return int.from_bytes(bytes(data[off:off + reg.size]), 'little', signed=reg.signed)

    # --- unit conversions ------------------------------------------------------------------
    @property
    def rad_per_tick(self) -> float:
        return self.position_span_rad / (self.ticks_per_span - 1 if self.protocol == 1
                                         else self.ticks_per_span)

    @property
    def max_tick(self) -> int:
        return self.ticks_per_span - 1

    def position_to_rad(self, ticks: int) -> float:
        """Present/Goal Position ticks -> rad about the centre tick."""
        return (int(ticks) - self.center_tick) * self.rad_per_tick

    def rad_to_position(self, rad: float) -> int:
        """rad -> Goal Position ticks, rounded and clipped to the model's range."""
        tick = int(round(rad / self.rad_per_tick)) + self.center_tick
        return min(max(tick, 0), self.max_tick)

    @property
    def velocity_unit_rad_s(self) -> float:
        return self.velocity_unit_rpm * RPM_TO_RAD_S

    def velocity_to_rad_s(self, raw: int) -> float:
        """Present Speed/Velocity -> rad/s (Protocol 1.0: bit 10 set = clockwise = negative)."""
        if self.protocol == 1:
            magnitude = raw & 0x3FF
            return (-magnitude if raw & 0x400 else magnitude) * self.velocity_unit_rad_s
        return raw * self.velocity_unit_rad_s

    def rad_s_to_velocity(self, rad_s: float) -> int:
        """rad/s -> Present Speed raw encoding (inverse of velocity_to_rad_s; emulator use)."""
        units = int(round(abs(rad_s) / self.velocity_unit_rad_s))
        if self.protocol == 1:
            units = min(units, 0x3FF)
            return units | (0x400 if rad_s < 0 else 0)
        return units if rad_s >= 0 else -units

    def rad_s_to_speed_limit(self, rad_s: float) -> int:
        """|rad/s| -> Moving Speed / Profile Velocity units; 0 stays 0 (= no limit).

        A small nonzero speed rounds up to 1 unit so that it never turns into 'unlimited'.
        """
        speed = abs(float(rad_s))
        if speed == 0.0:
            return 0
        units = max(1, int(round(speed / self.velocity_unit_rad_s)))
        return min(units, 0x3FF) if self.protocol == 1 else min(units, 32767)

    def speed_limit_to_rad_s(self, raw: int) -> float:
        """Moving Speed / Profile Velocity units -> rad/s; 0 -> inf (no limit)."""
        if raw == 0:
            return math.inf
        return (raw & 0x3FF if self.protocol == 1 else raw) * self.velocity_unit_rad_s

    def load_to_fraction(self, raw: int) -> float:
        """Present Load (0.1 %) or Present Current -> signed fraction of stall torque."""
        if 'present_current' in self.registers:
            return raw * self.current_unit_a / self.stall_current_a
        if self.protocol == 1:
            magnitude = raw & 0x3FF
            return (-magnitude if raw & 0x400 else magnitude) / 1000.0
        return raw / 1000.0

    def fraction_to_load(self, fraction: float) -> int:
        """Signed fraction of stall torque -> raw Present Load/Current (emulator use)."""
        if 'present_current' in self.registers:
            units = int(round(fraction * self.stall_current_a / self.current_unit_a))
            return max(-32768, min(32767, units))
        units = min(int(round(abs(fraction) * 1000.0)), 1000 if self.protocol == 2 else 0x3FF)
        if self.protocol == 1:
            return units | (0x400 if fraction < 0 else 0)
        return units if fraction >= 0 else -units

    @staticmethod
    def voltage_to_v(raw: int) -> float:
        """Present (Input) Voltage, 0.1 V units -> V."""
        return raw * 0.1

    @staticmethod
    def temperature_to_c(raw: int) -> float:
        """Present Temperature, 1 degC units."""
        return float(raw)

    def decode_present(self, data: bytes | bytearray | list[int]) -> PresentState:
        """Decode a read of ``read_block`` into SI units."""
        start, _ = self.read_block
        load_name = 'present_current' if 'present_current' in self.registers else 'present_load'
        speed_name = 'present_speed' if self.protocol == 1 else 'present_velocity'
        voltage_name = 'present_voltage' if self.protocol == 1 else 'present_input_voltage'
        return PresentState(
            position_rad=self.position_to_rad(self.decode('present_position', data, start)),
            velocity_rad_s=self.velocity_to_rad_s(self.decode(speed_name, data, start)),
            load_fraction=self.load_to_fraction(self.decode(load_name, data, start)),
            voltage_v=self.voltage_to_v(self.decode(voltage_name, data, start)),
            temperature_c=self.temperature_to_c(self.decode('present_temperature', data, start)),
        )


def _p1_table(name: str, number: int, stall_nm: float, stall_a: float, no_load_rpm: float,
              temp_limit_c: int) -> ControlTable:
    return ControlTable(
        model_name=name, model_number=number, protocol=1,
        registers=MappingProxyType(_p1_registers(number, temp_limit_c)),
        ticks_per_span=1024, position_span_rad=math.radians(300.0), center_tick=512,
        velocity_unit_rpm=0.111, stall_torque_nm=stall_nm, stall_current_a=stall_a,
        no_load_speed_rad_s=no_load_rpm * RPM_TO_RAD_S,
        read_names=('present_position', 'present_speed', 'present_load', 'present_voltage',
                    'present_temperature'),
    )


def _p2_table(name: str, number: int, stall_nm: float, stall_a: float, no_load_rpm: float,
              temp_limit_c: int, current_sensing: bool) -> ControlTable:
    return ControlTable(
        model_name=name, model_number=number, protocol=2,
        registers=MappingProxyType(_p2_registers(number, temp_limit_c, current_sensing)),
        ticks_per_span=4096, position_span_rad=2.0 * math.pi, center_tick=2048,
        velocity_unit_rpm=0.229, stall_torque_nm=stall_nm, stall_current_a=stall_a,
        no_load_speed_rad_s=no_load_rpm * RPM_TO_RAD_S,
        current_unit_a=0.00269 if current_sensing else 0.0,
        read_names=('present_current' if current_sensing else 'present_load',
                    'present_velocity', 'present_position', 'present_input_voltage',
                    'present_temperature'),
    )


# Datasheet figures at 12 V (e-Manual): stall torque, stall current, no-load speed.
AX12A = _p1_table('AX-12A', 12, 1.5, 1.5, 59.0, 70)
AX18A = _p1_table('AX-18A', 18, 1.8, 2.2, 97.0, 75)
XL430 = _p2_table('XL430-W250', 1060, 1.5, 1.4, 61.0, 72, current_sensing=False)
XM430 = _p2_table('XM430-W350', 1020, 4.1, 2.3, 46.0, 80, current_sensing=True)

MODELS_BY_NUMBER: Mapping[tuple[int, int], ControlTable] = MappingProxyType({
    (t.protocol, t.model_number): t for t in (AX12A, AX18A, XL430, XM430)})
MODELS_BY_NAME: Mapping[str, ControlTable] = MappingProxyType({
    'ax12a': AX12A, 'ax18a': AX18A, 'xl430': XL430, 'xm430': XM430})


def table_for_model(protocol: int, model_number: int) -> ControlTable:
    """The control table of a pinged model; ControlTableError lists the known ones."""
    try:
        return MODELS_BY_NUMBER[(int(protocol), int(model_number))]
    except KeyError:
        known = ', '.join(f'{t.model_name} (P{p}, {n})' for (p, n), t in MODELS_BY_NUMBER.items())
        raise ControlTableError(
            f'unknown Dynamixel model number {model_number} on protocol {protocol}; '
            f'expected one of {known}') from None


def decode_error_flags(protocol: int, flags: int) -> tuple[str, ...]:
    """Names of the set bits of a hardware error byte.

    ``flags`` is the Protocol 1.0 status error byte, or the Protocol 2.0 Hardware Error Status
    register (not the 2.0 status-packet error field, see P2_STATUS_ERRORS).
    """
    table = P1_ERROR_BITS if int(protocol) == 1 else P2_HARDWARE_ERROR_BITS
    return tuple(name for bit, name in table.items() if flags & (1 << bit))
