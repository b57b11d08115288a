"""A Dynamixel bus on the real ``dynamixel_sdk``: detect, read, command, protect. No ROS here.

What it does, per cycle (:meth:`DynamixelBus.poll`):

1. Reads present position, speed, load, voltage and temperature of every servo in one block per
   servo: a Sync Read on Protocol 2.0 (one instruction, every servo answers in turn), single
   READs on Protocol 1.0 (AX servos have neither Sync Read nor Bulk Read), and on a Protocol
   2.0 bus that answers single READs but never a Sync Read (given up after
   :data:`SYNC_READ_GIVE_UP` cycles, noted once).
2. Counts every timeout, corrupt reply (checksum/CRC) and retry per servo; a servo that fails
   ``silent_after`` cycles in a row is marked silent, dropped from the cycle (so it no longer
   costs a timeout per cycle) and probed again every ``probe_interval_cycles``.
3. Decodes hardware error flags (Protocol 1.0 status error byte; Protocol 2.0 Hardware Error
   Status, read when a reply carries the alert bit).
4. Safety: a servo above ``temperature_limit_c`` or reporting overheating gets torque off in the
   same cycle, then every other servo too, and the bus is ``aborted`` (commands ignored) until
   :meth:`DynamixelBus.set_torque` ``(True)`` is called with all servos cool again.

Why not ``GroupSyncRead.txRxPacket``: its receive loop stops at the first servo that does not
answer and then throws away the replies of the servos after it, so one silent servo would blind
the whole cycle. Here the Sync Read instruction is sent by the SDK's ``syncReadTx`` and the
replies are taken with the SDK's ``rxPacket`` and assigned by the ID in each reply.
Writes use the SDK's ``GroupSyncWrite``.

Timing: the SDK's PortHandler waits ``2 * 16 ms + 2 ms`` for a reply and busy-polls the port
meanwhile. :class:`FastPortHandler` makes the wait ``packet bytes * byte time + margin`` (a few ms)
and sleeps in ``select`` instead of spinning, which frees the CPU (and the GIL for an in-process
emulator).

Effort is an estimate: load fraction (Present Load, or Present Current over stall current) times
the datasheet stall torque at the rated voltage (12 V; 5 V for XL330); these servos measure no
torque.

Models: each servo's control table comes from the model number it reports
(:func:`hexapod_bench_drivers.control_tables.table_for_model`: AX, MX on Protocol 1.0, MX(2.0)
and X series on 2.0), so one Protocol 1.0 bus may mix AX-18A and MX-28. A servo of an unknown
model is left out of the cycle; if no servo is usable, :class:`BusError` carries the refusal,
which names the known models. Only Torque Enable, Goal Position and Moving Speed / Profile
Velocity are ever written (never the AX compliance or MX gain registers at 26-29).
"""

from __future__ import annotations

import math
import select
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from dynamixel_sdk import GroupSyncWrite, PacketHandler, PortHandler
from dynamixel_sdk.protocol1_packet_handler import PKT_ID as P1_PKT_ID
from dynamixel_sdk.protocol1_packet_handler import PKT_INSTRUCTION as P1_PKT_INSTRUCTION
from dynamixel_sdk.protocol1_packet_handler import PKT_LENGTH as P1_PKT_LENGTH
from dynamixel_sdk.robotis_def import COMM_RX_CORRUPT, COMM_RX_TIMEOUT, COMM_SUCCESS, INST_PING

from hexapod_bench_drivers.control_tables import (
    ERROR_OVERHEATING,
    ControlTable,
    ControlTableError,
    decode_error_flags,
    table_for_model,
)

__all__ = [
    'BusError',
    'DynamixelBus',
    'FastPortHandler',
    'JointConfig',
    'JointMapError',
    'PollResult',
    'ServoHealth',
    'ServoReading',
    'load_joint_map',
    'parse_joint_map',
]

P2_ALERT = 0x80
P2_ID, P2_ERROR, P2_PARAM0 = 4, 8, 9   # indices in a Protocol 2.0 status packet


class BusError(RuntimeError):
    """The port cannot be opened, or no configured servo answers."""


class JointMapError(ValueError):
    """The joint-name -> servo-ID map is malformed."""


@dataclass(frozen=True)
class JointConfig:
    """One joint on the bus: joint angle = direction * servo angle + offset_rad."""

    name: str
    servo_id: int
    direction: int = 1
    offset_rad: float = 0.0

    def to_joint(self, servo_rad: float) -> float:
        return self.direction * servo_rad + self.offset_rad

    def to_servo(self, joint_rad: float) -> float:
        return (joint_rad - self.offset_rad) * self.direction


def parse_joint_map(data: Mapping[str, Any]) -> tuple[JointConfig, ...]:
    """Joint map from a mapping ``{'joints': {name: {id, direction, offset_rad}}}``.

    ``joints`` may also be a list of ``{name, id, direction, offset_rad}``. ``direction`` is +1 or
    -1 (default +1); ``offset_rad`` defaults to 0. Names and IDs must be unique.
    """
    joints = data.get('joints') if isinstance(data, Mapping) else None
    if joints is None:
        raise JointMapError("joint map: expected a top-level 'joints' mapping or list")
    items = (list(joints.items()) if isinstance(joints, Mapping)
             else [(j.get('name'), j) for j in joints])
    out = []
    for name, spec in items:
        if not isinstance(name, str) or not name or not isinstance(spec, Mapping):
            raise JointMapError(f'joint map: entry {name!r}: expected a name and a mapping')
        try:
            servo_id = int(spec['id'])
            direction = int(spec.get('direction', 1))
            offset = float(spec.get('offset_rad', 0.0))
        except (KeyError, TypeError, ValueError) as err:
            raise JointMapError(f'joint map: entry {name!r}: expected id (int), direction, '
                                f'offset_rad; got {dict(spec)!r}') from err
        if not 0 <= servo_id <= 252:
            raise JointMapError(f'joint map: {name!r} id {servo_id}: expected 0..252')
        if direction not in (1, -1):
            raise JointMapError(f'joint map: {name!r} direction {direction}: expected 1 or -1')
        out.append(JointConfig(name, servo_id, direction, offset))
    names = [j.name for j in out]
    ids = [j.servo_id for j in out]
    if len(set(names)) != len(names) or len(set(ids)) != len(ids):
        raise JointMapError('joint map: names and ids must be unique, got '
                            f'{list(zip(names, ids))}')
    if not out:
        raise JointMapError('joint map: no joints')
    return tuple(out)


def load_joint_map(path: str | Path) -> tuple[JointConfig, ...]:
    """Joint map from a YAML file (see :func:`parse_joint_map`)."""
    import yaml

    try:
        data = yaml.safe_load(Path(path).read_text())
    except (OSError, yaml.YAMLError) as err:
        raise JointMapError(f'joint map {str(path)!r}: cannot read: {err}') from err
    return parse_joint_map(data or {})


#: cycles in a row with single READs answered but no Sync Read before the bus stops trying it
SYNC_READ_GIVE_UP = 3


class FastPortHandler(PortHandler):
    """PortHandler with a short reply deadline that sleeps in ``select`` rather than spinning.

    Parameters
    ----------
    port_name : str
        Serial device (``/dev/ttyUSB0``) or the emulator's pty.
    timeout_margin_ms : float
        Reply deadline = bytes on the wire * byte time + this margin [ms]. The SDK's default is
        34 ms (two USB latency timers); with the FTDI latency timer at 1 ms, a few ms suffice.
    """

    def __init__(self, port_name: str, *, timeout_margin_ms: float = 5.0) -> None:
        super().__init__(port_name)
        self.timeout_margin_ms = float(timeout_margin_ms)

    def setPacketTimeout(self, packet_length: int) -> None:  # noqa: N802 (SDK API)
        self.packet_start_time = self.getCurrentTime()
        self.packet_timeout = self.tx_time_per_byte * packet_length + self.timeout_margin_ms

    def readPort(self, length: int) -> bytes:  # noqa: N802 (SDK API)
        if self.ser.in_waiting == 0:
            left_ms = self.packet_timeout - self.getTimeSinceStart()
            if left_ms > 0:
                select.select([self.ser.fileno()], [], [], min(left_ms, 1.0) / 1000.0)
        return self.ser.read(length)


@dataclass
class ServoHealth:
    """Communication counters and state of one servo (cumulative since open)."""

    servo_id: int
    model: str = 'unknown'
    reads_ok: int = 0
    timeouts: int = 0
    corrupt: int = 0
    retries: int = 0
    failed_cycles: int = 0
    consecutive_failures: int = 0
    error_replies: int = 0
    silent: bool = False
    last_error_flags: int = 0
    torque_enabled: bool = False
    #: the servo's Status Return Level as read at open (2: replies to every instruction,
    #: 1: to READ and PING only, so writes are verified by reading back); -1 not read yet
    status_return_level: int = -1


@dataclass(frozen=True)
class ServoReading:
    """One servo's state in the joint frame; NaN fields when ``ok`` is False.

    position_rad, velocity_rad_s : joint angle and rate (direction and offset applied).
    effort_nm : load fraction * stall torque * direction (an estimate, see module doc).
    error_flags : hardware flags (1.0 status error byte / 2.0 Hardware Error Status).
    """

    name: str
    servo_id: int
    ok: bool
    position_rad: float = math.nan
    velocity_rad_s: float = math.nan
    effort_nm: float = math.nan
    load_fraction: float = math.nan
    voltage_v: float = math.nan
    temperature_c: float = math.nan
    error_flags: int = 0


@dataclass(frozen=True)
class PollResult:
    """One cycle: readings in joint-map order, and whether the safety abort fired now."""

    readings: tuple[ServoReading, ...]
    aborted_now: bool = False
    abort_reason: str = ''


@dataclass
class _Servo:
    joint: JointConfig
    health: ServoHealth
    table: ControlTable | None = None
    last_probe_cycle: int = field(default=-10**9)
    refusal: str = ''   # why an answering servo's model was refused (names the known models)


class DynamixelBus:
    """Servos of one protocol on one port, driven through the real ``dynamixel_sdk``.

    Parameters
    ----------
    port_name : str
        Serial device or emulator pty.
    joints : sequence of JointConfig
    protocol : int
        1 (AX, MX) or 2 (X series, MX(2.0) firmware).
    baud_rate : int
        One of the SDK's rates (1 000 000 default).
    timeout_margin_ms : float
        Reply deadline margin (see FastPortHandler).
    retries : int
        Extra single-servo attempts after a failed read in a cycle.
    silent_after : int
        Failed cycles in a row before a servo is declared silent.
    probe_interval_cycles : int
        A silent servo is tried again every this many cycles.
    temperature_limit_c : float
        Above it: torque off and abort (see module doc).
    port_handler : PortHandler, optional
        Injected for tests; default FastPortHandler.
    """

    def __init__(self, port_name: str, joints: Sequence[JointConfig], *, protocol: int = 1,
                 baud_rate: int = 1_000_000, timeout_margin_ms: float = 5.0, retries: int = 1,
                 silent_after: int = 3, probe_interval_cycles: int = 50,
                 temperature_limit_c: float = 70.0,
                 port_handler: PortHandler | None = None) -> None:
        if protocol not in (1, 2):
            raise ValueError(f'protocol: expected 1 or 2, got {protocol!r}')
        if not joints:
            raise ValueError('joints: expected at least one JointConfig')
        self.protocol = int(protocol)
        self.baud_rate = int(baud_rate)
        self.retries = max(0, int(retries))
        self.silent_after = max(1, int(silent_after))
        self.probe_interval_cycles = max(1, int(probe_interval_cycles))
        self.temperature_limit_c = float(temperature_limit_c)
        self.port = port_handler or FastPortHandler(port_name, timeout_margin_ms=timeout_margin_ms)
        self.packet = PacketHandler(float(protocol))
        self.servos = [_Servo(j, ServoHealth(j.servo_id)) for j in joints]
        self._by_id = {s.joint.servo_id: s for s in self.servos}
        self._by_name = {s.joint.name: s for s in self.servos}
        self.cycle = 0
        #: Protocol 2.0: read with Sync Read; cleared (see :meth:`read_all`) on a bus whose
        #: servos answer single READs but never a Sync Read
        self.sync_read = self.protocol == 2
        self._sync_unanswered = 0
        #: one-line events of the bus a node should log once (drained by :meth:`take_notes`)
        self.notes: list[str] = []
        self.aborted = False
        self.abort_reason = ''
        self.is_open = False

    # --- lifecycle -------------------------------------------------------------------------
    def open(self) -> DynamixelBus:
        """Open the port and ping every servo; BusError if none answers."""
        try:
            ok = self.port.openPort() and self.port.setBaudRate(self.baud_rate)
        except Exception as err:  # pyserial raises SerialException/OSError subclasses
            raise BusError(f'port {self.port.getPortName()!r}: cannot open: {err}') from err
        if not ok:
            raise BusError(f'port {self.port.getPortName()!r}: cannot open at '
                           f'{self.baud_rate} baud (expected one of the SDK rates)')
        self.is_open = True
        for s in self.servos:
            self._ping(s)
        if not any(s.table is not None for s in self.servos):
            self.close()
            refused = [f'id {s.joint.servo_id}: {s.refusal}' for s in self.servos if s.refusal]
            if refused:
                raise BusError(f'port {self.port.getPortName()!r}: no servo of a known model; '
                               + '; '.join(refused))
            raise BusError(f'port {self.port.getPortName()!r}: no servo answered a Protocol '
                           f'{self.protocol}.0 ping; expected IDs '
                           f'{[s.joint.servo_id for s in self.servos]}')
        return self

    def close(self) -> None:
        if self.is_open:
            self.port.closePort()
            self.is_open = False

    def __enter__(self) -> DynamixelBus:
        return self.open()

    def __exit__(self, *exc: object) -> None:
        self.close()

    def _ping(self, s: _Servo) -> bool:
        for _ in range(1 + self.retries):
            try:
                model, result, _err = self.packet.ping(self.port, s.joint.servo_id)
            except IndexError:
                # the SDK's Protocol 1.0 ping reads the model number after the ping and indexes
                # the reply unchecked: a late status packet (the ping's own, after its deadline)
                # taken for that read is 'success' with no data. A corrupt exchange: drop what
                # is in the input buffer and try again.
                self.port.clearPort()
                s.health.corrupt += 1
                continue
            if result == COMM_SUCCESS:
                try:
                    s.table = table_for_model(self.protocol, model)
                except ControlTableError as err:
                    s.health.model = f'unsupported model {model}'
                    s.refusal = str(err)
                    return False
                if not self._read_status_return_level(s):
                    return False
                s.health.model = s.table.model_name
                s.health.silent = False
                s.health.consecutive_failures = 0
                return True
            self._count(s, result)
        if self.protocol == 1 and self._bare_ping(s):
            # The SDK's Protocol 1.0 ping is a PING and a READ of the model number: a servo
            # that answers the PING alone is at Status Return Level 0.
            self._refuse_level_0(s)
            return False
        s.health.silent = True
        return False

    def _bare_ping(self, s: _Servo) -> bool:
        """A Protocol 1.0 PING without the SDK's model-number READ: answered or not."""
        tx = [0] * 6
        tx[P1_PKT_ID], tx[P1_PKT_LENGTH], tx[P1_PKT_INSTRUCTION] = s.joint.servo_id, 2, INST_PING
        _rx, result, _err = self.packet.txRxPacket(self.port, tx)
        return bool(result == COMM_SUCCESS)

    def _refuse_level_0(self, s: _Servo) -> None:
        s.table = None
        s.health.model = 'unreadable (Status Return Level 0)'
        s.refusal = (f'answers PING but no READ: its Status Return Level is 0 (the servo '
                     f'replies to nothing else); set it to 1 or 2 (register '
                     f'{"16" if self.protocol == 1 else "68"}, e.g. with Dynamixel Wizard: this '
                     f'driver never writes configuration registers)')

    def _read_status_return_level(self, s: _Servo) -> bool:
        """Read the servo's Status Return Level after its PING (False, refused, at level 0).

        Level 1 is a common setting on real robots (it halves the bus time of writes): such a
        servo answers READ and PING only, so its torque writes are sent without waiting for a
        reply and checked by reading the register back (:meth:`set_torque`)."""
        assert s.table is not None
        data, _ = self._read_single(s, s.table.reg('status_return_level').address, 1,
                                    1 + self.retries)
        if data is None:
            self._refuse_level_0(s)
            return False
        level = int(data[0])
        if level < 2 and s.health.status_return_level != level:
            self.notes.append(
                f'{s.joint.name} (id {s.joint.servo_id}) has Status Return Level {level}: it '
                'does not acknowledge writes, so torque writes are checked by reading back')
        s.health.status_return_level = level
        return True

    # --- reading ---------------------------------------------------------------------------
    @property
    def joint_names(self) -> list[str]:
        return [s.joint.name for s in self.servos]

    def health(self) -> list[ServoHealth]:
        return [s.health for s in self.servos]

    def _count(self, s: _Servo, result: int) -> None:
        if result == COMM_RX_TIMEOUT:
            s.health.timeouts += 1
        elif result == COMM_RX_CORRUPT:
            s.health.corrupt += 1
        else:
            s.health.timeouts += 1  # port busy / tx fail: counted as a missed reply

    def _active(self) -> list[_Servo]:
        """Servos read this cycle; a silent one is probed every probe_interval_cycles."""
        out = []
        for s in self.servos:
            if s.table is None or s.health.silent:
                if self.cycle - s.last_probe_cycle >= self.probe_interval_cycles:
                    s.last_probe_cycle = self.cycle
                    if s.table is None:
                        self._ping(s)
                        if s.table is None:
                            continue
                    out.append(s)
                continue
            out.append(s)
        return out

    def _read_single(self, s: _Servo, start: int, length: int,
                     attempts: int) -> tuple[list[int] | None, int]:
        for k in range(attempts):
            if k:
                s.health.retries += 1
            data, result, error = self.packet.readTxRx(self.port, s.joint.servo_id, start, length)
            if result == COMM_SUCCESS and len(data) == length:
                return list(data), error
            self._count(s, result)
        return None, 0

    def _sync_read(self, servos: list[_Servo], start: int,
                   length: int) -> dict[int, tuple[list[int], int]]:
        """Protocol 2.0 Sync Read; replies assigned by ID, so a silent servo costs only itself."""
        ids = [s.joint.servo_id for s in servos]
        got: dict[int, tuple[list[int], int]] = {}
        if self.packet.syncReadTx(self.port, start, length, ids, len(ids), False) != COMM_SUCCESS:
            return got
        pending = list(ids)
        while pending:
            self.port.setPacketTimeout(length + 11)
            rx, result = self.packet.rxPacket(self.port, False)
            sid = rx[P2_ID] if len(rx) > P2_ID else None
            if result == COMM_SUCCESS and sid in pending:
                data = list(rx[P2_PARAM0:-2])
                if len(data) != length:
                    continue  # a stale reply to an earlier instruction (a late servo)
                pending.remove(sid)
                got[sid] = (data, rx[P2_ERROR])
            elif result == COMM_RX_CORRUPT and sid in pending:
                pending.remove(sid)
                self._by_id[sid].health.corrupt += 1
            elif result != COMM_SUCCESS:
                break
        for sid in pending:
            self._by_id[sid].health.timeouts += 1  # no (valid) reply before the deadline
        return got

    def _hardware_flags(self, s: _Servo, status_error: int) -> int:
        if self.protocol == 1:
            return status_error & 0x7F
        if s.table is None:
            return 0
        if not status_error & P2_ALERT:
            return 0
        data, _ = self._read_single(s, s.table.reg('hardware_error_status').address, 1, 1)
        return data[0] if data else s.health.last_error_flags

    def read_all(self) -> tuple[ServoReading, ...]:
        """One read of every active servo, in joint-map order (NaN readings for failures)."""
        self.cycle += 1
        active = self._active()
        raw: dict[int, tuple[list[int], int]] = {}
        synced = self.protocol == 2 and self.sync_read and bool(active)
        if synced:
            blocks: dict[tuple[int, int], list[_Servo]] = {}
            for s in active:
                assert s.table is not None
                blocks.setdefault(s.table.read_block, []).append(s)
            for (start, length), group in blocks.items():
                raw.update(self._sync_read(group, start, length))
        sync_answered = bool(raw)
        for s in active:
            sid = s.joint.servo_id
            assert s.table is not None
            if sid in raw:
                continue
            if synced:
                # The sync reply was lost or corrupt: this is a retry.
                if self.retries == 0:
                    continue
                s.health.retries += 1
                data, err = self._read_single(s, *s.table.read_block, attempts=self.retries)
            else:
                attempts = 1 if s.health.silent else 1 + self.retries
                data, err = self._read_single(s, *s.table.read_block, attempts=attempts)
            if data is not None:
                raw[sid] = (data, err)
        if synced:
            self._note_sync_support(sync_answered, single_answered=bool(raw))
        readings = []
        for s in self.servos:
            sid = s.joint.servo_id
            if sid not in raw or s.table is None:
                if s in active:
                    s.health.failed_cycles += 1
                    s.health.consecutive_failures += 1
                    if s.health.consecutive_failures >= self.silent_after:
                        s.health.silent = True
                readings.append(ServoReading(s.joint.name, sid, False,
                                             error_flags=s.health.last_error_flags))
                continue
            data, status_error = raw[sid]
            h = s.health
            h.reads_ok += 1
            h.consecutive_failures = 0
            h.silent = False
            flags = self._hardware_flags(s, status_error)
            if flags or (status_error & (0x7F if self.protocol == 2 else 0)):
                h.error_replies += 1
            h.last_error_flags = flags
            st = s.table.decode_present(data)
            j = s.joint
            readings.append(ServoReading(
                name=j.name, servo_id=sid, ok=True,
                position_rad=j.to_joint(st.position_rad),
                velocity_rad_s=j.direction * st.velocity_rad_s,
                effort_nm=j.direction * st.load_fraction * s.table.stall_torque_nm,
                load_fraction=j.direction * st.load_fraction,
                voltage_v=st.voltage_v, temperature_c=st.temperature_c, error_flags=flags))
        return tuple(readings)

    def _note_sync_support(self, sync_answered: bool, single_answered: bool) -> None:
        """A bus whose servos answer single READs but no Sync Read for
        :data:`SYNC_READ_GIVE_UP` cycles in a row (an adapter or emulator without the
        instruction, firmware that lacks it) is read servo by servo from then on, noted once:
        each cycle would otherwise wait out a Sync Read deadline first."""
        if sync_answered or not single_answered:
            self._sync_unanswered = 0
            return
        self._sync_unanswered += 1
        if self._sync_unanswered >= SYNC_READ_GIVE_UP:
            self.sync_read = False
            self.notes.append(
                f'no servo answered Sync Read in {SYNC_READ_GIVE_UP} cycles in a row while '
                'single READs were answered: reading the servos one by one from now on')

    def take_notes(self) -> list[str]:
        """The bus events noted since the last call (each returned once)."""
        out, self.notes = self.notes, []
        return out

    def poll(self) -> PollResult:
        """read_all() then the temperature safety check (torque off and abort)."""
        readings = self.read_all()
        hot = [r for r in readings if r.ok and (r.temperature_c > self.temperature_limit_c
                                                or r.error_flags & ERROR_OVERHEATING)]
        if not hot or self.aborted:
            return PollResult(readings)
        # The overheating servos first, then the rest: each write is a round trip.
        order = [r.name for r in hot] + [n for n in self.joint_names
                                         if n not in {r.name for r in hot}]
        self.set_torque(False, order)
        self.aborted = True
        self.abort_reason = '; '.join(
            f'{r.name} (id {r.servo_id}) at {r.temperature_c:.0f} degC, flags '
            f'{list(decode_error_flags(self.protocol, r.error_flags))}' for r in hot) + (
            f' > limit {self.temperature_limit_c:.0f} degC: torque off, aborted')
        return PollResult(readings, True, self.abort_reason)

    # --- writing ---------------------------------------------------------------------------
    def set_torque(self, enabled: bool, names: Iterable[str] | None = None) -> dict[str, bool]:
        """Torque Enable on (True) or off for ``names`` (all by default); per-joint success.

        Turning torque on clears an abort only if no servo is above the limit any more.
        """
        if enabled and self.aborted:
            readings = self.read_all()
            hot = [r.name for r in readings if r.ok and r.temperature_c > self.temperature_limit_c]
            if hot:
                return {n: False for n in (names or self.joint_names)}
            self.aborted = False
            self.abort_reason = ''
        out = {}
        for name in (names if names is not None else self.joint_names):
            s = self._by_name[name]
            if s.table is None:
                out[name] = False
                continue
            ok = False
            for k in range(1 + self.retries):
                if k:
                    s.health.retries += 1
                address = s.table.reg('torque_enable').address
                if s.health.status_return_level >= 2:
                    result, _err = self.packet.write1ByteTxRx(
                        self.port, s.joint.servo_id, address, int(bool(enabled)))
                else:
                    # no acknowledgement at Status Return Level 1: write, then read back
                    result = self.packet.write1ByteTxOnly(
                        self.port, s.joint.servo_id, address, int(bool(enabled)))
                    if result == COMM_SUCCESS:
                        data, _ = self._read_single(s, address, 1, 1)
                        if data is None:
                            continue  # the read-back was counted
                        if data[0] != int(bool(enabled)):
                            continue  # the write was lost: send it again
                if result == COMM_SUCCESS:
                    ok = True
                    break
                self._count(s, result)
            if ok:
                s.health.torque_enabled = bool(enabled)
            out[name] = ok
        return out

    def write_goals(self, positions_rad: Mapping[str, float],
                    speeds_rad_s: Mapping[str, float] | None = None) -> int:
        """Sync Write goal positions (joint frame) and, if given, moving speeds; 0 if aborted.

        Unknown names and non-finite values are skipped. A speed of 0 means 'as fast as
        possible' (the servos' own convention). Returns the number of servos written.
        """
        if self.aborted:
            return 0
        groups: dict[tuple[int, int], GroupSyncWrite] = {}
        count = 0
        for name, target in positions_rad.items():
            s = self._by_name.get(name)
            if s is None or s.table is None or not math.isfinite(target):
                continue
            t = s.table
            goal = t.encode('goal_position', t.rad_to_position(s.joint.to_servo(target)))
            speed = None if speeds_rad_s is None else speeds_rad_s.get(name)
            if speed is not None and math.isfinite(speed):
                start, length = t.goal_block
                limit = t.encode(t.speed_limit_register, t.rad_s_to_speed_limit(speed))
                first_goal = t.reg('goal_position').address < t.reg(t.speed_limit_register).address
                payload = goal + limit if first_goal else limit + goal
            else:
                reg = t.reg('goal_position')
                start, length, payload = reg.address, reg.size, goal
            group = groups.get((start, length))
            if group is None:
                group = groups[(start, length)] = GroupSyncWrite(self.port, self.packet, start,
                                                                 length)
            group.addParam(s.joint.servo_id, list(payload))
            count += 1
        for group in groups.values():
            group.txPacket()
        return count
