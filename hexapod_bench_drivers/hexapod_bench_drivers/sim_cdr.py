"""Fast little-endian CDR encoding of the simulators' high-rate messages.

rosbags' generic serializer costs about a millisecond per message on a loaded machine, which
would keep the batch simulators below real time. These encoders write the same bytes as
``Typestore.serialize_cdr`` (checked in ``test_sim_bag.py``) for the fixed ROS 2 types the
simulators publish, with numpy doing the array packing.
"""

from __future__ import annotations

import struct
from collections.abc import Sequence
from functools import lru_cache

import numpy as np
from numpy.typing import ArrayLike

__all__ = ['CdrBuffer', 'battery_state', 'gait_phase', 'joint_state', 'point_stamped',
           'servo_status', 'wrench_stamped']

_HEADER = b'\x00\x01\x00\x00'


class CdrBuffer:
    """Append-only CDR payload with alignment relative to the payload start."""

    __slots__ = ('parts', 'pos')

    def __init__(self) -> None:
        self.parts: list[bytes] = [_HEADER]
        self.pos = 0

    def align(self, size: int) -> None:
        pad = -self.pos % size
        if pad:
            self.parts.append(b'\x00' * pad)
            self.pos += pad

    def raw(self, data: bytes) -> None:
        self.parts.append(data)
        self.pos += len(data)

    def pack(self, fmt: str, size: int, *values: object) -> None:
        self.align(size)
        self.raw(struct.pack('<' + fmt, *values))

    def string(self, text: str) -> None:
        data = text.encode('utf-8') + b'\x00'
        self.pack('I', 4, len(data))
        self.raw(data)

    def strings(self, texts: Sequence[str]) -> None:
        self.pack('I', 4, len(texts))
        for text in texts:
            self.string(text)

    def array(self, values: ArrayLike, dtype: str) -> None:
        arr = np.ascontiguousarray(values, dtype=dtype)
        self.pack('I', 4, arr.size)
        if arr.size:
            self.align(arr.dtype.itemsize)
            self.raw(arr.astype(arr.dtype.newbyteorder('<'), copy=False).tobytes())

    def header(self, t_ns: int, frame_id: str) -> None:
        self.pack('iI', 4, int(t_ns // 1_000_000_000), int(t_ns % 1_000_000_000))
        self.string(frame_id)

    def bytes(self) -> bytes:
        return b''.join(self.parts)


@lru_cache(maxsize=64)
def _prefix(names: tuple[str, ...], frame_id: str) -> tuple[bytes, int]:
    """Encoded ``frame_id`` and name list after the stamp, and the payload offset at its end."""
    b = CdrBuffer()
    b.pack('iI', 4, 0, 0)
    b.string(frame_id)
    b.strings(names)
    return b.bytes()[12:], b.pos


_PAD = tuple(b'\x00' * i for i in range(8))
_STAMP = struct.Struct('<iI')
_U32 = struct.Struct('<I')
_NAN = float('nan')
#: BatteryState from ``voltage`` to ``present`` (4-aligned after the header's frame_id)
_BATTERY_FIELDS = struct.Struct('<fffffffBBB?')
#: GaitPhase's period, duty factor, step length and height, sweep and leg-offset angles and
#: cycle phase (8-aligned)
_GAIT_NUMBERS = struct.Struct('<ddddddd')
_U8 = struct.Struct('<B')


def joint_state(t_ns: int, names: Sequence[str], position: ArrayLike, velocity: ArrayLike,
                effort: ArrayLike, frame_id: str = '') -> bytes:
    """sensor_msgs/msg/JointState (the name block is cached: the hot path of the bags)."""
    prefix, pos = _prefix(tuple(names), frame_id)
    parts = [_HEADER, _STAMP.pack(int(t_ns // 1_000_000_000), int(t_ns % 1_000_000_000)),
             prefix]
    for values in (position, velocity, effort):
        arr = np.asarray(values, dtype='<f8')
        pad = -pos % 4
        parts.append(_PAD[pad])
        parts.append(_U32.pack(arr.size))
        pos += pad + 4
        if arr.size:
            pad = -pos % 8
            parts.append(_PAD[pad])
            data = arr.tobytes()
            parts.append(data)
            pos += pad + len(data)
    return b''.join(parts)


@lru_cache(maxsize=64)
def _battery_blocks(frame_id: str) -> tuple[bytes, bytes]:
    """BatteryState's encoded ``frame_id`` (after the stamp, padded to the 4-aligned
    ``voltage``) and its constant tail (the empty cell arrays, location and serial number)."""
    b = CdrBuffer()
    b.pack('iI', 4, 0, 0)
    b.string(frame_id)
    b.align(4)
    head = b.bytes()[12:]
    b = CdrBuffer()
    b.pos = 4     # after the 4-aligned 'fffffffBBB?' block: only the position mod 4 counts
    b.array((), 'f4')
    b.array((), 'f4')
    b.string('')
    b.string('')
    return head, b.bytes()[4:]


def battery_state(t_ns: int, voltage_v: float, current_a: float, *, status: int,
                  technology: int = 3, frame_id: str = '') -> bytes:
    """sensor_msgs/msg/BatteryState with unknown (NaN) temperature, charge and capacities
    (the same bytes as :class:`CdrBuffer` field by field; the constant parts cached)."""
    head, tail = _battery_blocks(frame_id)
    nan = _NAN
    return b''.join((_HEADER, _STAMP.pack(int(t_ns // 1_000_000_000),
                                          int(t_ns % 1_000_000_000)), head,
                     _BATTERY_FIELDS.pack(voltage_v, nan, current_a, nan, nan, nan, nan,
                                          status, 1, technology, True), tail))


@lru_cache(maxsize=64)
def _gait_blocks(gait: str, leg_names: tuple[str, ...], n_offsets: int,
                 n_stance: int) -> tuple[bytes, bytes, bytes]:
    """GaitPhase's constant parts around its numbers: the header's empty frame_id and the gait
    name (padded to the 8-aligned period); the leg names and the offsets' count (padded to
    their 8-aligned values); the in-stance flags' count. Every block starts and ends where
    the message's own alignment puts it, so the blocks and the numbers join into the bytes
    :class:`CdrBuffer` writes field by field."""
    b = CdrBuffer()
    b.pack('iI', 4, 0, 0)
    b.string('')
    b.string(gait)
    b.align(8)
    head = b.bytes()[12:]
    b = CdrBuffer()
    b.pos = 8     # after the 8-aligned numbers: only the position mod 8 counts
    b.strings(leg_names)
    b.pack('I', 4, n_offsets)
    if n_offsets:
        b.align(8)
    names = b.bytes()[4:]
    b = CdrBuffer()
    # after the offsets' 8-byte values (ending 8-aligned), or after their count if none
    b.pos = 8 + (0 if n_offsets else len(names) % 8)
    b.pack('I', 4, n_stance)
    return head, names, b.bytes()[4:]


def gait_phase(t_ns: int, gait: str, period_s: float, duty_factor: float, step_length_m: float,
               step_height_m: float, cycle_phase: float, leg_names: Sequence[str],
               phase_offsets: ArrayLike, in_stance: ArrayLike, supporting_legs: int,
               sweep_angle_rad: float = 0.0, leg_offset_rad: float = 0.0) -> bytes:
    """hexapod_interfaces/msg/GaitPhase (the same bytes as :class:`CdrBuffer` field by field;
    the names and counts, constant along a trace, cached)."""
    offsets = np.ascontiguousarray(phase_offsets, dtype='<f8')
    stance = np.ascontiguousarray(np.asarray(in_stance, dtype=bool).view(np.uint8),
                                  dtype='u1')
    head, names, count = _gait_blocks(gait, tuple(leg_names), offsets.size, stance.size)
    return b''.join((_HEADER, _STAMP.pack(int(t_ns // 1_000_000_000),
                                          int(t_ns % 1_000_000_000)), head,
                     _GAIT_NUMBERS.pack(period_s, duty_factor, step_length_m, step_height_m,
                                        sweep_angle_rad, leg_offset_rad, cycle_phase),
                     names, offsets.tobytes(), count, stance.tobytes(),
                     _U8.pack(supporting_legs)))


def servo_status(t_ns: int, names: Sequence[str], temperature_c: ArrayLike,
                 voltage_v: ArrayLike, load: ArrayLike, error: ArrayLike) -> bytes:
    """hexapod_interfaces/msg/ServoStatus."""
    b = CdrBuffer()
    b.header(t_ns, '')
    b.strings(names)
    b.array(temperature_c, 'f4')
    b.array(voltage_v, 'f4')
    b.array(load, 'f4')
    b.array(error, 'u1')
    return b.bytes()


def wrench_stamped(t_ns: int, force_n: Sequence[float], torque_nm: Sequence[float],
                   frame_id: str) -> bytes:
    """geometry_msgs/msg/WrenchStamped."""
    b = CdrBuffer()
    b.header(t_ns, frame_id)
    b.pack('dddddd', 8, *force_n, *torque_nm)
    return b.bytes()


def point_stamped(t_ns: int, point_m: Sequence[float], frame_id: str) -> bytes:
    """geometry_msgs/msg/PointStamped."""
    b = CdrBuffer()
    b.header(t_ns, frame_id)
    b.pack('ddd', 8, *point_m)
    return b.bytes()
