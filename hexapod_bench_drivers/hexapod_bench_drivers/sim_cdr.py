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


def battery_state(t_ns: int, voltage_v: float, current_a: float, *, status: int,
                  technology: int = 3, frame_id: str = '') -> bytes:
    """sensor_msgs/msg/BatteryState with unknown (NaN) temperature, charge and capacities."""
    nan = float('nan')
    b = CdrBuffer()
    b.header(t_ns, frame_id)
    b.pack('fffffff', 4, voltage_v, nan, current_a, nan, nan, nan, nan)
    b.pack('BBB?', 1, status, 1, technology, True)
    b.array((), 'f4')
    b.array((), 'f4')
    b.string('')
    b.string('')
    return b.bytes()


def gait_phase(t_ns: int, gait: str, period_s: float, duty_factor: float, step_length_m: float,
               step_height_m: float, cycle_phase: float, leg_names: Sequence[str],
               phase_offsets: ArrayLike, in_stance: ArrayLike, supporting_legs: int,
               sweep_angle_rad: float = 0.0, leg_offset_rad: float = 0.0) -> bytes:
    """hexapod_interfaces/msg/GaitPhase."""
    b = CdrBuffer()
    b.header(t_ns, '')
    b.string(gait)
    b.pack('dddddd', 8, period_s, duty_factor, step_length_m, step_height_m, sweep_angle_rad,
           leg_offset_rad)
    b.pack('d', 8, cycle_phase)
    b.strings(leg_names)
    b.array(phase_offsets, 'f8')
    b.array(np.asarray(in_stance, dtype=bool).view(np.uint8), 'u1')
    b.pack('B', 1, supporting_legs)
    return b.bytes()


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
