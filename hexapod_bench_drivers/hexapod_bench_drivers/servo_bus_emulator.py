"""A Dynamixel bus on a pseudo-terminal: Protocol 1.0 and 2.0 servos with physics and faults.

The emulator opens a pty pair (raw, no echo), keeps the slave open so the port never hangs up,
and serves the master side from a background thread: it parses instruction packets (checksum for
1.0, CRC-16 and byte stuffing for 2.0), answers status packets from a per-servo control table
(:mod:`hexapod_bench_drivers.control_tables`) and steps each servo's physics by the time elapsed
since its last access. Any client that opens :attr:`ServoBusEmulator.port_name` as a serial port
(the real ``dynamixel_sdk`` PortHandler, pyserial, the driver node) talks to it as to real servos.

Instructions served (ROBOTIS e-Manual, Protocol 1.0 and 2.0 pages). Protocol 1.0: PING, READ,
WRITE, REG_WRITE, ACTION, FACTORY_RESET (all registers to their defaults, ID back to 1),
SYNC_WRITE, BULK_READ (MX servos only: AX/RX servos have no Bulk Read and stay silent, as for any
broadcast; each listed servo answers after the previous one's status, so the chain stops at a
silent one). REBOOT is not a Protocol 1.0 MX/AX instruction (the SDK's 1.0 ``reboot`` sends
nothing): Instruction Error. Protocol 2.0: PING (also broadcast), READ, WRITE, REG_WRITE, ACTION,
FACTORY_RESET (0xFF all, 0x01 all but ID, 0x02 all but ID and baud rate; broadcast Reset-all is
ignored from firmware v42), REBOOT, CLEAR (multi-turn revolution count; Result Fail while the
servo moves), SYNC_READ, SYNC_WRITE, BULK_READ, BULK_WRITE, FAST_SYNC_READ and FAST_BULK_READ
(one combined status packet from ID 0xFE; X430/540 firmware v45+, XL330 v46+; MX(2.0) has
neither and stays silent). Any other instruction to one servo gets Instruction Error; broadcast
instructions get status packets only for PING and the reads. Status Return Level is honoured.

Fault injection per servo (:meth:`ServoBusEmulator.inject`): ``no_answer`` (silent),
``bad_checksum`` (reply with a corrupted checksum/CRC), ``error_bits`` (hardware error flags in
the reply; Protocol 2.0 sets Hardware Error Status and the alert bit; a flag selected in the
Shutdown register is an Alarm Shutdown: on Protocol 2.0 torque off, Torque Enable kept at 0
until REBOOT clears the fault; on Protocol 1.0, as the AX/RX/MX e-Manual says under Torque
Limit (34), Torque Limit becomes 0 and Torque Enable keeps its value, and only a non-zero
Torque Limit written once the error is gone gives the servo its torque back), ``late_reply``
(answer after a delay, holding the bus as a slow servo does), ``overheat`` (present
temperature forced), ``refuse`` (a READ, Sync Read or Bulk Read answered with ``error_bits``
as the status error and no data: Protocol 2.0 Access Error 0x07 is what a servo of another
model whose table lacks the register answers).
:attr:`ServoBusEmulator.adapter_latency_s` delays every reply on its way to the host without
holding the bus, as a USB adapter's latency timer does (FTDI/U2D2: 16 ms by default on Linux).
:attr:`EmulatedServo.read_hook` is called before a servo answers a READ, Sync Read or Bulk
Read, fast ones included (a test can stamp each reply, e.g. count requests in Present
Position); :attr:`EmulatedServo.write_hook` after it takes a write, before its reply (a test
can act at the moment a register is written, e.g. stop the driver at a Torque Enable).

Bus and adapter faults: :attr:`ServoBusEmulator.echo` returns every byte the host sends before
the replies (a half-duplex adapter without direction control);
:attr:`ServoBusEmulator.duplicate_ids` sends every status packet of those IDs twice (a second
servo at the ID, answering after the first); :attr:`ServoBusEmulator.colliding_ids` merges it
with a twin's answering at the same moment (a wired AND: replies carrying data arrive with a
broken checksum, a PING's intact); :attr:`ServoBusEmulator.corrupt_instructions`
corrupts that many of the next instructions addressed to one servo on their way (the servo
answers with a checksum / CRC error); :meth:`ServoBusEmulator.power_cycle` gives a servo its
power-on RAM values (Torque Enable 0, Goal Position at the present position), between two
requests if called so (a servo rebooted within one read cycle); :meth:`ServoBusEmulator.replace`
puts a servo of another model at an ID (a servo replaced while the bus runs).

Physics: :class:`hexapod_bench_drivers.servo_model.ServoModel` when importable (the simulator's
electromechanical model), else :class:`FirstOrderServo`, a first-order stand-in. Either sits
behind :class:`ServoPhysics`. Moving Speed / Profile Velocity limit the goal the physics tracks.

Operating Mode (Protocol 2.0): in modes 0, 1 and 16 (current, velocity, PWM) a servo ignores
Goal Position (it holds where it is); in modes 4 and 5 positions span +-1 048 575 ticks.
Protocol 1.0 wheel mode (CW and CCW Angle Limit both 0) ignores Goal Position too (here it
holds; a real servo turns at Moving Speed).

Models: every ControlTable of :mod:`hexapod_bench_drivers.control_tables` (AX-12A/18A/12W and
MX-28/64/106 on Protocol 1.0; MX(2.0), XL430, XM430, XH430, XC430, XM540, XL330 on 2.0), mixed
models on one bus allowed (:meth:`ServoBusEmulator.of_models`). Present Load or Present Current
(and the Protocol 1.0 MX-64/106 Current register) follow the model's table; the emulator writes
only power-on defaults to gain or compliance registers. Present Load (AX, RX, MX, XL430, XC430,
MX-28(2.0)) is the drive's PWM duty with the ServoModel physics, as the e-Manual says of it ("an
inferred value based on the internal output value"): it carries the back-EMF, so it has the
velocity's sign. Present Current (XM430, XH430, XM540, XL330, MX-64/106(2.0)) is "the current
value flowing through the device's motor": the physics' signed winding current in the model's
unit (2.69 mA, 3.36 mA, 1 mA), torque-like (positive driving the positive direction, negative
while braking a load that back-drives the shaft), clipped to the e-Manual's range +-Current
Limit (38) of the servo. Before, the PWM duty was written there too (X-series efforts followed
the velocity's sign). Both are signed as the torque the servo applies: a load pulling the
positive way reads negative (FirstOrderServo read it positive).

Run standalone: ``python -m hexapod_bench_drivers.servo_bus_emulator --model ax18a --ids 1-18``
(``--model MX-28``, ``--model xm430w210``, ...) prints the port name and serves until
interrupted.
"""

from __future__ import annotations

import math
import os
import select
import signal
import subprocess
import sys
import threading
import time
import tty
from collections.abc import Callable, Iterable, Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass, field
from typing import Any, Protocol

import numpy as np

from hexapod_common.cli_args import NumberArgumentParser
from hexapod_bench_drivers.control_tables import (
    ERROR_INPUT_VOLTAGE,
    ERROR_OVERHEATING,
    EXTENDED_POSITION_LIMIT,
    GOAL_POSITION_MODES,
    MULTI_TURN_MODES,
    MODELS_BY_NAME,
    ControlTable,
    ControlTableError,
    Register,
    table_by_name,
)

__all__ = [
    'FAULT_KINDS',
    'Fault',
    'FirstOrderServo',
    'ServoBusEmulator',
    'ServoPhysics',
    'ServoStepOutput',
    'EmulatedServo',
    'crc16',
    'emulator_process',
    'fast_read_supported',
    'p1_bulk_read_supported',
    'make_physics',
    'p1_checksum',
    'p1_packet',
    'p2_packet',
]

FAULT_KINDS = ('no_answer', 'bad_checksum', 'error_bits', 'late_reply', 'overheat', 'refuse')

BROADCAST_ID = 0xFE
INST_PING, INST_READ, INST_WRITE, INST_REG_WRITE, INST_ACTION = 0x01, 0x02, 0x03, 0x04, 0x05
INST_FACTORY_RESET, INST_REBOOT, INST_CLEAR, INST_STATUS = 0x06, 0x08, 0x10, 0x55
INST_SYNC_READ, INST_SYNC_WRITE, INST_BULK_READ, INST_BULK_WRITE = 0x82, 0x83, 0x92, 0x93
INST_FAST_SYNC_READ, INST_FAST_BULK_READ = 0x8A, 0x9A

P1_ERR_CHECKSUM, P1_ERR_RANGE, P1_ERR_INSTRUCTION = 0x10, 0x08, 0x40
P2_ERR_RESULT_FAIL, P2_ERR_INSTRUCTION, P2_ERR_CRC, P2_ERR_DATA_RANGE = 0x01, 0x02, 0x03, 0x04
P2_ERR_DATA_LENGTH, P2_ERR_ACCESS = 0x05, 0x07
P2_ALERT = 0x80

#: Protocol 2.0 Factory Reset options: registers each one keeps (e-Manual, Factory Reset 0x06)
P2_FACTORY_RESET_KEEP: dict[int, frozenset[str]] = {
    0xFF: frozenset(), 0x01: frozenset({'id'}), 0x02: frozenset({'id', 'baud_rate'})}
#: Protocol 2.0 Clear: option 0x01 and its fixed bytes reset the multi-turn revolution count
P2_CLEAR_MULTI_TURN = bytes([0x01, 0x44, 0x58, 0x4C, 0x22])
#: lowest firmware version with Clear (0x10) and with Broadcast + Reset-all refused (e-Manual:
#: MX(2.0) and X series from v42)
P2_CLEAR_MIN_FIRMWARE = 42
#: Fast Sync Read / Fast Bulk Read: lowest firmware version per model family (e-Manual:
#: X430/540 series v45, X330 v46; MX(2.0) is not listed and does not have them)
P2_FAST_READ_MIN_FIRMWARE: dict[str, int] = {
    'XL430': 45, 'XM430': 45, 'XH430': 45, 'XC430': 45, 'XM540': 45, 'XL330': 46}


def p1_bulk_read_supported(table: ControlTable) -> bool:
    """Protocol 1.0 Bulk Read (0x92) is MX firmware only; AX and RX servos do not have it."""
    return table.protocol == 1 and table.model_name.startswith('MX')


def fast_read_supported(table: ControlTable, firmware_version: int) -> bool:
    """Whether a Protocol 2.0 servo of ``table`` with this firmware serves Fast Sync/Bulk Read."""
    minimum = P2_FAST_READ_MIN_FIRMWARE.get(table.model_name[:5])
    return table.protocol == 2 and minimum is not None and firmware_version >= minimum


# --- packet codecs ---------------------------------------------------------------------------

def _crc_table() -> list[int]:
    table = []
    for i in range(256):
        crc = i << 8
        for _ in range(8):
            crc = ((crc << 1) ^ 0x8005) if crc & 0x8000 else (crc << 1)
        table.append(crc & 0xFFFF)
    return table


_CRC_TABLE = _crc_table()


def crc16(data: bytes | bytearray) -> int:
    """Dynamixel Protocol 2.0 CRC (CRC-16, polynomial 0x8005, initial value 0, not reflected)."""
    crc = 0
    for byte in data:
        crc = ((crc << 8) ^ _CRC_TABLE[((crc >> 8) ^ byte) & 0xFF]) & 0xFFFF
    return crc


def p1_checksum(body: bytes | bytearray) -> int:
    """Protocol 1.0 checksum: inverted low byte of the sum of ID, LENGTH, INST/ERR, PARAMS."""
    return (~sum(body)) & 0xFF


def p1_packet(servo_id: int, inst_or_error: int, params: bytes = b'') -> bytes:
    """A Protocol 1.0 packet (instruction or status) with its checksum."""
    body = bytes([servo_id, len(params) + 2, inst_or_error]) + bytes(params)
    return b'\xff\xff' + body + bytes([p1_checksum(body)])


def _stuff(params: bytes) -> bytes:
    return params.replace(b'\xff\xff\xfd', b'\xff\xff\xfd\xfd')


def _unstuff(params: bytes) -> bytes:
    return params.replace(b'\xff\xff\xfd\xfd', b'\xff\xff\xfd')


def p2_packet(servo_id: int, instruction: int, params: bytes = b'', *,
              error: int | None = None) -> bytes:
    """A Protocol 2.0 packet with byte stuffing and CRC; ``error`` given -> a status packet."""
    payload = bytes([instruction]) + (bytes([error]) if error is not None else b'') + _stuff(
        bytes(params))
    length = len(payload) + 2
    head = b'\xff\xff\xfd\x00' + bytes([servo_id, length & 0xFF, length >> 8]) + payload
    crc = crc16(head)
    return head + bytes([crc & 0xFF, crc >> 8])


@dataclass(frozen=True)
class _Packet:
    servo_id: int
    instruction: int
    params: bytes
    checksum_ok: bool


def _parse_p1(buf: bytearray) -> tuple[_Packet | None, int]:
    """First complete packet in ``buf`` and the number of bytes consumed (junk included)."""
    start = buf.find(b'\xff\xff')
    if start < 0:
        return None, max(0, len(buf) - 1)
    # Skip extra 0xFF (a valid ID is <= 0xFE, and 0xFF 0xFF 0xFF means the header starts later).
    while start + 2 < len(buf) and buf[start + 2] == 0xFF:
        start += 1
    if len(buf) < start + 4:
        return None, start
    length = buf[start + 3]
    end = start + 4 + length
    if length < 2:
        return None, start + 2
    if len(buf) < end:
        return None, start
    body = bytes(buf[start + 2:end - 1])
    ok = p1_checksum(body) == buf[end - 1]
    return _Packet(body[0], body[2], body[3:], ok), end


def _parse_p2(buf: bytearray) -> tuple[_Packet | None, int]:
    start = buf.find(b'\xff\xff\xfd\x00')
    if start < 0:
        return None, max(0, len(buf) - 3)
    if len(buf) < start + 7:
        return None, start
    length = buf[start + 5] | (buf[start + 6] << 8)
    end = start + 7 + length
    if length < 3:
        return None, start + 4
    if len(buf) < end:
        return None, start
    pkt = bytes(buf[start:end])
    ok = crc16(pkt[:-2]) == (pkt[-2] | (pkt[-1] << 8))
    return _Packet(pkt[4], pkt[7], _unstuff(pkt[8:-2]), ok), end


# --- physics ---------------------------------------------------------------------------------

class ServoPhysics(Protocol):
    """Servos of one model stepped together: the simulator's ServoModel API (arrays of count)."""

    torque_enabled: Any
    moving_speed_rad_s: Any

    def step(self, dt_s: float, goal_position_rad: Any, external_torque_nm: Any,
             supply_voltage_v: Any) -> Any: ...


@dataclass(frozen=True)
class ServoStepOutput:
    """The subset of the simulator's ServoOutput the emulator reads; arrays of shape (count,).

    ``load_fraction``: what Present Load reports, a signed fraction of the stall torque, its
    sign that of the torque the servo applies (ServoModel: the PWM duty, as AX/MX/XL430
    firmware infers the load from its output). ``winding_current_a``: the signed motor current
    [A] that Present Current (X series, MX(2.0)) and the MX-64/106 Current register report.
    """

    position_rad: np.ndarray
    velocity_rad_s: np.ndarray
    load_fraction: np.ndarray
    temperature_c: np.ndarray
    winding_current_a: np.ndarray


class FirstOrderServo:
    """Stand-in physics: first-order position tracking with a load-dependent speed limit.

    velocity = clip((goal - position) / time_constant_s, +-v_max) with v_max falling linearly with
    the external torque from the no-load speed to 0 at stall, and capped by
    ``moving_speed_rad_s`` (0 = no cap). The servo holds its load quasi-statically: it applies
    minus the external torque, so load = -external torque / stall torque (torque-like, as the
    simulator's ServoModel: a load pulling the positive way is held by a negative torque) and
    the motor current is that torque over the datasheet's torque per ampere (stall torque /
    (stall current - standby current), ``ControlTable.torque_per_amp_nm_a``: the driver's
    reading of it is the torque). Stall torque and no-load speed scale with
    supply voltage / the table's rated voltage (12 V, or 5 V for XL330). The temperature stays
    at its initial value. Same call shape as ServoModel.
    """

    def __init__(self, table: ControlTable, *, count: int = 1,
                 initial_position_rad: Any = 0.0, initial_temperature_c: Any = 26.0,
                 time_constant_s: float = 0.02) -> None:
        self.table = table
        self.count = int(count)
        self.torque_enabled = np.zeros(count, dtype=bool)
        self.moving_speed_rad_s = np.zeros(count)
        self.position_rad = np.broadcast_to(np.asarray(initial_position_rad, float),
                                            (count,)).copy()
        self.velocity_rad_s = np.zeros(count)
        self.temperature_c = np.broadcast_to(np.asarray(initial_temperature_c, float),
                                             (count,)).copy()
        self.time_constant_s = float(time_constant_s)

    def step(self, dt_s: float, goal_position_rad: Any, external_torque_nm: Any = 0.0,
             supply_voltage_v: Any = 12.0) -> ServoStepOutput:
        goal = np.broadcast_to(np.asarray(goal_position_rad, float), (self.count,))
        volts = np.broadcast_to(np.asarray(supply_voltage_v, float), (self.count,))
        scale = volts / self.table.rated_voltage_v
        stall = self.table.stall_torque_nm * scale
        torque = np.broadcast_to(np.asarray(external_torque_nm, float), (self.count,))
        v_max = self.table.no_load_speed_rad_s * scale * np.maximum(0.0,
                                                                    1.0 - abs(torque / stall))
        v_max = np.where(self.moving_speed_rad_s > 0,
                         np.minimum(v_max, self.moving_speed_rad_s), v_max)
        step = (goal - self.position_rad) * (1.0 - math.exp(-dt_s / self.time_constant_s))
        step = np.where(self.torque_enabled, np.clip(step, -v_max * dt_s, v_max * dt_s), 0.0)
        self.velocity_rad_s = step / dt_s
        self.position_rad = self.position_rad + step
        # the torque the servo applies, as a fraction of the (rated) stall torque
        load = np.where(self.torque_enabled, -torque / self.table.stall_torque_nm, 0.0) + 0.0
        amps = load * self.table.stall_torque_nm / self.table.torque_per_amp_nm_a
        return ServoStepOutput(self.position_rad.copy(), self.velocity_rad_s.copy(), load,
                               self.temperature_c.copy(), amps)


def make_physics(table: ControlTable, *, count: int, initial_position_rad: Any = 0.0,
                 initial_temperature_c: Any = 26.0, prefer_model: bool = True) -> ServoPhysics:
    """The simulator's ServoModel for ``table``'s model when importable, else FirstOrderServo."""
    if prefer_model:
        try:
            from hexapod_bench_drivers.servo_model import ServoModel, ServoParams
            params = ServoParams.by_name(table.model_name)
        except (ImportError, AttributeError, ValueError):
            pass
        else:
            # 2 ms sub-steps: stable (per the model's docs) and cheap enough for a 1 kHz bus.
            return ServoModel(params, count=count, initial_position_rad=initial_position_rad,
                              initial_temperature_c=initial_temperature_c,
                              ambient_temperature_c=float(np.min(initial_temperature_c)),
                              max_substep_s=2e-3, torque_enabled=False)
    return FirstOrderServo(table, count=count, initial_position_rad=initial_position_rad,
                           initial_temperature_c=initial_temperature_c)


# --- servos ----------------------------------------------------------------------------------

@dataclass
class Fault:
    """An injected fault; ``count`` replies are affected (None: until cleared)."""

    kind: str
    count: int | None = None
    error_bits: int = 0
    delay_s: float = 0.0
    temperature_c: float = 0.0


@dataclass
class EmulatedServo:
    """One servo: its control-table memory and faults; its physics lives in the bus's group.

    Parameters
    ----------
    servo_id : int
        Bus ID, 0..252.
    table : ControlTable
        Model; sets the protocol and the memory layout.
    initial_position_rad : float
        Start position about the centre tick [rad].
    initial_temperature_c : float
        Start winding temperature [degC].
    external_torque_nm : float
        Torque the load applies on the output shaft [N m]; may be changed while running.
    """

    servo_id: int
    table: ControlTable
    initial_position_rad: float = 0.0
    initial_temperature_c: float = 26.0
    external_torque_nm: float = 0.0
    memory: bytearray = field(init=False)
    faults: dict[str, Fault] = field(init=False, default_factory=dict)
    fault_hits: dict[str, int] = field(init=False, default_factory=dict)
    registered: tuple[int, bytes] | None = field(init=False, default=None)
    physics_error: int = field(init=False, default=0)
    #: called (under the bus lock) before the servo answers a READ, Sync Read or Bulk Read
    #: (Fast Sync/Bulk Read and Protocol 1.0 Bulk Read included)
    read_hook: Callable[[EmulatedServo], None] | None = field(init=False, default=None)
    #: called (under the bus lock) with the address and bytes of every write the servo takes
    #: (WRITE, SYNC_WRITE, BULK_WRITE, ACTION), once it is applied and before any reply
    write_hook: Callable[[EmulatedServo, int, bytes], None] | None = field(init=False,
                                                                           default=None)

    def __post_init__(self) -> None:
        self.memory = bytearray(self.table.memory_size)
        for reg in self.table.registers.values():
            self.memory[reg.address:reg.address + reg.size] = reg.default.to_bytes(
                reg.size, 'little', signed=reg.signed)
        self.set('id', self.servo_id)
        self.set('model_number', self.table.model_number)   # (a table derived with replace)
        self.set('present_temperature', int(round(self.initial_temperature_c)))
        tick = self.table.rad_to_position(self.initial_position_rad)
        self.set('goal_position', tick)
        self.set('present_position', tick)

    def get(self, name: str) -> int:
        """Integer value of register ``name``."""
        return self.table.decode(name, self.memory)

    def set(self, name: str, value: int) -> None:
        """Store ``value`` in register ``name`` (no access check: the servo's own side)."""
        reg = self.table.reg(name)
        self.memory[reg.address:reg.address + reg.size] = self.table.encode(name, value)

    @property
    def protocol(self) -> int:
        return self.table.protocol

    def hardware_errors(self) -> int:
        """Hardware error flags now: over the temperature limit, physics flags, injected bits."""
        flags = self.physics_error
        if self.get('present_temperature') > self.get('temperature_limit'):
            flags |= ERROR_OVERHEATING
        if 'error_bits' in self.faults:
            flags |= self.faults['error_bits'].error_bits
        return flags

    def take_fault(self, kind: str) -> Fault | None:
        """The active fault of ``kind`` for this reply (its count decremented), or None."""
        fault = self.faults.get(kind)
        if fault is None:
            return None
        self.fault_hits[kind] = self.fault_hits.get(kind, 0) + 1
        if fault.count is not None:
            fault.count -= 1
            if fault.count <= 0:
                del self.faults[kind]
        return fault


def _get(memory: bytearray, reg: Register) -> int:
    return int.from_bytes(memory[reg.address:reg.address + reg.size], 'little', signed=reg.signed)


def _put(memory: bytearray, reg: Register, value: int) -> None:
    memory[reg.address:reg.address + reg.size] = int(value).to_bytes(reg.size, 'little',
                                                                      signed=reg.signed)


class _Group:
    """Servos of one model sharing one vectorised physics object."""

    def __init__(self, servos: list[EmulatedServo], prefer_model: bool) -> None:
        self.servos = servos
        t = self.table = servos[0].table
        self.physics = make_physics(
            t, count=len(servos),
            initial_position_rad=np.array([t.position_to_rad(s.get('goal_position'))
                                           for s in servos]),
            initial_temperature_c=np.array([s.initial_temperature_c for s in servos]),
            prefer_model=prefer_model)
        r = t.registers
        p1 = t.protocol == 1
        self.r_torque = r['torque_enable']
        self.r_goal = r['goal_position']
        self.r_limit = r[t.speed_limit_register]
        self.r_pos = r['present_position']
        self.r_speed = r['present_speed' if p1 else 'present_velocity']
        self.r_load = r['present_current' if 'present_current' in r else 'present_load']
        self.r_volt = r['present_voltage' if p1 else 'present_input_voltage']
        self.r_temp = r['present_temperature']
        self.r_temp_limit = r['temperature_limit']
        self.r_moving = r['moving']
        self.r_shutdown = r['shutdown']
        #: Protocol 1.0: an Alarm Shutdown sets Torque Limit to 0 (Torque Enable unchanged)
        self.r_torque_limit = r['torque_limit'] if p1 else None
        self.r_hw = r.get('hardware_error_status')
        self.r_mode = r.get('operating_mode')   # Protocol 2.0
        self.r_p1_current = r.get('current')   # MX-64/MX-106 on Protocol 1.0 (2048 = 0 A)
        self.r_current_limit = r.get('current_limit')   # Protocol 2.0 with current sensing
        self.r_cw = r.get('cw_angle_limit')    # Protocol 1.0: both limits 0 is wheel mode
        self.r_ccw = r.get('ccw_angle_limit')

    def shift_position(self, servo: EmulatedServo, delta_rad: float) -> None:
        """Move ``servo``'s physics position (and ServoModel's setpoint) by ``-delta_rad``.

        Used by Clear (multi-turn): the shaft does not move, only the count the servo keeps.
        """
        k = next(i for i, s in enumerate(self.servos) if s is servo)
        phys: Any = self.physics
        if hasattr(phys, 'state') and hasattr(phys, 'set_state'):   # ServoModel
            state = phys.state()
            for key in ('motor_position_rad', '_setpoint_rad'):
                if key in state:
                    state[key][k] -= delta_rad
            phys.set_state(state)
        elif hasattr(phys, 'position_rad'):   # FirstOrderServo
            phys.position_rad[k] -= delta_rad

    def step(self, dt_s: float, supply_voltage_v: float) -> None:
        """Advance the physics by ``dt_s`` and write the present-value registers."""
        t = self.table
        phys = self.physics
        mems = [s.memory for s in self.servos]
        phys.torque_enabled = np.array([_get(m, self.r_torque) != 0 for m in mems])
        if self.r_torque_limit is not None:   # Protocol 1.0: Torque Limit 0 is limp too
            phys.torque_enabled &= np.array([_get(m, self.r_torque_limit) != 0 for m in mems])
        limits = np.array([_get(m, self.r_limit) for m in mems], dtype=float)
        if t.protocol == 1:
            limits = np.bitwise_and(limits.astype(int), 0x3FF).astype(float)
        phys.moving_speed_rad_s = limits * t.velocity_unit_rad_s
        goal = (np.array([_get(m, self.r_goal) for m in mems], dtype=float)
                - t.center_tick) * t.rad_per_tick
        lo, hi = np.zeros(len(mems)), np.full(len(mems), float(t.max_tick))
        if self.r_mode is not None:
            # Operating Mode: velocity, current and PWM modes ignore Goal Position (here the
            # servo holds where it is); modes 4 and 5 span several turns.
            modes = [_get(m, self.r_mode) for m in mems]
            here = (np.array([_get(m, self.r_pos) for m in mems], dtype=float)
                    - t.center_tick) * t.rad_per_tick
            goal = np.where([md in GOAL_POSITION_MODES for md in modes], goal, here)
            multi = np.array([md in MULTI_TURN_MODES for md in modes])
            lo = np.where(multi, -EXTENDED_POSITION_LIMIT, lo)
            hi = np.where(multi, EXTENDED_POSITION_LIMIT, hi)
        if self.r_mode is None and self.r_cw is not None and self.r_ccw is not None:
            wheel = [_get(m, self.r_cw) == 0 and _get(m, self.r_ccw) == 0 for m in mems]
            if any(wheel):   # wheel mode ignores Goal Position (here: holds)
                here = (np.array([_get(m, self.r_pos) for m in mems], dtype=float)
                        - t.center_tick) * t.rad_per_tick
                goal = np.where(wheel, here, goal)
        torque = np.array([s.external_torque_nm for s in self.servos])
        out = phys.step(dt_s, goal, torque, supply_voltage_v)
        errors = getattr(out, 'error', None)
        errors = ([int(e) & (ERROR_INPUT_VOLTAGE | ERROR_OVERHEATING) for e in errors]
                  if errors is not None else [0] * len(mems))
        # Raw register values for all servos at once; the loop below only stores them.
        pos = np.clip(np.rint(np.asarray(out.position_rad) / t.rad_per_tick) + t.center_tick,
                      lo, hi).astype(int).tolist()
        vel = np.asarray(out.velocity_rad_s, dtype=float)
        vel_units = np.rint(np.abs(vel) / t.velocity_unit_rad_s).astype(int)
        load = np.asarray(out.load_fraction, dtype=float)
        # Present Current (and the MX-64/106 Current register) report the motor's own current,
        # torque-like (negative while it brakes a load that back-drives it), not the PWM duty
        amps = getattr(out, 'winding_current_a', None)   # (a physics without it: the load)
        amps = load * t.stall_current_a if amps is None else np.asarray(amps, dtype=float)
        if t.protocol == 1:
            vel_raw = (np.minimum(vel_units, 0x3FF) | np.where(vel < 0, 0x400, 0)).tolist()
            load_raw = (np.minimum(np.rint(np.abs(load) * 1000).astype(int), 0x3FF)
                        | np.where(load < 0, 0x400, 0)).tolist()
        else:
            vel_raw = (np.sign(vel).astype(int) * vel_units).tolist()
            if self.r_current_limit is not None:
                # e-Manual range of Present Current (as Goal Current's): +-Current Limit (38)
                limit = np.array([_get(m, self.r_current_limit) for m in mems], dtype=float)
                load_raw = np.clip(np.rint(amps / t.current_unit_a), -limit, limit).astype(
                    int).tolist()
            else:
                load_raw = np.clip(np.rint(load * 1000), -1000, 1000).astype(int).tolist()
        p1_current = ([t.a_to_p1_current(a) for a in amps.tolist()]
                      if self.r_p1_current is not None else None)
        temp = np.clip(np.rint(np.asarray(out.temperature_c, dtype=float)), 0, 255).astype(
            int).tolist()
        moving = (np.abs(vel) > 0.05).tolist()
        volt = max(0, min(255, int(round(supply_voltage_v * 10))))
        for k, s in enumerate(self.servos):
            m = mems[k]
            s.physics_error = flags = errors[k]
            temperature = temp[k]
            if s.faults:
                if 'overheat' in s.faults:
                    temperature = max(0, min(255, int(round(s.faults['overheat'].temperature_c))))
                if 'error_bits' in s.faults:
                    flags |= s.faults['error_bits'].error_bits
            _put(m, self.r_pos, pos[k])
            _put(m, self.r_speed, vel_raw[k])
            _put(m, self.r_load, load_raw[k])
            if p1_current is not None:
                _put(m, self.r_p1_current, p1_current[k])
            _put(m, self.r_volt, volt)
            _put(m, self.r_temp, temperature)
            _put(m, self.r_moving, int(moving[k]))
            if temperature > m[self.r_temp_limit.address]:
                flags |= ERROR_OVERHEATING
            if self.r_hw is not None:
                _put(m, self.r_hw, flags)
            if flags & m[self.r_shutdown.address]:
                # Real servos drop torque on an error selected in the Shutdown register:
                # Protocol 1.0 by Torque Limit 0 (e-Manual, Torque Limit 34), 2.0 Torque Enable
                if self.r_torque_limit is not None:
                    _put(m, self.r_torque_limit, 0)
                else:
                    m[self.r_torque.address] = 0


# --- the bus ---------------------------------------------------------------------------------

class ServoBusEmulator:
    """Servos of one protocol on a pseudo-terminal, served from a thread.

    Parameters
    ----------
    servos : sequence of EmulatedServo
        All of one protocol, unique IDs; models may be mixed (AX-18A and MX-28 on one 1.0 bus).
    supply_voltage_v : float, optional
        Bus supply [V]; default the servos' rated voltage (12 V, 5 V for XL330; 12 V if they
        differ).
    clock : callable, optional
        Monotonic time source [s] for the physics (default ``time.monotonic``).
    min_step_s : float
        Physics is advanced when a packet arrives and at least this long has passed [s].
    prefer_model : bool
        Use the simulator's ServoModel when importable (else the first-order stand-in).

    Use as a context manager, or ``start()``/``stop()``. Open :attr:`port_name` with the SDK.
    Physics is stepped when a packet arrives and ``min_step_s`` has passed, so present values
    are at most that old (4 ms default: one physics step costs ~0.4 ms for 18 servos).
    """

    def __init__(self, servos: Sequence[EmulatedServo], *, supply_voltage_v: float | None = None,
                 clock: Callable[[], float] = time.monotonic, min_step_s: float = 4e-3,
                 prefer_model: bool = True) -> None:
        if not servos:
            raise ValueError('servos: expected at least one EmulatedServo, got none')
        protocols = {s.protocol for s in servos}
        if len(protocols) != 1:
            raise ValueError(f'servos: expected one protocol on a bus, got {sorted(protocols)}')
        ids = [s.servo_id for s in servos]
        if len(set(ids)) != len(ids) or not all(0 <= i <= 252 for i in ids):
            raise ValueError(f'servos: expected unique IDs in 0..252, got {ids}')
        self.protocol = protocols.pop()
        self.servos = {s.servo_id: s for s in servos}
        if supply_voltage_v is None:
            rated = {s.table.rated_voltage_v for s in servos}
            supply_voltage_v = rated.pop() if len(rated) == 1 else 12.0
        self.supply_voltage_v = float(supply_voltage_v)
        volt_raw = max(0, min(255, int(round(self.supply_voltage_v * 10))))
        for s in servos:   # the supply is seen before the first physics step
            s.set('present_voltage' if s.protocol == 1 else 'present_input_voltage', volt_raw)
        self.clock = clock
        self.lock = threading.RLock()
        self.min_step_s = float(min_step_s)
        by_model: dict[str, list[EmulatedServo]] = {}
        for s in servos:
            by_model.setdefault(s.table.model_name, []).append(s)
        self._prefer_model = prefer_model
        self._groups = [_Group(g, prefer_model) for g in by_model.values()]
        self._last_step_s: float | None = None
        self.packets_received = 0
        self.packets_corrupt = 0
        self.replies_sent = 0
        #: delay of every reply on its way to the host [s], not holding the bus (USB latency)
        self.adapter_latency_s = 0.0
        self._outbox: list[tuple[float, bytes]] = []   # (due time, reply) under latency
        #: return every received byte before replying (a half-duplex adapter's echo)
        self.echo = False
        #: IDs whose status packets are sent twice (two servos at one ID)
        self.duplicate_ids: set[int] = set()
        #: IDs with a second servo answering at the same moment: the two status packets
        #: collide on the wire (a wired AND of the two byte streams), so a reply whose data
        #: differ from the twin's arrives with a broken checksum; a PING's, whose bytes the
        #: twin shares, arrives intact
        self.colliding_ids: set[int] = set()
        #: this many of the next instructions to one servo arrive corrupted
        self.corrupt_instructions = 0
        #: servos pushed off their ID when a Factory Reset gave another servo the same ID (a
        #: real bus then has two servos answering at one ID; the emulator keeps the reset one)
        self.displaced: list[EmulatedServo] = []
        self._group_of = {id(s): g for g in self._groups for s in g.servos}
        self._master, self._slave = os.openpty()
        tty.setraw(self._slave)
        self.port_name = os.ttyname(self._slave)
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None

    @classmethod
    def of_model(cls, model: str | ControlTable, ids: Iterable[int],
                 **kw: Any) -> ServoBusEmulator:
        """Servos of one model at ``ids``: a ControlTable, or a name (``ax18a``, ``MX-28``,
        ``mx64_2``, ``XM430-W210``, ...; see control_tables.MODELS_BY_NAME)."""
        if isinstance(model, ControlTable):
            table = model
        else:
            try:
                table = table_by_name(model)
            except ControlTableError as err:
                raise ValueError(f'model: {err}') from None
        return cls([EmulatedServo(i, table) for i in ids], **kw)

    @classmethod
    def of_models(cls, servos: Iterable[tuple[int, str | ControlTable]],
                  **kw: Any) -> ServoBusEmulator:
        """A mixed bus: ``[(id, model), ...]``, models as in :meth:`of_model` (one protocol)."""
        out = []
        for servo_id, model in servos:
            try:
                table = model if isinstance(model, ControlTable) else table_by_name(model)
            except ControlTableError as err:
                raise ValueError(f'model of id {servo_id}: {err}') from None
            out.append(EmulatedServo(servo_id, table))
        return cls(out, **kw)

    # lifecycle
    def start(self) -> ServoBusEmulator:
        if self._thread is None:
            self._thread = threading.Thread(target=self._run, name='servo-bus-emulator',
                                            daemon=True)
            self._thread.start()
        return self

    def stop(self) -> None:
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout=2.0)
            self._thread = None
        for fd in (self._master, self._slave):
            try:
                os.close(fd)
            except OSError:
                pass
        self._master = self._slave = -1

    def __enter__(self) -> ServoBusEmulator:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.stop()

    # test/operator API
    def servo(self, servo_id: int) -> EmulatedServo:
        return self.servos[servo_id]

    def inject(self, servo_id: int, kind: str, *, count: int | None = None,
               error_bits: int = 0, delay_s: float = 0.0, temperature_c: float = 0.0) -> None:
        """Inject a fault into one servo's replies (see FAULT_KINDS)."""
        if kind not in FAULT_KINDS:
            raise ValueError(f'kind: expected one of {FAULT_KINDS}, got {kind!r}')
        with self.lock:
            self.servos[servo_id].faults[kind] = Fault(kind, count, error_bits, delay_s,
                                                       temperature_c)
            self._advance(force=True)  # registers show an overheat or error bits at once

    def clear_faults(self, servo_id: int | None = None) -> None:
        with self.lock:
            for s in ([self.servos[servo_id]] if servo_id is not None else self.servos.values()):
                s.faults.clear()
            self._advance(force=True)

    def power_cycle(self, servo_id: int) -> None:
        """Servo ``servo_id`` loses power and comes back: its RAM registers (Torque Enable and
        after) to their power-on defaults, Goal Position to where it stands, faults cleared."""
        with self.lock:
            self._advance(force=True)
            servo = self.servos[servo_id]
            torque = servo.table.reg('torque_enable').address
            for name, reg in servo.table.registers.items():
                if reg.writable and reg.address >= torque:
                    _put(servo.memory, reg, reg.default)
            servo.set('goal_position', servo.get('present_position'))
            if servo.protocol == 1:   # Torque Limit starts at Max Torque (EEPROM, 14)
                servo.set('torque_limit', servo.get('max_torque'))
            servo.registered = None
            servo.faults.clear()

    def replace(self, servo_id: int, model: str | ControlTable, *,
                initial_position_rad: float = 0.0) -> EmulatedServo:
        """Another servo at ``servo_id``: one of ``model`` (a name as in :meth:`of_model`, or
        a ControlTable: one with a model number no table has stands for an unknown model),
        with its power-on registers, at ``initial_position_rad``, in place of the one there (a
        servo replaced while the bus runs; the old one's faults go with it). The physics of
        the servos that shared a model with the old or the new one restart at their goals."""
        table = model if isinstance(model, ControlTable) else table_by_name(model)
        if table.protocol != self.protocol:
            raise ValueError(f'model: expected a Protocol {self.protocol}.0 model, got '
                             f'{table.model_name} (Protocol {table.protocol}.0)')
        with self.lock:
            self._advance(force=True)
            new = EmulatedServo(servo_id, table, initial_position_rad)
            new.set('present_voltage' if new.protocol == 1 else 'present_input_voltage',
                    max(0, min(255, int(round(self.supply_voltage_v * 10)))))
            old = self.servos[servo_id]
            self.servos[servo_id] = new
            kept = [g for g in self._groups if all(x is not old for x in g.servos)
                    and g.table.model_name != table.model_name]
            in_kept = {id(x) for g in kept for x in g.servos}
            regroup: dict[str, list[EmulatedServo]] = {}
            for s in self.servos.values():
                if id(s) not in in_kept:
                    regroup.setdefault(s.table.model_name, []).append(s)
            self._groups = kept + [_Group(g, self._prefer_model) for g in regroup.values()]
            self._group_of = {id(s): g for g in self._groups for s in g.servos}
            return new

    def read_register(self, servo_id: int, name: str) -> int:
        """A register as the servo holds it now (physics advanced to now)."""
        with self.lock:
            self._advance(force=True)
            return self.servos[servo_id].get(name)

    def _advance(self, force: bool = False) -> None:
        """Step every servo's physics to now (lazily: only when a packet arrives)."""
        now = self.clock()
        if self._last_step_s is None:
            self._last_step_s = now
            return
        dt = now - self._last_step_s
        if dt >= self.min_step_s or (force and dt > 0):
            self._last_step_s = now
            for g in self._groups:
                g.step(dt, self.supply_voltage_v)

    def present_position_rad(self, servo_id: int) -> float:
        s = self.servos[servo_id]
        return s.table.position_to_rad(self.read_register(servo_id, 'present_position'))

    # the thread
    def _run(self) -> None:
        buf = bytearray()
        parse = _parse_p1 if self.protocol == 1 else _parse_p2
        while not self._stop.is_set():
            try:
                wait_s = 0.05
                if self._outbox:
                    wait_s = min(wait_s, max(0.0, self._outbox[0][0] - time.monotonic()))
                ready, _, _ = select.select([self._master], [], [], wait_s)
                self._deliver_due()
                if not ready:
                    continue
                chunk = os.read(self._master, 4096)
            except (OSError, ValueError):
                return
            if self.echo:
                try:
                    os.write(self._master, chunk)
                except OSError:
                    return
            buf += chunk
            while True:
                pkt, consumed = parse(buf)
                if consumed:
                    del buf[:consumed]
                if pkt is None:
                    break
                self.packets_received += 1
                if self.corrupt_instructions > 0 and pkt.servo_id in self.servos:
                    self.corrupt_instructions -= 1
                    pkt = _Packet(pkt.servo_id, pkt.instruction, pkt.params, False)
                with self.lock:
                    replies = self._handle(pkt)
                replies = [r for reply in replies
                           for r in ([reply, (0.0, reply[1])] if self._twin(reply[1])
                                     else [reply])]
                for delay_s, data in replies:
                    if delay_s > 0:
                        time.sleep(delay_s)  # a late servo holds the bus, as on real hardware
                    if self.adapter_latency_s > 0:
                        self._outbox.append((time.monotonic() + self.adapter_latency_s, data))
                        continue
                    try:
                        os.write(self._master, data)
                    except OSError:
                        return
                    self.replies_sent += 1

    def _twin(self, reply: bytes) -> bool:
        """Whether ``reply`` is a status packet of an ID with a second servo on it."""
        if not self.duplicate_ids:
            return False
        at = 2 if self.protocol == 1 else 4
        return len(reply) > at and reply[at] in self.duplicate_ids

    def _deliver_due(self) -> None:
        """Replies held by the adapter latency whose time has come, in order."""
        now = time.monotonic()
        while self._outbox and self._outbox[0][0] <= now:
            os.write(self._master, self._outbox.pop(0)[1])
            self.replies_sent += 1

    def _status(self, servo: EmulatedServo, error: int, params: bytes = b'',
                *, is_read: bool = False, is_ping: bool = False) -> list[tuple[float, bytes]]:
        """The status reply of ``servo`` after faults and Status Return Level."""
        level = servo.get('status_return_level')
        if not is_ping and (level == 0 or (level == 1 and not is_read)):
            return []
        if servo.take_fault('no_answer') is not None:
            return []
        hw = servo.hardware_errors()
        refuse = servo.take_fault('refuse') if is_read else None
        if refuse is not None:
            error, params = refuse.error_bits, b''
        if servo.protocol == 1:
            data = p1_packet(servo.servo_id, error | hw, params)
        else:
            data = p2_packet(servo.servo_id, INST_STATUS, params,
                             error=error | (P2_ALERT if hw else 0))
        if servo.take_fault('bad_checksum') is not None:
            data = data[:-1] + bytes([data[-1] ^ 0x5A])
        if servo.servo_id in self.colliding_ids and not is_ping:
            # (a PING's reply carries the model and firmware, the same on twins: intact)
            # the twin reads other values (its own position, load...): other parameter bytes
            other = bytes(b ^ 0x5A for b in params)
            if servo.protocol == 1:
                twin = p1_packet(servo.servo_id, error | hw, other)
            else:
                twin = p2_packet(servo.servo_id, INST_STATUS, other,
                                 error=error | (P2_ALERT if hw else 0))
            data = bytes(a & b for a, b in zip(data, twin))
        late = servo.take_fault('late_reply')
        if 'error_bits' in servo.faults:
            servo.take_fault('error_bits')
        return [(late.delay_s if late is not None else 0.0, data)]

    def _access(self, servo: EmulatedServo, address: int, length: int,
                write: bool) -> int:
        """0 if the access is inside the table (and writable for a write), else an error code."""
        self._advance()
        mem = len(servo.memory)
        if length <= 0 or address < 0 or address + length > mem:
            return P1_ERR_RANGE if servo.protocol == 1 else P2_ERR_ACCESS
        if write:
            for reg in servo.table.registers.values():
                overlap = reg.address < address + length and address < reg.address + reg.size
                if overlap and not reg.writable:
                    return P1_ERR_RANGE if servo.protocol == 1 else P2_ERR_ACCESS
        return 0

    def _write(self, servo: EmulatedServo, address: int, data: bytes) -> int:
        err = self._access(servo, address, len(data), write=True)
        if err == 0:
            # Hardware-error shutdown while the error lasts: Protocol 2.0 Torque Enable stays 0
            # (X series: until REBOOT); Protocol 1.0 Torque Limit stays 0. The write is
            # otherwise applied and the reply carries the error (alert bit / error byte).
            held = 'torque_enable' if servo.protocol == 2 else 'torque_limit'
            reg = servo.table.reg(held)
            if (address < reg.address + reg.size and reg.address < address + len(data)
                    and servo.hardware_errors() & servo.get('shutdown')):
                data = bytearray(data)
                for at in range(max(address, reg.address),
                                min(address + len(data), reg.address + reg.size)):
                    data[at - address] = 0
            servo.memory[address:address + len(data)] = data
            if servo.write_hook is not None:
                servo.write_hook(servo, address, bytes(data))
        return err

    def _handle(self, pkt: _Packet) -> list[tuple[float, bytes]]:
        # Physics is advanced lazily: a servo is stepped to now whenever a packet touches it.
        if self.protocol == 1:
            return self._handle_p1(pkt)
        return self._handle_p2(pkt)

    def _handle_p1(self, pkt: _Packet) -> list[tuple[float, bytes]]:
        servo = self.servos.get(pkt.servo_id)
        p = pkt.params
        if not pkt.checksum_ok:
            self.packets_corrupt += 1
            return self._status(servo, P1_ERR_CHECKSUM) if servo is not None else []
        if pkt.instruction == INST_SYNC_WRITE and pkt.servo_id == BROADCAST_ID and len(p) >= 2:
            address, length = p[0], p[1]
            for k in range(2, len(p) - length + 1, length + 1):
                target = self.servos.get(p[k])
                if target is not None:
                    self._write(target, address, bytes(p[k + 1:k + 1 + length]))
            return []
        if pkt.instruction == INST_ACTION and pkt.servo_id == BROADCAST_ID:
            for s in self.servos.values():
                self._action(s)
            return []
        if pkt.instruction == INST_BULK_READ and pkt.servo_id == BROADCAST_ID:
            return self._p1_bulk_read(p)
        if pkt.instruction == INST_FACTORY_RESET and pkt.servo_id == BROADCAST_ID:
            for s in list(self.servos.values()):
                self._factory_reset(s, frozenset())
            return []
        if servo is None:
            return []
        if pkt.instruction == INST_FACTORY_RESET:
            # Reply first (from the old ID, at the old Status Return Level), then reset: all
            # registers to their defaults, the ID to 1 (Protocol 1.0 has no options).
            reply = self._status(servo, 0)
            self._factory_reset(servo, frozenset())
            return reply
        if pkt.instruction == INST_PING:
            return self._status(servo, 0, is_ping=True)
        if pkt.instruction == INST_READ and len(p) == 2:
            err = self._access(servo, p[0], p[1], write=False)
            if servo.read_hook is not None:
                servo.read_hook(servo)
            data = bytes(servo.memory[p[0]:p[0] + p[1]]) if err == 0 else b''
            return self._status(servo, err, data, is_read=True)
        if pkt.instruction == INST_WRITE and len(p) >= 2:
            return self._status(servo, self._write(servo, p[0], bytes(p[1:])))
        if pkt.instruction == INST_REG_WRITE and len(p) >= 2:
            servo.registered = (p[0], bytes(p[1:]))
            return self._status(servo, 0)
        if pkt.instruction == INST_ACTION:
            self._action(servo)
            return self._status(servo, 0)
        return self._status(servo, P1_ERR_INSTRUCTION)

    def _action(self, servo: EmulatedServo) -> None:
        if servo.registered is not None:
            self._write(servo, servo.registered[0], servo.registered[1])
            servo.registered = None

    def _p1_bulk_read(self, p: bytes) -> list[tuple[float, bytes]]:
        """Protocol 1.0 Bulk Read: params [0x00, len1, id1, addr1, len2, id2, addr2, ...].

        Each listed servo answers with a normal status packet once the previous one's status
        has gone by (e-Manual), so the chain stops at the first servo that does not answer: an
        absent ID, an AX/RX servo (no Bulk Read: silent, as for any broadcast), Status Return
        Level 0 or an injected ``no_answer``. An ID listed again is skipped (e-Manual: only its
        first entry is processed).
        """
        out: list[tuple[float, bytes]] = []
        seen: set[int] = set()
        for k in range(1, len(p) - 2, 3):
            length, servo_id, address = p[k], p[k + 1], p[k + 2]
            if servo_id in seen:
                continue
            seen.add(servo_id)
            s = self.servos.get(servo_id)
            if s is None or not p1_bulk_read_supported(s.table):
                break
            err = self._access(s, address, length, write=False)
            if s.read_hook is not None:
                s.read_hook(s)
            data = bytes(s.memory[address:address + length]) if err == 0 else b''
            reply = self._status(s, err, data, is_read=True)
            if not reply:
                break
            out += reply
        return out

    def _factory_reset(self, servo: EmulatedServo, keep: frozenset[str]) -> None:
        """Writable registers back to their ControlTable defaults, except those in ``keep``.

        The defaults are the emulator's power-on values from control_tables (Return Delay Time
        0 and Baud Rate 1 / 3 there; the pty has no baud rate or reply delay). Read-only items
        (model number, firmware, present values) are the servo's own and stay. A pending
        REG_WRITE is dropped. Protocol 2.0 firmware reboots after the reset (e-Manual), which
        also clears an injected ``error_bits`` fault as REBOOT does. A changed ID re-addresses
        the servo (see :attr:`ServoBusEmulator.displaced`).
        """
        self._advance()
        for name, reg in servo.table.registers.items():
            if reg.writable and name not in keep:
                _put(servo.memory, reg, reg.default)
        servo.registered = None
        if servo.protocol == 2:
            servo.faults.pop('error_bits', None)
        new_id = servo.get('id')
        if new_id != servo.servo_id:
            del self.servos[servo.servo_id]
            other = self.servos.get(new_id)
            if other is not None:
                self.displaced.append(other)
            servo.servo_id = new_id
            self.servos[new_id] = servo

    def _p2_factory_reset(self, servo: EmulatedServo, p: bytes,
                          broadcast: bool) -> list[tuple[float, bytes]]:
        """Protocol 2.0 Factory Reset of ``servo``: reply first, then reset.

        Options (e-Manual): 0xFF all, 0x01 all but ID, 0x02 all but ID and baud rate. Broadcast
        with 0xFF is ignored from firmware v42. The e-Manual names no torque-on refusal (it does
        for Control Table Backup), so none is made. An option outside the three, or a missing
        one, is answered with Data Range / Data Length Error and changes nothing (what real
        firmware answers there is not documented).
        """
        if len(p) != 1:
            return [] if broadcast else self._status(servo, P2_ERR_DATA_LENGTH)
        keep = P2_FACTORY_RESET_KEEP.get(p[0])
        if keep is None:
            return [] if broadcast else self._status(servo, P2_ERR_DATA_RANGE)
        if broadcast and p[0] == 0xFF and servo.get('firmware_version') >= P2_CLEAR_MIN_FIRMWARE:
            return []
        reply = [] if broadcast else self._status(servo, 0)
        self._factory_reset(servo, keep)
        return reply

    def _p2_clear(self, servo: EmulatedServo, p: bytes,
                  broadcast: bool) -> list[tuple[float, bytes]]:
        """Protocol 2.0 Clear 0x01 (multi-turn): Present Position to its value within one turn.

        e-Manual: MX(2.0) and X series from firmware v42 (older: Instruction Error); only while
        the servo is stopped (Moving = 0), else Result Fail and nothing changes. Torque may be
        on (ROBOTIS' clear_multi_turn example clears a servo holding position): the emulator
        then shifts Goal Position by the same whole turns so the servo keeps holding still
        (the firmware's internal handling of the goal is not documented). Other parameters
        (reserved options) are answered with Data Range Error.
        """
        if servo.get('firmware_version') < P2_CLEAR_MIN_FIRMWARE:
            return [] if broadcast else self._status(servo, P2_ERR_INSTRUCTION)
        if bytes(p) != P2_CLEAR_MULTI_TURN:
            return [] if broadcast else self._status(servo, P2_ERR_DATA_RANGE)
        self._advance(force=True)
        if servo.get('moving'):
            return [] if broadcast else self._status(servo, P2_ERR_RESULT_FAIL)
        table = servo.table
        position = servo.get('present_position')
        turns_ticks = position - position % table.ticks_per_span
        if turns_ticks:
            self._group_of[id(servo)].shift_position(servo, turns_ticks * table.rad_per_tick)
            servo.set('present_position', position - turns_ticks)
            goal = servo.get('goal_position') - turns_ticks
            servo.set('goal_position', max(-EXTENDED_POSITION_LIMIT,
                                           min(EXTENDED_POSITION_LIMIT, goal)))
        return [] if broadcast else self._status(servo, 0)

    def _fast_read(self, requests: list[tuple[int, int, int]]) -> list[tuple[float, bytes]]:
        """Fast Sync Read / Fast Bulk Read: one status packet (ID 0xFE) for all listed servos.

        Wire format (e-Manual): header, ID 0xFE, LEN = 1 + sum(4 + length_i), INST 0x55, then
        per servo ``[error, id, data..., crc_l, crc_h]``, where each CRC is the CRC-16 of the
        packet up to it (the last one is the packet's CRC), no byte stuffing. Every servo sends
        its own segment; the chain stops at a servo that does not answer (absent, a model or
        firmware without fast reads, Status Return Level 0, ``no_answer``), leaving the host a
        packet shorter than its LEN. ``late_reply`` delays that servo's segment,
        ``bad_checksum`` corrupts its CRC on the wire, ``error_bits`` sets its alert bit. A
        read outside the table gives Access Error and zeros in that servo's segment (keeping
        the segment length the host expects). A repeated ID is skipped.
        """
        unique: list[tuple[int, int, int]] = []
        for req in requests:
            if all(req[0] != u[0] for u in unique):
                unique.append(req)
        if not unique:
            return []
        length = 1 + sum(4 + n for _, _, n in unique)
        packet = bytearray(b'\xff\xff\xfd\x00') + bytes(
            [BROADCAST_ID, length & 0xFF, length >> 8, INST_STATUS])
        segments: list[tuple[float, int]] = []   # (delay, end offset in packet)
        corrupt: list[int] = []
        for servo_id, address, n in unique:
            s = self.servos.get(servo_id)
            if s is None or not fast_read_supported(s.table, s.get('firmware_version')):
                break
            err = self._access(s, address, n, write=False)
            if s.read_hook is not None:
                s.read_hook(s)
            if s.get('status_return_level') == 0 or s.take_fault('no_answer') is not None:
                break
            data = bytes(s.memory[address:address + n]) if err == 0 else bytes(n)
            alert = P2_ALERT if s.hardware_errors() else 0
            packet += bytes([err | alert, s.servo_id]) + data
            crc = crc16(packet)
            packet += bytes([crc & 0xFF, crc >> 8])
            if s.take_fault('bad_checksum') is not None:
                corrupt.append(len(packet) - 1)
            late = s.take_fault('late_reply')
            if 'error_bits' in s.faults:
                s.take_fault('error_bits')
            segments.append((late.delay_s if late is not None else 0.0, len(packet)))
        for i in corrupt:
            packet[i] ^= 0x5A
        out: list[tuple[float, bytes]] = []
        start = 0
        for delay_s, end in segments:
            out.append((delay_s, bytes(packet[start:end])))
            start = end
        return out

    def _handle_p2(self, pkt: _Packet) -> list[tuple[float, bytes]]:
        p = pkt.params
        inst = pkt.instruction
        servo = self.servos.get(pkt.servo_id)
        u16 = int.from_bytes
        if not pkt.checksum_ok:
            self.packets_corrupt += 1
            return self._status(servo, P2_ERR_CRC) if servo is not None else []
        if pkt.servo_id == BROADCAST_ID:
            if inst == INST_PING:
                out: list[tuple[float, bytes]] = []
                for s in sorted(self.servos.values(), key=lambda s: s.servo_id):
                    out += self._ping_reply(s)
                return out
            if inst == INST_SYNC_WRITE and len(p) >= 4:
                address, length = u16(p[0:2], 'little'), u16(p[2:4], 'little')
                for k in range(4, len(p) - length + 1, length + 1):
                    target = self.servos.get(p[k])
                    if target is not None:
                        self._write(target, address, bytes(p[k + 1:k + 1 + length]))
                return []
            if inst == INST_BULK_WRITE:
                k = 0
                while k + 5 <= len(p):
                    address, length = u16(p[k + 1:k + 3], 'little'), u16(p[k + 3:k + 5], 'little')
                    target = self.servos.get(p[k])
                    if target is not None:
                        self._write(target, address, bytes(p[k + 5:k + 5 + length]))
                    k += 5 + length
                return []
            if inst == INST_SYNC_READ and len(p) >= 4:
                address, length = u16(p[0:2], 'little'), u16(p[2:4], 'little')
                return self._multi_read([(i, address, length) for i in p[4:]])
            if inst in (INST_BULK_READ, INST_FAST_BULK_READ):
                reqs = [(p[k], u16(p[k + 1:k + 3], 'little'), u16(p[k + 3:k + 5], 'little'))
                        for k in range(0, len(p) - 4, 5)]
                return (self._multi_read(reqs) if inst == INST_BULK_READ
                        else self._fast_read(reqs))
            if inst == INST_FAST_SYNC_READ and len(p) >= 4:
                address, length = u16(p[0:2], 'little'), u16(p[2:4], 'little')
                return self._fast_read([(i, address, length) for i in p[4:]])
            if inst == INST_ACTION:
                for s in self.servos.values():
                    self._action(s)
            if inst == INST_FACTORY_RESET:
                for s in list(self.servos.values()):
                    self._p2_factory_reset(s, p, broadcast=True)
            if inst == INST_CLEAR:
                for s in list(self.servos.values()):
                    self._p2_clear(s, p, broadcast=True)
            return []
        if servo is None:
            return []
        if inst == INST_PING:
            return self._ping_reply(servo)
        if inst == INST_READ and len(p) == 4:
            address, length = u16(p[0:2], 'little'), u16(p[2:4], 'little')
            err = self._access(servo, address, length, write=False)
            if servo.read_hook is not None:
                servo.read_hook(servo)
            data = bytes(servo.memory[address:address + length]) if err == 0 else b''
            return self._status(servo, err, data, is_read=True)
        if inst == INST_WRITE and len(p) >= 2:
            return self._status(servo, self._write(servo, u16(p[0:2], 'little'), bytes(p[2:])))
        if inst == INST_REG_WRITE and len(p) >= 2:
            servo.registered = (u16(p[0:2], 'little'), bytes(p[2:]))
            return self._status(servo, 0)
        if inst == INST_ACTION:
            self._action(servo)
            return self._status(servo, 0)
        if inst == INST_REBOOT:
            servo.faults.pop('error_bits', None)
            servo.set('torque_enable', 0)
            return self._status(servo, 0)
        if inst == INST_FACTORY_RESET:
            return self._p2_factory_reset(servo, p, broadcast=False)
        if inst == INST_CLEAR:
            return self._p2_clear(servo, p, broadcast=False)
        return self._status(servo, P2_ERR_INSTRUCTION)

    def _ping_reply(self, servo: EmulatedServo) -> list[tuple[float, bytes]]:
        params = servo.table.encode('model_number', servo.table.model_number) + bytes(
            [servo.get('firmware_version')])
        return self._status(servo, 0, params, is_ping=True)

    def _multi_read(self, requests: list[tuple[int, int, int]]) -> list[tuple[float, bytes]]:
        out: list[tuple[float, bytes]] = []
        for servo_id, address, length in requests:
            s = self.servos.get(servo_id)
            if s is None:
                continue
            err = self._access(s, address, length, write=False)
            if s.read_hook is not None:
                s.read_hook(s)
            data = bytes(s.memory[address:address + length]) if err == 0 else b''
            out += self._status(s, err, data, is_read=True)
        return out


def _parse_ids(text: str) -> list[int]:
    ids: list[int] = []
    for part in text.split(','):
        if '-' in part:
            lo, hi = part.split('-')
            ids += range(int(lo), int(hi) + 1)
        elif part.strip():
            ids.append(int(part))
    return ids


@contextmanager
def emulator_process(model: str, ids: Iterable[int], *,
                     supply_voltage_v: float | None = None) -> Iterator[str]:
    """Run an emulated bus in a child process (own interpreter, own GIL); yields the port name.

    Real servos do not share the driver's CPU time; this is the fair set-up for benchmarks.
    """
    ids_text = ','.join(str(i) for i in ids)
    volts = [] if supply_voltage_v is None else ['--supply-voltage', str(supply_voltage_v)]
    proc = subprocess.Popen(
        [sys.executable, '-m', 'hexapod_bench_drivers.servo_bus_emulator', '--model', model,
         '--ids', ids_text, *volts],
        stdout=subprocess.PIPE, text=True)
    try:
        assert proc.stdout is not None
        port = proc.stdout.readline().strip()
        if not port:
            raise RuntimeError(f'emulator process for {model} {ids_text} printed no port name')
        yield port
    finally:
        proc.send_signal(signal.SIGINT)
        try:
            proc.wait(timeout=5.0)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()


def main(argv: Sequence[str] | None = None) -> int:
    """Serve an emulated bus on a pty until interrupted; prints the port name first."""
    parser = NumberArgumentParser(description=__doc__.split('\n')[0])
    parser.add_argument('--model', default='ax18a',
                        help=f'model name, one of {", ".join(sorted(MODELS_BY_NAME))} '
                             '(case and dashes ignored: MX-28, MX-64(2.0), XM430-W210)')
    parser.add_argument('--ids', default='1-18', help='IDs, e.g. 1-18 or 1,2,5')
    parser.add_argument('--supply-voltage', type=float, default=None,
                        help='bus supply [V]; default the model\'s rated voltage')
    args = parser.parse_args(argv)
    with ServoBusEmulator.of_model(args.model, _parse_ids(args.ids),
                                   supply_voltage_v=args.supply_voltage) as emu:
        print(emu.port_name, flush=True)
        # the port name alone left a new user guessing how to point the driver at it
        first = next(iter(emu.servos.values()), None)
        protocol = 2 if first is not None and first.table.protocol == 2 else 1
        print(f'serving {len(emu.servos)} emulated {args.model} servo(s); try: '
              f'dynamixel_driver --ros-args -p port:={emu.port_name} -p protocol:={protocol} '
              '-p joints_file:=hexapod_ax18a_joints.yaml (Ctrl-C stops)', file=sys.stderr,
              flush=True)
        try:
            while True:
                time.sleep(3600)
        except KeyboardInterrupt:
            pass
    return 0


if __name__ == '__main__':
    raise SystemExit(main())
