"""Another lab's robot bags through the offline energy analysis (``read_robot_bag``).

The bags are written here with rosbags' own ``Writer`` (as ``ros2 bag record`` would write them:
sqlite3 or mcap, optionally without message definitions and downgraded to a Foxy-era metadata
version 4-6 with QoS profiles as YAML strings), never with the project's ``BagWriter``:
4 and 8 legs with the contract joint names, a wave gait, joint states at 50 Hz and battery at
10 Hz with jittered stamps, and the drivers' quirks (current positive on discharge, NaN current,
zero header stamps, stamps a few ms out of order, duplicated messages).
"""

from __future__ import annotations

import numpy as np
import pytest

from hexapod_common.testbags import P0_W
from hexapod_common.testbags import downgrade_sqlite_bag as downgrade
from hexapod_common.testbags import write_foreign_robot_bag as write_outside_bag
from hexapod_energy.bag_io import read_robot_bag
from hexapod_energy.errors import BagContentError


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


def test_joints_split_over_two_messages_per_sample(tmp_path):
    whole = read_robot_bag(write_outside_bag(tmp_path / 'a') and tmp_path / 'a', mass_kg=2.0)
    write_outside_bag(tmp_path / 'b', split_joints=True)
    split = read_robot_bag(tmp_path / 'b', mass_kg=2.0)
    # P_out is the sum over joints: a driver publishing one message per servo bus must not
    # halve it (the mean over messages of each message's sum did)
    np.testing.assert_allclose(split.power_out_w, whole.power_out_w, rtol=1e-12)
    np.testing.assert_allclose(split.power_in_w, whole.power_in_w, rtol=1e-12)


def test_battery_stamped_on_another_clock_is_moved_onto_the_others(tmp_path):
    """Battery stamps 5000 s ahead of the recorder's receive times (a board on its own clock):
    moved onto the other topics' clock, noted (this bag used to be refused, 'different
    clocks'); the figures are those of the bag stamped on one clock."""
    write_outside_bag(tmp_path / 'ref')
    write_outside_bag(tmp_path / 'bag', battery_clock_s=5000.0)
    ref = read_robot_bag(tmp_path / 'ref', mass_kg=2.0)
    got = read_robot_bag(tmp_path / 'bag', mass_kg=2.0)
    assert got.windows == ref.windows
    assert got.power_in_w == pytest.approx(ref.power_in_w, rel=1e-6)
    assert any('/battery_state stamped on another clock' in n for n in got.extra['notes'])


def _bench_bag(path, *, nan_every: int) -> None:
    """A short bench bag written with rosbags' Writer; every ``nan_every``-th battery current
    is NaN (a power meter's glitch)."""
    import math

    from rosbags.rosbag2 import StoragePlugin, Writer

    from hexapod_common.testbags import foreign_typestore

    store = foreign_typestore()
    T = store.types

    def header(t):
        ns = int(round(t * 1e9))
        return T['std_msgs/msg/Header'](stamp=T['builtin_interfaces/msg/Time'](
            sec=ns // 10**9, nanosec=ns % 10**9), frame_id='')

    nan = math.nan
    msgs = [(100.0, '/bench/session', 'hexapod_interfaces/msg/BenchSession',
             T['hexapod_interfaces/msg/BenchSession'](
                 header=header(100.0), session_id='s0', state='walking', load_mass=0.1,
                 frequency=1.0, duty_factor=0.5, step_length=0.1, step_height=0.04))]
    for k, t in enumerate(np.arange(100.0, 102.0, 0.01)):
        cur = nan if k % nan_every == 0 else -0.5
        msgs.append((t, '/battery_state', 'sensor_msgs/msg/BatteryState',
                     T['sensor_msgs/msg/BatteryState'](
                         header=header(t), voltage=12.0, temperature=nan, current=cur,
                         charge=nan, capacity=nan, design_capacity=nan, percentage=nan,
                         power_supply_status=2, power_supply_health=0,
                         power_supply_technology=0, present=True,
                         cell_voltage=np.zeros(0, np.float32),
                         cell_temperature=np.zeros(0, np.float32), location='',
                         serial_number='')))
        msgs.append((t, '/bench/ground_force', 'geometry_msgs/msg/WrenchStamped',
                     T['geometry_msgs/msg/WrenchStamped'](
                         header=header(t), wrench=T['geometry_msgs/msg/Wrench'](
                             force=T['geometry_msgs/msg/Vector3'](x=0.0, y=0.0, z=2.0),
                             torque=T['geometry_msgs/msg/Vector3'](x=0.0, y=0.0, z=0.0)))))
        msgs.append((t, '/bench/leg_tip', 'geometry_msgs/msg/PointStamped',
                     T['geometry_msgs/msg/PointStamped'](
                         header=header(t), point=T['geometry_msgs/msg/Point'](
                             x=0.0, y=0.0, z=0.0))))
    with Writer(path, version=8, storage_plugin=StoragePlugin.SQLITE3) as w:
        conns = {}
        for i, (t, topic, typ, msg) in enumerate(sorted(msgs, key=lambda m: m[0])):
            if topic not in conns:
                conns[topic] = w.add_connection(topic, typ, typestore=store)
            w.write(conns[topic], int(t * 1e9) + i, store.serialize_cdr(msg, typ))


def test_bench_bag_battery_glitches_dropped_and_all_nan_refused(tmp_path):
    from hexapod_energy.bag_io import read_bench_bag

    _bench_bag(tmp_path / 'glitch', nan_every=10)
    data = read_bench_bag(tmp_path / 'glitch')
    assert data.battery_a.size == 180 and np.all(np.isfinite(data.battery_a))
    assert any('20 /battery_state' in n for n in data.notes)
    _bench_bag(tmp_path / 'nan', nan_every=1)
    with pytest.raises(BagContentError, match='voltage and current'):
        read_bench_bag(tmp_path / 'nan')
