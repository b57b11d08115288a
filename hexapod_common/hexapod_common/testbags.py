"""Generated bags for tests and benchmarks (no committed data)."""

from __future__ import annotations

import math
import sqlite3
from collections.abc import Collection
from functools import lru_cache
from io import StringIO
from pathlib import Path
from typing import Any

import numpy as np
from rosbags.rosbag2 import StoragePlugin, Writer
from rosbags.typesys import Stores, get_types_from_msg, get_typestore
from ruamel.yaml import YAML

from hexapod_common.bags import BagWriter, find_msg_dir, new_msg, stamp

__all__ = ['MIXED_TYPES', 'P0_W', 'PERIOD_S', 'RAW_COUNT_RECEIVER', 'downgrade_sqlite_bag',
           'foreign_typestore', 'lab_bench_truth', 'write_foreign_robot_bag',
           'write_lab_bench_bag', 'write_mixed_bag',
           'restamp_topic', 'rewrite_bag', 'write_two_battery_robot_bag']

LEGS = ('L1', 'L2', 'L3', 'R1', 'R2', 'R3')
JOINTS = [f'{leg}_{j}' for leg in LEGS for j in ('coxa', 'femur', 'tibia')]


#: topics and types of :func:`write_mixed_bag`
MIXED_TYPES = {'/joint_states': 'sensor_msgs/msg/JointState',
               '/battery_state': 'sensor_msgs/msg/BatteryState',
               '/gait/phase': 'hexapod_interfaces/msg/GaitPhase'}

#: A receiver for replay tests and benchmarks, run as ``python -c RAW_COUNT_RECEIVER NS TOTAL
#: DEPTH TYPES_JSON`` in its own process: reliable subscriptions (KEEP_ALL when DEPTH is 0) to
#: NS + each topic, prints ``ready``, counts raw messages until TOTAL arrive (or 3 s pass
#: without one after the first, or 300 s in all) and prints the counts per topic as JSON.
RAW_COUNT_RECEIVER = """
import json, sys, time
import rclpy
from rclpy.executors import SingleThreadedExecutor
from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy
from hexapod_common.ros_types import ros_message_class
ns, total, depth = sys.argv[1], int(sys.argv[2]), int(sys.argv[3])
types = json.loads(sys.argv[4])
rclpy.init()
node = rclpy.create_node('raw_count_receiver')
qos = QoSProfile(history=HistoryPolicy.KEEP_ALL, reliability=ReliabilityPolicy.RELIABLE) \\
    if depth == 0 else QoSProfile(depth=depth, reliability=ReliabilityPolicy.RELIABLE)
counts = dict.fromkeys(types, 0)
last = [None]
for topic, msgtype in types.items():
    def cb(_m, _t=topic):
        counts[_t] += 1
        last[0] = time.monotonic()
    node.create_subscription(ros_message_class(msgtype), ns + topic, cb, qos, raw=True)
ex = SingleThreadedExecutor()
ex.add_node(node)
print('ready', flush=True)
deadline = time.monotonic() + 300
while sum(counts.values()) < total and time.monotonic() < deadline:
    ex.spin_once(timeout_sec=0.05)
    if last[0] is not None and time.monotonic() - last[0] > 3.0:
        break  # the sender is done (a lossy sender never reaches the total)
print(json.dumps(counts), flush=True)
"""


def write_mixed_bag(path: str | Path, n_messages: int, *, storage: str = 'mcap',
                    rate_hz: float = 100.0, t0_ns: int = 1_700_000_000_000_000_000
                    ) -> dict[str, int]:
    """A bag of ``n_messages`` JointState (18 joints), BatteryState and GaitPhase, in turn.

    Returns the count per topic.
    """
    topics = ('/joint_states', '/battery_state', '/gait/phase')
    counts = dict.fromkeys(topics, 0)
    dt_ns = int(1e9 / rate_hz)
    with BagWriter(path, storage=storage) as writer:
        for k in range(n_messages):
            tick, which = divmod(k, 3)
            t_ns = t0_ns + tick * dt_ns + which * 1000
            t = tick / rate_hz
            header = stamp(t_ns)
            if which == 0:
                q = np.sin(t + np.arange(18))
                msg = new_msg('sensor_msgs/msg/JointState', header=header, name=JOINTS,
                              position=q, velocity=np.cos(t + np.arange(18)), effort=0.1 * q)
                writer.write(topics[0], 'sensor_msgs/msg/JointState', msg, t_ns)
            elif which == 1:
                msg = new_msg('sensor_msgs/msg/BatteryState', header=header, voltage=11.9,
                              current=-2.0 - 0.5 * math.sin(t), present=True)
                writer.write(topics[1], 'sensor_msgs/msg/BatteryState', msg, t_ns)
            else:
                phase = t % 1.0
                in_stance = [((phase - o) % 1.0) < 0.5 for o in (0, .5, 0, .5, 0, .5)]
                msg = new_msg('hexapod_interfaces/msg/GaitPhase', header=header, gait='tripod',
                              period=1.0, duty_factor=0.5, step_length=0.1, step_height=0.04,
                              cycle_phase=phase, leg_names=list(LEGS),
                              phase_offsets=[0, .5, 0, .5, 0, .5], in_stance=in_stance,
                              supporting_legs=sum(in_stance))
                writer.write(topics[2], 'hexapod_interfaces/msg/GaitPhase', msg, t_ns)
            counts[topics[which]] += 1
    return counts


# -- bags as other labs record them ------------------------------------------------------

@lru_cache(maxsize=1)
def foreign_typestore() -> Any:
    """Another lab's typestore: plain Jazzy plus the GaitPhase and BenchSession it publishes."""
    store = get_typestore(Stores.ROS2_JAZZY)
    for name in ('GaitPhase', 'BenchSession'):
        store.register(get_types_from_msg((find_msg_dir() / f'{name}.msg').read_text(),
                                          f'hexapod_interfaces/msg/{name}'))
    return store


#: truth of :func:`write_foreign_robot_bag`: mean battery power [W], its swing [W], battery
#: voltage [V], gait period [s]
P0_W, P_AMP_W, VOLT_V, PERIOD_S = 9.0, 1.5, 11.5, 2.0
ODOM_SPEED_MPS = 0.12
BAG_T0_S = 1_750_000_000.0
NO_HASH = 'RIHS01_' + '0' * 64


def _header(t_s: float) -> Any:
    T = foreign_typestore().types
    ns = int(round(t_s * 1e9))
    return T['std_msgs/msg/Header'](
        stamp=T['builtin_interfaces/msg/Time'](sec=ns // 10**9, nanosec=ns % 10**9), frame_id='')


def _wave(legs: int) -> tuple[list[str], list[float]]:
    k = legs // 2
    names = [f'L{i + 1}' for i in range(k)] + [f'R{i + 1}' for i in range(k)]
    offsets = [((k - 1 - i) + side * k) / legs for side in range(2) for i in range(k)]
    return names, offsets


def _joint_power_w(t_s: float, n_joints: int) -> tuple[np.ndarray, np.ndarray]:
    """Efforts [N m] and velocities [rad/s] of one joint sample (positive power varies)."""
    phase = 2 * np.pi * (t_s / PERIOD_S + np.arange(n_joints) / 7)
    return 0.3 + 0.1 * np.sin(phase), 0.6 * np.cos(phase)


def write_foreign_robot_bag(path: str | Path, *, legs: int = 4, duration_s: float = 12.0,
                      sign: float = -1.0, zero_stamps: bool = False, nan_current: bool = False,
                      swap_every: int = 0, duplicate_every: int = 0, storage: str = 'sqlite3',
                      msgdef: bool = True, unknown_topic: bool = False, seed: int = 0,
                      split_joints: bool = False, battery_clock_s: float = 0.0,
                      idle_offset_samples: int = 0, milli: bool = False,
                      nan_effort_joints: tuple[int, ...] = (), nan_velocity_every: int = 0,
                      gap_s: tuple[float, float] | None = None, battery: bool = True,
                      odom_twist_only: bool = False, step_length_m: float = 0.06
                      ) -> dict[str, Any]:
    """A robot bag as another lab's ``ros2 bag record`` writes it: rosbags' own ``Writer``
    (not :class:`~hexapod_common.bags.BagWriter`), sqlite3 or mcap, optionally without message
    definitions; a wave gait on ``legs`` legs with the contract joint names, joint states and
    ``/gait/phase`` at 50 Hz and ``/battery_state`` at 10 Hz with +-3 ms jittered stamps, the
    battery power ``P0_W + P_AMP_W sin(2 pi t / PERIOD_S)``.

    Driver quirks on request: ``sign`` +1 (current positive on discharge), ``zero_stamps``
    (header stamps left 0), ``nan_current``, ``swap_every`` (receive order swapped every n
    messages), ``duplicate_every`` (every n-th message recorded twice), ``unknown_topic`` (a
    ``lab_msgs/msg/Thing`` topic no typestore knows), ``split_joints`` (each sample's joints
    in two JointState messages, one per side, as drivers with one servo bus per side publish
    them), ``battery_clock_s`` (battery stamps on another clock, this far ahead),
    ``idle_offset_samples`` (the first n battery samples read a +20 mA sensor offset, the
    servos not yet drawing), ``milli`` (voltage in mV, current in mA), ``nan_effort_joints``
    (joint indices whose effort is NaN: no effort interface), ``nan_velocity_every`` (every
    n-th joint sample has one velocity NaN), ``gap_s`` (no message of any topic in that span),
    ``battery`` False (the ``/battery_state`` connection without messages),
    ``odom_twist_only`` (``/odom`` with the body speed ``ODOM_SPEED_MPS`` in its twist, the
    pose left at 0), ``step_length_m`` on ``/gait/phase`` (0: a clock-driven schedule that
    does not know the speed). Returns ``{'joints': names, 'pout': (n, 2) array of (stamp [s],
    positive joint power [W] of the joints with finite values)}``.
    """
    STORE = foreign_typestore()
    T = STORE.types
    rng = np.random.default_rng(seed)
    names, offsets = _wave(legs)
    duty = 1 - 1 / legs
    joints = [f'{leg}_{j}' for leg in names for j in ('coxa', 'femur', 'tibia')]
    msgs: list[tuple[float, str, str, object]] = []
    pout = []
    def gone(t: float) -> bool:
        return gap_s is not None and gap_s[0] <= t < gap_s[1]

    for k, t in enumerate(np.arange(0.0, duration_s, 0.02)):
        ts = t + rng.uniform(-0.003, 0.003)
        if gone(ts):
            continue
        eff, vel = _joint_power_w(ts, len(joints))
        eff[list(nan_effort_joints)] = math.nan
        if nan_velocity_every and k % nan_velocity_every == 0:
            vel[1] = math.nan
        jp = eff * vel
        pout.append((ts, float(np.sum(np.clip(jp[np.isfinite(jp)], 0, None)))))
        if odom_twist_only:
            msgs.append((ts + 2e-4, '/odom', 'nav_msgs/msg/Odometry', T['nav_msgs/msg/Odometry'](
                header=_header(ts), child_frame_id='base_link',
                pose=T['geometry_msgs/msg/PoseWithCovariance'](
                    pose=T['geometry_msgs/msg/Pose'](
                        position=T['geometry_msgs/msg/Point'](x=0.0, y=0.0, z=0.0),
                        orientation=T['geometry_msgs/msg/Quaternion'](x=0.0, y=0.0, z=0.0,
                                                                      w=1.0)),
                    covariance=np.zeros(36)),
                twist=T['geometry_msgs/msg/TwistWithCovariance'](
                    twist=T['geometry_msgs/msg/Twist'](
                        linear=T['geometry_msgs/msg/Vector3'](x=ODOM_SPEED_MPS, y=0.0, z=0.0),
                        angular=T['geometry_msgs/msg/Vector3'](x=0.0, y=0.0, z=0.0)),
                    covariance=np.zeros(36)))))
        parts = [np.arange(len(joints))]
        if split_joints:  # one message per side (one servo bus each), same stamp
            half = len(joints) // 2
            parts = [np.arange(half), np.arange(half, len(joints))]
        for idx in parts:
            msgs.append((ts, '/joint_states', 'sensor_msgs/msg/JointState',
                         T['sensor_msgs/msg/JointState'](
                             header=_header(0.0 if zero_stamps else ts),
                             name=[joints[i] for i in idx], position=0.1 * vel[idx],
                             velocity=vel[idx], effort=eff[idx])))
        phase = (t / PERIOD_S) % 1.0
        stance = np.array([((phase - o) % 1.0) < duty for o in offsets], bool)
        msgs.append((ts + 5e-4, '/gait/phase', 'hexapod_interfaces/msg/GaitPhase',
                     T['hexapod_interfaces/msg/GaitPhase'](
                         header=_header(0.0 if zero_stamps else ts), gait='wave',
                         period=PERIOD_S, duty_factor=duty, step_length=step_length_m,
                         step_height=0.03,
                         sweep_angle=0.0, leg_offset=0.0, cycle_phase=phase, leg_names=names,
                         phase_offsets=np.array(offsets), in_stance=stance,
                         supporting_legs=int(stance.sum()))))
    for k, t in enumerate(np.arange(0.0, duration_s, 0.1)):
        ts = t + rng.uniform(-0.003, 0.003)
        if gone(ts):
            continue
        power = P0_W + P_AMP_W * math.sin(2 * math.pi * ts / PERIOD_S)
        current = math.nan if nan_current else math.copysign(power / VOLT_V, sign)
        if k < idle_offset_samples:
            current = -sign * 0.02
        nan = math.nan
        unit = 1e3 if milli else 1.0
        msgs.append((ts + 1e-3, '/battery_state', 'sensor_msgs/msg/BatteryState',
                     T['sensor_msgs/msg/BatteryState'](
                         header=_header(0.0 if zero_stamps else ts + battery_clock_s),
                         voltage=VOLT_V * unit,
                         temperature=25.0, current=current * unit, charge=nan, capacity=nan,
                         design_capacity=nan, percentage=nan, power_supply_status=2,
                         power_supply_health=0, power_supply_technology=0, present=True,
                         cell_voltage=np.zeros(0, np.float32),
                         cell_temperature=np.zeros(0, np.float32), location='',
                         serial_number='')))
    if unknown_topic:
        msgs += [(t, '/lab/thing', 'lab_msgs/msg/Thing', None)
                 for t in np.arange(0.0, duration_s, 0.5)]
    msgs.sort(key=lambda x: x[0])
    if swap_every:  # receive order differs from stamp order by a few ms
        for i in range(0, len(msgs) - 1, swap_every):
            msgs[i], msgs[i + 1] = msgs[i + 1], msgs[i]
    if duplicate_every:
        msgs = [m for i, x in enumerate(msgs)
                for m in ((x, x) if i % duplicate_every == 0 else (x,))]
    if not battery:  # the connection stays (``ros2 bag record -a`` of a silent topic)
        silent = [m for m in msgs if m[1] == '/battery_state'][:1]
        msgs = [m for m in msgs if m[1] != '/battery_state']
    plugin = StoragePlugin.SQLITE3 if storage == 'sqlite3' else StoragePlugin.MCAP
    with Writer(path, version=8, storage_plugin=plugin) as w:
        conns = {}
        for _, topic, typ, _ in msgs:
            if topic in conns:
                continue
            if typ == 'lab_msgs/msg/Thing':
                conns[topic] = w.add_connection(topic, typ, msgdef='' if not msgdef
                                                else 'float64 x', rihs01=NO_HASH)
            elif msgdef:
                conns[topic] = w.add_connection(topic, typ, typestore=STORE)
            else:
                conns[topic] = w.add_connection(topic, typ, msgdef='', rihs01=NO_HASH)
        if not battery:
            for _, topic, typ, _ in silent:
                conns[topic] = w.add_connection(topic, typ, typestore=STORE)
        for i, (ts, topic, typ, msg) in enumerate(msgs):
            data = b'\x00\x01\x00\x00' + np.float64(1.0).tobytes() if msg is None else \
                STORE.serialize_cdr(msg, typ)
            w.write(conns[topic], int((BAG_T0_S + max(ts, 0.0) + 1e-9 * i) * 1e9), data)
    pout_arr = np.array(pout)
    return {'joints': joints, 'pout': pout_arr}


QOS_YAML = (
    '- history: 3\n  depth: 0\n  reliability: 1\n  durability: 2\n  deadline:\n'
    '    sec: 2147483647\n    nsec: 4294967295\n  lifespan:\n    sec: 2147483647\n'
    '    nsec: 4294967295\n  liveliness: 1\n  liveliness_lease_duration:\n'
    '    sec: 2147483647\n    nsec: 4294967295\n  avoid_ros_namespace_conventions: false')


def downgrade_sqlite_bag(path: str | Path, version: int) -> None:
    """Turn a rosbags sqlite3 bag into what a Foxy/Galactic ``ros2 bag record`` leaves:
    metadata ``version`` 4-6, no type hashes, QoS profiles as a YAML string, and a database
    without the schema/metadata/message_definitions tables."""
    path = Path(path)
    yaml = YAML(typ='safe')
    meta = yaml.load((path / 'metadata.yaml').read_text())
    info = meta['rosbag2_bagfile_information']
    info['version'] = version
    info.pop('ros_distro', None)
    if version < 6:
        info.pop('custom_data', None)
    if version < 5:
        info.pop('files', None)
    for topic in info['topics_with_message_count']:
        topic['topic_metadata'].pop('type_description_hash', None)
        topic['topic_metadata']['offered_qos_profiles'] = QOS_YAML
    out = StringIO()
    yaml.default_flow_style = False
    yaml.dump(meta, out)
    (path / 'metadata.yaml').write_text(out.getvalue())
    for db in path.glob('*.db3'):
        con = sqlite3.connect(db)
        con.executescript('''
          DROP TABLE IF EXISTS schema; DROP TABLE IF EXISTS metadata;
          DROP TABLE IF EXISTS message_definitions;
          CREATE TABLE topics2(id INTEGER PRIMARY KEY, name TEXT NOT NULL, type TEXT NOT NULL,
            serialization_format TEXT NOT NULL, offered_qos_profiles TEXT NOT NULL);
          INSERT INTO topics2
            SELECT id, name, type, serialization_format, offered_qos_profiles FROM topics;
          DROP TABLE topics; ALTER TABLE topics2 RENAME TO topics;''')
        con.execute('UPDATE topics SET offered_qos_profiles = ?', (QOS_YAML,))
        con.commit()
        con.execute('PRAGMA journal_mode=DELETE')
        con.close()


def write_two_battery_robot_bag(path: str | Path, *, servo_w: float = 30.0,
                                logic_w: float = 5.0, period_s: float = 0.5,
                                duration_s: float = 12.0, logic_hz: float = 10.0,
                                logic_frame: str = 'logic',
                                logic_stops_s: float | None = None) -> dict[str, float]:
    """A tripod robot bag whose ``/battery_state`` carries two packs (ROS current sign): the
    servo pack (frame_id ``servo``, 12 V, 50 Hz, ``servo_w`` plus a 10 % ripple at the gait
    period) and a logic pack (``logic_frame``, 7.4 V, ``logic_hz``, ``logic_w`` steady; silent
    after ``logic_stops_s``). Returns the mean powers of each pack."""
    with BagWriter(path) as w:
        for k, t in enumerate(np.arange(0.0, duration_s, 0.01)):
            ns = int(round(t * 1e9))
            if k % 2 == 0:
                p = servo_w * (1.0 + 0.1 * math.sin(2 * math.pi * t / period_s))
                w.write('/battery_state', 'sensor_msgs/msg/BatteryState', new_msg(
                    'sensor_msgs/msg/BatteryState', header=stamp(ns, 'servo'), voltage=12.0,
                    current=-p / 12.0), ns)
            if k % int(round(100 / logic_hz)) == 0 and (logic_stops_s is None
                                                        or t < logic_stops_s):
                lns = ns + 3_000_000  # its own clock phase
                w.write('/battery_state', 'sensor_msgs/msg/BatteryState', new_msg(
                    'sensor_msgs/msg/BatteryState', header=stamp(lns, logic_frame),
                    voltage=7.4, current=-logic_w / 7.4), lns)
            w.write('/gait/phase', 'hexapod_interfaces/msg/GaitPhase', new_msg(
                'hexapod_interfaces/msg/GaitPhase', header=stamp(ns), gait='tripod',
                period=period_s, duty_factor=0.5, step_length=0.1, step_height=0.04,
                cycle_phase=(t / period_s) % 1.0, leg_names=list(LEGS),
                phase_offsets=[0.0, 0.5, 0.0, 0.5, 0.0, 0.5],
                in_stance=[((t / period_s) % 1.0 - o) % 1.0 < 0.5
                           for o in (0.0, 0.5, 0.0, 0.5, 0.0, 0.5)],
                supporting_legs=3), ns)
    return {'servo_w': servo_w, 'logic_w': logic_w}


def rewrite_bag(src: str | Path, dst: str | Path, edit: Any, *,
                topics: Collection[str] | None = None) -> Path:
    """Copy a bag, calling ``edit(topic, msg)`` on every deserialised message (to change it in
    place; receive times kept); a message for which ``edit`` returns False is dropped.

    ``topics``: the only topics ``edit`` changes or drops; the other topics' messages are
    copied as stored instead of decoded and encoded again (the same bytes for bags of
    little-endian CDR as rosbags and the simulators write; 4-5 times faster for a bench bag
    of which one topic is edited)."""
    from hexapod_common.bags import iter_messages, open_reader

    with open_reader(src) as reader, BagWriter(dst) as w:
        for m in iter_messages(reader):
            if topics is not None and m.topic not in topics:
                w.write(m.topic, m.msgtype, m.data, m.stamp_ns)
                continue
            msg = reader.deserialize(m.data, m.msgtype)
            if edit(m.topic, msg) is False:
                continue
            w.write(m.topic, m.msgtype, msg, m.stamp_ns)
    return Path(dst)


def restamp_topic(src: str | Path, dst: str | Path, topic: str, dt_s: float) -> Path:
    """Copy a bag, moving ``topic``'s header stamps by ``dt_s`` (receive times kept): the topic
    as a driver stamping on another clock would have recorded it."""
    def edit(name: str, msg: Any) -> None:
        if name == topic:
            ns = msg.header.stamp.sec * 10**9 + msg.header.stamp.nanosec + int(dt_s * 1e9)
            msg.header.stamp.sec, msg.header.stamp.nanosec = ns // 10**9, ns % 10**9

    return rewrite_bag(src, dst, edit)


def lab_bench_truth(load_kg: float, freq_hz: float) -> dict[str, float]:
    """The exact phase powers [W] of :func:`write_lab_bench_bag` (after an outside review's
    generator): basal ``2 + L``, stance ``2 + L + 1.5 f + 3 L f``, swing
    ``2 + 0.2 L + 3 f + f^2``."""
    big_l, f = load_kg, freq_hz
    return {'basal': 2.0 + big_l, 'stance': 2.0 + big_l + 1.5 * f + 3.0 * big_l * f,
            'swing': 2.0 + 0.2 * big_l + 3.0 * f + f * f}


def write_lab_bench_bag(path: str | Path, sessions: list[tuple[float, float]], *,
                        heat_s: float = 1.0, walk_s: float = 4.0, cool_s: float = 1.5,
                        rate_hz: float = 100.0, t0_s: float = 1_700_000_000.0,
                        with_session_topic: bool = True, drop_msgs: tuple[int, ...] = (),
                        load_scale: float = 1.0, pause: tuple[float, float] | None = None
                        ) -> list[dict[str, Any]]:
    """A single-leg bench bag as a lab without this project's gait node records it:
    ``/battery_state`` (12 V, discharge negative), ``/bench/ground_force`` and
    ``/bench/leg_tip`` at ``rate_hz``, and ``/bench/session`` ('heating', 'walking',
    'cooling' per session; the indices in ``drop_msgs`` are not written, as lost messages);
    no ``/gait/phase``. ``sessions``: (load kg, step frequency Hz), each standing
    ``heat_s``, walking ``walk_s`` (stance first, duty factor 0.5) and standing ``cool_s``;
    the power is constant within each phase (:func:`lab_bench_truth`), the tip rises
    0.04 sin in swing, the force is the load's weight in stance. ``load_scale`` multiplies
    the written loads (1000: grams). ``pause`` (start, length) [s from the walk's start]:
    the leg stands that long inside every walk. Returns the sessions (id, load, frequency,
    walk start and end stamps [s])."""
    plan: list[dict[str, Any]] = []
    t = t0_s
    for k, (load, freq) in enumerate(sessions):
        w0 = t + heat_s
        plan.append({'id': f's{k:03d}_L{load:g}_f{freq:g}', 'load': load, 'freq': freq,
                     'h0': t, 'w0': w0, 'w1': w0 + walk_s, 'c1': w0 + walk_s + cool_s})
        t = plan[-1]['c1']

    def state(tt: float, s: dict[str, Any]) -> tuple[float, float, float]:
        load, f = s['load'], s['freq']
        truth = lab_bench_truth(load, f)
        dt = tt - s['w0']
        paused = pause is not None and pause[0] <= dt < pause[0] + pause[1]
        if f <= 0 or not (s['w0'] <= tt < s['w1']) or paused:
            return truth['basal'], 9.81 * (load + 0.2), 0.0
        if pause is not None and dt >= pause[0] + pause[1]:
            dt -= pause[1]
        ph = (dt * f) % 1.0
        if ph < 0.5:
            return truth['stance'], 9.81 * (load + 0.2), 0.0
        return truth['swing'], 0.0, 0.04 * math.sin(math.pi * (ph - 0.5) / 0.5)

    msgs = [(s[key], s, st) for s in plan
            for key, st in (('h0', 'heating'), ('w0', 'walking'), ('w1', 'cooling'))]
    msgs = [m for i, m in enumerate(msgs) if i not in drop_msgs] if with_session_topic else []
    times = np.arange(plan[0]['h0'], plan[-1]['c1'] - 1e-9, 1.0 / rate_hz)
    Path(path).parent.mkdir(parents=True, exist_ok=True)
    with BagWriter(path) as w:
        k = 0
        for tt in times:
            while k < len(msgs) and msgs[k][0] <= tt:
                ts, s, st = msgs[k]
                ns = int(round(ts * 1e9))
                w.write('/bench/session', 'hexapod_interfaces/msg/BenchSession',
                        new_msg('hexapod_interfaces/msg/BenchSession', header=stamp(ns),
                                session_id=s['id'], state=st, load_mass=s['load'] * load_scale,
                                frequency=s['freq'], duty_factor=0.5, step_length=0.1,
                                step_height=0.04), ns)
                k += 1
            s = next(x for x in plan if x['h0'] <= tt < x['c1'] + 1e-9)
            p, fz, z = state(float(tt), s)
            ns = int(round(tt * 1e9))
            w.write('/battery_state', 'sensor_msgs/msg/BatteryState',
                    new_msg('sensor_msgs/msg/BatteryState', header=stamp(ns, 'supply'),
                            voltage=12.0, current=-p / 12.0, power_supply_status=2,
                            present=True), ns)
            wrench = new_msg('geometry_msgs/msg/WrenchStamped', header=stamp(ns, 'cell'))
            wrench.wrench.force.z = fz
            w.write('/bench/ground_force', 'geometry_msgs/msg/WrenchStamped', wrench, ns)
            point = new_msg('geometry_msgs/msg/PointStamped', header=stamp(ns, 'mocap'))
            point.point.z = z
            w.write('/bench/leg_tip', 'geometry_msgs/msg/PointStamped', point, ns)
    return [{'session_id': s['id'], 'load_kg': s['load'], 'frequency_hz': s['freq'],
             'walk_start_s': s['w0'], 'walk_end_s': s['w1']} for s in plan]
