"""Dynamixel control tables as data: addresses, sizes, unit conversions, error bits.

Models, each figure from its ROBOTIS e-Manual page (https://emanual.robotis.com/docs/en/dxl/ +
``page``): protocol ``P``, model number, ticks over degrees, centre tick, velocity unit [rpm],
stall torque [N m], stall current [A] and no-load speed [rpm] at the rated voltage ``V``,
Present Current unit ``I mA`` (``-``: the model reports Present Load, 0.1 %), Temperature Limit
default ``T`` [degC]:

===========  =  ======  =========  ======  =====  =====  ====  =====  ==  ====  ==  ============
model        P  number  ticks/deg  centre  rpm/u  N m    A     rpm    V   I mA  T   page
===========  =  ======  =========  ======  =====  =====  ====  =====  ==  ====  ==  ============
AX-12A       1  12      1024/300   512     0.111  1.5    1.5   59     12  -     70  ax/ax-12a
AX-18A       1  18      1024/300   512     0.111  1.8    2.2   97     12  -     75  ax/ax-18a
AX-12W       1  300     1024/300   512     0.111  0.2    1.4   54(1)  12  -     70  ax/ax-12w
RX-24F       1  24      1024/300   512     0.111  2.6    2.4   126    12  -     80  rx/rx-24f
RX-28        1  28      1024/300   512     0.111  3.7    1.9   85     18  -     80  rx/rx-28
RX-64        1  64      1024/300   512     0.111  5.3    2.6   64     18  -     80  rx/rx-64
MX-28        1  29      4096/360   2048    0.114  2.5    1.4   55     12  -     80  mx/mx-28
MX-64        1  310     4096/360   2048    0.114  6.0    4.1   63     12  (2)   80  mx/mx-64
MX-106       1  320     4096/360   2048    0.114  8.4    5.2   45     12  (2)   80  mx/mx-106
MX-28(2.0)   2  30      4096/360   2048    0.229  2.5    1.4   55     12  -     80  mx/mx-28-2
MX-64(2.0)   2  311     4096/360   2048    0.229  6.0    4.1   63     12  3.36  80  mx/mx-64-2
MX-106(2.0)  2  321     4096/360   2048    0.229  8.4    5.2   45     12  3.36  80  mx/mx-106-2
XL430-W250   2  1060    4096/360   2048    0.229  1.5    1.4   61     12  -     72  x/xl430-w250
XM430-W350   2  1020    4096/360   2048    0.229  4.1    2.3   46     12  2.69  80  x/xm430-w350
XM430-W210   2  1030    4096/360   2048    0.229  3.0    2.3   77     12  2.69  80  x/xm430-w210
XH430-W210   2  1010    4096/360   2048    0.229  2.5    1.3   50     12  2.69  80  x/xh430-w210
XH430-W350   2  1000    4096/360   2048    0.229  3.4    1.3   30     12  2.69  80  x/xh430-w350
XC430-W150   2  1070    4096/360   2048    0.229  1.6    1.4   106    12  -     80  x/xc430-w150
XC430-W240   2  1080    4096/360   2048    0.229  1.9    1.4   70     12  -     80  x/xc430-w240
XM540-W150   2  1130    4096/360   2048    0.229  7.3    4.4   53     12  2.69  80  x/xm540-w150
XM540-W270   2  1120    4096/360   2048    0.229  10.6   4.4   30     12  2.69  80  x/xm540-w270
XL330-M077   2  1190    4096/360   2048    0.229  0.215  1.47  383    5   1.0   70  x/xl330-m077
XL330-M288   2  1200    4096/360   2048    0.229  0.52   1.47  103    5   1.0   70  x/xl330-m288
===========  =  ======  =========  ======  =====  =====  ====  =====  ==  ====  ==  ============

(1) AX-12W: 54 rpm in joint mode (the driver's mode; 470 rpm in wheel mode), velocity unit as
    AX-12A (the page shares the AX Moving Speed description).
(2) MX-64/MX-106 on Protocol 1.0 have a Current register (68, RW, 2048 = 0 A, 4.5 mA per unit,
    ``p1_current_unit_a``); the driver still reads Present Load there (one 8-byte block), the
    emulator fills Current too. XH430 stall figures are for the 12 V W-variants (the V-variants
    are 24 V servos with a different current unit and are not listed). XC430 and MX-28(2.0) sense
    no current (Present Load, 0.1 %); XL330 is a 5 V servo (Present Current, 1 mA).
    XL330 operating range: -5..+70 degC on the rendered page (-5..+60 in the e-Manual's source
    data); its Temperature Limit default is 70. MX Present Speed reads 'about 0.11 rpm' on the
    page, with the example 300 -> 34.33 rpm (0.1144 rpm): the Moving Speed unit 0.114 is used.

Standby current (``standby_current_a``, the Specifications' "Standby Current": the electronics'
draw, which the stall current includes and Present Current, the motor's current, does not; it
is taken out of the stall current in the torque per ampere): 40 mA for the XM430-W350/W210,
XH430-W210/W350 and XM540-W150/W270, 17 mA for the XL330-M077/M288, 100 mA for the MX(2.0)
(the MX pages' common figure); the pages render it from the e-Manual's source data
(github.com/ROBOTIS-GIT/emanual, ``_data/dxl_x_info.yml`` and ``_data/dxl_mx_info.yml``). It is
used for Present Current only; the Present Load models keep 0 (XL430-W250: 52 mA, entered, as
its ServoModel preset's). No page gives a gear efficiency: the XM430-W350's 0.739
(``gear_efficiency``) is its ServoModel preset's calibration (k_t / k_e from the datasheet
points and the model's gear friction). The other Present Current models have none (1: no
back-drive correction; ``dynamixel_bus`` notes it and takes the driver's ``gear_efficiency``):
k_t / k_e from the datasheet points alone reads 0.73 for the XM430-W350 but 0.89 for the
XM430-W210 (the same stall current, another gear), 0.64-0.87 for the others and 1.19 for the
XL330-M077 (above 1: its stall and no-load points are not those of one linear motor), so it is
no default.

Protocol 1.0 MX servos use the AX addresses for everything the driver touches (Torque Enable 24,
Goal Position 30, Moving Speed 32, the present block 36..43), but addresses 26-28 are D/I/P gains
(not compliance margins/slopes), positions span 4096 ticks over 360 deg about 2048, and speeds
count 0.114 rpm. Nothing here writes 26-29 on any model (the emulator writes only power-on
defaults). Protocol 2.0 MX(2.0) firmware uses the X-series addresses.

RX-28 and RX-64 figures are at 18.5 V (``V`` 18 above, 18.5 in the table); the RX series has
the AX control table (compliance margins and slopes, punch 32), Max Voltage Limit 190.

Not described (outside the list that was checked): XL-320, RX-10, EX, DX, Pro, P, Y, XH540, XW,
XD, XC330, MX-12W and the XH430-V (24 V) variants; they are refused by model number.

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
    'ALL_MODELS',
    'AX12A',
    'AX12W',
    'AX18A',
    'MX28',
    'MX28_2',
    'MX64',
    'MX64_2',
    'MX106',
    'MX106_2',
    'RX24F',
    'RX28',
    'RX64',
    'XC430_W150',
    'XC430_W240',
    'XH430_W210',
    'XH430_W350',
    'XL330_M077',
    'XL330_M288',
    'XM430_W210',
    'XM540_W150',
    'XM540_W270',
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
    'BACK_DRIVE_DEAD_BAND_RAD_S',
    'GEAR_EFFICIENCY_MIN',
    'EXTENDED_POSITION_LIMIT',
    'GOAL_POSITION_MODES',
    'MULTI_TURN_MODES',
    'OPERATING_MODES',
    'decode_error_flags',
    'known_model_names',
    'table_by_name',
    'table_for_model',
]

RPM_TO_RAD_S = 2.0 * math.pi / 60.0

#: Present Current to torque (:meth:`ControlTable.current_to_torque_nm`): below this output
#: speed a servo whose current opposes its velocity is taken as driving (no back-drive
#: correction); the correction then grows linearly to its full ``1 / eta^2`` at twice this
#: speed [rad/s]. About two Present Velocity units (0.024 rad/s), so a shaft at rest whose
#: velocity reading flickers by a unit keeps the driving form, and a velocity that crosses
#: the band changes the effort continuously (no jump of 1 / eta^2 = 1.8 at one speed).
BACK_DRIVE_DEAD_BAND_RAD_S = 0.05

#: The lowest gear efficiency a driver accepts as a parameter: a back-driven effort is the
#: current's torque over ``eta^2``, 11x at 0.3. Servo spur gearboxes are about 0.5-0.9 (the
#: XM430-W350's datasheet points give 0.739), so a lower figure is taken for a typo (0.07 for
#: 0.7 would multiply every back-driven effort by 200) and refused.
GEAR_EFFICIENCY_MIN = 0.3


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

#: Protocol 2.0 Operating Mode (register 11, X series and MX(2.0)) values and their names
OPERATING_MODES = {0: 'current control', 1: 'velocity control', 3: 'position control',
                   4: 'extended position control (multi-turn)',
                   5: 'current-based position control', 16: 'PWM control'}
#: modes that follow Goal Position; the others (current, velocity, PWM) ignore it
GOAL_POSITION_MODES = frozenset({3, 4, 5})
#: modes whose Goal Position spans several turns, +-EXTENDED_POSITION_LIMIT ticks
MULTI_TURN_MODES = frozenset({4, 5})
EXTENDED_POSITION_LIMIT = 1_048_575


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


def _p1_registers(model_number: int, temperature_limit_c: int, *, mx: bool = False,
                  current: bool = False, max_voltage_limit: int = 140,
                  compliance_margin: int = 1, compliance_slope: int = 32,
                  punch: int = 32) -> dict[str, Register]:
    """Protocol 1.0 table: AX layout, or MX (``mx``) with PID gains at 26-28 and 4096 ticks.

    ``current``: MX-64/MX-106 Current (68), Torque Control Mode Enable (70), Goal Torque (71).
    """
    r = Register
    regs = {
        'model_number': r(0, 2, default=model_number),
        'firmware_version': r(2, 1, default=24),
        'id': r(3, 1, True, default=1),
        'baud_rate': r(4, 1, True, default=1),
        'return_delay_time': r(5, 1, True, default=0),
        'cw_angle_limit': r(6, 2, True, default=0),
        'ccw_angle_limit': r(8, 2, True, default=4095 if mx else 1023),
        'temperature_limit': r(11, 1, True, default=temperature_limit_c),
        'min_voltage_limit': r(12, 1, True, default=60),
        'max_voltage_limit': r(13, 1, True, default=max_voltage_limit),
        'max_torque': r(14, 2, True, default=1023),
        'status_return_level': r(16, 1, True, default=2),
        'alarm_led': r(17, 1, True, default=36),
        'shutdown': r(18, 1, True, default=36),
        'torque_enable': r(24, 1, True),
        'led': r(25, 1, True),
        'goal_position': r(30, 2, True, default=2048 if mx else 512),
        'moving_speed': r(32, 2, True),
        'torque_limit': r(34, 2, True, default=1023),
        'present_position': r(36, 2, default=2048 if mx else 512),
        'present_speed': r(38, 2),
        'present_load': r(40, 2),
        'present_voltage': r(42, 1, default=120),
        'present_temperature': r(43, 1, default=26),
        'registered': r(44, 1),
        'moving': r(46, 1),
        'lock': r(47, 1, True),
        'punch': r(48, 2, True, default=punch),
    }
    if mx:
        regs.update({
            'multi_turn_offset': r(20, 2, True),
            'resolution_divider': r(22, 1, True, default=1),
            'd_gain': r(26, 1, True, default=0),
            'i_gain': r(27, 1, True, default=0),
            'p_gain': r(28, 1, True, default=32),
            'realtime_tick': r(50, 2),
            'goal_acceleration': r(73, 1, True),
        })
        if current:
            regs.update({
                'current': r(68, 2, True, default=2048),
                'torque_control_mode_enable': r(70, 1, True),
                'goal_torque': r(71, 2, True),
            })
    else:
        regs.update({
            'cw_compliance_margin': r(26, 1, True, default=compliance_margin),
            'ccw_compliance_margin': r(27, 1, True, default=compliance_margin),
            'cw_compliance_slope': r(28, 1, True, default=compliance_slope),
            'ccw_compliance_slope': r(29, 1, True, default=compliance_slope),
        })
    return regs


def _p2_registers(model_number: int, temperature_limit_c: int, current_sensing: bool, *,
                  max_voltage_limit: int = 140, min_voltage_limit: int = 60,
                  current_limit: int = 1193, velocity_limit: int = 265, shutdown: int = 52,
                  position_p_gain: int = 640) -> dict[str, Register]:
    """Protocol 2.0 table (X series and MX(2.0)): the items the driver and emulator use."""
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
        'max_voltage_limit': r(32, 2, True, default=max_voltage_limit),
        'min_voltage_limit': r(34, 2, True, default=min_voltage_limit),
        'pwm_limit': r(36, 2, True, default=885),
        'velocity_limit': r(44, 4, True, default=velocity_limit),
        'max_position_limit': r(48, 4, True, default=4095),
        'min_position_limit': r(52, 4, True, default=0),
        'shutdown': r(63, 1, True, default=shutdown),
        'torque_enable': r(64, 1, True),
        'led': r(65, 1, True),
        'status_return_level': r(68, 1, True, default=2),
        'registered_instruction': r(69, 1),
        'hardware_error_status': r(70, 1),
        'position_p_gain': r(84, 2, True, default=position_p_gain),
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
        regs['current_limit'] = r(38, 2, True, default=current_limit)
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
        At ``rated_voltage_v``; effort estimate = load fraction * stall torque.
    no_load_speed_rad_s : float
        At ``rated_voltage_v``.
    current_unit_a : float
        One Present Current unit [A] (Protocol 2.0 models that sense current), else 0.
    read_names : tuple of str
        The registers of one present-state read (their span is ``read_block``).
    rated_voltage_v : float
        Supply voltage of the datasheet figures [V] (12, or 5 for XL330).
    p1_current_unit_a : float
        Protocol 1.0 MX-64/MX-106 Current (68) unit [A] (value 2048 = 0 A), else 0.
    page : str
        e-Manual page of the model (the source of every figure).
    standby_current_a : float
        The datasheet's standby current [A] (the electronics), which its stall current
        includes and Present Current (the motor's current) does not: taken out of the stall
        current in the torque per ampere. Entered for every Present Current model (and the
        XL430-W250, whose preset has it); 0 for the other Present Load models.
    gear_efficiency : float
        Gear efficiency ``eta`` of the model's ServoModel preset (its ``gear_efficiency``,
        from the datasheet points and the model's friction: XM430-W350 0.739, XL430-W250
        0.785); 1 (no back-drive correction) for the models without a preset, whose efforts
        take the driver's ``gear_efficiency`` when one is given. Used only with Present
        Current.
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
    rated_voltage_v: float = 12.0
    p1_current_unit_a: float = 0.0
    page: str = ''
    standby_current_a: float = 0.0
    gear_efficiency: float = 1.0

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
        """A 300 deg span (AX) has its end ticks 0 and 1023 at both ends; a full turn wraps."""
        full_turn = self.position_span_rad >= 2.0 * math.pi - 1e-9
        return self.position_span_rad / (self.ticks_per_span if full_turn
                                         else self.ticks_per_span - 1)

    @property
    def max_tick(self) -> int:
        return self.ticks_per_span - 1

    def position_to_rad(self, ticks: int) -> float:
        """Present/Goal Position ticks -> rad about the centre tick."""
        return (int(ticks) - self.center_tick) * self.rad_per_tick

    def rad_to_position(self, rad: float, *, multi_turn: bool = False) -> int:
        """rad -> Goal Position ticks, rounded and clipped to the model's range (one turn), or
        with ``multi_turn`` (Operating Mode 4 or 5) to +-EXTENDED_POSITION_LIMIT."""
        tick = int(round(rad / self.rad_per_tick)) + self.center_tick
        if multi_turn:
            return min(max(tick, -EXTENDED_POSITION_LIMIT), EXTENDED_POSITION_LIMIT)
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

    @property
    def torque_per_amp_nm_a(self) -> float:
        """Output torque per ampere of Present Current while the motor drives [N m/A]: the
        stall torque over the stall current less the standby current (XM430-W350: 4.1 / 2.26 =
        1.814; XM540-W150 7.3 / 4.36 = 1.674, where the e-Manual prints stall torque / stall
        current, 1.659; MX-64(2.0) 6.0 / 4.0 = 1.500 for its printed 1.463). The gear's losses
        when driving are in it (the stall torque is measured at the output)."""
        return self.stall_torque_nm / (self.stall_current_a - self.standby_current_a)

    def current_to_torque_nm(self, current_a: float, velocity_rad_s: float, *,
                             gear_efficiency: float | None = None,
                             dead_band_rad_s: float = BACK_DRIVE_DEAD_BAND_RAD_S) -> float:
        """Joint torque [N m] from the motor's current (Present Current, A) and the output
        velocity (rad/s), both in the servo frame; signed as the torque the servo applies.

        Driving (current and velocity of one sign, or the shaft within ``dead_band_rad_s``
        of rest): ``current * torque_per_amp_nm_a``, the datasheet's N m/A, whose stall point
        carries the gear efficiency ``eta`` of a motor driving its load. Back-driven (the
        load drives the motor: current against the velocity, joint power negative), the gear's
        losses are on the load's side: the output torque is the motor's torque divided by
        ``eta``, ``current * torque_per_amp_nm_a / eta^2``. The correction is 0 up to
        ``dead_band_rad_s`` and grows linearly to its full value at twice that speed (see
        :data:`BACK_DRIVE_DEAD_BAND_RAD_S`). ``gear_efficiency`` (0, 1] overrides the table's
        ``eta`` (1: no correction)."""
        eta = self.gear_efficiency if gear_efficiency is None else float(gear_efficiency)
        torque = current_a * self.torque_per_amp_nm_a
        if eta >= 1.0 or current_a * velocity_rad_s >= 0.0:
            return torque
        speed = abs(velocity_rad_s)
        if dead_band_rad_s > 0.0:
            ramp = min(max(speed / dead_band_rad_s - 1.0, 0.0), 1.0)
        else:
            ramp = 1.0
        return torque * (1.0 + ramp * (1.0 / (eta * eta) - 1.0))

    def fraction_to_load(self, fraction: float) -> int:
        """Signed fraction of stall torque -> raw Present Load/Current (emulator use)."""
        if 'present_current' in self.registers:
            units = int(round(fraction * self.stall_current_a / self.current_unit_a))
            return max(-32768, min(32767, units))
        units = min(int(round(abs(fraction) * 1000.0)), 1000 if self.protocol == 2 else 0x3FF)
        if self.protocol == 1:
            return units | (0x400 if fraction < 0 else 0)
        return units if fraction >= 0 else -units

    def p1_current_to_a(self, raw: int) -> float:
        """Protocol 1.0 MX-64/106 Current (68) -> A (2048 = 0 A); ControlTableError elsewhere."""
        if not self.p1_current_unit_a:
            raise ControlTableError(f'{self.model_name} has no Protocol 1.0 Current register')
        return (int(raw) - 2048) * self.p1_current_unit_a

    def a_to_p1_current(self, current_a: float) -> int:
        """A -> Protocol 1.0 Current (68) raw value, clipped to 0..4095 (emulator use)."""
        if not self.p1_current_unit_a:
            raise ControlTableError(f'{self.model_name} has no Protocol 1.0 Current register')
        return max(0, min(4095, 2048 + int(round(current_a / self.p1_current_unit_a))))

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


_EMANUAL = 'https://emanual.robotis.com/docs/en/dxl/'
_P1_READ = ('present_position', 'present_speed', 'present_load', 'present_voltage',
            'present_temperature')


def _p1_table(name: str, number: int, stall_nm: float, stall_a: float, no_load_rpm: float,
              temp_limit_c: int, *, page: str, mx: bool = False, current: bool = False,
              rated_voltage_v: float = 12.0, **register_defaults: int) -> ControlTable:
    return ControlTable(
        model_name=name, model_number=number, protocol=1,
        registers=MappingProxyType(_p1_registers(number, temp_limit_c, mx=mx, current=current,
                                                 **register_defaults)),
        ticks_per_span=4096 if mx else 1024,
        position_span_rad=2.0 * math.pi if mx else math.radians(300.0),
        center_tick=2048 if mx else 512,
        velocity_unit_rpm=0.114 if mx else 0.111, stall_torque_nm=stall_nm,
        stall_current_a=stall_a, no_load_speed_rad_s=no_load_rpm * RPM_TO_RAD_S,
        read_names=_P1_READ, p1_current_unit_a=0.0045 if current else 0.0,
        rated_voltage_v=rated_voltage_v, page=_EMANUAL + page,
    )


def _p2_table(name: str, number: int, stall_nm: float, stall_a: float, no_load_rpm: float,
              temp_limit_c: int, current_sensing: bool, *, page: str,
              current_unit_a: float = 0.00269, rated_voltage_v: float = 12.0,
              standby_current_a: float = 0.0, gear_efficiency: float = 1.0,
              **register_defaults: int) -> ControlTable:
    return ControlTable(
        model_name=name, model_number=number, protocol=2,
        registers=MappingProxyType(_p2_registers(number, temp_limit_c, current_sensing,
                                                 **register_defaults)),
        ticks_per_span=4096, position_span_rad=2.0 * math.pi, center_tick=2048,
        velocity_unit_rpm=0.229, stall_torque_nm=stall_nm, stall_current_a=stall_a,
        no_load_speed_rad_s=no_load_rpm * RPM_TO_RAD_S,
        current_unit_a=current_unit_a if current_sensing else 0.0,
        read_names=('present_current' if current_sensing else 'present_load',
                    'present_velocity', 'present_position', 'present_input_voltage',
                    'present_temperature'),
        rated_voltage_v=rated_voltage_v, page=_EMANUAL + page,
        standby_current_a=standby_current_a, gear_efficiency=gear_efficiency,
    )


# Datasheet figures (e-Manual, see the module table): stall torque [N m], stall current [A] and
# no-load speed [rpm] at the rated voltage, Temperature Limit default [degC]; register defaults
# (voltage, current and velocity limits) from each model's control table. Present Current
# models: the standby current of the page's Specifications (``standby_current_a``, see the
# module doc); a gear efficiency only where a ServoModel preset derives one (XM430-W350).
_X12V = dict(max_voltage_limit=160, min_voltage_limit=95)
AX12A = _p1_table('AX-12A', 12, 1.5, 1.5, 59.0, 70, page='ax/ax-12a/')
AX18A = _p1_table('AX-18A', 18, 1.8, 2.2, 97.0, 75, page='ax/ax-18a/')
AX12W = _p1_table('AX-12W', 300, 0.2, 1.4, 54.0, 70, page='ax/ax-12w/', compliance_margin=4,
                  compliance_slope=64)
# RX series: the AX layout and units (compliance at 26-29, 1024 ticks over 300 deg, 0.111 rpm),
# Temperature Limit 80, Max Voltage Limit 19.0 V; RX-28 and RX-64 rated at 18.5 V.
RX24F = _p1_table('RX-24F', 24, 2.6, 2.4, 126.0, 80, page='rx/rx-24f/', max_voltage_limit=190)
RX28 = _p1_table('RX-28', 28, 3.7, 1.9, 85.0, 80, page='rx/rx-28/', max_voltage_limit=190,
                 rated_voltage_v=18.5)
RX64 = _p1_table('RX-64', 64, 5.3, 2.6, 64.0, 80, page='rx/rx-64/', max_voltage_limit=190,
                 rated_voltage_v=18.5)
MX28 = _p1_table('MX-28', 29, 2.5, 1.4, 55.0, 80, page='mx/mx-28/', mx=True,
                 max_voltage_limit=160, punch=0)
MX64 = _p1_table('MX-64', 310, 6.0, 4.1, 63.0, 80, page='mx/mx-64/', mx=True, current=True,
                 max_voltage_limit=240, punch=0)
MX106 = _p1_table('MX-106', 320, 8.4, 5.2, 45.0, 80, page='mx/mx-106/', mx=True, current=True,
                  max_voltage_limit=160, punch=0)
MX28_2 = _p2_table('MX-28(2.0)', 30, 2.5, 1.4, 55.0, 80, False, page='mx/mx-28-2/',
                   velocity_limit=380, position_p_gain=850, **_X12V)
MX64_2 = _p2_table('MX-64(2.0)', 311, 6.0, 4.1, 63.0, 80, True, page='mx/mx-64-2/',
                   current_unit_a=0.00336, standby_current_a=0.1, current_limit=1941,
                   velocity_limit=435, position_p_gain=850, **_X12V)
MX106_2 = _p2_table('MX-106(2.0)', 321, 8.4, 5.2, 45.0, 80, True, page='mx/mx-106-2/',
                    current_unit_a=0.00336, standby_current_a=0.1, current_limit=2047,
                    velocity_limit=360, position_p_gain=850, **_X12V)
# XL430-W250 and XM430-W350: standby current (e-Manual) and the gear efficiency of their
# ServoModel presets (ServoParams.gear_efficiency, k_t / k_e from the datasheet points; a test
# keeps them equal). The XL430 reports Present Load (a PWM duty): neither is used for it.
XL430 = _p2_table('XL430-W250', 1060, 1.5, 1.4, 61.0, 72, current_sensing=False,
                  page='x/xl430-w250/', standby_current_a=0.052, gear_efficiency=0.785)
XM430 = _p2_table('XM430-W350', 1020, 4.1, 2.3, 46.0, 80, current_sensing=True,
                  page='x/xm430-w350/', standby_current_a=0.04, gear_efficiency=0.739)
XM430_W210 = _p2_table('XM430-W210', 1030, 3.0, 2.3, 77.0, 80, True, page='x/xm430-w210/',
                       standby_current_a=0.04, current_limit=1193, velocity_limit=330,
                       position_p_gain=800, **_X12V)
XH430_W210 = _p2_table('XH430-W210', 1010, 2.5, 1.3, 50.0, 80, True, page='x/xh430-w210/',
                       standby_current_a=0.04, current_limit=648, velocity_limit=360,
                       position_p_gain=900, **_X12V)
XH430_W350 = _p2_table('XH430-W350', 1000, 3.4, 1.3, 30.0, 80, True, page='x/xh430-w350/',
                       standby_current_a=0.04, current_limit=648, velocity_limit=130,
                       position_p_gain=900, **_X12V)
XC430_W150 = _p2_table('XC430-W150', 1070, 1.6, 1.4, 106.0, 80, False, page='x/xc430-w150/',
                       max_voltage_limit=160, min_voltage_limit=60, velocity_limit=460,
                       position_p_gain=460)
XC430_W240 = _p2_table('XC430-W240', 1080, 1.9, 1.4, 70.0, 80, False, page='x/xc430-w240/',
                       max_voltage_limit=160, min_voltage_limit=60, velocity_limit=306,
                       position_p_gain=700)
XM540_W150 = _p2_table('XM540-W150', 1130, 7.3, 4.4, 53.0, 80, True, page='x/xm540-w150/',
                       standby_current_a=0.04, current_limit=2047, velocity_limit=230,
                       position_p_gain=800, **_X12V)
XM540_W270 = _p2_table('XM540-W270', 1120, 10.6, 4.4, 30.0, 80, True, page='x/xm540-w270/',
                       standby_current_a=0.04, current_limit=2047, velocity_limit=128,
                       position_p_gain=800, **_X12V)
XL330_M077 = _p2_table('XL330-M077', 1190, 0.215, 1.47, 383.0, 70, True, page='x/xl330-m077/',
                       current_unit_a=0.001, rated_voltage_v=5.0, standby_current_a=0.017,
                       max_voltage_limit=70, min_voltage_limit=35, current_limit=1750,
                       velocity_limit=1620, shutdown=53, position_p_gain=400)
XL330_M288 = _p2_table('XL330-M288', 1200, 0.52, 1.47, 103.0, 70, True, page='x/xl330-m288/',
                       current_unit_a=0.001, rated_voltage_v=5.0, standby_current_a=0.017,
                       max_voltage_limit=70, min_voltage_limit=35, current_limit=1750,
                       velocity_limit=445, shutdown=53, position_p_gain=400)

ALL_MODELS: tuple[ControlTable, ...] = (
    AX12A, AX18A, AX12W, RX24F, RX28, RX64, MX28, MX64, MX106, MX28_2, MX64_2, MX106_2, XL430,
    XM430, XM430_W210, XH430_W210, XH430_W350, XC430_W150, XC430_W240, XM540_W150, XM540_W270,
    XL330_M077, XL330_M288)

MODELS_BY_NUMBER: Mapping[tuple[int, int], ControlTable] = MappingProxyType({
    (t.protocol, t.model_number): t for t in ALL_MODELS})


def _name_key(name: str) -> str:
    """'MX-28(2.0)' -> 'mx28_2', 'XM430-W210' -> 'xm430w210', 'ax18a' -> 'ax18a'."""
    key = name.lower().replace('(2.0)', '_2').replace('2.0', '_2')
    return ''.join(c for c in key if c.isalnum() or c == '_').replace('__', '_')


#: Lower-case keys without dashes ('ax18a', 'mx28', 'mx28_2', 'xm430w210'); 'xl430' and 'xm430'
#: (the W250 and W350) are kept as short names.
MODELS_BY_NAME: Mapping[str, ControlTable] = MappingProxyType({
    **{_name_key(t.model_name): t for t in ALL_MODELS}, 'xl430': XL430, 'xm430': XM430})


def table_by_name(name: str) -> ControlTable:
    """A model by name, case and dashes ignored: 'MX-28', 'mx28', 'MX-28(2.0)', 'mx28_2'."""
    try:
        return MODELS_BY_NAME[_name_key(name)]
    except KeyError:
        raise ControlTableError(
            f'model {name!r}: expected one of {", ".join(t.model_name for t in ALL_MODELS)}'
        ) from None


def known_model_names(protocol: int | None = None) -> str:
    """Names of the described models (of one protocol if given), comma separated."""
    return ', '.join(t.model_name for t in ALL_MODELS
                     if protocol is None or t.protocol == int(protocol))


def table_for_model(protocol: int, model_number: int) -> ControlTable:
    """The control table of a pinged model; ControlTableError names the known models."""
    try:
        return MODELS_BY_NUMBER[(int(protocol), int(model_number))]
    except KeyError:
        raise ControlTableError(
            f'unknown Dynamixel model number {model_number} on Protocol {int(protocol)}.0; '
            f'known on Protocol 1.0: {known_model_names(1)}; '
            f'on Protocol 2.0: {known_model_names(2)}') from None


def decode_error_flags(protocol: int, flags: int) -> tuple[str, ...]:
    """Names of the set bits of a hardware error byte.

    ``flags`` is the Protocol 1.0 status error byte, or the Protocol 2.0 Hardware Error Status
    register (not the 2.0 status-packet error field, see P2_STATUS_ERRORS).
    """
    table = P1_ERROR_BITS if int(protocol) == 1 else P2_HARDWARE_ERROR_BITS
    return tuple(name for bit, name in table.items() if flags & (1 << bit))
