"""Message <-> frozen dataclass conversions, one per message type.

Only attribute access and ``np.asarray``, so each converter serves rclpy messages (live) and
rosbags-decoded messages (offline) alike. Times are float seconds from ``header.stamp``.

Joint names outside the contract (DESIGN section 4: ``L1..Lk``/``R1..Rk`` legs, ``<leg>_hip``,
``<leg>_coxa``...), e.g. a PhantomX's ``j_c1_lf`` or a RHex's ``hip_0``, are renamed by
:func:`joint_state_from_msg` through a process-wide joint map: the environment variable
``HEXAPOD_JOINT_MAP`` (JSON ``{"recorded name": "contract name"}``), set by
``hexapod-analyze --joint-map FROM:=TO ...`` (and inherited by its ``--jobs`` workers; a live
node started with the variable set reads the same names). Names not in the map pass unchanged.
"""

from __future__ import annotations

import json
import math
import os
import re
from dataclasses import dataclass
from functools import lru_cache, wraps
from typing import Any, Callable, TypeVar

import numpy as np

__all__ = [
    'BatterySample',
    'GaitPhaseSample',
    'JOINT_MAP_ENV',
    'MOCAP_TF_ENV',
    'MOCAP_TYPES',
    'JointStateSample',
    'PoseSample',
    'ServoStatusSample',
    'WrenchSample',
    'PointSample',
    'battery_from_msg',
    'battery_source',
    'current_sign_factor',
    'gait_phase_from_msg',
    'gait_phase_problem',
    'joint_map',
    'joint_state_from_msg',
    'parse_joint_map',
    'parse_mocap_tf',
    'pick_transform',
    'point_from_msg',
    'pose_from_msg',
    'servo_status_from_msg',
    'stamp_to_s',
    's_to_stamp',
    'wrench_from_msg',
]


def current_sign_factor(voltage_v: Any, current_a: Any, mode: str) -> float:
    """Factor s such that input power P_in = s * V * I.

    ``mode``: ``'ros'`` (sensor_msgs/BatteryState: current negative while discharging, s = -1),
    ``'positive_discharge'`` (s = +1, some drivers) or ``'auto'`` (the sign that makes the
    median V * I over the finite samples a positive input power; the median, so that a few
    regenerative or glitch samples do not decide it). Raises ValueError on another mode.
    """
    if mode == 'ros':
        return -1.0
    if mode == 'positive_discharge':
        return 1.0
    if mode != 'auto':
        raise ValueError(f'current sign must be ros, positive_discharge or auto, got {mode!r}')
    vi = np.asarray(voltage_v, dtype=float) * np.asarray(current_a, dtype=float)
    vi = vi[np.isfinite(vi)]
    return -1.0 if vi.size == 0 or float(np.median(vi)) <= 0 else 1.0


_Conv = TypeVar('_Conv', bound=Callable[..., Any])


def _of_type(kind: str) -> Callable[[_Conv], _Conv]:
    """A converter whose message lacks a field it reads raises ValueError naming the type
    expected (the message is dropped and counted like a NaN one), not AttributeError: a bag
    that records a contract topic as another type (``/battery_state`` as std_msgs/Float64, a
    lab's own joint message) ended offline in "failed: AttributeError ... please report it",
    exit 1 (an outside review). Live subscriptions are typed and never see one."""
    def wrap(fn: _Conv) -> _Conv:
        @wraps(fn)
        def conv(msg: Any, *args: Any, **kw: Any) -> Any:
            try:
                return fn(msg, *args, **kw)
            except AttributeError as err:
                field = getattr(err, 'name', None) or str(err)
                name = getattr(msg, '__msgtype__', None) or type(msg).__name__
                raise ValueError(f'{name} is not a {kind} (no field {field!r})') from None
        return conv  # type: ignore[return-value]
    return wrap


def stamp_to_s(stamp: Any) -> float:
    """``builtin_interfaces/Time`` -> seconds."""
    return float(stamp.sec) + 1e-9 * float(stamp.nanosec)


def s_to_stamp(t_s: float) -> tuple[int, int]:
    """Seconds -> (sec, nanosec), rounded to the nanosecond."""
    ns = int(round(t_s * 1e9))
    return ns // 1_000_000_000, ns % 1_000_000_000


@dataclass(frozen=True)
class JointStateSample:
    """``sensor_msgs/JointState``: positions [rad], velocities [rad/s], efforts [N m].

    Arrays have one entry per name; a missing field (empty in the message) is an empty array.
    """

    t_s: float
    names: tuple[str, ...]
    position: np.ndarray
    velocity: np.ndarray
    effort: np.ndarray
    #: what :func:`joint_state_from_msg` left out ('' when nothing): a velocity or effort
    #: array of another length than the names
    malformed: str = ''


#: Environment variable holding the process-wide joint-name map (JSON object, see module doc).
JOINT_MAP_ENV = 'HEXAPOD_JOINT_MAP'


def parse_joint_map(items: Any) -> dict[str, str]:
    """``['hip_0:=L1_hip', ...]`` -> ``{'hip_0': 'L1_hip', ...}``; ValueError on a malformed
    item, a name mapped twice or two names mapped to one."""
    out: dict[str, str] = {}
    for item in items:
        src, sep, dst = str(item).partition(':=')
        if not sep or not src.strip() or not dst.strip():
            raise ValueError(f'a joint map item is FROM:=TO (recorded joint name := contract '
                             f'name, e.g. hip_0:=L1_hip), got {item!r}')
        src, dst = src.strip(), dst.strip()
        if src in out and out[src] != dst:
            raise ValueError(f'joint {src!r} mapped twice ({out[src]!r}, {dst!r})')
        out[src] = dst
    targets = list(out.values())
    dup = sorted({t for t in targets if targets.count(t) > 1})
    if dup:
        raise ValueError(f'joint map sends several names to {dup}')
    return out


@lru_cache(maxsize=8)
def _joint_map_from(text: str) -> tuple[tuple[str, str], ...]:
    try:
        doc = json.loads(text)
        if not isinstance(doc, dict):
            raise ValueError('not an object')
        pairs = parse_joint_map([f'{k}:={v}' for k, v in doc.items()])
    except ValueError as err:
        raise ValueError(f'{JOINT_MAP_ENV} is not a JSON object of joint names '
                         f'{{"recorded": "contract"}}: {err}') from None
    return tuple(pairs.items())


def joint_map() -> dict[str, str]:
    """The process-wide joint-name map (empty when ``HEXAPOD_JOINT_MAP`` is unset)."""
    text = os.environ.get(JOINT_MAP_ENV, '')
    return dict(_joint_map_from(text)) if text else {}


@_of_type('JointState')
def joint_state_from_msg(msg: Any) -> JointStateSample:
    """Convert a JointState; raises ValueError when the positions' length disagrees with the
    names. A velocity or effort array of another length (a driver filling efforts for some
    joints only) is left out, empty, and said in ``malformed``: the positions still give the
    gait cycles (the whole message used to be dropped, and a robot without /gait/phase got no
    window at all).

    Names are renamed through the process-wide joint map (module doc) when it is set.
    """
    names = tuple(msg.name)
    text = os.environ.get(JOINT_MAP_ENV)
    if text:
        mapping = dict(_joint_map_from(text))
        names = tuple(mapping.get(n, n) for n in names)
    arrays = []
    bad = []
    for field in ('position', 'velocity', 'effort'):
        arr = np.asarray(getattr(msg, field), dtype=float)
        if arr.size not in (0, len(names)):
            what = f'JointState.{field} has {arr.size} values for {len(names)} names'
            if field == 'position':
                raise ValueError(what)
            bad.append(what)
            arr = np.zeros(0)
        arrays.append(arr)
    return JointStateSample(stamp_to_s(msg.header.stamp), names, *arrays,
                            malformed='; '.join(bad) + ': left out' if bad else '')


@dataclass(frozen=True)
class BatterySample:
    """``sensor_msgs/BatteryState`` as measured: voltage [V], current [A] in the message's sign;
    ``source``: which battery (``header.frame_id``, else ``location``, else ``serial_number``;
    several on one topic are summed by :mod:`hexapod_common.battery`); ``present``: the
    message's ``present`` (False: no battery there, see
    :class:`hexapod_common.battery.AbsentBatteryFilter`)."""

    t_s: float
    voltage_v: float
    current_a: float
    temperature_c: float
    source: str = ''
    present: bool = True


#: a current [A] at or above which a 0 V battery sample is a glitch, not a supply switched off
#: (the simulated bench's supply reads 0 V and +-10 mA of noise while cooling: 0 W, kept)
ZERO_VOLT_CURRENT_A = 0.1


@_of_type('BatteryState')
def battery_from_msg(msg: Any) -> BatterySample:
    """Convert a BatteryState; NaN voltage or current raise ValueError, and so does a voltage
    no battery delivers power at: below 0 V, or 0 V while a current of
    :data:`ZERO_VOLT_CURRENT_A` or more flows (a monitor's glitch or a driver filling 0 for
    "unknown"; counted, one sample in 10 at -V read P_in -21 %, at 0 V -10 %, silently: an
    outside review). 0 V and 0 A together pass (an absent battery,
    :class:`hexapod_common.battery.AbsentBatteryFilter`)."""
    v, i = float(msg.voltage), float(msg.current)
    if not (math.isfinite(v) and math.isfinite(i)):
        raise ValueError(f'BatteryState without voltage/current (voltage={v}, current={i})')
    if v < 0.0 or (v == 0.0 and abs(i) >= ZERO_VOLT_CURRENT_A):
        raise ValueError(f'BatteryState with voltage {v} V (current {i} A): not a battery '
                         'voltage (a pack delivers power above 0 V)')
    return BatterySample(stamp_to_s(msg.header.stamp), v, i, float(msg.temperature),
                         battery_source(msg), bool(getattr(msg, 'present', True)))


def battery_source(msg: Any) -> str:
    """Which battery a BatteryState reports: ``header.frame_id``, else ``location``, else
    ``serial_number`` ('' when all are empty)."""
    for value in (getattr(msg.header, 'frame_id', ''), getattr(msg, 'location', ''),
                  getattr(msg, 'serial_number', '')):
        if value:
            return str(value)
    return ''


@dataclass(frozen=True)
class GaitPhaseSample:
    """``hexapod_interfaces/GaitPhase``."""

    t_s: float
    gait: str
    period_s: float
    duty_factor: float
    step_length_m: float
    step_height_m: float
    sweep_angle_rad: float
    leg_offset_rad: float
    cycle_phase: float
    leg_names: tuple[str, ...]
    phase_offsets: np.ndarray
    in_stance: np.ndarray
    supporting_legs: int

    @property
    def speed_mps(self) -> float:
        """Nominal speed of the schedule, step_length / (beta T); 0 for a clock gait."""
        if self.period_s <= 0 or self.duty_factor <= 0:
            return 0.0
        return self.step_length_m / (self.duty_factor * self.period_s)


#: GaitPhase fields that must be finite numbers (a NaN period gives NaN speeds silently)
GAIT_PHASE_FINITE = ('period', 'duty_factor', 'step_length', 'step_height', 'sweep_angle',
                     'leg_offset', 'cycle_phase')


@_of_type('GaitPhase')
def gait_phase_from_msg(msg: Any) -> GaitPhaseSample:
    """Convert a GaitPhase; a non-finite number in :data:`GAIT_PHASE_FINITE` or in
    ``phase_offsets`` raises ValueError naming the field (the message is dropped), and so
    does a schedule no gait has (:func:`gait_phase_problem`)."""
    values = {name: float(getattr(msg, name)) for name in GAIT_PHASE_FINITE}
    bad = [f'{name}={v}' for name, v in values.items() if not math.isfinite(v)]
    offsets = np.asarray(msg.phase_offsets, dtype=float)
    if not np.all(np.isfinite(offsets)):
        bad.append(f'phase_offsets={offsets.tolist()}')
    if bad:
        raise ValueError(f'GaitPhase with non-finite {", ".join(bad)}')
    problem = gait_phase_problem(values, len(msg.leg_names), offsets.size)
    if problem:
        raise ValueError(f'GaitPhase with {problem}')
    return GaitPhaseSample(
        stamp_to_s(msg.header.stamp), str(msg.gait), values['period'],
        values['duty_factor'], values['step_length'], values['step_height'],
        values['sweep_angle'], values['leg_offset'], values['cycle_phase'],
        tuple(msg.leg_names), offsets,
        np.asarray(msg.in_stance, dtype=bool), int(msg.supporting_legs))


def gait_phase_problem(values: dict[str, float], n_legs: int, n_offsets: int) -> str:
    """What makes a GaitPhase's (finite) numbers a schedule no gait has, or ''.

    A negative period, step length or height, a walking period (> 0) with a duty factor
    outside (0, 1), no leg names, or phase offsets that are not one per leg. The offline
    readers refused such a bag (exit 2) while the live ``energy_monitor`` published from
    its messages: a duty factor 1.5 read the speed 0.067 m/s for 0.2 and specific
    resistance 19.7 for 6.6; a negative step length took the joint efforts the PWM test
    refuses (efficiency 0.396 for 0.013); no leg names read P_out 0 W and efficiency 0; a
    negative period was taken offline and live for a robot standing (P_out 0 W, speed 0,
    exit 0: an outside review). Now such a message is dropped like a NaN one, live and
    offline. A period of 0 is a standing schedule (any duty factor)."""
    period = values['period']
    if period < 0.0:
        return f'period {period} s < 0'
    if period > 0.0 and not 0.0 < values['duty_factor'] < 1.0:
        return f'duty_factor {values["duty_factor"]} outside (0, 1)'
    for name in ('step_length', 'step_height'):
        if values[name] < 0.0:
            return f'{name} {values[name]} m < 0'
    if n_legs == 0:
        return 'no leg_names'
    if n_offsets != n_legs:
        return f'{n_offsets} phase_offsets for {n_legs} leg_names'
    return ''


@dataclass(frozen=True)
class ServoStatusSample:
    """``hexapod_interfaces/ServoStatus``."""

    t_s: float
    names: tuple[str, ...]
    temperature_c: np.ndarray
    voltage_v: np.ndarray
    load: np.ndarray
    error: np.ndarray


@_of_type('ServoStatus')
def servo_status_from_msg(msg: Any) -> ServoStatusSample:
    """Convert a ServoStatus."""
    return ServoStatusSample(
        stamp_to_s(msg.header.stamp), tuple(msg.name),
        np.asarray(msg.temperature, dtype=float), np.asarray(msg.voltage, dtype=float),
        np.asarray(msg.load, dtype=float), np.asarray(msg.error, dtype=np.uint8))


@dataclass(frozen=True)
class PoseSample:
    """``geometry_msgs/PoseStamped``: position [m], orientation quaternion (x, y, z, w)."""

    t_s: float
    frame_id: str
    position_m: np.ndarray
    orientation_xyzw: np.ndarray


#: message types a motion-capture bridge publishes a body pose as (``/mocap/body``), by the
#: short names of the nodes' ``mocap_type`` parameter: PoseStamped (the contract; vrpn, mocap
#: bridges), TransformStamped (vicon_bridge), PoseWithCovarianceStamped, Odometry (bridges that
#: publish a rigid body as odometry)
MOCAP_TYPES = {
    'PoseStamped': 'geometry_msgs/msg/PoseStamped',
    'TransformStamped': 'geometry_msgs/msg/TransformStamped',
    'PoseWithCovarianceStamped': 'geometry_msgs/msg/PoseWithCovarianceStamped',
    'Odometry': 'nav_msgs/msg/Odometry',
}


#: environment variable naming the body pose to read from ``/tf`` (``PARENT:CHILD``), set by
#: ``hexapod-analyze --mocap-tf`` (inherited by its ``--jobs`` workers)
MOCAP_TF_ENV = 'HEXAPOD_MOCAP_TF'


def parse_mocap_tf(text: str) -> tuple[str, str]:
    """``'world:base_link'`` -> ``('world', 'base_link')`` (leading slashes of ROS 1 frame
    names dropped); ValueError naming the expected form."""
    parent, sep, child = str(text).partition(':')
    parent, child = parent.strip().lstrip('/'), child.strip().lstrip('/')
    if not sep or not parent or not child:
        raise ValueError(f'a motion-capture transform is PARENT:CHILD (e.g. world:base_link, '
                         f'the frames of /tf), got {text!r}')
    return parent, child


def pick_transform(msg: Any, parent: str, child: str) -> Any:
    """The TransformStamped of ``parent -> child`` in a ``tf2_msgs/TFMessage`` (frame names
    compared without leading slashes), or None."""
    for tr in msg.transforms:
        if (str(tr.header.frame_id).lstrip('/') == parent
                and str(tr.child_frame_id).lstrip('/') == child):
            return tr
    return None


@_of_type('body pose')
def pose_from_msg(msg: Any) -> PoseSample:
    """Convert a body pose: a PoseStamped (the contract), or the same pose as another
    motion-capture bridge publishes it (:data:`MOCAP_TYPES`): TransformStamped
    (``transform.translation/rotation``), PoseWithCovarianceStamped or Odometry
    (``pose.pose``). Raises ValueError for anything else."""
    if hasattr(msg, 'transform'):
        p, q = msg.transform.translation, msg.transform.rotation
    else:
        pose = getattr(msg, 'pose', None)
        if pose is not None and hasattr(pose, 'pose'):  # with covariance / odometry
            pose = pose.pose
        if pose is None or not hasattr(pose, 'position'):
            raise ValueError(f'{type(msg).__name__} is not a body pose (expected one of '
                             f'{", ".join(MOCAP_TYPES)})')
        p, q = pose.position, pose.orientation
    return PoseSample(stamp_to_s(msg.header.stamp), str(msg.header.frame_id),
                      np.array([p.x, p.y, p.z], dtype=float),
                      np.array([q.x, q.y, q.z, q.w], dtype=float))


@dataclass(frozen=True)
class WrenchSample:
    """``geometry_msgs/WrenchStamped``: force [N], torque [N m]."""

    t_s: float
    force_n: np.ndarray
    torque_nm: np.ndarray


def _stamp_or_zero(msg: Any) -> float:
    """The header stamp [s], 0 for a message without a header (std_msgs scalars: the
    reader stands the bag's receive time in for it)."""
    header = getattr(msg, 'header', None)
    return stamp_to_s(header.stamp) if header is not None else 0.0


@_of_type('force')
def wrench_from_msg(msg: Any) -> WrenchSample:
    """Convert a bench force: a WrenchStamped (the contract; F/T sensor drivers), or a load
    cell's normal force as a ``geometry_msgs/Vector3Stamped`` (the force vector) or a
    ``std_msgs/Float32``/``Float64`` (the normal force, as ``force.z``; no header: stamp 0).
    Raises ValueError for anything else."""
    zero = np.zeros(3)
    if hasattr(msg, 'wrench'):
        f, m = msg.wrench.force, msg.wrench.torque
        return WrenchSample(stamp_to_s(msg.header.stamp),
                            np.array([f.x, f.y, f.z], dtype=float),
                            np.array([m.x, m.y, m.z], dtype=float))
    if hasattr(msg, 'vector'):
        v = msg.vector
        return WrenchSample(_stamp_or_zero(msg), np.array([v.x, v.y, v.z], dtype=float), zero)
    if hasattr(msg, 'data') and np.ndim(msg.data) == 0:
        return WrenchSample(0.0, np.array([0.0, 0.0, float(msg.data)]), zero)
    raise ValueError(f'{type(msg).__name__} is not a force (expected WrenchStamped, '
                     'Vector3Stamped, Float32 or Float64)')


@dataclass(frozen=True)
class PointSample:
    """``geometry_msgs/PointStamped``: point [m]."""

    t_s: float
    point_m: np.ndarray


@_of_type('point')
def point_from_msg(msg: Any) -> PointSample:
    """Convert a tracked point: a PointStamped (the contract; a single marker), or the
    position of a PoseStamped, TransformStamped, PoseWithCovarianceStamped, Odometry (a rigid
    body on the leg tip) or Vector3Stamped. Raises ValueError for anything else."""
    if hasattr(msg, 'point'):
        p = msg.point
    elif hasattr(msg, 'vector'):
        p = msg.vector
    else:
        try:
            p = pose_from_msg(msg)
        except ValueError:
            raise ValueError(f'{type(msg).__name__} is not a point (expected PointStamped, '
                             'PoseStamped, TransformStamped, PoseWithCovarianceStamped, '
                             'Odometry or Vector3Stamped)') from None
        return PointSample(p.t_s, p.position_m)
    return PointSample(stamp_to_s(msg.header.stamp), np.array([p.x, p.y, p.z], dtype=float))


@dataclass(frozen=True)
class OdometrySample:
    """``nav_msgs/Odometry``: pose of ``child_frame_id`` in ``frame_id`` (position [m],
    orientation quaternion (x, y, z, w)) and twist in ``child_frame_id`` (linear [m/s],
    angular [rad/s])."""

    t_s: float
    frame_id: str
    child_frame_id: str
    position_m: np.ndarray
    orientation_xyzw: np.ndarray
    linear_velocity_mps: np.ndarray
    angular_velocity_rad_s: np.ndarray


@_of_type('Odometry')
def odometry_from_msg(msg: Any) -> OdometrySample:
    """Convert a nav_msgs/Odometry; a non-finite position raises ValueError."""
    p, q = msg.pose.pose.position, msg.pose.pose.orientation
    v, w = msg.twist.twist.linear, msg.twist.twist.angular
    position = np.array([p.x, p.y, p.z], dtype=float)
    if not np.all(np.isfinite(position)):
        raise ValueError(f'Odometry with a non-finite position {position.tolist()}')
    return OdometrySample(stamp_to_s(msg.header.stamp), str(msg.header.frame_id),
                          str(msg.child_frame_id), position,
                          np.array([q.x, q.y, q.z, q.w], dtype=float),
                          np.array([v.x, v.y, v.z], dtype=float),
                          np.array([w.x, w.y, w.z], dtype=float))


__all__ += ['OdometrySample', 'odometry_from_msg']


#: a leg joint's name in the contract (DESIGN: ``<leg>_<joint>``, legs L1..Lk and R1..Rk;
#: zero-based leg numbers, L0..., are taken as legs too)
LEG_JOINT_RE = re.compile(r'^([LR])(\d+)_\w+$')


class LegJointFilter:
    """Leaves joints that are not a leg's out of the joint states of a stream that names leg
    joints (:data:`LEG_JOINT_RE`): a gripper, a head or a tail beside the legs.

    Their motion had entered the gait-cycle detection and their joint power P_out (an outside
    review, another lab's bag with two gripper joints opening every 2 s beside 18 leg joints:
    the cycles read 0.80 and 1.60 s for one steady 0.80 s gait, P_out 7.00 W for the legs'
    5.11, no note). Their electrical power stays in the battery's P_in. A stream that never
    names a leg joint (another naming convention, which ``--joint-map`` translates) is passed
    whole.

    ``legs_present``: True or False when the caller knows whether the stream names leg joints
    (offline: from the bag's name sets, :meth:`names_have_legs`; the SLIP analysis needs
    contract hips, so its live node takes True); None (live energy) to decide from the
    stream: until a leg joint is named every sample passes whole, and the first one that
    names a leg joint settles it (from then on other joints are left out; the caller may
    purge what it took before). A stream is never taken as having no legs for good: a first
    version held the samples naming no leg joint and, after 100 of them, passed every later
    sample whole, grippers included (a review: a gripper publishing 2.5 s before the legs'
    driver gave live P_out 4.6 W for 1.03), and windows ending while samples were held read
    P_out 0 W. ``dropped`` holds the names left out (messages per name), ``samples_dropped``
    the messages that named no leg joint at all.
    """

    #: name sets remembered (a stream whose name sets change every message: cleared beyond)
    CACHE = 256

    def __init__(self, legs_present: bool | None = None) -> None:
        self.legs_present = legs_present
        self.dropped: dict[str, int] = {}
        self.samples_dropped = 0
        self._cache: dict[tuple[str, ...], tuple[list[int] | None, tuple[str, ...]]] = {}

    @staticmethod
    def names_have_legs(name_sets: Any) -> bool:
        """Whether any of ``name_sets`` (iterables of joint names) names a leg joint."""
        return any(LEG_JOINT_RE.match(str(n)) for names in name_sets for n in names)

    @staticmethod
    def is_leg(name: str) -> bool:
        return LEG_JOINT_RE.match(name) is not None

    def _split(self, names: tuple[str, ...]) -> tuple[list[int] | None, tuple[str, ...]]:
        """(indices of the leg joints, None when every name is one; the other names)."""
        hit = self._cache.get(names)
        if hit is None:
            keep = [k for k, n in enumerate(names) if LEG_JOINT_RE.match(n)]
            other = tuple(n for n in names if not LEG_JOINT_RE.match(n))
            hit = (None if len(keep) == len(names) else keep, other)
            if len(self._cache) >= self.CACHE:
                self._cache.clear()
            self._cache[names] = hit
        return hit

    def _drop(self, other: tuple[str, ...]) -> None:
        for n in other:
            self.dropped[n] = self.dropped.get(n, 0) + 1

    def apply(self, sample: JointStateSample) -> JointStateSample | None:
        """``sample`` itself or with its leg joints only; None when left out (it names no leg
        joint in a stream that names some)."""
        if self.legs_present is False:
            return sample
        names = tuple(sample.names)
        keep, other = self._split(names)
        if keep is None:          # leg joints only (or no names at all)
            if names and self.legs_present is None:
                self.legs_present = True
            return sample
        if not keep:              # no leg joint in it
            if self.legs_present is None:
                return sample     # undecided: as it is (another naming convention?)
            self._drop(other)
            self.samples_dropped += 1
            return None
        self.legs_present = True
        self._drop(other)

        def pick(a: np.ndarray) -> np.ndarray:
            return a[keep] if a.size == len(names) else a

        return JointStateSample(sample.t_s, tuple(names[k] for k in keep),
                                pick(sample.position), pick(sample.velocity),
                                pick(sample.effort), malformed=sample.malformed)

    def note(self, out_of: str = 'the gait cycles and P_out (their electrical power stays '
                                 'in P_in)') -> str:
        """What was left out (of ``out_of``), for the run's notes ('' when nothing)."""
        if not self.dropped:
            return ''
        names = sorted(self.dropped)
        shown = ', '.join(names[:6]) + (f' and {len(names) - 6} more' if len(names) > 6 else '')
        return (f'joint(s) {shown} are not leg joints (L1..Lk/R1..Rk_<joint>): left out of '
                f'{out_of}; rename leg joints with --joint-map if they are legs (a live '
                f'node reads the map from {JOINT_MAP_ENV}, JSON {{"recorded": "L1_coxa"}})')


__all__ += ['LEG_JOINT_RE', 'LegJointFilter']
