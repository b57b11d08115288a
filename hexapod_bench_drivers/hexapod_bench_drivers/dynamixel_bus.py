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
   Status of every servo whose reply carries the alert bit, every cycle, all in one Sync Read
   of register 70: a persistent alert costs one request a cycle, not one per servo, and a new
   flag such as Overheating is seen in the cycle it appears; on a bus without Sync Read an
   alerted servo's READ starts at Torque Enable while its alert stays, no extra request).
4. Torque Enable, read without an extra request where it can be: with single READs (Protocol
   1.0, a Protocol 2.0 bus without Sync Read) one servo per cycle in turn has its READ start at
   Torque Enable (24 / 64; 12 more bytes on Protocol 1.0), every servo within ``len(joints)``
   cycles; with Sync Read registers 64-70 (Torque Enable to Hardware Error Status) of every
   servo in one Sync Read every ``torque_check_interval_cycles`` cycles (10 by default),
   which then also carries the alerted servos' flags.
5. Safety: a servo above ``temperature_limit_c`` or reporting overheating gets torque off in the
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

Late replies: a short deadline means a reply can arrive after it (a USB adapter holds replies
for its latency timer, 16 ms by default on Linux FTDI/U2D2; a servo may answer late). Such a
reply is never taken as the answer to a later request:

- a reply must carry the requested ID *and* the requested number of parameters, and a retry
  asks for one byte more than the attempt it repeats (a READ from one address lower), so the
  late reply to the failed attempt cannot pass for the retry's; other packets are counted as
  late (``ServoHealth.late_replies``) and skipped;
- after a request that went unanswered, the line is drained until it stays quiet for one margin
  before anything is sent, and bytes already waiting before a request are counted and dropped;
- the margin adapts: the pings at open wait :data:`PROBE_MARGIN_MS` and the margin is raised to
  cover their round trips; a late reply raises it to 1.5 x its lateness (capped at
  :data:`MAX_MARGIN_MS`), noted; a ``/dev/ttyUSB*`` adapter whose sysfs ``latency_timer`` is
  above 1 ms adds it to the margin, with a note that says how to set it to 1.

A servo that answers PING but no READ is taken to be at Status Return Level 0 only when the
line was quiet after the failed READs (no late reply to blame).

Effort is an estimate; these servos measure no torque. Present Current (X series, MX(2.0)) is the
motor's current, so the effort is a torque, signed as the torque the servo applies
(:meth:`hexapod_bench_drivers.control_tables.ControlTable.current_to_torque_nm`): driving, the
current times the datasheet's torque per ampere, stall torque / (stall current - standby current),
whose stall point carries the gear efficiency ``eta`` (XM430-W350: 4.1 N m / (2.3 - 0.04) A = 1.814
N m/A; every Present Current model has its e-Manual standby current, so the XM540-W150 reads 1.674
where the e-Manual prints stall torque / stall current, 1.659); back-driven (the current against
the velocity: the load drives the motor through the lossy gear) that torque divided by ``eta^2``,
with a dead band about rest
(:data:`~hexapod_bench_drivers.control_tables.BACK_DRIVE_DEAD_BAND_RAD_S`). ``eta`` is the model's
(XM430-W350 0.739 from its ServoModel preset; 1, no correction, for the models without one: the
XM430-W210, XH430, XM540, XL330 and MX(2.0), noted at open with their IDs), or the bus's
``gear_efficiency`` for every servo. On the emulator's XM430 a servo lifting 1 N m at 1 rad/s reads
1.05 N m and lowering it 1.03 N m (one constant: 1.03 and 0.55); the excess is the gear's
load-independent friction, which the current carries and the datasheet does not give. Present Load
(AX, RX, MX on Protocol 1.0, XL430, XC430, MX-28(2.0)) is inferred from the drive's output
(e-Manual), a PWM duty whose back-EMF part follows the velocity: not a torque (``energy_monitor``
refuses such efforts); its effort stays load fraction times the datasheet stall torque at the rated
voltage.

Models: each servo's control table comes from the model number it reports
(:func:`hexapod_bench_drivers.control_tables.table_for_model`: AX, MX on Protocol 1.0, MX(2.0)
and X series on 2.0), so one Protocol 1.0 bus may mix AX-18A and MX-28. A servo of an unknown
model is left out of the cycle; if no servo is usable, :class:`BusError` carries the refusal,
which names the known models. The model number (register 0) is read again when a servo answers
after a failed cycle or silence (before its data are decoded), when it refuses a READ (an
access error), and at every PING: another model at the ID (a servo replaced, another servo
set to the ID) is left out naming both models (``refused``) until the driver is restarted or
the first model answers there again. Only Torque Enable, Goal Position, Moving Speed / Profile
Velocity and (Protocol 1.0, after an Alarm Shutdown, below) Torque Limit are ever written (never
the AX compliance or MX gain registers at 26-29, never EEPROM).

Operating Mode (Protocol 2.0, register 11) is read at open: in Extended Position (4) and
Current-based Position (5) modes goals span +-1 048 575 ticks (multi-turn); a servo in a mode
that ignores Goal Position (0 current, 1 velocity, 16 PWM) is still read, but its goals and
torque on are refused, named in :attr:`DynamixelBus.refused` and noted.

Protocol 1.0 wheel mode (CW and CCW Angle Limit both 0: the servo ignores Goal Position and
turns endlessly at Moving Speed) is read at open and refused the same way; Moving Speed is never
written to such a servo.

Torque on is checked by reading Torque Enable back: a servo that keeps it at 0 with a hardware
error (X series in hardware-error shutdown stays off until REBOOT) is reported as failed, with
the error in ``ServoHealth.torque_error``. Torque Enable is read back again when a servo answers
after a failed cycle or silence (a power-cycled servo comes back with Torque Enable 0) and when
it raises a new hardware error flag (Alarm Shutdown turns torque off): ``torque_enabled`` follows
the register, also between those events through the reads of step 4 (a servo rebooted
between two reads, no reply missed), and torque lost that the driver had turned on is reported
in ``ServoHealth.torque_lost`` (never turned on again by the bus: call ``set_torque(True)``).

Protocol 1.0 Alarm Shutdown: AX/RX/MX(1.0) firmware signals it by setting Torque Limit (34) to 0
and keeps Torque Enable at 1 (e-Manual, Torque Limit: "the motor loses its torque because the
value becomes 0"; it stays 0 after the error clears). The READs that start at Torque Enable
reach Torque Limit (24-43, no extra request): a Torque Limit of 0 where the driver turned torque
on is torque lost (``torque_enabled`` False, ``torque_lost`` naming register 34). Torque on reads
Torque Enable and Torque Limit back in one READ; a Torque Limit of 0 is written back from Max
Torque (14, EEPROM, its power-on value) and read back, refused with the reason when Max Torque
is 0 too or the error is still on: torque on never succeeds with Torque Limit 0.

Goal limits: goals are clipped to the servo's own limits, read at open (Protocol 1.0 CW/CCW
Angle Limit 6/8; 2.0 Min/Max Position Limit 52/48 in position mode 3, not in the multi-turn
modes), where a goal outside is not applied (1.0 Angle Limit Error, 2.0 Data Limit Error, no
status to a Sync Write); else to one turn. Clipped goals are counted (``goals_clipped``) and said
once per episode (a run of clipped goals), naming the joint, the angle and the limit in the
joint frame.

Run-time transitions (a servo going silent or answering again, a hardware error flag appearing or
clearing, torque lost, goals clipped to the servo's limits, the loop rate falling below
:data:`RATE_LOW_FRACTION` of the requested rate, given ``rate_hz``; a corrupted instruction
reported by a servo) are queued for the log once per transition, throttled per kind and servo
(:class:`EventLog`, :meth:`DynamixelBus.take_events`).

The port: an ``OSError`` from the serial device (a USB adapter unplugged: EIO), or the
``termios.error`` the input flush before each transaction raises then, closes the bus and
raises :class:`PortLostError`, which names the port; later torque writes are skipped.

Adapter echo: a half-duplex adapter without direction control returns every transmitted byte.
A received packet equal to the instruction just sent is that echo: skipped (never taken for a
reply, not counted as late), noted once.

Duplicate IDs: a second status packet of an ID, as long as its last reply taken, while no later
request went to that ID, is a second servo at that ID: counted in
``ServoHealth.duplicate_replies`` (not as a late reply, the margin is kept), noted once, and the
servo's readings are marked failed for :data:`DUPLICATE_HOLD_CYCLES` cycles (either servo may
have answered). Two replies that collide on the wire arrive corrupt: that case still reads as a
silent servo. A reply of the requested ID that carries an instruction or checksum error and no
data (the servo received a corrupted instruction: Protocol 1.0 checksum or instruction error,
2.0 Instruction or CRC Error) is counted in ``ServoHealth.rejected_instructions`` and retried,
not taken as late; another Protocol 2.0 error with no data (Access Error: a register the model
does not have; result fail, data range / length / limit) is an instruction the servo received
intact and refused: counted in ``ServoHealth.refused_instructions``, logged as such, not
retried, and the servo's model number is read again.
"""

from __future__ import annotations

import math
import os
import re
import select
import time
from collections import deque
from collections.abc import Callable, Hashable, Iterable, Iterator, Mapping, Sequence
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

try:
    import termios
    #: pyserial's reset_input_buffer() (``clearPort`` before every transaction) raises
    #: termios.error (errno EIO) on a vanished device, which is not an OSError
    _PORT_ERRORS: tuple[type[BaseException], ...] = (OSError, termios.error)
except ImportError:                 # not POSIX
    _PORT_ERRORS = (OSError,)

from dynamixel_sdk import GroupSyncWrite, PacketHandler, PortHandler
from dynamixel_sdk.protocol1_packet_handler import PKT_ID as P1_PKT_ID
from dynamixel_sdk.protocol1_packet_handler import PKT_INSTRUCTION as P1_PKT_INSTRUCTION
from dynamixel_sdk.protocol1_packet_handler import PKT_LENGTH as P1_PKT_LENGTH
from dynamixel_sdk.robotis_def import COMM_RX_CORRUPT, COMM_RX_TIMEOUT, COMM_SUCCESS, INST_PING

from hexapod_bench_drivers.control_tables import (
    ALL_MODELS,
    BACK_DRIVE_DEAD_BAND_RAD_S,
    ERROR_OVERHEATING,
    EXTENDED_POSITION_LIMIT,
    GEAR_EFFICIENCY_MIN,
    GOAL_POSITION_MODES,
    MULTI_TURN_MODES,
    OPERATING_MODES,
    P2_STATUS_ERRORS,
    ControlTable,
    ControlTableError,
    PresentState,
    Register,
    decode_error_flags,
    table_for_model,
)

__all__ = [
    'BusError',
    'DUPLICATE_HOLD_CYCLES',
    'DynamixelBus',
    'EVENT_LOG_INTERVAL_S',
    'EventLog',
    'FastPortHandler',
    'JointConfig',
    'JointMapError',
    'MAX_MARGIN_MS',
    'PROBE_MARGIN_MS',
    'PollResult',
    'PortLostError',
    'RATE_LOW_FRACTION',
    'RateMonitor',
    'ServoHealth',
    'ServoReading',
    'TORQUE_CHECK_INTERVAL_CYCLES',
    'TorqueOffReport',
    'load_joint_map',
    'parse_joint_map',
    'usb_latency_timer_ms',
]

P2_ALERT = 0x80
P2_ID, P2_ERROR, P2_PARAM0 = 4, 8, 9   # indices in a Protocol 2.0 status packet
P1_ERROR, P1_PARAM0 = 4, 5              # indices in a Protocol 1.0 status packet

#: reply deadline margin of the pings at open, whose round trips set the working margin [ms]
#: (the SDK's own deadline is 34 ms: two 16 ms USB latency timers and 2 ms)
PROBE_MARGIN_MS = 40.0
#: the margin is never raised above this by late replies or round trips [ms]
MAX_MARGIN_MS = 60.0
#: sysfs directory of USB serial adapters (FTDI, U2D2), each with its ``latency_timer`` [ms]
SYSFS_USB_SERIAL = Path('/sys/bus/usb-serial/devices')


class BusError(RuntimeError):
    """The port cannot be opened, or no configured servo answers."""


class PortLostError(BusError):
    """The serial device failed while the bus was open (a USB adapter unplugged): closed."""


#: a run-time event of one kind and servo is logged at most once per this long; the state it
#: settled in is logged once the time is up [s]
EVENT_LOG_INTERVAL_S = 5.0
#: the loop rate is reported low below this fraction of the requested rate ...
RATE_LOW_FRACTION = 0.8
#: ... and recovered at or above this fraction (hysteresis)
RATE_OK_FRACTION = 0.9
#: cycles a servo's readings stay marked failed after a second reply to one request
DUPLICATE_HOLD_CYCLES = 10
#: result of a request the servo refused (an error and no data, not noise): not retried; not
#: one of the SDK's COMM_* codes
RESULT_REFUSED = -3900
#: Protocol 2.0 status errors that mean the servo received a corrupted instruction (noise on
#: the way to it); the others (result fail, data range / length / limit, access error) mean
#: it received the instruction intact and could not carry it out
P2_NOISE_ERRORS = frozenset({0x02, 0x03})
#: what a Protocol 2.0 status error that is not noise says about the instruction
P2_REFUSAL_HINTS = {
    0x01: 'the servo could not process the instruction',
    0x04: 'a value outside the register\'s range',
    0x05: 'fewer bytes than the register holds',
    0x06: 'a value beyond the servo\'s limit registers',
    0x07: 'a register this model does not have (or read-only / write-only, or EEPROM written '
          'with torque on)',
}


class EventLog:
    """Run-time transitions as log lines: one per transition, throttled per key.

    A key logs at most ``burst`` lines per ``interval_s`` (2: going wrong and recovering are
    both logged at once); a transition beyond that is held back, and the last one held is
    logged once the interval allows (with the number of transitions held), so the log ends
    in the state the bus is in.
    """

    def __init__(self, interval_s: float = EVENT_LOG_INTERVAL_S, burst: int = 2,
                 clock: Callable[[], float] = time.monotonic) -> None:
        self.interval_s = float(interval_s)
        self.burst = max(1, int(burst))
        self.clock = clock
        self._recent: dict[Hashable, deque[float]] = {}
        self._held: dict[Hashable, tuple[str, str, int]] = {}
        self._lines: list[tuple[str, str]] = []

    def _room(self, key: Hashable, now: float) -> bool:
        recent = self._recent.setdefault(key, deque())
        while recent and now - recent[0] >= self.interval_s:
            recent.popleft()
        return len(recent) < self.burst

    def event(self, key: Hashable, level: str, message: str) -> None:
        """A transition: ``level`` 'warning' (trouble) or 'info' (recovered)."""
        now = self.clock()
        if key not in self._held and self._room(key, now):
            self._recent[key].append(now)
            self._lines.append((level, message))
        else:
            held = self._held.get(key)
            self._held[key] = (level, message, 1 + (held[2] if held else 0))

    def take(self) -> list[tuple[str, str]]:
        """The (level, message) lines due now, each returned once."""
        now = self.clock()
        for key, (level, message, count) in list(self._held.items()):
            if self._room(key, now):
                del self._held[key]
                self._recent[key].append(now)
                self._lines.append((level, f'{message} ({count} transitions within '
                                           f'{self.interval_s:g} s logged as one)'))
        out, self._lines = self._lines, []
        return out


class RateMonitor:
    """Achieved read-loop rate over a sliding window against the requested rate.

    :meth:`tick` at every cycle; a 'warning' event when the rate falls below
    :data:`RATE_LOW_FRACTION` of the requested one, 'info' when it is back at
    :data:`RATE_OK_FRACTION`. ``None`` otherwise.
    """

    def __init__(self, requested_hz: float, window_s: float = 2.0) -> None:
        self.requested_hz = float(requested_hz)
        self.window_s = float(window_s)
        self._ticks: deque[float] = deque()
        self.low = False
        self.achieved_hz = math.nan

    def tick(self, now_s: float, cycle_ms: float = math.nan,
             servos: int = 0) -> tuple[str, str] | None:
        t = self._ticks
        t.append(now_s)
        while len(t) > 2 and now_s - t[1] >= self.window_s:
            t.popleft()
        if now_s - t[0] < self.window_s:
            return None
        self.achieved_hz = (len(t) - 1) / (now_s - t[0])
        if not self.low and self.achieved_hz < RATE_LOW_FRACTION * self.requested_hz:
            self.low = True
            took = f'; a read cycle takes {cycle_ms:.1f} ms' if math.isfinite(cycle_ms) else ''
            period_ms = 1e3 / self.requested_hz
            if math.isfinite(cycle_ms) and cycle_ms < 0.5 * period_ms:
                # the bus has time to spare: the loop is not scheduled often enough (an
                # outside review: 1.6 ms cycles of a 10 ms period blamed on the bus)
                why = (f'the bus has time to spare ({cycle_ms:.1f} of {period_ms:.1f} ms a '
                       'period): the host does not run the loop often enough (CPU load, '
                       'other callbacks on the node\'s executor); give the driver its own '
                       'process or core, or lower rate_hz')
            else:
                why = ('the bus cannot keep up; lower rate_hz, check for silent or slow '
                       'servos (the reply margin), set the USB latency timer to 1 ms or '
                       'raise the baud rate')
            return ('warning', f'read loop at {self.achieved_hz:.1f} Hz, requested '
                    f'{self.requested_hz:g} Hz ({servos} servos{took}): {why}')
        if self.low and self.achieved_hz >= RATE_OK_FRACTION * self.requested_hz:
            self.low = False
            return ('info', f'read loop back at {self.achieved_hz:.1f} Hz (requested '
                    f'{self.requested_hz:g} Hz)')
        return None


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


#: keys of one joint map entry (``name`` in the list form)
_JOINT_KEYS = frozenset({'name', 'id', 'direction', 'offset_rad'})


def parse_joint_map(data: Mapping[str, Any]) -> tuple[JointConfig, ...]:
    """Joint map from a mapping ``{'joints': {name: {id, direction, offset_rad}}}``.

    ``joints`` may also be a list of ``{name, id, direction, offset_rad}``. ``direction`` is +1 or
    -1 (default +1); ``offset_rad`` defaults to 0 and must be finite. Names and IDs must be
    unique; any other key is refused (a ``dirction: -1`` typo left a mirrored joint at +1).
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
        unknown = sorted(str(k) for k in set(spec) - _JOINT_KEYS)
        if unknown:
            raise JointMapError(f'joint map: entry {name!r}: unknown key(s) {unknown}; '
                                f'expected {sorted(_JOINT_KEYS - {"name"})}')
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
        if not math.isfinite(offset):
            raise JointMapError(f'joint map: {name!r} offset_rad {offset}: expected a finite '
                                'angle [rad]')
        out.append(JointConfig(name, servo_id, direction, offset))
    names = [j.name for j in out]
    ids = [j.servo_id for j in out]
    if len(set(names)) != len(names) or len(set(ids)) != len(ids):
        raise JointMapError('joint map: names and ids must be unique, got '
                            f'{list(zip(names, ids))}')
    if not out:
        raise JointMapError('joint map: no joints')
    return tuple(out)


def config_file(path: str | Path) -> Path:
    """``path`` as given when it exists (absolute, or relative to the working directory),
    else the package's own ``config/`` file of that name (the source tree's, or the installed
    ``share/hexapod_bench_drivers/config``): ``dynamixel_driver.yaml`` names
    ``hexapod_ax18a_joints.yaml``, which the README's command, run from the repository root,
    could not find (new-user review)."""
    given = Path(path).expanduser()
    if given.is_absolute() or given.exists():
        return given
    candidates = [Path(__file__).resolve().parents[1] / 'config' / given]
    try:
        from ament_index_python.packages import get_package_share_directory

        candidates.append(Path(get_package_share_directory('hexapod_bench_drivers'))
                          / 'config' / given)
    except Exception:   # noqa: BLE001 - no ament index (a plain pip install): not there
        pass
    return next((c for c in candidates if c.exists()), given)


def load_joint_map(path: str | Path) -> tuple[JointConfig, ...]:
    """Joint map from a YAML file (see :func:`parse_joint_map`; a relative path not found
    from the working directory is looked up in the package's ``config/``,
    :func:`config_file`)."""
    import yaml

    try:
        data = yaml.safe_load(config_file(path).read_text())
    except (OSError, yaml.YAMLError) as err:
        raise JointMapError(f'joint map {str(path)!r}: cannot read: {err}') from err
    return parse_joint_map(data or {})


def _usb_latency_timer_file(port_name: str) -> Path | None:
    names = {Path(port_name).name, Path(os.path.realpath(port_name)).name}
    for name in sorted(names):
        if re.fullmatch(r'ttyUSB\d+', name):
            return SYSFS_USB_SERIAL / name / 'latency_timer'
    return None


def usb_latency_timer_ms(port_name: str) -> int | None:
    """The latency timer [ms] of a ``/dev/ttyUSB*`` adapter (or a link to one), else None.

    Read from :data:`SYSFS_USB_SERIAL` ``/<tty>/latency_timer``: an FTDI adapter holds received
    bytes up to this long before passing them to the host (16 ms by default on Linux).
    """
    path = _usb_latency_timer_file(port_name)
    try:
        return None if path is None else int(path.read_text().strip())
    except (OSError, ValueError):
        return None


#: cycles in a row with single READs answered but no Sync Read before the bus stops trying it
SYNC_READ_GIVE_UP = 3
#: Protocol 2.0 with Sync Read: Torque Enable of every servo is read every this many cycles
#: (one Sync Read of registers 64-70; a torque loss without a missed reply is seen within them)
TORQUE_CHECK_INTERVAL_CYCLES = 10


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

    def clearPort(self) -> None:  # noqa: N802 (SDK API)
        # Some SDK releases flush the output here; unread input is what must go.
        self.ser.reset_input_buffer()

    def writePort(self, packet: Any) -> int:  # noqa: N802 (SDK API)
        self.last_tx = bytes(packet)   # to recognise an adapter's echo of it
        return self.ser.write(packet)  # type: ignore[no-any-return]

    def readPort(self, length: int) -> bytes:  # noqa: N802 (SDK API)
        if self.ser.in_waiting == 0:
            left_ms = self.packet_timeout - self.getTimeSinceStart()
            if left_ms > 0:
                select.select([self.ser.fileno()], [], [], min(left_ms, 1.0) / 1000.0)
        return self.ser.read(length)


#: failed requests that decide why a servo reads as failing (:meth:`ServoHealth.silence`)
RECENT_FAILURES = 3


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
    #: replies that came after their deadline (skipped, never taken as a later answer)
    late_replies: int = 0
    #: Protocol 2.0 Operating Mode read at open (3 position, 4 extended position, ...); -1 not
    #: read (Protocol 1.0, or no reply)
    operating_mode: int = -1
    #: why the last torque-on failed when the servo answered (hardware error, mode), else ''
    torque_error: str = ''
    #: torque the driver turned on that the servo no longer has (power cycled, hardware error
    #: shutdown), else ''; cleared by the next successful set_torque
    torque_lost: str = ''
    #: second status packets to one request (two servos at one ID), see DUPLICATE_HOLD_CYCLES
    duplicate_replies: int = 0
    #: replies reporting that the servo received a corrupted instruction (checksum / CRC /
    #: instruction error, no data): noise on the way to the servo; retried
    rejected_instructions: int = 0
    #: replies saying the servo could not carry out an instruction it received intact (Protocol
    #: 2.0 result fail, data range / length / limit error, access error: a register its model
    #: does not have), no data: not noise, not retried; its model number is read again
    refused_instructions: int = 0
    #: failed requests since the last good reply whose answer came garbled (broken checksum
    #: or packet), and those that got no answer at all: a servo silent on garbled replies is
    #: answering, but over another servo at its ID, at another baud rate or through noise
    streak_garbled: int = 0
    streak_no_reply: int = 0
    #: goals clipped to the servo's limits (:meth:`DynamixelBus.write_goals`), and the last
    #: one described while they keep coming ('' once a goal is inside the limits again)
    goals_clipped: int = 0
    goal_clip: str = ''
    #: the kinds of the last failed requests ('g' garbled, 'n' no reply, 'r' refused by the
    #: servo), newest last
    recent_failures: deque[str] = field(default_factory=lambda: deque(maxlen=RECENT_FAILURES))

    def silence(self) -> str:
        """Why the servo reads as failing: ``'garbled replies'`` when most of its last
        :data:`RECENT_FAILURES` failed requests were answered garbled, ``'refused reads'``
        when most were refused by the servo (an access error), else ``'no reply'``
        (a garbled burst followed by silence reads as silence once the silence dominates;
        the whole streak's majority had kept it 'garbled' and flipped later)."""
        counts = {k: self.recent_failures.count(k) for k in 'gnr'}
        if counts['r'] > counts['g'] + counts['n']:
            return 'refused reads'
        if counts['g'] > counts['n']:
            return 'garbled replies'
        return 'no reply'


@dataclass(frozen=True)
class ServoReading:
    """One servo's state in the joint frame; NaN fields when ``ok`` is False.

    position_rad, velocity_rad_s : joint angle and rate (direction and offset applied).
    effort_nm : joint torque estimate [N m] (Present Current through the gear model, or
        Present Load fraction * stall torque; times direction; see the module doc).
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


def _p1_torque_off_table() -> ControlTable | None:
    """A Protocol 1.0 table whose Torque Enable address every described 1.0 model shares
    (24), for the blind torque off of a servo whose model a Status Return Level 0 hides."""
    p1 = [t for t in ALL_MODELS if t.protocol == 1]
    addresses = {t.reg('torque_enable').address for t in p1}
    return p1[0] if len(addresses) == 1 else None


P1_TORQUE_OFF_TABLE = _p1_torque_off_table()


@dataclass(frozen=True)
class TorqueOffReport:
    """What torque off at shutdown did (:meth:`DynamixelBus.torque_off_at_shutdown`), by joint.

    confirmed : Torque Enable 0 acknowledged or read back.
    unconfirmed : servos the driver wrote (torque on, goals) whose torque off was not
        confirmed (silent, garbled, left out since): they may still hold their position.
    blind : left out at Status Return Level 0 (Protocol 2.0: model known from its PING;
        Protocol 1.0: every described model has Torque Enable at 24): Torque Enable 0 sent,
        no reply expected (such a servo executes writes; it never answers).
    never_written : left out (unknown model, silent since start): never written by the
        driver; their torque state is unknown.
    port_error : the port failed when torque off was sent (nothing confirmed).
    """

    confirmed: tuple[str, ...] = ()
    unconfirmed: tuple[str, ...] = ()
    blind: tuple[str, ...] = ()
    never_written: tuple[str, ...] = ()
    port_error: str = ''

    @property
    def ok(self) -> bool:
        """Every servo the driver wrote confirmed torque off."""
        return not self.unconfirmed and not self.port_error

    def lines(self) -> list[tuple[str, str]]:
        """(level 'info', 'warning' or 'error', message) for the log."""
        out = []
        if self.port_error:
            out.append(('error', f'torque off at shutdown not sent: {self.port_error}'))
        if self.unconfirmed:
            out.append(('error', 'torque off at shutdown not confirmed by '
                        f'{", ".join(self.unconfirmed)}: they may still hold their position'))
        if self.blind:
            out.append(('warning', 'torque off at shutdown sent without a reply to '
                        f'{", ".join(self.blind)} (left out at Status Return Level 0: the servo '
                        'carries out writes but never answers): not confirmed'))
        if self.never_written:
            out.append(('warning', f'{", ".join(self.never_written)}: left out, never written; '
                        'torque state unknown'))
        if self.confirmed:
            out.append(('info', f'torque off on {len(self.confirmed)} servo(s)'))
        return out


@dataclass
class _Servo:
    joint: JointConfig
    health: ServoHealth
    table: ControlTable | None = None
    last_probe_cycle: int = field(default=-10**9)
    refusal: str = ''   # why an answering servo's model was refused (names the known models)
    #: why the servo's goals and torque on are refused while it is still read (its mode)
    command_refusal: str = ''
    last_duplicate_cycle: int = field(default=-10**9)   # cycle of its last second reply
    silent_since_cycle: int = 0
    #: the model first detected at the ID: the joint's readings are decoded with its table,
    #: and another model answering there later is left out (:meth:`DynamixelBus._model_changed`)
    first_model: ControlTable | None = None
    #: the servo refused a READ it received intact (an access error): its model is read again
    refused_read: bool = False
    #: (low, high, registers) Goal Position ticks it accepts, read at open (Protocol 1.0
    #: CW/CCW Angle Limit; 2.0 Min/Max Position Limit in position mode), else None
    goal_range: tuple[int, int, str] | None = None
    #: the driver sent it a torque write or a goal (its torque may be on because of the driver)
    written: bool = False
    #: the control table of a servo left out at Status Return Level 0 whose model is known
    #: (Protocol 2.0: from its PING reply): torque off is sent to it blind at shutdown
    level0_table: ControlTable | None = None
    #: Protocol 1.0: the last non-zero Torque Limit (34) read, what torque on writes back
    #: after an Alarm Shutdown zeroed it (0: none read yet, Max Torque then)
    torque_limit_seen: int = 0


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
    rate_hz : float, optional
        The rate :meth:`poll` is called at; given, a loop rate well below it is reported
        (:class:`RateMonitor`, :meth:`take_events`).
    torque_check_interval_cycles : int
        Protocol 2.0 with Sync Read: every servo's Torque Enable is read every this many
        cycles (see the module doc, step 4).
    gear_efficiency : float, optional
        Gear efficiency ``eta`` in [GEAR_EFFICIENCY_MIN, 1] (0.3; lower is refused as a
        typo) for the efforts from Present Current of every servo (back-driven: torque /
        eta^2); None (default): each model's own (``ControlTable.gear_efficiency``, 1 for
        the models without a figure: noted, see :meth:`take_notes`).
    back_drive_dead_band_rad_s : float
        Speed below which a servo whose current opposes its velocity is still taken as driving
        (full correction from twice it; see ``BACK_DRIVE_DEAD_BAND_RAD_S``) [rad/s].
    port_handler : PortHandler, optional
        Injected for tests; default FastPortHandler.
    """

    def __init__(self, port_name: str, joints: Sequence[JointConfig], *, protocol: int = 1,
                 baud_rate: int = 1_000_000, timeout_margin_ms: float = 5.0, retries: int = 1,
                 silent_after: int = 3, probe_interval_cycles: int = 50,
                 temperature_limit_c: float = 70.0, rate_hz: float | None = None,
                 torque_check_interval_cycles: int = TORQUE_CHECK_INTERVAL_CYCLES,
                 gear_efficiency: float | None = None,
                 back_drive_dead_band_rad_s: float = BACK_DRIVE_DEAD_BAND_RAD_S,
                 port_handler: PortHandler | None = None) -> None:
        if protocol not in (1, 2):
            raise ValueError(f'protocol: expected 1 or 2, got {protocol!r}')
        if not joints:
            raise ValueError('joints: expected at least one JointConfig')
        if gear_efficiency is not None and not GEAR_EFFICIENCY_MIN <= gear_efficiency <= 1.0:
            raise ValueError(f'gear_efficiency: expected a value in [{GEAR_EFFICIENCY_MIN}, 1] '
                             f'(servo gears are about 0.5-0.9) or None, got '
                             f'{gear_efficiency!r}')
        if not (math.isfinite(back_drive_dead_band_rad_s) and back_drive_dead_band_rad_s >= 0):
            raise ValueError('back_drive_dead_band_rad_s: expected a finite value >= 0, got '
                             f'{back_drive_dead_band_rad_s!r}')
        self.gear_efficiency = None if gear_efficiency is None else float(gear_efficiency)
        self.back_drive_dead_band_rad_s = float(back_drive_dead_band_rad_s)
        self.protocol = int(protocol)
        self.baud_rate = int(baud_rate)
        self.retries = max(0, int(retries))
        self.silent_after = max(1, int(silent_after))
        self.probe_interval_cycles = max(1, int(probe_interval_cycles))
        self.temperature_limit_c = float(temperature_limit_c)
        self.torque_check_interval_cycles = max(1, int(torque_check_interval_cycles))
        #: servos whose registers 64-70 the last such Sync Read asked and did not get: asked
        #: again in the next cycle (their Torque Enable had waited a whole interval more)
        self._status_missed: set[int] = set()
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
        #: late status packets seen on the bus (each also counted on its servo when known)
        self.late_replies = 0
        self._margin_ms = float(timeout_margin_ms)
        self._set_port_margin(self._margin_ms)
        self._dirty = False                      # a request went unanswered: drain first
        self._tx_ms = 0.0                        # when the last request was sent [ms]
        self._failed_tx_ms: float | None = None  # when the last unanswered one was sent [ms]
        self._measuring_round_trip = False
        self._round_trip_ms = 0.0                # slowest reply beyond its wire time at open
        #: run-time transitions for the log (see :meth:`take_events`)
        self.events = EventLog()
        self.rate = RateMonitor(rate_hz) if rate_hz else None
        #: goal names not in the joint map, already said (see :meth:`write_goals`)
        self.unknown_command_names: set[str] = set()
        #: the adapter echoes transmitted bytes (seen at least once; the echo is skipped)
        self.echo = False
        #: why the port was lost (see :class:`PortLostError`), else ''
        self.port_lost = ''
        #: {id: status packet length} of each ID's last reply taken, while no later request
        #: went to that ID: another packet like it is a second servo at that ID (a late reply
        #: belongs to an unanswered request, whose retry asks for another length)
        self._answered: dict[int, int] = {}
        #: joints the last :meth:`set_torque` did not write because its ``stop`` asked so
        self.not_written: list[str] = []
        #: index in ``servos`` of the last servo whose READ started at Torque Enable (single
        #: READs: one servo a cycle in turn, see :meth:`_torque_turn`)
        self._round_robin = -1
        #: Present Current models already noted for their lack of a gear efficiency
        #: (:meth:`_note_back_drive`)
        self._back_drive_noted: set[str] = set()

    # --- lifecycle -------------------------------------------------------------------------
    def open(self) -> DynamixelBus:
        """Open the port and ping every servo; BusError if none answers.

        The pings wait :data:`PROBE_MARGIN_MS` and their round trips set the reply margin (see
        the module doc); a USB adapter's latency timer above 1 ms is added to it, noted.
        """
        try:
            ok = self.port.openPort() and self.port.setBaudRate(self.baud_rate)
        except Exception as err:  # pyserial raises SerialException/OSError subclasses
            raise BusError(f'port {self.port.getPortName()!r}: cannot open: {err}') from err
        if not ok:
            raise BusError(f'port {self.port.getPortName()!r}: cannot open at '
                           f'{self.baud_rate} baud (expected one of the SDK rates)')
        self.is_open = True
        self._check_usb_latency_timer()
        self._round_trip_ms = 0.0
        self._set_port_margin(max(self._margin_ms, PROBE_MARGIN_MS))
        self._measuring_round_trip = True
        try:
            for s in self.servos:
                self._ping(s)
        finally:
            self._measuring_round_trip = False
            self._set_port_margin(self._margin_ms)
        self._settle_margin()
        self._note_back_drive()
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
            self.is_open = False
            self.port.closePort()

    @contextmanager
    def _port_guard(self) -> Iterator[None]:
        """An OSError of the serial device (EIO: the USB adapter unplugged), or the
        termios.error pyserial's input flush raises then, closes the bus and becomes a
        PortLostError naming the port."""
        try:
            yield
        except _PORT_ERRORS as err:
            name = self.port.getPortName()
            self.port_lost = (f'port {name} lost: {type(err).__name__}: {err} (USB adapter '
                              'unplugged or the device failed); the servos keep their last '
                              'torque state and goals; reconnect the adapter and restart the '
                              'driver')
            self.is_open = False
            try:
                self.port.closePort()
            except Exception:   # noqa: BLE001 - the device is gone; closing is best effort
                pass
            raise PortLostError(self.port_lost) from err

    def __enter__(self) -> DynamixelBus:
        return self.open()

    def __exit__(self, *exc: object) -> None:
        self.close()

    # --- reply margin ----------------------------------------------------------------------
    @property
    def reply_margin_ms(self) -> float:
        """The working reply deadline margin [ms] (configured, then raised; see module doc)."""
        return self._margin_ms

    def _set_port_margin(self, margin_ms: float) -> None:
        if hasattr(self.port, 'timeout_margin_ms'):
            self.port.timeout_margin_ms = float(margin_ms)

    def _port_margin_ms(self) -> float:
        return float(getattr(self.port, 'timeout_margin_ms', self._margin_ms))

    def _raise_margin(self, margin_ms: float, why: str) -> None:
        new = min(MAX_MARGIN_MS, float(math.ceil(margin_ms)))
        if new <= self._margin_ms:
            return
        self.notes.append(f'{why}: reply deadline margin raised from {self._margin_ms:.0f} to '
                          f'{new:.0f} ms (a USB adapter holds replies for its latency timer: '
                          'set it to 1 ms, see the README)')
        self._margin_ms = new
        self._set_port_margin(max(self._port_margin_ms(), new))

    def _check_usb_latency_timer(self) -> None:
        name = self.port.getPortName()
        timer = usb_latency_timer_ms(name)
        if timer is None or timer <= 1:
            return
        path = _usb_latency_timer_file(name)
        new = min(MAX_MARGIN_MS, self._margin_ms + timer)
        self.notes.append(
            f'port {name}: USB latency timer {timer} ms ({path}): the adapter holds replies up '
            f'to {timer} ms, so the reply deadline margin is {new:.0f} ms instead of '
            f'{self._margin_ms:.0f}; set it to 1 ms: echo 1 | sudo tee {path} (or a udev rule, '
            'see the README)')
        self._margin_ms = new

    def _settle_margin(self) -> None:
        """After the pings at open: a margin that covers the slowest round trip seen."""
        if self._round_trip_ms > 0:
            self._raise_margin(1.5 * self._round_trip_ms + 1.0,
                               f'replies at open came up to {self._round_trip_ms:.1f} ms after '
                               'their requests')

    # --- transactions: one request, its own reply, never a late one -----------------------
    def _now_ms(self) -> float:
        return time.monotonic() * 1000.0

    def _prepare(self, ids: Iterable[int] = ()) -> None:
        """Before sending (a request to ``ids``): drain a line that may still carry a late
        reply, drop (and count) what is waiting, and stamp the request."""
        self.port.is_using = False
        if self._dirty:
            self._drain()
        ser = self.port.ser
        waiting = ser.in_waiting
        if waiting:
            self._late_bytes(ser.read(waiting))
        for sid in ids:
            self._answered.pop(sid, None)
        self._tx_ms = self._now_ms()

    def _failed(self) -> None:
        """The request stamped last went (partly) unanswered: its reply may still come."""
        self._dirty = True
        self._failed_tx_ms = self._tx_ms

    def _drain(self) -> None:
        """Read until the line stays quiet for one margin (late bytes counted, bounded)."""
        ser = self.port.ser
        start = self._now_ms()
        while True:
            quiet_s = self._port_margin_ms() / 1000.0
            ready, _, _ = select.select([ser.fileno()], [], [], quiet_s)
            if not ready:
                break
            data = ser.read(ser.in_waiting or 1)
            if data:
                self._late_bytes(data)
            if self._now_ms() - start > 4 * MAX_MARGIN_MS:
                ser.reset_input_buffer()   # a babbling line (noise, another baud rate)
                break
        self._dirty = False

    def _late_bytes(self, data: bytes) -> None:
        """Bytes that arrived with no request waiting for them: count the status packets (the
        adapter's echo of the last instruction skipped, a second reply counted as such)."""
        echo = getattr(self.port, 'last_tx', b'')
        if echo and echo in data:
            data = data.replace(echo, b'', 1)
            self._note_echo()
        head = b'\xff\xff\xfd\x00' if self.protocol == 2 else b'\xff\xff'
        at = 4 if self.protocol == 2 else 2
        packets = []
        k = data.find(head)
        while k >= 0 and k + at < len(data):
            packets.append((data[k + at], self._packet_length(data, k)))
            k = data.find(head, k + at + 1)
        for sid, length in packets:
            if self._answered.get(sid, -1) == length:
                self._duplicate(sid)
            elif sid != 0xFE:   # the broadcast ID is never a servo's reply (an echo)
                self._late(sid)

    def _packet_length(self, data: bytes, k: int) -> int | None:
        """Length of the packet whose header starts at ``data[k]`` (None: cut short)."""
        if self.protocol == 2:
            return (data[k + 5] | (data[k + 6] << 8)) + 7 if k + 6 < len(data) else None
        return data[k + 3] + 4 if k + 3 < len(data) else None

    def _duplicate(self, sid: int) -> None:
        """A second status packet to one request: two servos answer at ``sid``."""
        s = self._by_id.get(sid)
        if s is None:
            return
        first = s.health.duplicate_replies == 0
        s.health.duplicate_replies += 1
        s.last_duplicate_cycle = self.cycle
        if first:
            self.notes.append(
                f'{s.joint.name} (id {sid}) duplicate id? two replies came to one request: two '
                'servos share this ID; its readings are marked failed (either servo may have '
                'answered); give each servo its own ID (one at a time on the bus, e.g. with '
                'Dynamixel Wizard)')

    def _note_echo(self) -> None:
        if not self.echo:
            self.echo = True
            self.notes.append(
                f'port {self.port.getPortName()} echoes every transmitted byte (a half-duplex '
                'adapter without direction control): the echo is skipped from now on, at the '
                'cost of bus time; an adapter with echo suppression (U2D2, USB2Dynamixel) '
                'avoids it')

    def _late(self, sid: int) -> None:
        """One late status packet of ``sid``: counted, and the margin raised to cover it."""
        self.late_replies += 1
        s = self._by_id.get(sid)
        if s is not None:
            s.health.late_replies += 1
        since = self._failed_tx_ms if self._failed_tx_ms is not None else self._tx_ms
        late_ms = self._now_ms() - since
        self._raise_margin(1.5 * late_ms + 1.0,
                           f'a reply of id {sid} came {late_ms:.1f} ms after its request')

    def _rx(self) -> tuple[list[int], int]:
        if self.protocol == 2:
            return self.packet.rxPacket(self.port, False)  # type: ignore[no-any-return]
        return self.packet.rxPacket(self.port)  # type: ignore[no-any-return]

    def _params(self, rx: list[int]) -> list[int]:
        return list(rx[P2_PARAM0:-2]) if self.protocol == 2 else list(rx[P1_PARAM0:-1])

    def _receive(self, sid: int, n_params: int) -> tuple[list[int] | None, int, int]:
        """The status packet of ``sid`` with ``n_params`` parameters before the deadline set
        for the request: (parameters, error byte, result). Other packets are late, skipped."""
        # A Protocol 1.0 PING's status packet with error byte 0x01 (Input Voltage Error: an AX
        # servo on a 4S pack or a sagging battery) is byte for byte the PING instruction: a
        # packet equal to the instruction is the echo only when another one follows it (a
        # second review: such a servo was left silent and the port said to echo)
        twin = None
        while True:
            rx, result = self._rx()
            if result != COMM_SUCCESS:
                if twin is None:
                    self._failed()
                    return None, 0, result
                # nothing followed: it was the servo's reply
                rx, twin, result = twin, None, COMM_SUCCESS
            elif bytes(rx) == getattr(self.port, 'last_tx', None) and twin is None:
                self.port.setPacketTimeout(self._status_bytes(n_params))
                if self._ping_twin(rx):
                    twin = rx
                else:   # the adapter's echo of the request
                    self._note_echo()
                continue
            elif twin is not None:
                self._note_echo()         # the reply followed: the twin was the echo
                twin = None
            rid = rx[P2_ID] if self.protocol == 2 else rx[P1_PKT_ID]
            params = self._params(rx)
            error = rx[P2_ERROR if self.protocol == 2 else P1_ERROR]
            if rid == sid and len(params) == n_params:
                self._failed_tx_ms = None
                self._answered[rid] = len(rx)
                if self._measuring_round_trip:
                    wire_ms = len(rx) * self.port.tx_time_per_byte
                    self._round_trip_ms = max(self._round_trip_ms,
                                              self._now_ms() - self._tx_ms - wire_ms)
                return params, error, result
            if rid == sid and not params and error & self._rejected_bits:
                # The servo could not take the instruction and says so: no reply is late.
                self._failed_tx_ms = None
                return None, error, self._rejected(sid, error)
            if self._answered.get(rid, -1) == len(rx):
                self._duplicate(rid)
            else:
                self._late(rid)

    def _ping_twin(self, rx: list[int]) -> bool:
        """Whether ``rx`` (equal to the instruction just sent) could also be the servo's
        reply: a Protocol 1.0 PING, whose status packet with error byte 0x01 has the same
        bytes."""
        return self.protocol == 1 and len(rx) == 6 and rx[P1_PKT_INSTRUCTION] == INST_PING

    def _rejected(self, sid: int, error: int) -> int:
        """A reply of ``sid`` with an error and no data, for the log: a corrupted instruction
        (Protocol 1.0 checksum or instruction error, 2.0 Instruction or CRC Error: noise, the
        result COMM_RX_CORRUPT, retried) or an instruction the servo received intact and
        refused (any other 2.0 error, e.g. Access Error: :data:`RESULT_REFUSED`, not retried;
        the servo's model number is read again)."""
        s = self._by_id.get(sid)
        number = error & 0x7F
        noise = self.protocol == 1 or number in P2_NOISE_ERRORS
        if s is None:
            return COMM_RX_CORRUPT if noise else RESULT_REFUSED
        if self.protocol == 1:
            what = 'checksum' if error & 0x10 else 'instruction'
        else:
            what = P2_STATUS_ERRORS.get(number, 'status')
        name = f'{s.joint.name} (id {sid})'
        if noise:
            s.health.rejected_instructions += 1
            self.events.event(
                (sid, 'rejected'), 'warning',
                f'{name} reports a {what} error on an instruction it received (status error '
                f'{error:#04x}): noise on the way to the servo (cabling, termination, baud '
                'rate); retried')
            return COMM_RX_CORRUPT
        s.health.refused_instructions += 1
        s.refused_read = True
        model = s.table.model_name if s.table is not None else 'the model detected'
        self.events.event(
            (sid, 'refused'), 'warning',
            f'{name} reports {what} (status error {error:#04x}) on an instruction it received '
            f'intact: {P2_REFUSAL_HINTS.get(number, "it could not carry it out")}; is the '
            f'servo at this ID still the {model} the driver detected? (its model number is '
            'read again)')
        return RESULT_REFUSED

    @property
    def _rejected_bits(self) -> int:
        """Status error bits of a servo that could not take the instruction it received:
        Protocol 1.0 checksum 0x10 and instruction 0x40; Protocol 2.0 an error number."""
        return 0x50 if self.protocol == 1 else 0x7F

    def _status_bytes(self, n_params: int) -> int:
        return n_params + (11 if self.protocol == 2 else 6)

    # --- detection ---------------------------------------------------------------------------
    def _ping_once(self, s: _Servo) -> tuple[int | None, bool]:
        """One PING (and on Protocol 1.0 a READ of the model number): (model, PING answered).

        Not the SDK's ping: it takes any packet with the right ID for its answer (a late PING
        reply passed for the model READ)."""
        sid = s.joint.servo_id
        self._prepare([sid])
        if self.protocol == 2:
            tx = [0] * 10
            tx[P2_ID], tx[5], tx[6], tx[7] = sid, 3, 0, INST_PING
        else:
            tx = [0] * 6
            tx[P1_PKT_ID], tx[P1_PKT_LENGTH], tx[P1_PKT_INSTRUCTION] = sid, 2, INST_PING
        result = self.packet.txPacket(self.port, tx)
        if result != COMM_SUCCESS:
            self._count(s, result)
            return None, False
        n_params = 3 if self.protocol == 2 else 0
        self.port.setPacketTimeout(self._status_bytes(n_params))
        params, _err, result = self._receive(sid, n_params)
        if params is None:
            self._count(s, result)
            return None, False
        if self.protocol == 2:
            return params[0] | (params[1] << 8), True
        data, _ = self._read_settled(s, 0, 2)
        return (None, True) if data is None else (data[0] | (data[1] << 8), True)

    def _ping(self, s: _Servo) -> bool:
        """Detect ``s``: model, Status Return Level, Operating Mode (False: left out).

        A model other than the one first detected at the ID is left out
        (:meth:`_model_changed`); the first model answering again is taken back."""
        for _ in range(1 + self.retries):
            garbled = s.health.streak_garbled
            model, answered = self._ping_once(s)
            if model is None and not answered:
                continue
            if model is None:
                if s.health.streak_garbled > garbled:
                    self._refuse_garbled(s)
                    return False
                # PING answered, model READ not, on a quiet line: Status Return Level 0
                self._refuse_level_0(s)
                return False
            unknown = ''
            try:
                table: ControlTable | None = table_for_model(self.protocol, model)
            except ControlTableError as err:
                table, unknown = None, str(err)
            first = s.first_model
            if first is not None and (table is None or table.model_number != first.model_number):
                self._model_changed(s, model, table)
                return False
            if table is None:
                s.health.model = f'unsupported model {model}'
                s.refusal = unknown
                return False
            s.table = table
            if not self._measuring_round_trip:   # (the pings at open: noted together after)
                self._note_back_drive()
            garbled = s.health.streak_garbled
            if not self._read_status_return_level(s, garbled):
                return False
            self._read_operating_mode(s)
            self._read_wheel_mode(s)
            self._read_position_limits(s)
            if first is not None and s.refusal.startswith('model changed'):
                self.events.event((s.joint.servo_id, 'model'), 'info',
                                  f'{s.joint.name} (id {s.joint.servo_id}) answers as '
                                  f'{first.model_name} again, the model first detected: read '
                                  'again')
            s.refusal = ''
            s.first_model = s.table
            s.health.model = s.table.model_name
            s.health.silent = False
            # consecutive_failures is kept: a servo taken back at run time is checked as one
            # that answers again (model, Torque Enable) on its first good read
            s.health.streak_garbled = s.health.streak_no_reply = 0
            s.health.recent_failures.clear()
            return True
        s.health.silent = True
        return False

    def _model_changed(self, s: _Servo, number: int, table: ControlTable | None) -> None:
        """Another model answers at the ID of ``s`` (a servo replaced, or another servo set to
        this ID): left out, named with both models, until the driver is restarted or the first
        model answers there again. Not adopted with its own table: the joint's offset and
        direction, its Status Return Level and mode were set up for the first servo, and one
        run's data would mix two servos."""
        first = s.first_model
        assert first is not None
        now = (f'{table.model_name} (model number {number})' if table is not None
               else f'model number {number}, not a model the driver knows')
        s.table = None
        s.refused_read = False
        s.health.model = f'{table.model_name if table else number} (first {first.model_name})'
        refusal = (f'model changed: first detected as {first.model_name} (model number '
                   f'{first.model_number}), now answers as {now}: a servo replaced, or '
                   f'another servo set to this ID; read with the {first.model_name} control '
                   'table its numbers would be wrong, so it is left out until the driver is '
                   'restarted or a servo of the first model answers at this ID again')
        if s.refusal != refusal:
            self.events.event((s.joint.servo_id, 'model'), 'warning',
                              f'{s.joint.name} (id {s.joint.servo_id}) {refusal}')
        s.refusal = refusal

    def _model_still(self, s: _Servo) -> bool | None:
        """Model Number (address 0) read again: True when it is still the model of ``s``, False
        when another model answers (left out, :meth:`_model_changed`), None when unread."""
        assert s.table is not None and s.first_model is not None
        s.refused_read = False
        data, _ = self._read_single(s, 0, 2, 1 + self.retries)
        if data is None:
            return None
        number = data[0] | (data[1] << 8)
        if number == s.first_model.model_number:
            return True
        try:
            table: ControlTable | None = table_for_model(self.protocol, number)
        except ControlTableError:
            table = None
        self._model_changed(s, number, table)
        return False

    def _refuse_garbled(self, s: _Servo) -> None:
        """PING answered, its READs garbled: two servos at the ID (identical PING replies
        pass, replies carrying each one's data collide). Not Status Return Level 0, which a
        quiet line would mean (an outside review: twins at start-up were told to set a
        register that was already 2)."""
        s.table = None
        s.health.model = 'unreadable (garbled replies)'
        s.refusal = ('answers PING, but its READ replies arrive garbled (broken checksums): '
                     'a second servo at this ID? (two servos answering one request collide; '
                     'their identical PING replies pass; give each servo its own ID) or a '
                     'burst of line noise; tried again every '
                     f'{self.probe_interval_cycles} cycles')
        self.notes.append(f'{s.joint.name} (id {s.joint.servo_id}) left out: {s.refusal}')

    def _refuse_level_0(self, s: _Servo) -> None:
        if s.table is not None:     # Protocol 2.0: the model came with the PING's reply
            s.level0_table = s.table
        elif self.protocol == 1:
            # Protocol 1.0's PING carries no model, but every described 1.0 model has Torque
            # Enable at 24: it is turned off at shutdown too (it was left as it was, torque
            # state unknown)
            s.level0_table = P1_TORQUE_OFF_TABLE
        s.table = None
        s.health.model = 'unreadable (Status Return Level 0)'
        s.refusal = (f'answers PING but no READ: its Status Return Level is 0 (the servo '
                     f'replies to nothing else); set it to 1 or 2 (register '
                     f'{"16" if self.protocol == 1 else "68"}, e.g. with Dynamixel Wizard: this '
                     f'driver never writes configuration registers)')

    def _read_settled(self, s: _Servo, start: int, length: int) -> tuple[list[int] | None, int]:
        """A READ with retries whose failure stands only if the line then stays quiet: when a
        late reply turns up meanwhile (the margin is raised by it), the READ is tried again."""
        for _ in range(3):
            data, err = self._read_single(s, start, length, 1 + self.retries)
            if data is not None:
                return data, err
            late = self.late_replies
            self._drain()
            if self.late_replies == late:
                break
        return None, 0

    def _read_status_return_level(self, s: _Servo, garbled: int = -1) -> bool:
        """Read the servo's Status Return Level after its PING (False, refused, at level 0).

        Level 1 is a common setting on real robots (it halves the bus time of writes): such a
        servo answers READ and PING only, so its torque writes are sent without waiting for a
        reply and checked by reading the register back (:meth:`set_torque`)."""
        assert s.table is not None
        data, _ = self._read_settled(s, s.table.reg('status_return_level').address, 1)
        if data is None:
            if garbled >= 0 and s.health.streak_garbled > garbled:
                self._refuse_garbled(s)
            else:
                self._refuse_level_0(s)
            return False
        level = int(data[0])
        if level < 2 and s.health.status_return_level != level:
            self.notes.append(
                f'{s.joint.name} (id {s.joint.servo_id}) has Status Return Level {level}: it '
                'does not acknowledge writes, so torque writes are checked by reading back')
        s.health.status_return_level = level
        return True

    def _read_operating_mode(self, s: _Servo) -> None:
        """Protocol 2.0 Operating Mode: multi-turn goals, or goals refused (see module doc)."""
        assert s.table is not None
        if 'operating_mode' not in s.table.registers:
            return
        reg = s.table.reg('operating_mode')
        data, _ = self._read_settled(s, reg.address, 1)
        if data is None:
            self.notes.append(f'{s.joint.name} (id {s.joint.servo_id}): Operating Mode not '
                              'read; goals limited to one turn (position mode)')
            return
        mode = int(data[0])
        s.health.operating_mode = mode
        if mode in GOAL_POSITION_MODES:
            s.command_refusal = ''
            return
        label = OPERATING_MODES.get(mode, 'unknown mode')
        s.command_refusal = (
            f'Operating Mode {mode} ({label}) ignores Goal Position: its goals and torque on are '
            f'refused; set Operating Mode (register {reg.address}) to 3 (position) or 4 '
            '(extended position), e.g. with Dynamixel Wizard: this driver never writes '
            'configuration registers')
        self.notes.append(f'{s.joint.name} (id {s.joint.servo_id}): {s.command_refusal}')

    def _read_wheel_mode(self, s: _Servo) -> None:
        """Protocol 1.0 wheel mode, CW and CCW Angle Limit both 0: goals refused (module doc)."""
        assert s.table is not None
        t = s.table
        if 'cw_angle_limit' not in t.registers or 'operating_mode' in t.registers:
            return
        cw, ccw = t.reg('cw_angle_limit'), t.reg('ccw_angle_limit')
        data, _ = self._read_settled(s, cw.address, ccw.address + ccw.size - cw.address)
        if data is None:
            self.notes.append(f'{s.joint.name} (id {s.joint.servo_id}): CW/CCW Angle Limit '
                              f'(registers {cw.address}, {ccw.address}) not read; wheel mode '
                              'not checked')
            return
        low = t.decode('cw_angle_limit', data, cw.address)
        high = t.decode('ccw_angle_limit', data, cw.address)
        if low or high:
            s.command_refusal = ''
            # goals are clipped to them (a goal outside is an Angle Limit Error, not applied);
            # an MX in multi-turn mode (both 4095) is left to its one-turn clip
            s.goal_range = ((low, high, f'CW/CCW Angle Limit (registers {cw.address}/'
                             f'{ccw.address})') if low < high else None)
            return
        s.command_refusal = (
            f'wheel mode: CW Angle Limit (register {cw.address}) and CCW Angle Limit (register '
            f'{ccw.address}) are both 0, so the servo ignores Goal Position and turns endlessly '
            'at Moving Speed: its goals and torque on are refused; set CCW Angle Limit to '
            f'{t.max_tick} (joint mode), e.g. with Dynamixel Wizard: this driver never writes '
            'configuration registers')
        self.notes.append(f'{s.joint.name} (id {s.joint.servo_id}): {s.command_refusal}')

    def _read_position_limits(self, s: _Servo) -> None:
        """Protocol 2.0 Min/Max Position Limit (52/48), which bound Goal Position in position
        mode (3) only (a goal outside gets Data Limit Error and is not applied): goals are
        clipped to them (:meth:`write_goals`). Not in the multi-turn modes 4 and 5."""
        assert s.table is not None
        t = s.table
        if 'min_position_limit' not in t.registers:
            return      # Protocol 1.0: CW/CCW Angle Limit (:meth:`_read_wheel_mode`)
        s.goal_range = None
        if s.health.operating_mode != 3:
            return
        high, low = t.reg('max_position_limit'), t.reg('min_position_limit')
        start = min(high.address, low.address)
        end = max(high.address + high.size, low.address + low.size)
        data, _ = self._read_settled(s, start, end - start)
        if data is None:
            self.notes.append(f'{s.joint.name} (id {s.joint.servo_id}): Min/Max Position Limit '
                              f'(registers {low.address}/{high.address}) not read; goals '
                              'clipped to one turn only')
            return
        lo = t.decode('min_position_limit', data, start)
        hi = t.decode('max_position_limit', data, start)
        if lo <= hi:
            s.goal_range = (lo, hi, f'Min/Max Position Limit (registers {low.address}/'
                                    f'{high.address})')

    def _clip_goal(self, s: _Servo, target: float, multi_turn: bool) -> int:
        """Goal Position tick of ``target`` (joint frame [rad]) inside the servo's limits (its
        angle or position limits read at open, else one turn, or +-1 048 575 ticks in the
        multi-turn modes). A goal clipped is counted (``goals_clipped``); the first of an
        episode (clipped goals in a row) is a warning event naming the joint, the angle and
        the limit in the joint frame; ``goal_clip`` describes the last one until a goal inside
        ends the episode (info event)."""
        assert s.table is not None
        t = s.table
        tick = t.rad_to_position(s.joint.to_servo(target), multi_turn=True)
        if multi_turn:
            lo, hi, regs = -EXTENDED_POSITION_LIMIT, EXTENDED_POSITION_LIMIT, 'multi-turn range'
        elif s.goal_range is not None:
            lo, hi, regs = s.goal_range
        else:
            lo, hi, regs = 0, t.max_tick, 'one turn'
        name = f'{s.joint.name} (id {s.joint.servo_id})'
        if lo <= tick <= hi:
            if s.health.goal_clip:
                s.health.goal_clip = ''
                self.events.event((s.joint.servo_id, 'limit'), 'info',
                                  f'{name} goals inside its limits again '
                                  f'({s.health.goals_clipped} clipped so far)')
            return tick
        edge = lo if tick < lo else hi
        s.health.goals_clipped += 1
        first = not s.health.goal_clip
        j_lo, j_hi = sorted(s.joint.to_joint(t.position_to_rad(x)) for x in (lo, hi))
        limit = s.joint.to_joint(t.position_to_rad(edge))
        s.health.goal_clip = (
            f'goal {target:.3f} rad beyond its limit {limit:.3f} rad (joint frame; limits '
            f'{j_lo:.3f}..{j_hi:.3f} rad from {regs}, ticks {lo}..{hi}): clipped to the limit')
        if first:
            self.events.event((s.joint.servo_id, 'limit'), 'warning',
                              f'{name} {s.health.goal_clip}; the joint does not reach its '
                              'commands (said once until a goal inside the limits)')
        return edge

    @property
    def refused(self) -> dict[str, str]:
        """Joints left out (unknown model, Status Return Level 0) or whose commands are refused
        (Operating Mode), with the reason; silent servos are not listed (they are retried)."""
        return {s.joint.name: s.refusal or s.command_refusal for s in self.servos
                if s.refusal or s.command_refusal}

    # --- reading ---------------------------------------------------------------------------
    @property
    def joint_names(self) -> list[str]:
        return [s.joint.name for s in self.servos]

    def health(self) -> list[ServoHealth]:
        return [s.health for s in self.servos]

    def _count(self, s: _Servo, result: int) -> None:
        if result == RESULT_REFUSED:   # counted in refused_instructions
            s.health.recent_failures.append('r')
        elif result == COMM_RX_CORRUPT:
            s.health.corrupt += 1
            s.health.streak_garbled += 1
            s.health.recent_failures.append('g')
        else:   # a timeout; port busy / tx fail: counted as a missed reply
            s.health.timeouts += 1
            s.health.streak_no_reply += 1
            s.health.recent_failures.append('n')

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

    def _read_single(self, s: _Servo, start: int, length: int, attempts: int, *,
                     shifted: bool = False) -> tuple[list[int] | None, int]:
        """READ ``length`` bytes at ``start``: (data, status error) or (None, 0).

        Every other attempt (the first one too with ``shifted``, for a retry after a missed
        Sync Read) asks for one byte more, from one address lower (or one higher at 0), and
        drops it: the late reply to the attempt before has the wrong length for it."""
        sid = s.joint.servo_id
        for k in range(attempts):
            if k:
                s.health.retries += 1
            extra = (k % 2 == 1) != shifted
            lo = 1 if extra and start > 0 else 0
            n = length + (1 if extra else 0)
            self._prepare([sid])
            result = self.packet.readTx(self.port, sid, start - lo, n)
            if result == COMM_SUCCESS:
                self.port.setPacketTimeout(self._status_bytes(n))
                data, error, result = self._receive(sid, n)
                if data is not None:
                    return data[lo:lo + length], error
            self._count(s, result)
            if result == RESULT_REFUSED:
                break   # the servo would refuse it again
        return None, 0

    def _sync_read(self, servos: list[_Servo], start: int,
                   length: int) -> dict[int, tuple[list[int], int]]:
        """Protocol 2.0 Sync Read; replies assigned by ID, so a silent servo costs only itself.
        A packet of another ID, a second one of an ID or one of another length is late."""
        ids = [s.joint.servo_id for s in servos]
        got: dict[int, tuple[list[int], int]] = {}
        self._prepare(ids)
        if self.packet.syncReadTx(self.port, start, length, ids, len(ids), False) != COMM_SUCCESS:
            return got
        pending = list(ids)
        while pending:
            self.port.setPacketTimeout(length + 11)
            rx, result = self.packet.rxPacket(self.port, False)
            sid = rx[P2_ID] if len(rx) > P2_ID else None
            if result == COMM_SUCCESS:
                data = list(rx[P2_PARAM0:-2])
                if sid in pending and len(data) == length:
                    pending.remove(sid)
                    got[sid] = (data, rx[P2_ERROR])
                    self._answered[sid] = len(rx)
                elif sid in pending and not data and rx[P2_ERROR] & 0x7F:
                    # it could not take the Sync Read (an access error: another model?)
                    pending.remove(sid)
                    self._count(self._by_id[sid], self._rejected(int(sid), rx[P2_ERROR]))
                elif self._answered.get(sid, -1) == len(rx):
                    self._duplicate(int(sid))
                else:
                    self._late(int(rx[P2_ID]))
            elif result == COMM_RX_CORRUPT and sid in pending:
                pending.remove(sid)
                self._count(self._by_id[sid], COMM_RX_CORRUPT)
            else:
                break
        if pending:
            self._failed()
        for sid in pending:
            # no (valid) reply before the deadline
            self._count(self._by_id[sid], COMM_RX_TIMEOUT)
        return got

    def _hardware_flags(self, s: _Servo, status_error: int, *, known: int | None = None,
                        retry: bool = False) -> int:
        """The hardware error flags a reply's status error stands for: Protocol 1.0 its bits;
        Protocol 2.0 Hardware Error Status when the alert bit is set: ``known`` (read this
        cycle in the Sync Read of :meth:`_status_sync_read`), else read here (one READ; with
        ``retry`` the servo missed that Sync Read: ``retries`` attempts, as after a missed Sync
        Read of the present values); the last flags when it cannot be read."""
        if self.protocol == 1:
            return status_error & 0x7F
        if s.table is None or not status_error & P2_ALERT:
            return 0
        if known is not None:
            return known
        attempts = self.retries if retry else 1
        data, _ = self._read_single(s, s.table.reg('hardware_error_status').address, 1,
                                    attempts, shifted=retry)
        return s.health.last_error_flags if data is None else data[0]

    def read_all(self) -> tuple[ServoReading, ...]:
        """One read of every active servo, in joint-map order (NaN readings for failures).

        PortLostError when the serial device fails (see the module doc)."""
        if self.port_lost:
            raise PortLostError(self.port_lost)
        with self._port_guard():
            return self._read_all()

    def _read_all(self) -> tuple[ServoReading, ...]:
        self.cycle += 1
        active = self._active()
        raw: dict[int, tuple[list[int], int]] = {}
        synced = self.protocol == 2 and self.sync_read and bool(active)
        #: {id: (Torque Enable, Hardware Error Status or None)} read this cycle beside the
        #: present values (step 4 of the module doc)
        status: dict[int, tuple[bool | None, int | None]] = {}
        asked: set[int] = set()    # ids in this cycle's Sync Read of registers 64-70 / 70
        limits: dict[int, int] = {}   # Protocol 1.0 Torque Limit read this cycle, by id
        if synced:
            blocks: dict[tuple[int, int], list[_Servo]] = {}
            for s in active:
                assert s.table is not None
                blocks.setdefault(s.table.read_block, []).append(s)
            for (start, length), group in blocks.items():
                raw.update(self._sync_read(group, start, length))
        sync_answered = bool(raw)
        # single READs: one servo's READ starts at Torque Enable (no extra request)
        turn = None if synced else self._torque_turn(active)
        for s in active:
            sid = s.joint.servo_id
            assert s.table is not None
            if sid in raw:
                continue
            if synced:
                # The sync reply was lost or corrupt: this is a retry (not of a refused one:
                # its model is read instead, below).
                if self.retries == 0 or s.refused_read:
                    continue
                s.health.retries += 1
                data, err = self._read_single(s, *s.table.read_block, attempts=self.retries,
                                              shifted=True)
            else:
                attempts = 1 if s.health.silent else 1 + self.retries
                start, length = s.table.read_block
                torque = s.table.reg('torque_enable').address
                # the turn's servo, and on Protocol 2.0 a servo whose alert stays set: its
                # READ starts at Torque Enable, so Hardware Error Status comes with it (a
                # review: 6 alerted servos cost 11 requests a cycle on a bus without Sync
                # Read, one READ of register 70 each)
                widen = s is turn or (self.protocol == 2 and bool(s.health.last_error_flags))
                if widen:
                    start, length = torque, start + length - torque
                data, err = self._read_single(s, start, length, attempts=attempts)
                if data is not None and widen:
                    flags = None
                    if self.protocol == 2:
                        flags = data[s.table.reg('hardware_error_status').address - torque]
                    else:   # Torque Limit (34) is inside: 0 is a Protocol 1.0 Alarm Shutdown
                        limits[sid] = s.table.decode('torque_limit', data, torque)
                    status[sid] = (bool(data[0]), flags)
                    data = data[-s.table.read_block[1]:]
            if data is not None:
                raw[sid] = (data, err)
        if synced:
            self._note_sync_support(sync_answered, single_answered=bool(raw))
            status, asked = self._status_sync_read(active, raw)
        readings = []
        for s in self.servos:
            sid = s.joint.servo_id
            duplicate = self.cycle - s.last_duplicate_cycle <= DUPLICATE_HOLD_CYCLES
            if (s.refused_read and sid not in raw and s in active and s.table is not None
                    and self._model_still(s) is False):
                # its READ refused (access error): another model answers; left out now
                readings.append(ServoReading(s.joint.name, sid, False,
                                             error_flags=s.health.last_error_flags))
                continue
            if sid not in raw or s.table is None or duplicate:
                if s in active:
                    s.health.failed_cycles += 1
                    s.health.consecutive_failures += 1
                    if (s.health.consecutive_failures >= self.silent_after
                            and not s.health.silent and not duplicate):
                        self._went_silent(s)
                readings.append(ServoReading(s.joint.name, sid, False,
                                             error_flags=s.health.last_error_flags))
                continue
            data, status_error = raw[sid]
            h = s.health
            was_failing = h.consecutive_failures > 0
            if was_failing or s.refused_read:
                # A servo answering again may be another one (replaced, or set to this ID):
                # its model is read before its data are decoded with the model's table.
                same = self._model_still(s)
                if not same:
                    if same is None:   # not confirmed: withheld, still failing
                        h.failed_cycles += 1
                        h.consecutive_failures += 1
                    readings.append(ServoReading(s.joint.name, sid, False,
                                                 error_flags=h.last_error_flags))
                    continue
            h.reads_ok += 1
            if h.silent:
                self.events.event((sid, 'silent'), 'info',
                                  f'{s.joint.name} (id {sid}) answers again after '
                                  f'{self.cycle - s.silent_since_cycle} cycles silent')
            h.consecutive_failures = 0
            h.streak_garbled = h.streak_no_reply = 0
            h.recent_failures.clear()
            h.silent = False
            on, known = status.get(sid, (None, None))
            flags = self._hardware_flags(s, status_error, known=known, retry=sid in asked)
            if flags or (status_error & (0x7F if self.protocol == 2 else 0)):
                h.error_replies += 1
            new_flags = flags & ~h.last_error_flags
            self._note_flags(s, flags)
            h.last_error_flags = flags
            if was_failing or new_flags or on is not None:
                self._check_torque(s, came_back=was_failing, on=on, err=status_error,
                                   limit=limits.get(sid))
            st = s.table.decode_present(data)
            j = s.joint
            # + 0.0: a direction -1 joint at rest read -0.0 (an outside review)
            readings.append(ServoReading(
                name=j.name, servo_id=sid, ok=True,
                position_rad=j.to_joint(st.position_rad) + 0.0,
                velocity_rad_s=j.direction * st.velocity_rad_s + 0.0,
                effort_nm=j.direction * self._effort_nm(s.table, st) + 0.0,
                load_fraction=j.direction * st.load_fraction + 0.0,
                voltage_v=st.voltage_v, temperature_c=st.temperature_c, error_flags=flags))
        return tuple(readings)

    def _effort_nm(self, table: ControlTable, st: PresentState) -> float:
        """The servo-frame torque estimate of one reading (see the module doc)."""
        if 'present_current' not in table.registers:
            return st.load_fraction * table.stall_torque_nm
        return table.current_to_torque_nm(
            st.load_fraction * table.stall_current_a, st.velocity_rad_s,
            gear_efficiency=self.gear_efficiency,
            dead_band_rad_s=self.back_drive_dead_band_rad_s)

    def _status_eligible(self, s: _Servo, raw: Mapping[int, Any]) -> bool:
        """``s`` answered this cycle, and the cycle before (not coming back: its model is
        read first), and no second servo answers at its ID: its registers 64-70 may be read
        with the others'."""
        return (s.joint.servo_id in raw and s.table is not None and not s.refused_read
                and s.health.consecutive_failures == 0 and not s.health.silent
                and self.cycle - s.last_duplicate_cycle > DUPLICATE_HOLD_CYCLES)

    def _status_sync_read(self, active: list[_Servo], raw: Mapping[int, Any]
                          ) -> tuple[dict[int, tuple[bool | None, int | None]], set[int]]:
        """Protocol 2.0 with Sync Read, after the present values: every
        ``torque_check_interval_cycles`` cycles, or when an alert appears (a new flag may be an
        Alarm Shutdown: Torque Enable is checked), Torque Enable to Hardware Error Status
        (64-70) of every servo that answered, else Hardware Error Status (70) of those whose
        reply carried the alert bit: one Sync Read (none when no servo is alerted), so a new
        flag (Overheating) is known in the cycle it appears, whatever alert was set before.
        ({id: (Torque Enable or None, Hardware Error Status)}, the ids asked)."""
        eligible = [s for s in active if self._status_eligible(s, raw)]
        full = self.cycle % self.torque_check_interval_cycles == 0 or any(
            raw[s.joint.servo_id][1] & P2_ALERT and not s.health.last_error_flags
            or s.joint.servo_id in self._status_missed for s in eligible)
        blocks: dict[tuple[int, int], list[_Servo]] = {}
        for s in eligible:
            assert s.table is not None
            hw = s.table.reg('hardware_error_status')
            if full:
                torque = s.table.reg('torque_enable').address
                blocks.setdefault((torque, hw.address + hw.size - torque), []).append(s)
            elif raw[s.joint.servo_id][1] & P2_ALERT:
                blocks.setdefault((hw.address, hw.size), []).append(s)
        out: dict[int, tuple[bool | None, int | None]] = {}
        asked: set[int] = set()
        for (start, length), group in blocks.items():
            asked.update(s.joint.servo_id for s in group)
            for sid, (data, _err) in self._sync_read(group, start, length).items():
                out[sid] = (bool(data[0]) if full else None, data[-1])
        if full:
            self._status_missed = asked - set(out)
        return out, asked

    def _torque_turn(self, active: list[_Servo]) -> _Servo | None:
        """Single READs: the next servo (in joint-map order, after the last one) that answered
        the cycle before: its READ this cycle starts at Torque Enable (Protocol 1.0: 24, 12
        bytes more; 2.0: 64, with Hardware Error Status), so every servo's Torque Enable is
        read within ``len(joints)`` cycles at no extra request."""
        n = len(self.servos)
        for k in range(1, n + 1):
            i = (self._round_robin + k) % n
            s = self.servos[i]
            if (s in active and s.table is not None and not s.refused_read
                    and s.health.consecutive_failures == 0 and not s.health.silent
                    and self.cycle - s.last_duplicate_cycle > DUPLICATE_HOLD_CYCLES):
                self._round_robin = i
                return s
        return None

    def _went_silent(self, s: _Servo) -> None:
        s.health.silent = True
        s.silent_since_cycle = self.cycle
        h = s.health
        if h.silence() == 'refused reads':
            why = (f'its READs refused (status error, no data) in {h.consecutive_failures} '
                   'cycles in a row')
            check = 'the model at this ID and the log'
        elif h.silence() == 'garbled replies':
            why = (f'garbled replies (of its last {len(h.recent_failures)} failed requests '
                   f'{h.recent_failures.count("g")} with a broken checksum, '
                   f'{h.recent_failures.count("n")} unanswered) in '
                   f'{h.consecutive_failures} cycles in a row')
            check = ('a second servo at this ID (its replies collide), or noise on the line: '
                     'cabling, termination')
        else:
            why = f'no reply in {h.consecutive_failures} cycles in a row'
            check = 'its cable and power'
        self.events.event(
            (s.joint.servo_id, 'silent'), 'warning',
            f'{s.joint.name} (id {s.joint.servo_id}) went silent: {why}; probed every '
            f'{self.probe_interval_cycles} cycles from now on (check {check})')

    def _note_flags(self, s: _Servo, flags: int) -> None:
        """A hardware error flag appearing (warning) or all clearing (info), for the log."""
        old = s.health.last_error_flags
        name = f'{s.joint.name} (id {s.joint.servo_id})'
        if flags & ~old:
            self.events.event(
                (s.joint.servo_id, 'flags'), 'warning',
                f'{name} reports hardware error '
                f'{list(decode_error_flags(self.protocol, flags))} ('
                + ('status error byte' if self.protocol == 1 else 'Hardware Error Status')
                + f' {flags:#04x})')
        elif old and not flags:
            self.events.event((s.joint.servo_id, 'flags'), 'info',
                              f'{name} hardware error flags cleared')

    def _read_torque_enable(self, s: _Servo) -> tuple[bool | None, int, int | None]:
        """Torque Enable read by one READ: (on, status error, Protocol 1.0 Torque Limit, which
        the READ then reaches: registers 24-35); (None, 0, None) unread."""
        assert s.table is not None
        reg = s.table.reg('torque_enable')
        p1_limit = self._p1_torque_limit(s)
        end = reg.address + reg.size if p1_limit is None else p1_limit.address + p1_limit.size
        data, err = self._read_single(s, reg.address, end - reg.address, 1 + self.retries)
        if data is None:
            return None, 0, None   # counted; tried again later
        limit = None if p1_limit is None else s.table.decode('torque_limit', data, reg.address)
        return bool(data[0]), err, limit

    def _p1_torque_limit(self, s: _Servo) -> Register | None:
        """Torque Limit (34) of a Protocol 1.0 servo, whose Alarm Shutdown sets it to 0 (AX/RX/MX
        e-Manual, Torque Limit) and leaves Torque Enable at 1; None on Protocol 2.0."""
        if self.protocol != 1 or s.table is None or 'torque_limit' not in s.table.registers:
            return None
        return s.table.reg('torque_limit')

    def _check_torque(self, s: _Servo, came_back: bool, on: bool | None = None,
                      err: int = 0, limit: int | None = None) -> None:
        """Torque Enable (``on``, read here if not given) after a servo answered again
        (``came_back``), raised a new hardware error, or as read in :meth:`_read_all` (step 4
        of the module doc): ``torque_enabled`` follows it, and torque the driver had turned on
        but the servo lost is reported (``torque_lost``). On Protocol 1.0 a Torque Limit
        (``limit``, read with it) of 0 is torque lost as well: the Alarm Shutdown of AX/RX/MX
        servos zeroes it and keeps Torque Enable at 1. ``err``: the status error of this
        cycle's reply; the flags are those of this cycle (``last_error_flags``)."""
        assert s.table is not None
        reg = s.table.reg('torque_enable')
        if on is None:
            on, torque_err, limit = self._read_torque_enable(s)
            if on is None:
                return
            err |= torque_err
        limp = bool(on) and limit == 0      # Protocol 1.0 Alarm Shutdown
        if limit:
            s.torque_limit_seen = limit
        expected = s.health.torque_enabled
        s.health.torque_enabled = on and not limp
        if s.health.torque_enabled or not expected:
            return
        flags = s.health.last_error_flags | (err & 0x7F if self.protocol == 1 else 0)
        names = list(decode_error_flags(self.protocol, flags))
        if came_back:
            why = 'came back with torque off (power cycled or hardware error?)'
        elif flags:
            why = f'turned torque off itself with hardware error {names} (Alarm Shutdown)'
        elif limp:
            why = 'lost its torque in an Alarm Shutdown (its error flag already cleared)'
        else:
            why = ('torque off between two reads, no reply missed (rebooted, or power cycled '
                   'within a cycle?)')
        hint = ('; an X-series or MX(2.0) servo in hardware-error shutdown needs a REBOOT'
                if self.protocol == 2 and flags else '')
        if limp:
            what = ('Torque Limit (register 34) reads 0 (a Protocol 1.0 Alarm Shutdown; Torque '
                    'Enable still reads 1) where the driver had turned torque on')
            hint = ('; set_torque(True) writes Torque Limit back from Max Torque (register '
                    '14) once the error is gone')
        else:
            what = f'Torque Enable (register {reg.address}) reads 0 where the driver had ' \
                'turned it on'
        s.health.torque_lost = (
            f'{why}: {what}' + (f', hardware error {names}' if flags and came_back else '')
            + f'; the joint is limp; check its power, cable and load, then call set_torque(True)'
            + hint)
        self.events.event((s.joint.servo_id, 'torque'), 'warning',
                          f'{s.joint.name} (id {s.joint.servo_id}) {s.health.torque_lost}')

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

    def _note_back_drive(self) -> None:
        """Note the Present Current models on the bus that have no gear efficiency (their
        table's is 1) when the bus was given none: a servo its load back-drives reads the
        motor's torque, eta^2 of the joint's (see the module doc). Each model once, with its
        IDs: at open, and for a servo identified later."""
        if self.gear_efficiency is not None:
            return
        ids: dict[str, list[int]] = {}
        for s in self.servos:
            t = s.table
            if (t is not None and 'present_current' in t.registers and t.gear_efficiency >= 1.0
                    and t.model_name not in self._back_drive_noted):
                ids.setdefault(t.model_name, []).append(s.joint.servo_id)
        if not ids:
            return
        self._back_drive_noted.update(ids)
        which = ', '.join(f'{m} (id{"s" if len(v) > 1 else ""} {", ".join(map(str, v))})'
                          for m, v in ids.items())
        self.notes.append(
            f'{which}: no gear efficiency is known for '
            f'{"this model" if len(ids) == 1 else "these models"}, so the efforts from Present '
            'Current get no back-drive correction: a joint its load back-drives (a leg lowering '
            "its weight) reads the motor's torque, eta^2 of the joint's (0.55 at eta 0.74); "
            "give the driver your servos' gear_efficiency (-p gear_efficiency:=ETA; the "
            "XM430-W350's servo model has 0.739) to divide every servo's back-driven effort by "
            'ETA^2')

    def take_notes(self) -> list[str]:
        """The bus events noted since the last call (each returned once)."""
        out, self.notes = self.notes, []
        return out

    def take_events(self) -> list[tuple[str, str]]:
        """Run-time transitions due for the log, as (level, message), level 'warning' or
        'info'; once per transition, throttled (:class:`EventLog`)."""
        return self.events.take()

    def poll(self) -> PollResult:
        """read_all() then the temperature safety check (torque off and abort)."""
        start = time.monotonic()
        readings = self.read_all()
        if self.rate is not None:
            line = self.rate.tick(start, 1000.0 * (time.monotonic() - start), len(self.servos))
            if line is not None:
                self.events.event('rate', *line)
        hot = [r for r in readings if r.ok and (r.temperature_c > self.temperature_limit_c
                                                or r.error_flags & ERROR_OVERHEATING)]
        if not hot or self.aborted:
            return PollResult(readings)
        # The overheating servos first, then the rest: each write is a round trip.
        order = [r.name for r in hot] + [n for n in self.joint_names
                                         if n not in {r.name for r in hot}]
        self.set_torque(False, order)
        self.aborted = True
        self.abort_reason = '; '.join(self._hot_reason(r) for r in hot) + (
            ': torque off, aborted')
        return PollResult(readings, True, self.abort_reason)

    def _hot_reason(self, r: ServoReading) -> str:
        """Why ``r`` triggers the abort: above the limit, or the servo's overheating flag."""
        why = []
        if r.temperature_c > self.temperature_limit_c:
            why.append(f'at {r.temperature_c:.0f} degC > limit {self.temperature_limit_c:.0f} '
                       'degC')
        elif r.temperature_c >= self.temperature_limit_c:
            why.append(f'at {r.temperature_c:.0f} degC, not below the limit '
                       f'{self.temperature_limit_c:.0f} degC')
        if r.error_flags & ERROR_OVERHEATING:
            why.append(f'reports overheating (flags '
                       f'{list(decode_error_flags(self.protocol, r.error_flags))}) at '
                       f'{r.temperature_c:.0f} degC (limit {self.temperature_limit_c:.0f} degC)')
        return f'{r.name} (id {r.servo_id}) ' + ' and '.join(why)

    # --- writing ---------------------------------------------------------------------------
    def set_torque(self, enabled: bool, names: Iterable[str] | None = None, *,
                   stop: Callable[[], bool] | None = None) -> dict[str, bool]:
        """Torque Enable on (True) or off for ``names`` (all by default); per-joint success.

        Turning torque on clears an abort only once every servo that answers is below the
        limit and none reports its overheating flag; else nothing is written and
        ``abort_reason`` says which servo keeps the abort. Nothing is written once the port is
        lost (all False).

        ``stop``: asked before each servo's write; once it returns True nothing more is
        written (a stop requested during the torque-on pass at start-up: Ctrl-C, SIGTERM), the
        servos not written are False and named in :attr:`not_written`.
        """
        self.not_written = []
        if not self.is_open:
            return {n: False for n in (names if names is not None else self.joint_names)}
        with self._port_guard():
            return self._set_torque(enabled, names, stop)

    def _write_acked(self, s: _Servo, write: Callable[[int], int]) -> tuple[int, int]:
        """One write to ``s`` (``write(servo_id)`` sends it, no reply awaited) and, at Status
        Return Level 2, its status packet: (result, status error); a failure is counted."""
        sid = s.joint.servo_id
        self._prepare([sid])
        result = write(sid)
        error = 0
        if result == COMM_SUCCESS and s.health.status_return_level >= 2:
            self.port.setPacketTimeout(self._status_bytes(0))
            _ack, error, result = self._receive(sid, 0)
        if result != COMM_SUCCESS:
            self._count(s, result)
        return result, error

    def _set_torque(self, enabled: bool, names: Iterable[str] | None,
                    stop: Callable[[], bool] | None = None) -> dict[str, bool]:
        if enabled and self.aborted:
            readings = self._read_all()
            hot = [r for r in readings if r.ok and (r.temperature_c >= self.temperature_limit_c
                                                    or r.error_flags & ERROR_OVERHEATING)]
            if hot:
                self.abort_reason = '; '.join(self._hot_reason(r) for r in hot) + (
                    ': torque on refused, still aborted (every servo must be below the limit '
                    'with its overheating flag cleared)')
                return {n: False for n in (names if names is not None else self.joint_names)}
            self.aborted = False
            self.abort_reason = ''
        out = {}
        for name in (names if names is not None else self.joint_names):
            s = self._by_name[name]
            if stop is not None and (self.not_written or stop()):
                self.not_written.append(name)
                out[name] = False
                continue
            if s.table is None:
                out[name] = False
                continue
            if enabled and s.command_refusal:
                s.health.torque_error = s.command_refusal
                out[name] = False
                continue
            ok = False
            limit_stuck = False     # Protocol 1.0 Torque Limit stayed 0 after it was written
            s.health.torque_error = ''
            g0, n0 = s.health.streak_garbled, s.health.streak_no_reply
            for k in range(1 + self.retries):
                if k:
                    s.health.retries += 1
                address = s.table.reg('torque_enable').address
                value = int(bool(enabled))
                s.written = True
                result, error = self._write_acked(s, lambda sid: self.packet.write1ByteTxOnly(
                    self.port, sid, address, value))
                if result != COMM_SUCCESS:
                    continue
                if enabled or s.health.status_return_level < 2:
                    # Torque on is read back at every level (a servo in hardware-error
                    # shutdown acknowledges the write and keeps Torque Enable 0); torque off
                    # only where the write is not acknowledged (Status Return Level 1).
                    # Protocol 1.0 torque on: up to Torque Limit (24-35, one READ)
                    p1_limit = self._p1_torque_limit(s) if enabled else None
                    end = (address + 1 if p1_limit is None
                           else p1_limit.address + p1_limit.size)
                    data, read_error = self._read_single(s, address, end - address, 1)
                    if data is None:
                        continue  # the read-back was counted
                    if data[0] != value:
                        flags = self._hardware_flags(s, error | read_error)
                        if flags:
                            self._refuse_torque(s, flags)
                            break
                        continue  # the write was lost: send it again
                    seen = (s.table.decode('torque_limit', data, address)
                            if p1_limit is not None else None)
                    if seen:
                        s.torque_limit_seen = seen
                    if seen == 0:
                        restored = self._restore_torque_limit(s, error | read_error)
                        limit_stuck = restored is None
                        if restored is None:
                            continue    # not confirmed: the whole write again
                        if not restored:
                            break       # refused, torque_error says why
                ok = True
                break
            if ok:
                s.health.torque_enabled = bool(enabled)
                s.health.torque_lost = ''
            elif not s.health.torque_error:
                garbled = s.health.streak_garbled - g0
                silent = s.health.streak_no_reply - n0
                if garbled > silent:
                    why = ('the replies came garbled (broken checksums): a second servo at '
                           'this ID?')
                elif silent:
                    why = 'no reply'
                elif limit_stuck:
                    why = ('Torque Limit (register 34) still reads 0 after Max Torque was '
                           'written to it (Alarm Shutdown)')
                else:
                    why = 'Torque Enable did not read back as written'
                state = 'on' if enabled else 'off'
                s.health.torque_error = f'torque {state} not confirmed: {why}'
            out[name] = ok
        return out

    def torque_off_at_shutdown(self) -> TorqueOffReport:
        """Torque off on every servo, as at shutdown, reported by joint (:class:`TorqueOffReport`):
        a servo left out at Status Return Level 0 whose model is known gets Torque Enable 0
        without waiting for a reply; other left-out servos are not written. Never raises for
        the port (its failure is in ``port_error``)."""
        try:
            result = self.set_torque(False)
        except PortLostError as err:
            return TorqueOffReport(port_error=str(err))
        confirmed, unconfirmed, blind, never = [], [], [], []
        for s in self.servos:
            name = s.joint.name
            if s.table is not None:
                (confirmed if result.get(name) else unconfirmed).append(name)
            elif s.level0_table is not None and self._torque_off_blind(s):
                blind.append(name)
            elif s.written:
                unconfirmed.append(name)   # e.g. another model answers at its ID since
            else:
                never.append(name)
        return TorqueOffReport(tuple(confirmed), tuple(unconfirmed), tuple(blind), tuple(never))

    def _torque_off_blind(self, s: _Servo) -> bool:
        """Torque Enable 0 to a servo at Status Return Level 0 (no reply): True when sent."""
        assert s.level0_table is not None
        if not self.is_open:
            return False
        try:
            with self._port_guard():
                sid = s.joint.servo_id
                self._prepare([sid])
                address = s.level0_table.reg('torque_enable').address
                return bool(self.packet.write1ByteTxOnly(self.port, sid, address, 0)
                            == COMM_SUCCESS)
        except PortLostError:
            return False

    def _restore_torque_limit(self, s: _Servo, status_error: int) -> bool | None:
        """A Protocol 1.0 servo whose Torque Limit reads 0 at torque on (an Alarm Shutdown,
        e-Manual, Torque Limit 34: the servo stays limp with Torque Enable 1 until a non-zero
        value is written): Torque Limit written back from Max Torque (14, EEPROM, its power-on
        value) and read back; a lower Torque Limit read before the shutdown (set by hand) is
        written back instead (it was replaced by Max Torque). True restored (noted); False
        refused, ``torque_error`` says why (Max Torque 0 too, or the error still on); None not
        confirmed (tried again)."""
        assert s.table is not None
        limit, top = s.table.reg('torque_limit'), s.table.reg('max_torque')
        name = f'{s.joint.name} (id {s.joint.servo_id})'
        data, err = self._read_single(s, top.address, top.size, 1 + self.retries)
        if data is None:
            return None
        max_torque = s.table.decode('max_torque', data, top.address)
        if max_torque == 0:
            s.health.torque_error = (
                f'torque on refused: Torque Limit (register {limit.address}) reads 0 (Alarm '
                f'Shutdown, or set so) and Max Torque (register {top.address}, EEPROM), its '
                'power-on value, is 0 too: the servo would stay limp; set Max Torque, e.g. with '
                'Dynamixel Wizard (this driver never writes EEPROM)')
            self.notes.append(f'{name} {s.health.torque_error}')
            return False
        value = min(s.torque_limit_seen, max_torque) if s.torque_limit_seen else max_torque
        result, error = self._write_acked(s, lambda sid: self.packet.write2ByteTxOnly(
            self.port, sid, limit.address, value))
        if result != COMM_SUCCESS:
            return None
        data, read_error = self._read_single(s, limit.address, limit.size, 1)
        if data is None:
            return None
        if s.table.decode('torque_limit', data, limit.address):
            to = (f'Max Torque {max_torque} (register {top.address})' if value == max_torque
                  else f'{value}, its value before (Max Torque {max_torque})')
            self.notes.append(f'{name} Torque Limit (register {limit.address}) read 0 (a '
                              f'Protocol 1.0 Alarm Shutdown): written back to {to}')
            return True
        flags = self._hardware_flags(s, status_error | err | error | read_error)
        if flags:
            self._refuse_torque(s, flags, f'Torque Limit (register {limit.address}) stays 0')
            return False
        return None

    def _refuse_torque(self, s: _Servo, flags: int, held: str = '') -> None:
        """The servo keeps torque off with a hardware error: recorded and noted."""
        s.health.last_error_flags = flags
        s.health.error_replies += 1
        if self.protocol == 2:
            why = (f'Hardware Error Status {flags:#04x} '
                   f'{list(decode_error_flags(self.protocol, flags))}: an X-series or MX(2.0) '
                   'servo in hardware-error shutdown keeps torque off until it is rebooted '
                   '(REBOOT instruction, e.g. Dynamixel Wizard, or a power cycle) once the '
                   'cause is gone')
        else:
            why = (f'status error {flags:#04x} {list(decode_error_flags(self.protocol, flags))}: '
                   'the servo keeps torque off while the error lasts (Alarm Shutdown'
                   + (f'; {held}' if held else '') + ')')
        s.health.torque_error = f'torque on refused by the servo: {why}'
        self.notes.append(f'{s.joint.name} (id {s.joint.servo_id}) {s.health.torque_error}')

    def write_goals(self, positions_rad: Mapping[str, float],
                    speeds_rad_s: Mapping[str, float] | None = None) -> int:
        """Sync Write goal positions (joint frame) and, if given, moving speeds; 0 if aborted.

        Unknown names, non-finite values and servos whose commands are refused (Operating
        Mode, see :attr:`refused`) are skipped. Goals are clipped to the servo's limits read
        at open (Protocol 1.0 CW/CCW Angle Limit, 2.0 Min/Max Position Limit in position
        mode), else one turn, or to +-1 048 575 ticks in the multi-turn modes 4 and 5; a
        clipped goal is counted and said (:meth:`_clip_goal`). A speed of 0 means 'as fast as
        possible' (the servos' own convention). Returns the number of servos written.
        """
        if self.aborted or not self.is_open:
            return 0
        with self._port_guard():
            return self._write_goals(positions_rad, speeds_rad_s)

    def _write_goals(self, positions_rad: Mapping[str, float],
                     speeds_rad_s: Mapping[str, float] | None) -> int:
        groups: dict[tuple[int, int], GroupSyncWrite] = {}
        count = 0
        unknown = sorted(set(positions_rad) - set(self._by_name)
                         - self.unknown_command_names)
        if unknown:
            # said once per new name: a gait node at another leg_count or a typo in the joint
            # map (L1_femor) left joints uncommanded without a word (a quadruped review)
            self.unknown_command_names.update(unknown)
            missing = sorted(set(self._by_name) - set(positions_rad))
            self.notes.append(
                f'joint_commands name joint(s) not in the joint map, ignored: {unknown}'
                + (f'; the map\'s joints without a command there: {missing}' if missing
                   else '') + ' (the gait node\'s leg_count, or the names in joints_file?)')
        for name, target in positions_rad.items():
            s = self._by_name.get(name)
            if (s is None or s.table is None or s.command_refusal
                    or not math.isfinite(target)):
                continue
            t = s.table
            multi_turn = s.health.operating_mode in MULTI_TURN_MODES
            goal = t.encode('goal_position', self._clip_goal(s, target, multi_turn))
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
            s.written = True
            count += 1
        for group in groups.values():
            self._prepare()   # never talk over a late reply (a collision on the half-duplex line)
            group.txPacket()
        return count
