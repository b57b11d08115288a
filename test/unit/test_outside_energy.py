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


def test_battery_stamped_on_another_clock_is_refused_naming_it(tmp_path):
    write_outside_bag(tmp_path / 'bag', battery_clock_s=5000.0)
    with pytest.raises(BagContentError, match='different clocks'):
        read_robot_bag(tmp_path / 'bag', mass_kg=2.0)
