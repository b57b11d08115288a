"""Another lab's robot bags through the offline energy analysis (``read_robot_bag``).

The bags are written here with rosbags' own ``Writer`` (as ``ros2 bag record`` would write them:
sqlite3 or mcap, optionally without message definitions and downgraded to a Foxy-era metadata
version 4-6 with QoS profiles as YAML strings), never with the project's ``BagWriter``:
4 and 8 legs with the contract joint names, a wave gait, joint states at 50 Hz and battery at
10 Hz with jittered stamps, and the drivers' quirks (current positive on discharge, NaN current,
zero header stamps, stamps a few ms out of order, duplicated messages).
"""

from __future__ import annotations

import math
import sqlite3
from io import StringIO
from pathlib import Path

import numpy as np
import pytest
from rosbags.rosbag2 import StoragePlugin, Writer
from rosbags.typesys import Stores, get_types_from_msg, get_typestore
from ruamel.yaml import YAML

from hexapod_common.bags import find_msg_dir
from hexapod_energy.bag_io import read_robot_bag
from hexapod_energy.errors import BagContentError

STORE = get_typestore(Stores.ROS2_JAZZY)
STORE.register(get_types_from_msg((find_msg_dir() / 'GaitPhase.msg').read_text(),
                                  'hexapod_interfaces/msg/GaitPhase'))
T = STORE.types
P0_W, P_AMP_W, VOLT_V, PERIOD_S = 9.0, 1.5, 11.5, 2.0
BAG_T0_S = 1_750_000_000.0
NO_HASH = 'RIHS01_' + '0' * 64


def _header(t_s: float):
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


def write_outside_bag(path: Path, *, legs: int = 4, duration_s: float = 12.0,
                      sign: float = -1.0, zero_stamps: bool = False, nan_current: bool = False,
                      swap_every: int = 0, duplicate_every: int = 0, storage: str = 'sqlite3',
                      msgdef: bool = True, unknown_topic: bool = False, seed: int = 0) -> dict:
    """A robot bag as another lab records it; returns the truth."""
    rng = np.random.default_rng(seed)
    names, offsets = _wave(legs)
    duty = 1 - 1 / legs
    joints = [f'{leg}_{j}' for leg in names for j in ('coxa', 'femur', 'tibia')]
    msgs: list[tuple[float, str, str, object]] = []
    pout = []
    for t in np.arange(0.0, duration_s, 0.02):
        ts = t + rng.uniform(-0.003, 0.003)
        eff, vel = _joint_power_w(ts, len(joints))
        pout.append((ts, float(np.sum(np.clip(eff * vel, 0, None)))))
        msgs.append((ts, '/joint_states', 'sensor_msgs/msg/JointState',
                     T['sensor_msgs/msg/JointState'](
                         header=_header(0.0 if zero_stamps else ts), name=joints,
                         position=0.1 * vel, velocity=vel, effort=eff)))
        phase = (t / PERIOD_S) % 1.0
        stance = np.array([((phase - o) % 1.0) < duty for o in offsets], bool)
        msgs.append((ts + 5e-4, '/gait/phase', 'hexapod_interfaces/msg/GaitPhase',
                     T['hexapod_interfaces/msg/GaitPhase'](
                         header=_header(0.0 if zero_stamps else ts), gait='wave',
                         period=PERIOD_S, duty_factor=duty, step_length=0.06, step_height=0.03,
                         sweep_angle=0.0, leg_offset=0.0, cycle_phase=phase, leg_names=names,
                         phase_offsets=np.array(offsets), in_stance=stance,
                         supporting_legs=int(stance.sum()))))
    for t in np.arange(0.0, duration_s, 0.1):
        ts = t + rng.uniform(-0.003, 0.003)
        power = P0_W + P_AMP_W * math.sin(2 * math.pi * ts / PERIOD_S)
        current = math.nan if nan_current else math.copysign(power / VOLT_V, sign)
        nan = math.nan
        msgs.append((ts + 1e-3, '/battery_state', 'sensor_msgs/msg/BatteryState',
                     T['sensor_msgs/msg/BatteryState'](
                         header=_header(0.0 if zero_stamps else ts), voltage=VOLT_V,
                         temperature=25.0, current=current, charge=nan, capacity=nan,
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


def downgrade(path: Path, version: int) -> None:
    """Turn a rosbags sqlite3 bag into what a Foxy/Galactic ``ros2 bag record`` leaves:
    metadata ``version`` 4-6, no type hashes, QoS profiles as a YAML string, and a database
    without the schema/metadata/message_definitions tables."""
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


def _expected_pout_w(truth: dict, t0: float, t1: float) -> float:
    t, p = truth['pout'][:, 0], truth['pout'][:, 1]
    return float(np.mean(p[(t >= t0) & (t < t1)]))


def _check(run, truth: dict, sign: float = -1.0) -> None:
    assert run.windows >= 4
    assert run.current_sign == sign
    # whole wave cycles of a sinusoid around P0: the mean is P0 up to the 10 Hz trapezoid
    np.testing.assert_allclose(run.power_in_w, P0_W, rtol=2e-3)
    assert run.gait.gait == 'wave'
    assert len(run.gait.leg_names) * 3 == len(truth['joints'])
    # P_out: mean positive joint power over whole windows of 2 s, starting on cycle wraps
    np.testing.assert_allclose(run.power_out_w, float(np.mean(truth['pout'][:, 1])), rtol=0.03)


@pytest.mark.parametrize('legs', [4, 8])
@pytest.mark.parametrize('storage,version', [('sqlite3', 4), ('sqlite3', 5), ('sqlite3', 6),
                                             ('sqlite3', 8), ('mcap', 8)])
def test_wave_robot_bag_other_lab(tmp_path, legs, storage, version):
    bag = tmp_path / 'bag'
    truth = write_outside_bag(bag, legs=legs, storage=storage, msgdef=version >= 8)
    if version < 8:
        downgrade(bag, version)
    _check(read_robot_bag(bag, mass_kg=2.0), truth)


def test_positive_discharge_current_auto_detected(tmp_path):
    truth = write_outside_bag(tmp_path / 'bag', sign=+1.0)
    _check(read_robot_bag(tmp_path / 'bag', mass_kg=2.0, current_sign='auto'), truth, sign=1.0)


def test_nan_current_refused_with_one_clear_error(tmp_path):
    write_outside_bag(tmp_path / 'bag', nan_current=True)
    with pytest.raises(BagContentError) as err:
        read_robot_bag(tmp_path / 'bag', mass_kg=2.0)
    text = str(err.value)
    assert '\n' not in text
    assert '/battery_state' in text and 'current' in text and 'nan' in text


def test_zero_header_stamps_fall_back_to_receive_time(tmp_path):
    truth = write_outside_bag(tmp_path / 'bag', zero_stamps=True)
    run = read_robot_bag(tmp_path / 'bag', mass_kg=2.0)
    # receive times are the stamps + 0.5-1 ms and a bag offset: powers unchanged
    np.testing.assert_allclose(run.power_in_w, P0_W, rtol=3e-3)
    np.testing.assert_allclose(run.power_out_w, float(np.mean(truth['pout'][:, 1])), rtol=0.03)
    assert any('zero header stamp' in n and '/battery_state' in n for n in run.extra['notes'])


def test_out_of_order_and_duplicated_messages_change_nothing(tmp_path):
    clean = read_robot_bag(write_outside_bag(tmp_path / 'a') and tmp_path / 'a', mass_kg=2.0)
    write_outside_bag(tmp_path / 'b', swap_every=5, duplicate_every=3)
    messy = read_robot_bag(tmp_path / 'b', mass_kg=2.0)
    assert messy.windows == clean.windows
    np.testing.assert_allclose(messy.power_in_w, clean.power_in_w, rtol=1e-12)
    np.testing.assert_allclose(messy.power_out_w, clean.power_out_w, rtol=1e-12)
    assert any('duplicated' in n for n in messy.extra['notes'])


def test_replay_source_skips_unknown_type_once_in_foxy_bag(tmp_path):
    from hexapod_common.replay import ReplaySource

    bag = tmp_path / 'bag'
    write_outside_bag(bag, msgdef=False, unknown_topic=True)
    downgrade(bag, 4)
    warnings: list[str] = []
    with ReplaySource(str(bag), warn=warnings.append) as source:
        assert set(source.types) == {'/joint_states', '/gait/phase', '/battery_state'}
        counts: dict[str, int] = {}
        for m in source.messages():
            counts[m.topic] = counts.get(m.topic, 0) + 1
    assert counts == {'/joint_states': 600, '/gait/phase': 600, '/battery_state': 120}
    assert len(warnings) == 1 and '/lab/thing' in warnings[0]
